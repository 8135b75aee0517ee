#include "ld/track_restarts.hpp"

#include <cstdint>
#include <iterator>

namespace ld {

bool TrackRestartWatch::note(const std::vector<std::pair<int64_t, int32_t>>& ages) {
  ++lists_;
  bool restarted = false;
  for (const auto& [id, age] : ages) {
    const auto it = seen_.find(id);
    if (it == seen_.end()) continue;
    // the least the age can be now, had the same track gone on (less one:
    // this list itself may be one read late)
    const int64_t expected = int64_t{it->second.age} + (lists_ - it->second.list) - 1;
    if (int64_t{age} + kAgeSlack < expected) restarted = true;
  }
  if (restarted) {
    seen_.clear();
    ++restarts_;
  }
  for (const auto& [id, age] : ages) {
    auto [it, is_new] = seen_.try_emplace(id, Seen{age, lists_});
    if (!is_new && age >= it->second.age) it->second = Seen{age, lists_};
  }
  // (every 256 lists, the tracks not named for forget_after_ lists go)
  if (forget_after_ > 0 && lists_ % 256 == 0)
    for (auto it = seen_.begin(); it != seen_.end();)
      it = lists_ - it->second.list > forget_after_ ? seen_.erase(it) : std::next(it);
  return restarted;
}

}  // namespace ld
