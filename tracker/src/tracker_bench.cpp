#include "ld/tracker_bench.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "ld/hungarian.hpp"
#include "ld/tracker.hpp"

namespace ld {
namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

Landmark square(double cx, double cy, double side) {
  const double h = side / 2, q = side * 3 / 8;  // square centres at 1.5u of 9u
  Landmark lm;
  lm.corners = {cv::Point2f(float(cx - h), float(cy - h)), cv::Point2f(float(cx + h), float(cy - h)),
                cv::Point2f(float(cx + h), float(cy + h)), cv::Point2f(float(cx - h), float(cy + h))};
  lm.fip_tl = {float(cx - q), float(cy - q)};
  lm.fip_tr = {float(cx + q), float(cy - q)};
  lm.fip_bl = {float(cx - q), float(cy + q)};
  lm.ap = {float(cx + q), float(cy + q)};
  lm.score = 1;
  return lm;
}

}  // namespace

TrackerTiming timeTracker(int landmarks, int repeats, uint64_t seed) {
  TrackerTiming t;
  t.landmarks = landmarks;
  const int n = std::max(landmarks, 1);
  repeats = std::max(repeats, 1);
  std::mt19937_64 rng(seed);

  // Assignment alone: dense random matrices, one fresh matrix per run.
  {
    std::uniform_real_distribution<double> u(0.0, 100.0);
    std::vector<double> cost(static_cast<size_t>(n) * n);
    std::vector<int> row_to_col;
    Hungarian h;
    std::vector<double> ms;
    ms.reserve(static_cast<size_t>(repeats));
    for (int r = 0; r < repeats + 3; ++r) {
      for (double& c : cost) c = u(rng);
      const auto t0 = Clock::now();
      h.solve(cost.data(), n, n, row_to_col);
      if (r >= 3) ms.push_back(msSince(t0));  // the first runs warm the buffers
    }
    t.assignment_ms = median(ms);
  }

  // Whole update: landmarks 30 px wide on a grid 3 sizes apart, the camera
  // panning (common motion) with 1 px detection noise, 30 frames/s.
  {
    const int cols = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
    const double side = 30, pitch = 90;
    std::normal_distribution<double> noise(0.0, 1.0);
    std::vector<cv::Point2d> base(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) base[static_cast<size_t>(k)] = {pitch * (k % cols), pitch * (k / cols)};
    std::vector<Landmark> dets(static_cast<size_t>(n));
    Tracker tracker;
    std::vector<double> ms;
    ms.reserve(static_cast<size_t>(repeats));
    for (int f = 0; f < repeats + 3; ++f) {
      const double pan = 8.0 * f;
      for (size_t k = 0; k < dets.size(); ++k)
        dets[k] = square(base[k].x + pan + noise(rng), base[k].y + noise(rng), side);
      const auto t0 = Clock::now();
      tracker.update(dets, static_cast<int64_t>(f) * 33333);
      if (f >= 3) ms.push_back(msSince(t0));
    }
    t.update_ms = median(ms);
  }
  return t;
}

std::string trackerTable(const std::vector<int>& landmarks, int repeats, uint64_t seed) {
  std::string md = "Tracker: median ms over " + std::to_string(repeats) + (repeats == 1 ? " run" : " runs") +
                   "; assignment = one Hungarian solve of a dense NxN matrix (the worst case), update = one "
                   "Tracker::update() with N landmarks moving.\n\n| landmarks | assignment | update |\n|---|---|---|\n";
  char row[96];
  for (int n : landmarks) {
    const TrackerTiming t = timeTracker(n, repeats, seed);
    std::snprintf(row, sizeof row, "| %d | %.4f | %.4f |\n", n, t.assignment_ms, t.update_ms);
    md += row;
  }
  return md;
}

}  // namespace ld
