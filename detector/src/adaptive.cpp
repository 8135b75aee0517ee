#include "ld/adaptive.hpp"
#include "ld/input_checks.hpp"

#include <algorithm>
#include <chrono>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"
#include "stages.hpp"

namespace ld {

namespace {

// A sheet sample whose chromaticity (b, g, r over their sum) lies this far
// from the landmark's samples' median in a channel is not the light's
// (white paper under any light has the light's; a yellow sticker is 0.25 off).
constexpr double kOddSampleChroma = 0.06;

// How far one channel's veil may exceed the common veil of the light's colour
// when that colour is only assumed (no veiled blocks to measure it on).
constexpr double kVeilSpread = 1.25;
// The veil's colour is measured on this many veiled blocks at least.
constexpr int kVeilColourBlocks = 8;
// Under a veil that leaves less of the range than this above it, the stretch
// would amplify noise and JPEG blocks into colours: left alone.
constexpr int kMinHeadroom = 32;
// Near the clip the white over a veil can rise no higher than 255: the
// contrast asked for is at most this fraction of the range left.
constexpr double kClipContrast = 0.8;

// A colour (B, G, R) relative to its strongest channel, no channel under a quarter.
cv::Vec3d relativeColour(const cv::Vec3d& c) {
  const double top = std::max({c[0], c[1], c[2]});
  cv::Vec3d out;
  for (int k = 0; k < 3; ++k) out[k] = std::max(0.25, c[k] / top);
  return out;
}

// The glare pass's statistics are per kGlareBlock x kGlareBlock pixels.
constexpr int kGlareBlock = 8;

// The parameters as their comments bound them; std::invalid_argument naming
// the first that is not (max_gain 0 made every frame black, without a word).
const AdaptiveParams& checked(const AdaptiveParams& p) {
  const auto in = [](const char* name, double v, double lo, double hi) { requireWithin("AdaptiveParams", name, v, lo, hi); };
  in("target_white", p.target_white, 1, 255);
  in("max_gain", p.max_gain, 1, 64);
  in("bright_fraction", p.bright_fraction, 1e-4, 1);
  in("smoothing", p.smoothing, 1e-3, 1);
  in("landmark_memory_frames", p.landmark_memory_frames, 0, 1 << 20);
  in("deadband", p.deadband, 0, 10);
  in("denoise_sigma", p.denoise_sigma, 0, 20);
  in("denoise_above_gain", p.denoise_above_gain, 1, 1e9);
  in("glare_min_lift", p.glare_min_lift, 0, 255);
  in("glare_min_contrast", p.glare_min_contrast, 0, 255);
  in("glare_window", p.glare_window, 1, 4096);
  in("wide_hue_min_stretch", p.wide_hue_min_stretch, 1, std::numeric_limits<double>::infinity());
  return p;
}

}  // namespace

LightingAdapter::LightingAdapter(const AdaptiveParams& params)
    : params_(checked(params)),
      hist_(256),
      level_sums_(256),
      // the window in blocks (odd), and the reach of a veiled block's smoothing
      window_kernel_(cv::getStructuringElement(
          cv::MORPH_RECT, cv::Size(1, 1) * (std::max(1, params.glare_window / kGlareBlock) | 1))),
      spread_kernel_(cv::getStructuringElement(cv::MORPH_RECT, {5, 5})) {}

void LightingAdapter::reset() {
  white_ = {0, 0, 0};
  gains_ = {1, 1, 1};
  frames_since_landmark_ = 1 << 20;
}

void LightingAdapter::update(const cv::Vec3d& white) {
  if (!(white[0] > 0 && white[1] > 0 && white[2] > 0)) return;
  if (white_[0] <= 0) white_ = white;
  else white_ = (1 - params_.smoothing) * white_ + params_.smoothing * white;
}

const cv::Mat& LightingAdapter::deglare(const cv::Mat& bgr) {
  if (!(params_.glare_min_lift > 0)) return bgr;
  // Per 8x8 block: each channel's darkest value, and the whitest pixel (by
  // its weakest channel).
  const int bw = (bgr.cols + kGlareBlock - 1) / kGlareBlock, bh = (bgr.rows + kGlareBlock - 1) / kGlareBlock;
  block_min_.create(bh, bw, CV_8UC3);
  block_white_.create(bh, bw, CV_8UC1);
  for (int by = 0; by < bh; ++by) {
    const int y0 = by * kGlareBlock, y1 = std::min(bgr.rows, y0 + kGlareBlock);
    // The block row's darkest values down each column (vectorised), then
    // along each block; the white on every other pixel (a maximum is robust).
    bgr.row(y0).copyTo(row_min_);
    for (int y = y0 + 1; y < y1; ++y) cv::min(row_min_, bgr.row(y), row_min_);
    const uint8_t* m = row_min_.ptr<uint8_t>(0);
    for (int bx = 0; bx < bw; ++bx) {
      const int x0 = bx * kGlareBlock, x1 = std::min(bgr.cols, x0 + kGlareBlock);
      uint8_t lo[3] = {255, 255, 255}, hi = 0;
      for (int x = x0; x < x1; ++x)
        for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], m[3 * x + c]);
      for (int y = y0; y < y1; y += 4) {
        const uint8_t* p = bgr.ptr<uint8_t>(y);
        for (int x = x0; x < x1; x += 2) hi = std::max(hi, std::min({p[3 * x], p[3 * x + 1], p[3 * x + 2]}));
      }
      block_min_.at<cv::Vec3b>(by, bx) = {lo[0], lo[1], lo[2]};
      block_white_.at<uint8_t>(by, bx) = hi;
    }
  }
  // The frame's black level per channel: the 1st percentile of the blocks'.
  int black[3];
  for (int c = 0; c < 3; ++c) {
    std::fill(hist_.begin(), hist_.end(), 0);
    for (int y = 0; y < bh; ++y)
      for (int x = 0; x < bw; ++x) ++hist_[block_min_.at<cv::Vec3b>(y, x)[c]];
    int level = 0;
    for (int count = 0, want = std::max(1, bw * bh / 100); level < 255 && count + hist_[level] < want; ++level)
      count += hist_[level];
    black[c] = level;
  }
  // Local black (per channel) and white levels over the window.
  cv::erode(block_min_, local_black_, window_kernel_, {-1, -1}, 1, cv::BORDER_REPLICATE);
  cv::dilate(block_white_, local_white_, window_kernel_, {-1, -1}, 1, cv::BORDER_REPLICATE);
  // On a hot spot's slope the window's darkest thing sits where the veil is
  // weakest, so the local black lies under the block's veil by up to the
  // slope times the window's reach. The opening (the largest of the minima
  // of the windows that hold the block) takes it back up, by no more than
  // that: where the local black is flat, a larger opening is not the veil
  // but the colour of something that fills a window (a square's own ink),
  // and where it steps on one side only, that is an object's edge.
  cv::dilate(local_black_, local_open_, window_kernel_, {-1, -1}, 1, cv::BORDER_REPLICATE);
  const int reach = window_kernel_.cols / 2;
  for (int y = 0; y < bh; ++y) {
    const auto* up = local_black_.ptr<cv::Vec3b>(std::max(0, y - 1));
    const auto* row = local_black_.ptr<cv::Vec3b>(y);
    const auto* down = local_black_.ptr<cv::Vec3b>(std::min(bh - 1, y + 1));
    const auto* open = local_open_.ptr<cv::Vec3b>(y);
    auto* raised = local_open_.ptr<cv::Vec3b>(y);  // written in place: each block reads only its own
    for (int x = 0; x < bw; ++x) {
      const cv::Vec3b& left = row[std::max(0, x - 1)];
      const cv::Vec3b& right = row[std::min(bw - 1, x + 1)];
      for (int c = 0; c < 3; ++c) {
        // the slope on both sides alike: a step (an object's edge) is no slope
        const int e = row[x][c];
        const int slope = std::max(std::min(std::abs(right[c] - e), std::abs(e - left[c])),
                                   std::min(std::abs(down[x][c] - e), std::abs(e - up[x][c])));
        raised[x][c] = static_cast<uint8_t>(std::min(static_cast<int>(open[x][c]), e + slope * reach));
      }
    }
  }
  cv::swap(local_black_, local_open_);
  // Veiled blocks: every channel's local black well above the frame's black
  // in the light's colour (a veil lifts all of them; a coloured surface
  // some), with white well above it in the same window (ink and paper under
  // one veil, not a plain pale wall; near the clip, most of what is left of
  // the range) and enough of the range left to stretch.
  auto liftOf = [&](const cv::Vec3b& lb, const cv::Vec3d& light) {
    double lift = 255;
    for (int c = 0; c < 3; ++c) lift = std::min(lift, (lb[c] - black[c]) / light[c]);
    return lift;
  };
  auto isVeiled = [&](int y, int x, double lift) {
    const cv::Vec3b lb = local_black_.at<cv::Vec3b>(y, x);
    const int lb_min = std::min({lb[0], lb[1], lb[2]});
    const double contrast = std::min(params_.glare_min_contrast, kClipContrast * (255 - lb_min));
    return lift > params_.glare_min_lift && 255 - lb_min >= kMinHeadroom &&
           local_white_.at<uint8_t>(y, x) - lb_min > contrast;
  };
  // The light's colour relative to its strongest channel: the running
  // white estimate, or neutral before there is one ...
  cv::Vec3d light = white_[0] > 0 ? relativeColour(white_) : cv::Vec3d(1, 1, 1);
  // ... or, better, the veil's own colour (the light's: a reflection of the
  // lamp or window that lights the scene), measured on the veiled blocks as
  // the median ratio of each channel's lift to green's. With the colour
  // measured, each channel's veil is the common veil in that colour; with it
  // assumed, each channel may go a little above (kVeilSpread).
  for (auto& v : veil_ratios_) {
    v.clear();
    v.reserve(static_cast<size_t>(bw) * bh);  // (once per frame size: no allocation after)
  }
  for (int y = 0; y < bh; ++y)
    for (int x = 0; x < bw; ++x) {
      const cv::Vec3b lb = local_black_.at<cv::Vec3b>(y, x);
      if (!isVeiled(y, x, liftOf(lb, light))) continue;
      const double green = lb[1] - black[1];
      veil_ratios_[0].push_back((lb[0] - black[0]) / green);
      veil_ratios_[1].push_back((lb[2] - black[2]) / green);
    }
  double spread = kVeilSpread;
  if (veil_ratios_[0].size() >= static_cast<size_t>(kVeilColourBlocks)) {
    auto median = [](std::vector<double>& v) {
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      return v[v.size() / 2];
    };
    light = relativeColour({median(veil_ratios_[0]), 1.0, median(veil_ratios_[1])});
    spread = 1.0;
  }
  veil_colour_ = light;
  veil_coarse_.create(bh, bw, CV_8UC3);
  veiled_.create(bh, bw, CV_8UC1);
  bool any = false;
  for (int y = 0; y < bh; ++y)
    for (int x = 0; x < bw; ++x) {
      const cv::Vec3b lb = local_black_.at<cv::Vec3b>(y, x);
      // The largest veil of the light's colour under every channel's local
      // black; each channel's veil at most `spread` times that (a window
      // whose darkest thing in one channel is not dark, say a blue square's
      // blue, would lift that channel too far).
      const double lift = liftOf(lb, light);
      const bool veiled = isVeiled(y, x, lift);
      cv::Vec3b& v = veil_coarse_.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c)
        v[c] = cv::saturate_cast<uint8_t>(
            black[c] + (veiled ? std::min<double>(lb[c] - black[c], spread * lift * light[c]) : 0.0));
      veiled_.at<uint8_t>(y, x) = veiled ? 255 : 0;
      any |= veiled;
      if (veiled)
        for (int c = 0; c < 3; ++c)
          veil_stretch_ = std::max(veil_stretch_, (255.0 - black[c]) / std::max(1, 255 - v[c]));
    }
  if (!any) return bgr;
  glare_corrected_ = true;
  // A smooth veil (the blocks' steps would make edges); the blocks it
  // reaches after smoothing are the ones to correct.
  cv::GaussianBlur(veil_coarse_, veil_coarse_, {0, 0}, 1.0);
  cv::dilate(veiled_, veiled_, spread_kernel_);
  // Subtract it and stretch what is above it back to [black, 255], per
  // channel: out = black + (in - veil) * (255 - black) / (255 - veil), with
  // the veil interpolated between block centres (bilinear: one resize of the
  // block map) in the blocks that need it.
  int stretch[3][256];
  for (int c = 0; c < 3; ++c)
    for (int v = 0; v < 256; ++v) stretch[c][v] = ((255 - black[c]) << 8) / std::max(1, 255 - v);
  cv::resize(veil_coarse_, veil_full_, cv::Size(bw * kGlareBlock, bh * kGlareBlock), 0, 0, cv::INTER_LINEAR);
  bgr.copyTo(deglared_);
  for (int by = 0; by < bh; ++by) {
    const int y0 = by * kGlareBlock, y1 = std::min(bgr.rows, y0 + kGlareBlock);
    const uint8_t* veiled = veiled_.ptr<uint8_t>(by);
    for (int bx = 0; bx < bw;) {
      if (!veiled[bx]) {
        ++bx;
        continue;
      }
      // a run of veiled blocks along the row, corrected in one pass per pixel row
      const int first = bx;
      while (bx < bw && veiled[bx]) ++bx;
      const int x0 = 3 * first * kGlareBlock, x1 = 3 * std::min(bgr.cols, bx * kGlareBlock);
      for (int y = y0; y < y1; ++y) {
        const uint8_t* veil = veil_full_.ptr<uint8_t>(y);
        const uint8_t* src = bgr.ptr<uint8_t>(y);
        uint8_t* dst = deglared_.ptr<uint8_t>(y);
        for (int i = x0; i < x1; i += 3)
          for (int c = 0; c < 3; ++c) {
            const int v = veil[i + c];
            if (v > black[c] + 2)
              dst[i + c] = cv::saturate_cast<uint8_t>(black[c] + (((src[i + c] - v) * stretch[c][v]) >> 8));
          }
      }
    }
  }
  return deglared_;
}

const cv::Mat& LightingAdapter::correct(const cv::Mat& bgr_in) {
  gains_ = {1, 1, 1};
  glare_corrected_ = false;
  veil_stretch_ = 1.0;
  veil_colour_ = {1, 1, 1};
  if (bgr_in.empty() || bgr_in.type() != CV_8UC3) return bgr_in;
  const cv::Mat& bgr = deglare(bgr_in);
  if (frames_since_landmark_ < (1 << 20)) ++frames_since_landmark_;

  if (!fromLandmarks()) {
    // The whitest unclipped pixels, on a sparse grid: those whose weakest
    // channel is brightest. White and grey surfaces are bright in every
    // channel under any usual light; bright coloured ones (beige furniture,
    // yellow posters) are dark in one, so they do not pull the estimate.
    constexpr int kStep = 4;
    // One pass: per weakest-channel level, the count and the channel sums.
    std::fill(hist_.begin(), hist_.end(), 0);
    std::fill(level_sums_.begin(), level_sums_.end(), cv::Vec3d(0, 0, 0));
    int n = 0;
    for (int y = 0; y < bgr.rows; y += kStep) {
      const auto* row = bgr.ptr<cv::Vec3b>(y);
      for (int x = 0; x < bgr.cols; x += kStep, ++n) {
        const int v = std::min({row[x][0], row[x][1], row[x][2]});
        ++hist_[v];
        level_sums_[v] += cv::Vec3d(row[x][0], row[x][1], row[x][2]);
      }
    }
    const int want = std::max(1, static_cast<int>(params_.bright_fraction * n));
    int level = 249, count = 0;  // white clipped in every channel tells nothing
    for (; level > 0 && count + hist_[level] < want; --level) count += hist_[level];
    cv::Vec3d sum(0, 0, 0);
    int m = 0;
    for (int v = level; v < 250; ++v) sum += level_sums_[v], m += hist_[v];
    if (m > 0) update(sum / m);
  }
  if (white_[0] <= 0) return bgr;

  // Colour: raise the weaker channels of white to its strongest. Level:
  // brighten (never darken) so that white reaches the target.
  const double top = std::max({white_[0], white_[1], white_[2], 1.0});
  const double level = std::max(1.0, params_.target_white / top);
  bool needed = false;
  for (int c = 0; c < 3; ++c) {
    gains_[c] = std::clamp(level * top / std::max(white_[c], 1.0), 1.0 / params_.max_gain, params_.max_gain);
    needed |= std::abs(gains_[c] - 1.0) > params_.deadband;
  }
  if (!needed) {
    gains_ = {1, 1, 1};
    return bgr;
  }
  corrected_.create(bgr.size(), CV_8UC3);
  detail::scaleChannels(bgr, gains_, corrected_);  // (cv::multiply's values, without its buffer per call)
  // A strong correction amplifies the weak channel's noise and JPEG blocks
  // (under tungsten: blue) into speckled squares: smooth them back.
  if (params_.denoise_sigma > 0 && std::max({gains_[0], gains_[1], gains_[2]}) > params_.denoise_above_gain)
    cv::GaussianBlur(corrected_, corrected_, {0, 0}, params_.denoise_sigma);
  return corrected_;
}

void LightingAdapter::observe(const cv::Mat& original, const Detection& detection) {
  if (original.empty() || original.type() != CV_8UC3) return;
  // White sheet between the squares, beside the QR square (sheet units u).
  static const cv::Point2f kWhite[] = {{4.5f, 1.5f}, {1.5f, 4.5f}, {7.5f, 4.5f}, {4.5f, 7.5f}};
  cv::Vec3d sum(0, 0, 0);
  int m = 0;
  for (const Landmark& lm : detection.landmarks) {
    const cv::Matx33d H = layout::sheetToImage(lm.corners);
    std::array<cv::Vec3d, 4> white;
    size_t k = 0;
    for (const auto& w : kWhite) {
      const cv::Vec3d p = H * cv::Vec3d(w.x, w.y, 1.0);
      if (!(p[2] > 0)) continue;
      const int x = static_cast<int>(std::lround(p[0] / p[2])), y = static_cast<int>(std::lround(p[1] / p[2]));
      const cv::Rect r = cv::Rect(x - 1, y - 1, 3, 3) & cv::Rect(0, 0, original.cols, original.rows);
      if (r.area() == 0) continue;
      const cv::Scalar mean = cv::mean(original(r));
      if (std::max({mean[0], mean[1], mean[2]}) >= 250) continue;  // clipped: no colour information
      white[k++] = cv::Vec3d(mean[0], mean[1], mean[2]);
    }
    // A sample unlike the others in colour (a sticker where the detector
    // allows one spot, kSpotHue*) is not the light's: its chromaticity far
    // from the samples' median one. (Brightness may differ: a shadow.)
    std::array<cv::Vec3d, 4> chroma;
    for (size_t i = 0; i < k; ++i) chroma[i] = white[i] * (1.0 / std::max(1.0, cv::sum(white[i])[0]));
    cv::Vec3d median;  // per channel, of three samples or more
    for (int c = 0; c < 3 && k >= 3; ++c) {
      std::array<double, 4> v;
      // Insertion sort of the k <= 4 values (std::sort over part of a
      // std::array trips GCC 12's -Warray-bounds in the sanitizer build).
      for (size_t j = 0; j < k; ++j) {
        size_t i = j;
        for (; i > 0 && v[i - 1] > chroma[j][c]; --i) v[i] = v[i - 1];
        v[i] = chroma[j][c];
      }
      median[c] = k % 2 ? v[k / 2] : (v[k / 2 - 1] + v[k / 2]) / 2;
    }
    for (size_t i = 0; i < k; ++i) {
      if (k >= 3 && cv::norm(chroma[i] - median, cv::NORM_INF) > kOddSampleChroma) continue;
      sum += white[i];
      ++m;
    }
  }
  if (m == 0) return;
  update(sum / m);
  frames_since_landmark_ = 0;
}

AdaptiveDetector::AdaptiveDetector(const DetectorParams& params, const AdaptiveParams& adaptive)
    : detector_(params), adapter_(adaptive) {}

AdaptiveDetector::AdaptiveDetector(Detector detector, bool enabled, const AdaptiveParams& adaptive)
    : detector_(std::move(detector)), adapter_(adaptive), enabled_(enabled) {}

const cv::Mat& AdaptiveDetector::correct(const cv::Mat& bgr) {
  const cv::Mat& corrected = adapter_.correct(bgr);
  detector_.setGlareCorrected(adapter_.strongVeil());
  return corrected;
}

const cv::Mat& AdaptiveDetector::asBgr(const cv::Mat& image) {
  // (the adapter reads BGR: a BGRA frame went to the detector uncorrected,
  // and taught the adapter nothing)
  if (image.type() != CV_8UC4) return image;
  cv::cvtColor(image, bgr_, cv::COLOR_BGRA2BGR);
  return bgr_;
}

const Detection& AdaptiveDetector::detect(const cv::Mat& image) { return detectWith(image, nullptr); }

const Detection& AdaptiveDetector::detect(const cv::Mat& image, Explanation& why) { return detectWith(image, &why); }

// (the correction's time is the detection's first stage, "adapt": the
// stage timings of LANDMARKS and the bench said nothing of it)
const Detection& AdaptiveDetector::detectWith(const cv::Mat& image, Explanation* why) {
  const auto run = [&](const cv::Mat& frame) -> const Detection& {
    return why ? detector_.detect(frame, *why) : detector_.detect(frame);
  };
  if (!enabled_) return run(image);
  const auto t0 = std::chrono::steady_clock::now();
  const cv::Mat& bgr = asBgr(image);
  const cv::Mat& corrected = correct(bgr);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const Detection& d = run(corrected);
  detector_.addStageBefore("adapt", ms);
  adapter_.observe(bgr, d);
  return d;
}

}  // namespace ld
