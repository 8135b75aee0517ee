#include "ld/adaptive.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"

namespace ld {

LightingAdapter::LightingAdapter(const AdaptiveParams& params) : params_(params), hist_(256) {}

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

const cv::Mat& LightingAdapter::correct(const cv::Mat& bgr) {
  gains_ = {1, 1, 1};
  if (bgr.empty() || bgr.type() != CV_8UC3) return bgr;
  if (frames_since_landmark_ < (1 << 20)) ++frames_since_landmark_;

  if (!fromLandmarks()) {
    // The whitest unclipped pixels, on a sparse grid: those whose weakest
    // channel is brightest. White and grey surfaces are bright in every
    // channel under any usual light; bright coloured ones (beige furniture,
    // yellow posters) are dark in one, so they do not pull the estimate.
    constexpr int kStep = 4;
    std::fill(hist_.begin(), hist_.end(), 0);
    int n = 0;
    for (int y = 0; y < bgr.rows; y += kStep) {
      const auto* row = bgr.ptr<cv::Vec3b>(y);
      for (int x = 0; x < bgr.cols; x += kStep, ++n)
        ++hist_[std::min({row[x][0], row[x][1], row[x][2]})];
    }
    const int want = std::max(1, static_cast<int>(params_.bright_fraction * n));
    int level = 249, count = 0;  // white clipped in every channel tells nothing
    for (; level > 0 && count + hist_[level] < want; --level) count += hist_[level];
    cv::Vec3d sum(0, 0, 0);
    int m = 0;
    for (int y = 0; y < bgr.rows; y += kStep) {
      const auto* row = bgr.ptr<cv::Vec3b>(y);
      for (int x = 0; x < bgr.cols; x += kStep) {
        const int v = std::min({row[x][0], row[x][1], row[x][2]});
        if (v >= level && v < 250) sum += cv::Vec3d(row[x][0], row[x][1], row[x][2]), ++m;
      }
    }
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
  cv::multiply(bgr, cv::Scalar(gains_[0], gains_[1], gains_[2]), corrected_);
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
  std::vector<cv::Point2f> sheet, img(4);
  for (const auto& c : layout::kCornersU)
    sheet.emplace_back(static_cast<float>(c[0]), static_cast<float>(c[1]));
  cv::Vec3d sum(0, 0, 0);
  int m = 0;
  for (const Landmark& lm : detection.landmarks) {
    std::copy(lm.corners.begin(), lm.corners.end(), img.begin());
    const cv::Matx33d H(cv::getPerspectiveTransform(sheet, img));
    for (const auto& w : kWhite) {
      const cv::Vec3d p = H * cv::Vec3d(w.x, w.y, 1.0);
      if (!(p[2] > 0)) continue;
      const int x = static_cast<int>(std::lround(p[0] / p[2])), y = static_cast<int>(std::lround(p[1] / p[2]));
      const cv::Rect r = cv::Rect(x - 1, y - 1, 3, 3) & cv::Rect(0, 0, original.cols, original.rows);
      if (r.area() == 0) continue;
      const cv::Scalar mean = cv::mean(original(r));
      if (std::max({mean[0], mean[1], mean[2]}) >= 250) continue;  // clipped: no colour information
      sum += cv::Vec3d(mean[0], mean[1], mean[2]);
      ++m;
    }
  }
  if (m == 0) return;
  update(sum / m);
  frames_since_landmark_ = 0;
}

AdaptiveDetector::AdaptiveDetector(const DetectorParams& params, const AdaptiveParams& adaptive)
    : detector_(params), adapter_(adaptive) {}

const Detection& AdaptiveDetector::detect(const cv::Mat& bgr) {
  const Detection& d = detector_.detect(adapter_.correct(bgr));
  adapter_.observe(bgr, d);
  return d;
}

}  // namespace ld
