// The QR tests' count of a module estimate against the printed code: the
// data modules (all but the function patterns, which the reader redraws
// ideal) it gets wrong; and covers painted over a landmark's code. Tests
// include it by its path.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/artwork.hpp"
#include "ld/landmark_layout.hpp"
#include "../qr_reader/src/qr_function_patterns.hpp"

namespace ld::test {

// 1 for each of an n-module code's function-pattern modules (row-major).
inline std::vector<uint8_t> functionModules(int n) {
  std::vector<uint8_t> function(static_cast<size_t>(n) * n, 0);
  ld::detail::forEachFunctionModule(n, [&](int r, int c, bool) { function[static_cast<size_t>(r) * n + c] = 1; });
  return function;
}

// Paints each pixel of `image` (8-bit BGR) that lies in the sheet's [x0,
// x1] x [y0, y1] (units u) of the landmark at `corners` the colour
// `colour(u, v)` gives: a cover over part of its code.
template <typename Colour>
void paintOnSheet(cv::Mat& image, const std::array<cv::Point2f, 4>& corners, double x0, double x1, double y0,
                  double y1, Colour&& colour) {
  const cv::Matx33d to_sheet = ld::layout::sheetToImage(corners).inv();
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      const cv::Vec3d p = to_sheet * cv::Vec3d(x, y, 1.0);
      const double u = p[0] / p[2], v = p[1] / p[2];
      if (u >= x0 && u <= x1 && v >= y0 && v <= y1) image.at<cv::Vec3b>(y, x) = colour(u, v);
    }
}

struct DataModulesWrong {
  int wrong = 0;  // data modules `modules` has otherwise than `qr`
  int count = 0;  // data modules in the code
};
// `modules`: n x n, 1 dark, as the pixel model estimates them (an empty or
// short estimate counts only the modules it has).
inline DataModulesWrong wrongDataModules(const ld::artwork::QrCode& qr, const std::vector<uint8_t>& modules) {
  const int n = qr.size;
  const std::vector<uint8_t> function = functionModules(n);
  DataModulesWrong w;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const size_t i = static_cast<size_t>(r) * n + c;
      if (function[i]) continue;
      ++w.count;
      if (i < modules.size()) w.wrong += (modules[i] != 0) != qr.dark(c, r);
    }
  return w;
}

}  // namespace ld::test
