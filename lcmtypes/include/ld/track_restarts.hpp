// Telling from the tracked lists alone when the tracker started again.
//
// A tracker numbers its tracks from 1 and never reuses an id while it runs,
// but one that restarts (a crash, ld-run's restart, a new `ld-tracker`)
// numbers them from 1 again: from then on an id names another landmark, and a
// reader that remembers anything per id (payloads, a report's tracks) must
// start again too. The lists carry no run number; what shows the restart is a
// track's `age` (frames since the tracker created it). The tracker ages every
// track once for each frame it processes, and publishes one list per frame,
// so between two lists that name the same track its age grows by at least
// the number of lists in between. An id whose age grew by less (by more than
// kAgeSlack frames, what reordered messages can make: a list read up to 3
// lists late) is another track under the same id: the tracker started again.
#pragma once

#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

namespace ld {

class TrackRestartWatch {
 public:
  static constexpr int32_t kAgeSlack = 3;

  /// forget_after_lists > 0: a track not named for that many lists is
  /// forgotten (a long-running reader's memory stays bounded; a restart is
  /// still told from any track it knows); 0: none is.
  explicit TrackRestartWatch(int64_t forget_after_lists = 0) : forget_after_(forget_after_lists) {}

  /// Notes the tracks of one list as (track id, age), lists in the order
  /// they are read (a reader that reads only some lists notes those). True
  /// when they show that the tracker started again; the watch then knows
  /// only this list's tracks.
  bool note(const std::vector<std::pair<int64_t, int32_t>>& ages);
  /// Forgets a track (a reader that forgets tracks unseen for long).
  void forget(int64_t id) { seen_.erase(id); }
  /// Restarts seen so far.
  int64_t restarts() const { return restarts_; }
  size_t size() const { return seen_.size(); }

 private:
  struct Seen {
    int32_t age = 0;    ///< the oldest age seen
    int64_t list = 0;   ///< the list it was seen in (note's count)
  };
  std::unordered_map<int64_t, Seen> seen_;
  int64_t forget_after_ = 0, lists_ = 0, restarts_ = 0;
};

}  // namespace ld
