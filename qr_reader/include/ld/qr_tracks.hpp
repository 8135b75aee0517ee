// What ld-qr-reader needs besides decoding: joining tracked landmark lists to
// their images (lost and reordered messages tolerated), and remembering each
// track's payload with a bounded decode schedule so the reader never falls
// behind the camera.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "ld/track_restarts.hpp"

namespace ld {

/// Holds the newest images (raw encoded bytes, keyed by utime and seq) and
/// the landmark lists waiting for their image, and pairs them up whichever
/// arrives first.
class FrameMatcher {
 public:
  struct Key {
    int64_t utime = 0;
    int64_t seq = -1;  ///< -1: unknown, match by utime alone
    bool operator==(const Key& o) const {
      return utime == o.utime && (seq < 0 || o.seq < 0 || seq == o.seq);
    }
  };
  struct Pair {
    std::vector<uint8_t> image;  ///< encoded image_t
    std::vector<uint8_t> list;   ///< encoded landmark_list_t
    Key key;
  };

  /// Keeps at most `max_images` images and `max_lists` unmatched lists.
  explicit FrameMatcher(size_t max_images = 30, size_t max_lists = 30)
      : max_images_(max_images), max_lists_(max_lists) {}

  void addImage(const Key& key, const uint8_t* data, size_t size);
  void addList(const Key& key, const uint8_t* data, size_t size);

  /// The newest matched pair not yet taken, dropping older matched pairs
  /// (counted in skipped()). False when nothing is matched. A pair of a
  /// frame older than the last one taken, by up to kLateUs (a message
  /// reordered on the way, as Tracker::update takes it), or of the same
  /// frame again, is dropped and counted in late(): read, it took the
  /// tracks' ages for a restart and forgot every payload. Older by more, it
  /// is time starting again (a log replayed from its start) and taken. Where
  /// the utime stands still, the seq says it: up to kLateSeqs back is late.
  bool takeNewest(Pair& out);
  static constexpr int64_t kLateUs = 1'000'000, kLateSeqs = 3;  // (kLateUs: Tracker::kLateFrameUs)
  /// Late pairs (or images) in a row from behind, each newer than the ones
  /// before: time stepped back (Tracker::kStepBackFrames), the last taken.
  static constexpr int kStepBackFrames = 3;

  int64_t skipped() const { return skipped_; }
  int64_t late() const { return late_; }
  int64_t unmatchedDropped() const { return unmatched_dropped_; }
  /// Pairs made so far (taken, skipped or late).
  int64_t matched() const { return matched_; }

 private:
  struct Entry {
    Key key;
    std::vector<uint8_t> bytes;
  };
  void match();
  size_t max_images_, max_lists_;
  std::deque<Entry> images_, lists_;
  std::deque<Pair> ready_;
  std::vector<std::vector<uint8_t>> spare_;  // recycled buffers
  bool taken_any_ = false;
  Key last_taken_;
  // Frames in a row from behind the last one taken, each newer than the ones
  // before (count, of the lists' pairs or of the images), and the last's utime.
  struct BehindRun {
    int frames = 0;
    int64_t last = 0;
    void note(int64_t utime, int count) {
      frames = frames > 0 && utime > last ? frames + count : count;
      last = utime;
    }
  };
  BehindRun pairs_behind_, images_behind_;
  int64_t skipped_ = 0, late_ = 0, unmatched_dropped_ = 0, matched_ = 0;
};

/// The decoding time a frame may take: the first decode always runs, a later
/// one only while the time since the first began is under the budget (a
/// large pattern without a readable QR costs 20 ms a try and its stacked
/// frames 60 ms more, so a count of decodes alone let a frame take 300 ms).
/// The tracks not tried stay due and come first in the next frame's schedule.
class DecodeBudget {
 public:
  using Clock = std::chrono::steady_clock;
  explicit DecodeBudget(double budget_ms) : budget_ms_(budget_ms) {}
  /// Whether a decode may start at `now`; the first call starts the clock.
  bool allows(Clock::time_point now) {
    if (!started_) {
      started_ = true;
      t0_ = now;
      return true;
    }
    return std::chrono::duration<double, std::milli>(now - t0_).count() < budget_ms_;
  }

 private:
  double budget_ms_;
  bool started_ = false;
  Clock::time_point t0_;
};

struct QrScheduleParams {
  double retry_interval_s = 0.1;  ///< an undecoded track is tried at most this often
  double recheck_interval_s = 5.0;///< a decoded track is re-read this often
  int max_decodes_per_frame = 3;  ///< decode attempts per processed frame, all tracks
  double forget_after_s = 10.0;   ///< a track unseen this long is forgotten
};

/// Per-track payload memory and the decode schedule.
class QrTrackBook {
 public:
  explicit QrTrackBook(const QrScheduleParams& params = {}) : params_(params) {}

  /// The ages (frames since the tracker created them) of the tracks of a
  /// frame, as (track id, age), frames in the order they are read. When they
  /// show that the tracker started again (ld/track_restarts.hpp: a track
  /// younger than it can be), every id the book knows now means another
  /// landmark, and everything it knows is forgotten. Returns true when that
  /// happened.
  bool noteAges(const std::vector<std::pair<int64_t, int32_t>>& ages);

  /// Track ids present in a frame at `utime`, in the order given: returns
  /// those to decode now (undecoded first, least recently tried first),
  /// at most max_decodes_per_frame.
  std::vector<int64_t> schedule(const std::vector<int64_t>& track_ids, int64_t utime);

  /// Where a track's landmark is in a frame: its age (frames since the
  /// tracker created it), whether it was detected (a coasting landmark's
  /// place is the tracker's guess, and is not looked at), its centre and
  /// size (mean side of its corners) in pixels. A track whose payload is
  /// known and whose landmark is further from where its motion so far leads
  /// (its last detected place, moved on at the velocity between its last two)
  /// than its size per tracker frame is another landmark now (the tracker
  /// moved the id over: a landmark vanished and a neighbour took its id): its
  /// payload is forgotten and it is read again at once; the payload
  /// forgotten is returned. Once it has been seen coasting, it is detected
  /// again within 1.5 sizes of its path from its last place to where its
  /// motion leads (the robot may have stopped anywhere on it), however many
  /// frames it coasted: the tracker found it again by a gate, which a
  /// neighbour can be in (the allowance growing with the frames, a landmark
  /// coming in across the image as it left kept its payload for seconds).
  /// Tracks the book does not know yet (never scheduled) are left alone.
  std::optional<std::string> follow(int64_t track_id, int32_t age, bool visible, double cx, double cy,
                                    double size);

  /// Whether the last follow found the track's known landmark detected more
  /// than half as far from where its motion led as a jump would be: still
  /// the same landmark by the rule above, but a neighbour within its size
  /// may have taken the id (all of them shifted at once, as between frames
  /// of a turn with frames dropped): its code is looked at again at once.
  bool strayed(int64_t track_id) const;

  /// Makes a read track due for a re-read at once (its payload kept).
  void readAgain(int64_t track_id);

  /// Forgets the payload known for a track (its landmark shows another code
  /// now) and makes it due at once; the payload forgotten, if any.
  std::optional<std::string> forget(int64_t track_id);

  /// Records the outcome of a decode attempt of `track_id` on the frame
  /// (utime, seq).
  void record(int64_t track_id, int64_t utime, int64_t seq, const std::optional<std::string>& payload);

  struct Known {
    std::string payload;
    int64_t utime = 0, seq = -1;  ///< the frame it was read from
  };
  /// The payload known for a track, if any.
  const Known* payload(int64_t track_id) const;

  size_t size() const { return tracks_.size(); }

  /// The most tracks the book keeps: beyond them those scheduled longest ago
  /// are forgotten. It forgets a track unseen for forget_after_s of the
  /// frames' utime, so a publisher whose utime stands still made it forget
  /// none, every track the tracker ever made kept and walked at each frame.
  static constexpr size_t kMaxTracks = 4000;

 private:
  struct Track {
    std::optional<Known> known;
    int64_t last_try = INT64_MIN;
    int64_t last_seen = 0;
    int64_t last_frame = 0;  // the schedule call (counted) it was last named in
    bool placed = false;  // where it was last detected (follow)
    bool coasted = false;  // seen coasting since
    bool strayed = false;  // the last follow: off its path, short of a jump
    double cx = 0, cy = 0, size = 0, vx = 0, vy = 0;  // (velocity in px per tracker frame)
    int32_t age = 0;
  };
  QrScheduleParams params_;
  // (tracks not named for 3000 frames read, about 100 s at 30 frames/s,
  // leave the watch: coasting ones the schedule never sees included)
  TrackRestartWatch restarts_{3000};
  std::unordered_map<int64_t, Track> tracks_;
  int64_t frames_ = 0;  // schedule calls
};

}  // namespace ld
