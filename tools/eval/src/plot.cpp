// ld-eval's plots (ld/plot.hpp).
#include "ld/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

#include <opencv2/imgproc.hpp>

namespace ld {

cv::Mat drawRatePlot(const std::string& title, const std::string& xlabel, const std::vector<PlotSeries>& series) {
  constexpr int W = PlotLayout::kWidth, H = PlotLayout::kHeight, L = PlotLayout::kLeft, R = PlotLayout::kRight,
                T = PlotLayout::kTop, B = PlotLayout::kBottom;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  double x0 = 1e18, x1 = -1e18;
  for (const auto& s : series)
    for (const auto& p : s.points) x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
  if (!(x1 > x0)) x1 = x0 + 1;
  const auto px = [&](double x, double y) {
    return cv::Point(L + static_cast<int>(std::lround((x - x0) / (x1 - x0) * (W - L - R))),
                     T + static_cast<int>(std::lround((1 - y) * (H - T - B))));
  };
  const auto text = [&](const std::string& s, cv::Point at, double scale = 0.5) {
    cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  };
  for (int k = 0; k <= 10; ++k) {
    const double y = k / 10.0;
    cv::line(img, px(x0, y), px(x1, y), cv::Scalar(225, 225, 225));
    text(std::to_string(k * 10), px(x0, y) + cv::Point(-35, 5));
  }
  // Ticks at the sweep's values when there are few, else 8 even steps.
  std::vector<double> xs;
  if (!series.empty() && series[0].points.size() <= 17)
    for (const auto& p : series[0].points) xs.push_back(p.x);
  else
    for (int k = 0; k <= 8; ++k) xs.push_back(x0 + (x1 - x0) * k / 8);
  int label_end = -1;  // where the last tick label drawn ends
  for (double x : xs) {
    cv::line(img, px(x, 0), px(x, 1), cv::Scalar(235, 235, 235));
    std::ostringstream s;
    s << std::round(x * 100) / 100;
    // centred under its tick, kept inside the image, and left out where it
    // would run into the one before (the grid line stays)
    int baseline = 0;
    const int w = cv::getTextSize(s.str(), cv::FONT_HERSHEY_SIMPLEX, 0.5, 1, &baseline).width;
    const int left = std::clamp(px(x, 0).x - w / 2, 0, W - w - 2);
    if (left <= label_end + 6) continue;
    text(s.str(), {left, px(x, 0).y + 20});
    label_end = left + w;
  }
  cv::rectangle(img, px(x0, 1), px(x1, 0), cv::Scalar(0, 0, 0));
  text(title, {L, 30}, 0.6);
  text(xlabel, {W / 2 - 60, H - 15});
  text("%", {15, T + (H - T - B) / 2});
  const cv::Scalar colours[] = {{200, 80, 0}, {0, 0, 220}, {0, 150, 0}, {150, 0, 150}, {0, 140, 220}, {80, 80, 80}};
  // (the first series, ours, drawn last: on top where others have the same
  // rates; each series beneath it drawn wider, so that one with the same
  // rates shows on both sides of the line over it, where it was hidden: the
  // QR plot's short payloads over 2 frames under those of single frames)
  const auto width = [](size_t j) { return 2 + 2 * static_cast<int>(std::min<size_t>(j, 4)); };
  for (size_t j = series.size(); j-- > 0;) {
    const cv::Scalar c = colours[j % 6];
    const auto& pts = series[j].points;
    for (size_t k = 0; k < pts.size(); ++k) {
      cv::circle(img, px(pts[k].x, pts[k].y), width(j) / 2 + 2, c, cv::FILLED, cv::LINE_AA);
      if (k > 0) cv::line(img, px(pts[k - 1].x, pts[k - 1].y), px(pts[k].x, pts[k].y), c, width(j), cv::LINE_AA);
    }
  }
  // the legend on a white box with a thin frame, in the corner (or the
  // middle of the top or bottom) of the plot where it hides none of the
  // lines' points (it sat bottom left, over the low rates of small
  // landmarks in the size plot), else below the plot (the fewest hidden
  // still hid two of our points in the motion plot, and an AprilTag point
  // in the distance plot)
  int legend_w = 0;
  for (const auto& sr : series) {
    int baseline = 0;
    legend_w = std::max(legend_w, cv::getTextSize(sr.name, cv::FONT_HERSHEY_SIMPLEX, 0.5, 1, &baseline).width);
  }
  if (!series.empty()) {
    const cv::Size box_size(legend_w + 32 + 22, 22 * static_cast<int>(series.size()) + 6);
    const int left = L + 8, right = W - R - 8 - box_size.width, bottom = H - B - 8 - box_size.height, top = T + 8;
    cv::Rect box;
    size_t hidden_least = SIZE_MAX;
    const int middle = (left + right) / 2;
    for (const cv::Point corner : {cv::Point(left, bottom), cv::Point(right, bottom), cv::Point(middle, bottom),
                                   cv::Point(right, top), cv::Point(left, top), cv::Point(middle, top)}) {
      const cv::Rect at(corner, box_size);
      // (grown by the widest marker's radius: a point just outside the box
      // still had its dot cut)
      const cv::Rect near(at.x - 7, at.y - 7, at.width + 14, at.height + 14);
      size_t hidden = 0;  // the points, and the lines every 3 pixels between each two, under it
      for (const auto& sr : series)
        for (size_t k = 0; k < sr.points.size(); ++k) {
          const auto& a = sr.points[k];
          const auto& b = k > 0 ? sr.points[k - 1] : a;
          const cv::Point pa = px(a.x, a.y), pb = px(b.x, b.y);
          const int steps = std::max(1, static_cast<int>(std::ceil(cv::norm(pa - pb) / 3.0)));
          for (int f = 0; f < steps; ++f) {
            const double t = static_cast<double>(f) / steps;
            hidden += near.contains(px(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t));
          }
        }
      if (hidden < hidden_least) hidden_least = hidden, box = at;
    }
    // (below, in as many columns as fit side by side, up to three)
    const int n = static_cast<int>(series.size());
    int columns = 1, rows = n;
    if (hidden_least > 0) {
      columns = std::clamp((W - L - R) / box_size.width, 1, std::min(3, n));
      rows = (n + columns - 1) / columns;
      columns = (n + rows - 1) / rows;  // (4 in 3 columns fill two rows of 2: no empty third)
      const cv::Size below(box_size.width * columns, 22 * rows + 6);
      cv::copyMakeBorder(img, img, 0, below.height + 10, 0, 0, cv::BORDER_CONSTANT, cv::Scalar(255, 255, 255));
      box = cv::Rect(cv::Point(L, H + 2), below);
    }
    cv::rectangle(img, box, cv::Scalar(255, 255, 255), cv::FILLED);
    cv::rectangle(img, box, cv::Scalar(200, 200, 200), 1);
    for (size_t i = 0; i < series.size(); ++i) {
      const cv::Scalar c = colours[i % 6];
      const int row = static_cast<int>(i) % rows, column = static_cast<int>(i) / rows;
      const cv::Point at(box.x + 7 + column * box_size.width, box.y + 17 + 22 * row);
      cv::line(img, at, at + cv::Point(25, 0), c, width(i), cv::LINE_AA);
      text(series[i].name, at + cv::Point(32, 5));
    }
  }
  return img;
}

}  // namespace ld
