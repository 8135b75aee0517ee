// ld-eval's plots: line charts of rates against a swept value.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace ld {

struct PlotSeries {
  std::string name;
  std::vector<cv::Point2d> points;  ///< (x, rate 0..1)
};

/// The chart's layout in pixels: the image's size and the plot area's
/// margins (left, right, top, bottom), the legend's height below it aside.
struct PlotLayout {
  static constexpr int kWidth = 800, kHeight = 500, kLeft = 70, kRight = 20, kTop = 50, kBottom = 60;
};

/// A chart of rates (drawn 0 to 100 %) against x, one line per series, the
/// first series (ours) drawn last, on top, and each one beneath it wider.
/// The legend sits in the corner (or the middle of the top or bottom) of
/// the plot where it hides no point or line of a series; where every such
/// place would hide one, below the plot, the image then that much taller.
cv::Mat drawRatePlot(const std::string& title, const std::string& xlabel, const std::vector<PlotSeries>& series);

}  // namespace ld
