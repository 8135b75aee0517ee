// Timing of the tracker for benchmark tables (ld-bench, ld-bench-tracker).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ld {

struct TrackerTiming {
  int landmarks = 0;
  /// Median ms of one Hungarian solve of a dense landmarks x landmarks matrix
  /// of random costs (solver warmed up): the assignment step's worst case.
  double assignment_ms = 0;
  /// Median ms of one Tracker::update() with that many landmarks, all visible,
  /// moving together with a little noise (gates, prediction, assignment,
  /// report): what the tracker costs per frame.
  double update_ms = 0;
};

/// Times the assignment and the tracker update for `landmarks` landmarks over
/// `repeats` runs (deterministic inputs from `seed`).
TrackerTiming timeTracker(int landmarks, int repeats = 200, uint64_t seed = 1);

/// The tracker's benchmark table (Markdown, its caption first), timing each
/// count of `landmarks`: the same in ld-bench and ld-bench-tracker.
std::string trackerTable(const std::vector<int>& landmarks, int repeats, uint64_t seed = 1);

}  // namespace ld
