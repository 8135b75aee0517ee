// QrLook: a read code's modules as one sharp frame showed them, compared
// with later frames of the same track (qr_reader.hpp).
#include <algorithm>
#include <cmath>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "ld/input_checks.hpp"
#include "ld/landmark_layout.hpp"
#include "ld/qr_reader.hpp"
#include "qr_function_patterns.hpp"
#include "qr_sampling.hpp"

namespace ld {

namespace {

constexpr double kMinContrast = 16;  // gray levels between the function modules' dark and light
constexpr double kDarkBelow = 0.35, kLightAbove = 0.65;  // of the way from dark to light: a clear shade
// Clear enough to judge: function modules classed right, and the timing
// rows' alternate modules (the finest detail of any code: blur greys them
// first, and then isolated data modules read the other way).
constexpr double kMinClear = 0.95, kMinTimingClear = 0.9;

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
  cv::Mat map, sampled, gray, values, lo, hi;
  std::vector<cv::Point> at;  // sampleFunction's modules (x = column, y = row)
  std::vector<int8_t> now;    // compare's shades of the frame's modules
};
thread_local Samples t_samples;

// The homography from the sheet to the image, where the QR square lies in
// front of the camera as the corners put it (w above 0 at its corners, and
// so all over it: w is linear on the sheet); none for corners not finite or
// of no view.
std::optional<cv::Matx33d> qrSquareToImage(const std::array<cv::Point2f, 4>& corners) {
  if (!detail::finiteCorners(corners)) return std::nullopt;
  const cv::Matx33d h = layout::sheetToImage(corners);
  for (const double x : {layout::kQrMin, layout::kQrMax})
    for (const double y : {layout::kQrMin, layout::kQrMax})
      if (!(h(2, 0) * x + h(2, 1) * y + h(2, 2) > 1e-12)) return std::nullopt;
  return h;
}

// The image at t_samples.map's points, as gray (8-bit), in t_samples.gray.
void remapGray(const cv::Mat& image) {
  Samples& b = t_samples;
  cv::remap(image, b.sampled, b.map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  detail::toGray(b.sampled, b.gray);
}

// The n x n modules' shades (gray; sub x sub samples a quarter module apart
// averaged, sub odd) in t_samples.values.
void sample(const cv::Mat& image, const cv::Matx33d& sheet_to_image, int n, int sub = 3) {
  Samples& b = t_samples;
  const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);  // (one module of quiet zone)
  b.map.create(n * sub, n * sub, CV_32FC2);
  for (int r = 0; r < n * sub; ++r) {
    auto* row = b.map.ptr<cv::Vec2f>(r);
    const double y = r / sub + 0.5 + (r % sub - sub / 2) * 0.25;
    for (int c = 0; c < n * sub; ++c)
      row[c] = detail::moduleToImage(sheet_to_image, module, c / sub + 0.5 + (c % sub - sub / 2) * 0.25, y);
  }
  remapGray(image);
  b.gray.convertTo(b.gray, CV_32F);
  cv::resize(b.gray, b.values, {n, n}, 0, 0, cv::INTER_AREA);
}

// Only the function modules' shades (centre samples), into the n x n
// t_samples.values (the others left as they were): all levels() reads, for
// the size search, which tries up to 40 sizes on a near code.
void sampleFunction(const cv::Mat& image, const cv::Matx33d& sheet_to_image, int n) {
  Samples& b = t_samples;
  const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
  b.at.clear();
  detail::forEachFunctionModule(n, [&](int r, int c, bool) { b.at.emplace_back(c, r); });
  b.map.create(1, static_cast<int>(b.at.size()), CV_32FC2);
  auto* row = b.map.ptr<cv::Vec2f>(0);
  for (size_t i = 0; i < b.at.size(); ++i)
    row[i] = detail::moduleToImage(sheet_to_image, module, b.at[i].x + 0.5, b.at[i].y + 0.5);
  remapGray(image);
  b.values.create(n, n, CV_32F);
  const uint8_t* g = b.gray.ptr<uint8_t>(0);
  for (size_t i = 0; i < b.at.size(); ++i) b.values.at<float>(b.at[i].y, b.at[i].x) = g[i];
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

// t_samples.values levelled module by module: each module's shade as the
// way from the darkest to the lightest module around it (within
// kAround modules each way, smoothed), on 0-255. A hot spot or a shadow over
// part of the code lifts or lowers both shades there together; the code's
// own modules still lie on both sides of any few modules. Where the modules
// around differ by less than kMinContrast (a clipped hot spot), the shade is
// left half-way: unclear.
constexpr int kAround = 2;
void levelLocally() {
  Samples& b = t_samples;
  static const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, {2 * kAround + 1, 2 * kAround + 1});
  cv::erode(b.values, b.lo, kernel, {-1, -1}, 1, cv::BORDER_REPLICATE);
  cv::dilate(b.values, b.hi, kernel, {-1, -1}, 1, cv::BORDER_REPLICATE);
  cv::blur(b.lo, b.lo, {2 * kAround + 1, 2 * kAround + 1}, {-1, -1}, cv::BORDER_REPLICATE);
  cv::blur(b.hi, b.hi, {2 * kAround + 1, 2 * kAround + 1}, {-1, -1}, cv::BORDER_REPLICATE);
  for (int r = 0; r < b.values.rows; ++r) {
    float* v = b.values.ptr<float>(r);
    const float *lo = b.lo.ptr<float>(r), *hi = b.hi.ptr<float>(r);
    for (int c = 0; c < b.values.cols; ++c)
      v[c] = hi[c] - lo[c] < kMinContrast ? 127.5f : std::clamp(255.f * (v[c] - lo[c]) / (hi[c] - lo[c]), 0.f, 255.f);
  }
}

// Each of the n x n modules of t_samples.values: 1 dark, 0 light, -1 between.
void shades(const Levels& l, int n, std::vector<int8_t>& out) {
  out.resize(static_cast<size_t>(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) out[static_cast<size_t>(r * n + c)] = l.shade(t_samples.values.at<float>(r, c));
}

}  // namespace

bool QrLook::capture(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners) {
  n_ = 0;
  requireReadableImage(image, "QrLook::capture");
  const auto h = image.empty() ? std::nullopt : qrSquareToImage(corners);
  if (!h) return false;
  const double qr_px = layout::projectedQrSide(corners);
  // The code's size: the one whose function patterns the frame shows best.
  int best_n = 0;
  double best = -1;
  // (from the function modules' centres alone: a code of 300 px has 40 sizes to try)
  for (int n = 21; n <= 177 && qr_px / (n + 2) >= kMinPxPerModule; n += 4) {
    sampleFunction(image, *h, n);
    const Levels l = levels(t_samples.values, n);
    if (l.light - l.dark >= kMinContrast && l.clear + l.timing_clear > best) {
      best = l.clear + l.timing_clear;
      best_n = n;
    }
  }
  if (best_n == 0) return false;
  sample(image, *h, best_n);
  levelLocally();
  const Levels l = levels(t_samples.values, best_n);
  if (!l.sharp()) return false;
  shades(l, best_n, ref_);
  detail::forEachFunctionModule(best_n, [&](int r, int c, bool) { ref_[static_cast<size_t>(r * best_n + c)] = -1; });
  n_ = best_n;
  return true;
}

QrLook::Verdict QrLook::compare(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners) {
  requireReadableImage(image, "QrLook::compare");
  if (n_ == 0 || image.empty() || layout::projectedQrSide(corners) / (n_ + 2) < kMinPxPerModule)
    return Verdict::Unsure;
  const auto h = qrSquareToImage(corners);
  if (!h) return Verdict::Unsure;
  sample(image, *h, n_);
  levelLocally();
  const Levels l = levels(t_samples.values, n_);
  if (!l.sharp()) return Verdict::Unsure;
  std::vector<int8_t>& now = t_samples.now;
  shades(l, n_, now);
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
