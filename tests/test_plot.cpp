// ld-eval's plots (ld/plot.hpp): the legend hides no point of a series.
#include <cmath>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/plot.hpp"

namespace {

using L = ld::PlotLayout;

// Where a point (x in [x0, x1], rate 0..1) is drawn.
cv::Point pixel(double x, double rate, double x0, double x1) {
  return {L::kLeft + static_cast<int>(std::lround((x - x0) / (x1 - x0) * (L::kWidth - L::kLeft - L::kRight))),
          L::kTop + static_cast<int>(std::lround((1 - rate) * (L::kHeight - L::kTop - L::kBottom)))};
}

bool white(const cv::Mat& img, cv::Point p) { return img.at<cv::Vec3b>(p) == cv::Vec3b(255, 255, 255); }

// Pixels of the legend's frame's grey in `area`.
int framePixels(const cv::Mat& img, const cv::Rect& area) {
  int n = 0;
  for (int y = area.y; y < area.y + area.height; ++y)
    for (int x = area.x; x < area.x + area.width; ++x) n += img.at<cv::Vec3b>(y, x) == cv::Vec3b(200, 200, 200);
  return n;
}

// Every drawn point of every series shows its colour (not the legend's white box).
void expectEveryPointShows(const cv::Mat& img, const std::vector<ld::PlotSeries>& series, double x0, double x1) {
  for (const auto& s : series)
    for (const auto& p : s.points) EXPECT_FALSE(white(img, pixel(p.x, p.y, x0, x1))) << s.name << " at " << p;
}

TEST(Plot, LegendGoesInsideWhereItHidesNothing) {
  // rates high on the left and low on the right leave the top right free
  const std::vector<ld::PlotSeries> series{{"ours", {{0, 1}, {1, 0.9}, {2, 0.2}, {3, 0}}},
                                           {"theirs", {{0, 0.8}, {1, 0.5}, {2, 0.1}, {3, 0}}}};
  const cv::Mat img = ld::drawRatePlot("t", "x", series);
  EXPECT_EQ(img.cols, L::kWidth);
  EXPECT_EQ(img.rows, L::kHeight);
  expectEveryPointShows(img, series, 0, 3);
  // the legend's frame (its own grey) is inside the plot
  EXPECT_GT(framePixels(img, cv::Rect(L::kLeft, L::kTop, L::kWidth - L::kLeft - L::kRight,
                                      L::kHeight - L::kTop - L::kBottom)),
            100);
}

TEST(Plot, LegendGoesBelowWhereEveryPlaceInsideWouldHideAPoint) {
  // lines across every height at every x: no corner nor middle is free
  std::vector<ld::PlotSeries> series(4);
  for (int j = 0; j < 4; ++j) {
    series[static_cast<size_t>(j)].name = "series " + std::to_string(j);
    for (int k = 0; k <= 20; ++k) series[static_cast<size_t>(j)].points.emplace_back(k, ((k + j) % 4) / 3.0);
  }
  const cv::Mat img = ld::drawRatePlot("t", "x", series);
  EXPECT_EQ(img.cols, L::kWidth);
  EXPECT_GT(img.rows, L::kHeight);
  expectEveryPointShows(img, series, 0, 20);
  // the legend's frame is below the plot, none inside it, as wide as its
  // two columns of two (no empty third column)
  int frame_left = img.cols, frame_right = -1;
  for (int y = L::kHeight; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (img.at<cv::Vec3b>(y, x) == cv::Vec3b(200, 200, 200)) frame_left = std::min(frame_left, x), frame_right = x > frame_right ? x : frame_right;
  const int names = [] {
    int baseline = 0;
    return cv::getTextSize("series 0", cv::FONT_HERSHEY_SIMPLEX, 0.5, 1, &baseline).width;
  }();
  EXPECT_LT(frame_right - frame_left, 2 * (names + 60));
  EXPECT_GT(framePixels(img, cv::Rect(0, L::kHeight, img.cols, img.rows - L::kHeight)), 100);
  EXPECT_EQ(framePixels(img, cv::Rect(L::kLeft, L::kTop, L::kWidth - L::kLeft - L::kRight,
                                      L::kHeight - L::kTop - L::kBottom)),
            0);
}

}  // namespace
