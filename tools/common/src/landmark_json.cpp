#include "ld/landmark_json.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

namespace ld {
namespace {

double round3(double v) { return std::round(v * 1000.0) / 1000.0; }
double round6(double v) { return std::round(v * 1e6) / 1e6; }

nlohmann::ordered_json point(const cv::Point2f& p) { return {round3(p.x), round3(p.y)}; }

}  // namespace

nlohmann::ordered_json toJson(const Landmark& lm) {
  nlohmann::ordered_json j;
  j["fip_tl"] = point(lm.fip_tl);
  j["fip_tr"] = point(lm.fip_tr);
  j["fip_bl"] = point(lm.fip_bl);
  j["ap"] = point(lm.ap);
  j["corners"] = nlohmann::ordered_json::array();
  for (const auto& c : lm.corners) j["corners"].push_back(point(c));
  j["payload"] = lm.payload ? nlohmann::ordered_json(*lm.payload) : nlohmann::ordered_json(nullptr);
  if (lm.pose) {
    const Pose& p = *lm.pose;
    j["pose"] = {{"t", {round6(p.t[0]), round6(p.t[1]), round6(p.t[2])}},
                 {"rvec", {round6(p.rvec[0]), round6(p.rvec[1]), round6(p.rvec[2])}},
                 {"distance", round6(p.distance)}};
  }
  return j;
}

void drawLandmarks(cv::Mat& bgr, const std::vector<Landmark>& landmarks) {
  const int thick = std::max(1, bgr.cols / 640);
  for (const Landmark& lm : landmarks) {
    std::vector<cv::Point> quad;
    for (const auto& c : lm.corners) quad.emplace_back(cvRound(c.x), cvRound(c.y));
    cv::polylines(bgr, quad, true, cv::Scalar(0, 255, 0), thick, cv::LINE_AA);
    const cv::Scalar fip(255, 255, 0), ap(0, 255, 255);
    for (const auto& c : {lm.fip_tl, lm.fip_tr, lm.fip_bl})
      cv::drawMarker(bgr, c, fip, cv::MARKER_CROSS, 6 * thick, thick);
    cv::drawMarker(bgr, lm.ap, ap, cv::MARKER_DIAMOND, 6 * thick, thick);
    cv::circle(bgr, lm.corners[0], 4 * thick, cv::Scalar(0, 0, 255), thick, cv::LINE_AA);
    std::string label = lm.payload ? *lm.payload : "";
    if (lm.pose) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%s%.2f m", label.empty() ? "" : " ", lm.pose->distance);
      label += buf;
    }
    if (!label.empty()) drawLabel(bgr, label, lm.corners[0] + cv::Point2f(0, -6.0f * thick), cv::Scalar(0, 255, 0), thick);
  }
}

void drawLabel(cv::Mat& bgr, const std::string& text, cv::Point2f at, const cv::Scalar& colour, int thick) {
  const double scale = 0.45 * thick;
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thick, &baseline);
  // (inside the image where it fits, its outline and the letters below the
  // line included: a label by a corner near the right edge ran off it)
  const int margin = 3 * thick + 1;  // (the outline is drawn 3 * thick wide)
  const auto place = [](double v, int lo, int hi) {
    if (!std::isfinite(v)) return lo;
    return static_cast<int>(std::clamp(std::round(v), static_cast<double>(lo), static_cast<double>(std::max(lo, hi))));
  };
  const int x = place(at.x, margin, bgr.cols - size.width - margin);
  // (brackets rise above the height getTextSize gives: a quarter more)
  const int y = place(at.y, size.height + size.height / 4 + margin, bgr.rows - baseline - margin);
  cv::putText(bgr, text, {x, y}, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 3 * thick, cv::LINE_AA);
  cv::putText(bgr, text, {x, y}, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thick, cv::LINE_AA);
}

}  // namespace ld
