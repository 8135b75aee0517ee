// A process's memory as ld-run samples it over a run of any length.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace ld {

/// A process's resident memory, looked at every second (ld-run's summary,
/// `rss_kb`). The largest and the last are exact; the samples kept are at
/// most kRssSamplesKept: each look's at first, then every 2nd, 4th, ...
/// look's, the older ones thinned to match, so that a run of days keeps its
/// whole course in fixed memory (a sample a second grew without end).
struct RssSeries {
  static constexpr size_t kRssSamplesKept = 2000;
  int64_t max_kb = 0, last_kb = 0;
  std::vector<std::pair<double, int64_t>> samples;  // (seconds since start, kB)

  void add(double t, int64_t kb) {
    last_kb = kb;
    max_kb = std::max(max_kb, kb);
    if (looks_++ % every_ != 0) return;
    samples.emplace_back(t, kb);
    if (samples.size() < kRssSamplesKept) return;
    for (size_t i = 0; 2 * i < samples.size(); ++i) samples[i] = samples[2 * i];
    samples.resize((samples.size() + 1) / 2);
    every_ *= 2;
  }

 private:
  int64_t looks_ = 0, every_ = 1;
};

}  // namespace ld
