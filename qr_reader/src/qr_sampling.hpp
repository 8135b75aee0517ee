// Where a printed code's modules lie in the image, and images as gray: what
// the QR reader (qr_reader.cpp) and the look at a read code (qr_look.cpp)
// both sample with. Not a public interface.
#pragma once

#include <array>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"

namespace ld::detail {

// A point of an n-module symbol, in modules from its edge (`module`: a
// module's side in sheet units; the QR square holds the symbol and one
// module of quiet zone, as ld-generate prints it), in the image.
inline cv::Vec2f moduleToImage(const cv::Matx33d& sheet_to_image, double module, double x, double y) {
  const cv::Vec3d p =
      sheet_to_image * cv::Vec3d(layout::kQrMin + module * (1 + x), layout::kQrMin + module * (1 + y), 1.0);
  return {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])};
}

// `image` (gray, BGR or BGRA) as gray in `gray`, always `gray`'s own buffer
// (a gray image is copied, not shared, so a later colour frame is never
// converted into the caller's image).
inline void toGray(const cv::Mat& image, cv::Mat& gray) {
  if (image.channels() == 3) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4) cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  else image.copyTo(gray);
}

// Whether every corner is a finite point.
inline bool finiteCorners(const std::array<cv::Point2f, 4>& corners) {
  for (const auto& c : corners)
    if (!std::isfinite(c.x) || !std::isfinite(c.y)) return false;
  return true;
}

}  // namespace ld::detail
