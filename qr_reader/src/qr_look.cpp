// QrLook: a read code's modules as one sharp frame showed them, compared
// with later frames of the same track (qr_reader.hpp).
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "ld/input_checks.hpp"
#include "ld/landmark_layout.hpp"
#include "ld/qr_reader.hpp"
#include "qr_function_patterns.hpp"

namespace ld {

namespace {

constexpr double kMinContrast = 16;  // gray levels between the function modules' dark and light
constexpr double kDarkBelow = 0.35, kLightAbove = 0.65;  // of the way from dark to light: a clear shade
// Clear enough to judge: function modules classed right, and the timing
// rows' alternate modules (the finest detail of any code: blur greys them
// first, and then isolated data modules read the other way).
constexpr double kMinClear = 0.95, kMinTimingClear = 0.9;

bool finite(const std::array<cv::Point2f, 4>& corners) {
  for (const auto& c : corners)
    if (!std::isfinite(c.x) || !std::isfinite(c.y)) return false;
  return true;
}

bool isTiming(int n, int r, int c) { return (r == 6 && c >= 8 && c < n - 8) || (c == 6 && r >= 8 && r < n - 8); }

// How clear a frame's function modules are (the share classed right), and
// the shades of dark and light.
struct Levels {
  double dark = 0, light = 255, clear = 0, timing_clear = 0;
  bool sharp() const { return light - dark >= kMinContrast && clear >= kMinClear && timing_clear >= kMinTimingClear; }
  int8_t shade(float s) const {  // 1 dark, 0 light, -1 between
    const double v = (s - dark) / (light - dark);
    return v < kDarkBelow ? 1 : v > kLightAbove ? 0 : -1;
  }
};

// One thread's sampling buffers (a look keeps only its modules' shades).
struct Samples {
  cv::Mat map, sampled, gray, values;
  std::vector<cv::Point> at;  // sampleFunction's modules (x = column, y = row)
  std::vector<int8_t> now;    // compare's shades of the frame's modules
};
thread_local Samples t_samples;

// The n x n modules' shades (gray; sub x sub samples a quarter module apart
// averaged, sub odd) in t_samples.values; false where the homography puts
// them behind the camera.
bool sample(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners, int n, int sub = 3) {
  Samples& b = t_samples;
  const cv::Matx33d sheet_to_image = layout::sheetToImage(corners);
  const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);  // (one module of quiet zone)
  b.map.create(n * sub, n * sub, CV_32FC2);
  for (int r = 0; r < n * sub; ++r) {
    auto* row = b.map.ptr<cv::Vec2f>(r);
    const double y = r / sub + 0.5 + (r % sub - sub / 2) * 0.25;
    for (int c = 0; c < n * sub; ++c) {
      const double x = c / sub + 0.5 + (c % sub - sub / 2) * 0.25;
      const cv::Vec3d p = sheet_to_image * cv::Vec3d(layout::kQrMin + module * (1 + x),
                                                     layout::kQrMin + module * (1 + y), 1.0);
      if (!(p[2] > 1e-12)) return false;  // (beyond the horizon: corners of no view)
      row[c] = {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])};
    }
  }
  cv::remap(image, b.sampled, b.map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  if (b.sampled.channels() == 3) cv::cvtColor(b.sampled, b.gray, cv::COLOR_BGR2GRAY);
  else if (b.sampled.channels() == 4) cv::cvtColor(b.sampled, b.gray, cv::COLOR_BGRA2GRAY);
  else b.gray = b.sampled;
  b.gray.convertTo(b.gray, CV_32F);
  cv::resize(b.gray, b.values, {n, n}, 0, 0, cv::INTER_AREA);
  return true;
}

// Only the function modules' shades (centre samples), into the n x n
// t_samples.values (the others left as they were): all levels() reads, for
// the size search, which tries up to 40 sizes on a near code.
bool sampleFunction(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners, int n) {
  Samples& b = t_samples;
  const cv::Matx33d sheet_to_image = layout::sheetToImage(corners);
  const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
  b.at.clear();
  detail::forEachFunctionModule(n, [&](int r, int c, bool) { b.at.emplace_back(c, r); });
  b.map.create(1, static_cast<int>(b.at.size()), CV_32FC2);
  auto* row = b.map.ptr<cv::Vec2f>(0);
  for (size_t i = 0; i < b.at.size(); ++i) {
    const cv::Vec3d p = sheet_to_image * cv::Vec3d(layout::kQrMin + module * (1.5 + b.at[i].x),
                                                   layout::kQrMin + module * (1.5 + b.at[i].y), 1.0);
    if (!(p[2] > 1e-12)) return false;
    row[i] = {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])};
  }
  cv::remap(image, b.sampled, b.map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  if (b.sampled.channels() == 3) cv::cvtColor(b.sampled, b.gray, cv::COLOR_BGR2GRAY);
  else if (b.sampled.channels() == 4) cv::cvtColor(b.sampled, b.gray, cv::COLOR_BGRA2GRAY);
  else b.gray = b.sampled;
  b.values.create(n, n, CV_32F);
  const uint8_t* g = b.gray.ptr<uint8_t>(0);
  for (size_t i = 0; i < b.at.size(); ++i) b.values.at<float>(b.at[i].y, b.at[i].x) = g[i];
  return true;
}

Levels levels(const cv::Mat& values, int n) {
  double sum[2] = {0, 0};
  int count[2] = {0, 0};
  detail::forEachFunctionModule(n, [&](int r, int c, bool dark) {
    sum[dark] += values.at<float>(r, c);
    ++count[dark];
  });
  Levels l;
  if (count[0] == 0 || count[1] == 0) return l;
  l.dark = sum[1] / count[1];
  l.light = sum[0] / count[0];
  if (!(l.light - l.dark >= kMinContrast)) return l;
  int clear = 0, all = 0, timing_clear[2] = {0, 0}, timing[2] = {0, 0};
  detail::forEachFunctionModule(n, [&](int r, int c, bool dark) {
    const bool right = l.shade(values.at<float>(r, c)) == (dark ? 1 : 0);
    clear += right;
    ++all;
    if (isTiming(n, r, c)) {
      timing_clear[r == 6] += right;
      ++timing[r == 6];
    }
  });
  l.clear = static_cast<double>(clear) / all;
  // (the worse of the two rows: motion blur greys the one along it)
  l.timing_clear = 1.0;
  for (int k = 0; k < 2; ++k)
    if (timing[k] > 0) l.timing_clear = std::min(l.timing_clear, static_cast<double>(timing_clear[k]) / timing[k]);
  return l;
}

}  // namespace

bool QrLook::capture(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners) {
  n_ = 0;
  requireReadableImage(image, "QrLook::capture");
  if (image.empty() || !finite(corners)) return false;
  const double qr_px = layout::projectedQrSide(corners);
  // The code's size: the one whose function patterns the frame shows best.
  int best_n = 0;
  double best = -1;
  // (from the function modules' centres alone: a code of 300 px has 40 sizes to try)
  for (int n = 21; n <= 177 && qr_px / (n + 2) >= kMinPxPerModule; n += 4) {
    if (!sampleFunction(image, corners, n)) return false;
    const Levels l = levels(t_samples.values, n);
    if (l.light - l.dark >= kMinContrast && l.clear + l.timing_clear > best) {
      best = l.clear + l.timing_clear;
      best_n = n;
    }
  }
  if (best_n == 0 || !sample(image, corners, best_n)) return false;
  const cv::Mat& values = t_samples.values;
  const Levels l = levels(values, best_n);
  if (!l.sharp()) return false;
  ref_.resize(static_cast<size_t>(best_n) * best_n);
  for (int r = 0; r < best_n; ++r)
    for (int c = 0; c < best_n; ++c) ref_[static_cast<size_t>(r * best_n + c)] = l.shade(values.at<float>(r, c));
  detail::forEachFunctionModule(best_n, [&](int r, int c, bool) { ref_[static_cast<size_t>(r * best_n + c)] = -1; });
  n_ = best_n;
  return true;
}

QrLook::Verdict QrLook::compare(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners) {
  requireReadableImage(image, "QrLook::compare");
  if (n_ == 0 || image.empty() || !finite(corners) || layout::projectedQrSide(corners) / (n_ + 2) < kMinPxPerModule)
    return Verdict::Unsure;
  if (!sample(image, corners, n_)) return Verdict::Unsure;
  const cv::Mat& values = t_samples.values;
  const Levels l = levels(values, n_);
  if (!l.sharp()) return Verdict::Unsure;
  std::vector<int8_t>& now = t_samples.now;
  now.resize(static_cast<size_t>(n_) * n_);
  for (int r = 0; r < n_; ++r)
    for (int c = 0; c < n_; ++c) now[static_cast<size_t>(r * n_ + c)] = l.shade(values.at<float>(r, c));
  // A module turned counts where the frame shows a code around it: at least
  // kMinAround of its 8 neighbours clearly of the other shade. Under a
  // finger, a pen or its shadow the modules turn together, all dark on the
  // shaded side and all light on the lit one (a shaded finger over a corner
  // of the code turned enough both ways: a review); another code's modules
  // lie among others of either shade.
  auto amid = [&](int r, int c, int8_t shade) {
    int other = 0;
    for (int dr = -1; dr <= 1; ++dr)
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if ((dr || dc) && rr >= 0 && cc >= 0 && rr < n_ && cc < n_)
          other += now[static_cast<size_t>(rr * n_ + cc)] == 1 - shade;
      }
    return other >= kMinAround;
  };
  int both = 0, to_light = 0, to_dark = 0;
  double sr = 0, sc = 0, srr = 0, scc = 0, src = 0;  // where the turned modules lie
  for (int r = 0; r < n_; ++r)
    for (int c = 0; c < n_; ++c) {
      const int8_t was = ref_[static_cast<size_t>(r * n_ + c)], is = now[static_cast<size_t>(r * n_ + c)];
      if (was < 0 || is < 0) continue;
      ++both;
      if (is == was || !amid(r, c, is)) continue;
      ++(was ? to_light : to_dark);
      sr += r, sc += c, srr += r * r, scc += c * c, src += r * c;
    }
  const double least = std::max<double>(kMinTurned, kMinTurnedShare * both);
  if (to_light >= least && to_dark >= least) {
    // Another code's turned modules are strewn over the code; a pen's, or a
    // thin shadow's, lie along a line (the spread across its narrow way,
    // the smaller axis of their scatter, is under a module or two).
    const double k = to_light + to_dark, vr = srr / k - (sr / k) * (sr / k), vc = scc / k - (sc / k) * (sc / k),
                 cov = src / k - (sr / k) * (sc / k);
    const double narrow = (vr + vc) / 2 - std::sqrt((vr - vc) * (vr - vc) / 4 + cov * cov);
    if (narrow >= kMinSpread * kMinSpread) return Verdict::Other;
    return Verdict::Unsure;
  }
  return to_light + to_dark < least ? Verdict::Same : Verdict::Unsure;
}

}  // namespace ld
