// The CPU backend's filters (filters.hpp), and what both backends share:
// the resolved filter settings and Canny's hysteresis.
#include <cstdint>
#include <cstring>

#include <opencv2/imgproc.hpp>

#include "filters.hpp"

namespace ld::detail {

FilterSettings FilterSettings::from(const DetectorParams& p) {
  FilterSettings s;
  const bool paper = p.front_end == "paper";
  s.blur_kernel = p.blur_kernel >= 0 ? p.blur_kernel : (paper ? 9 : 0);
  // (the paper front end's own kernel takes a sigma given: it was dropped
  // for the paper's 3 without a word)
  s.blur_sigma = p.blur_kernel >= 0 || p.blur_sigma > 0 ? p.blur_sigma : (paper ? 3.0 : 0.0);
  s.mask = {p.saturation_threshold_blue, p.saturation_threshold, p.value_min};
  s.saturation_threshold = p.saturation_threshold;
  s.canny_low = p.canny_low;
  s.canny_high = p.canny_high;
  return s;
}

void hysteresis(const cv::Mat& nms, cv::Mat& edges, std::vector<int>& stack) {
  CV_Assert(nms.type() == CV_8UC1);
  const int w = nms.cols, h = nms.rows;
  if (edges.datastart == nms.datastart) edges.release();  // never written over its input
  edges.create(nms.size(), CV_8UC1);
  edges.setTo(0);
  stack.clear();
  auto push = [&](int x, int y) {
    uint8_t& e = edges.at<uint8_t>(y, x);
    if (e || nms.at<uint8_t>(y, x) == 0) return;
    e = 255;
    stack.push_back(y * w + x);
  };
  for (int y = 0; y < h; ++y) {
    const uint8_t* row = nms.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      // the map is mostly zeros: skip them eight at a time
      while (x + 8 <= w) {
        uint64_t word;
        std::memcpy(&word, row + x, 8);
        if (word) break;
        x += 8;
      }
      if (x >= w) break;
      if (row[x] != 2 || edges.at<uint8_t>(y, x)) continue;
      push(x, y);
      while (!stack.empty()) {
        const int i = stack.back();
        stack.pop_back();
        const int cx = i % w, cy = i / w;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int nx = cx + dx, ny = cy + dy;
            if ((dx || dy) && nx >= 0 && ny >= 0 && nx < w && ny < h) push(nx, ny);
          }
      }
    }
  }
}

namespace {

class CpuFilters final : public Filters {
 public:
  const char* name() const override { return "cpu"; }
  std::string info(bool paper) const override {
    return paper ? "cpu: OpenCV's blur and Canny" : "cpu: the vectorised label pass";
  }

  void labelMap(const cv::Mat& bgr, const FilterSettings& s, cv::Mat& labels, const cv::Mat*& filtered,
                StageTimer& timer) override {
    filtered = &bgr;
    if (s.blur_kernel > 1) {
      cv::GaussianBlur(bgr, blurred_, {s.blur_kernel, s.blur_kernel}, s.blur_sigma);
      filtered = &blurred_;
      timer.stamp("blur");
    }
    saturationMask(*filtered, s.mask, labels);
    timer.stamp("saturation");
  }

  void edgeMap(const cv::Mat& bgr, const FilterSettings& s, cv::Mat& edges, StageTimer& timer) override {
    const cv::Mat* src = &bgr;
    if (s.blur_kernel > 1) {
      cv::GaussianBlur(bgr, blurred_, {s.blur_kernel, s.blur_kernel}, s.blur_sigma);
      src = &blurred_;
      timer.stamp("blur");
    }
    saturationImage(*src, sat_);
    cv::threshold(sat_, sat_, s.saturation_threshold * 255.0, 0, cv::THRESH_TOZERO);
    timer.stamp("saturation");
    cv::Canny(sat_, edges, s.canny_low, s.canny_high);
    timer.stamp("edges");
  }

 private:
  cv::Mat blurred_, sat_;
};

}  // namespace

std::unique_ptr<Filters> makeCpuFilters() { return std::make_unique<CpuFilters>(); }

}  // namespace ld::detail
