#include "ld/markers.hpp"

#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"

namespace ld::markers {

std::string name(Kind kind) { return kind == Kind::AprilTag ? "AprilTag 3" : "ArUco"; }

Kind parse(const std::string& s) {
  if (s == "apriltag") return Kind::AprilTag;
  if (s == "aruco") return Kind::Aruco;
  throw std::invalid_argument("marker kind must be apriltag or aruco, not '" + s + "'");
}

namespace {

struct Family {
  apriltag_family_t* f = tag36h11_create();
  ~Family() { tag36h11_destroy(f); }
};

apriltag_family_t* family() {
  static Family fam;
  return fam.f;
}

cv::Mat aprilTagImage(int id) {
  apriltag_family_t* fam = family();
  if (id < 0 || id >= static_cast<int>(fam->ncodes)) throw std::invalid_argument("no such AprilTag id");
  image_u8_t* im = apriltag_to_image(fam, id);
  // The family image has one white module around the black border: drop it.
  const int b = (static_cast<int>(fam->total_width) - static_cast<int>(fam->width_at_border)) / 2;
  const cv::Mat full(im->height, im->width, CV_8UC1, im->buf, static_cast<size_t>(im->stride));
  cv::Mat tag = full(cv::Rect(b, b, im->width - 2 * b, im->height - 2 * b)).clone();
  // Debian's libapriltag exports apriltag_to_image but not image_u8_destroy;
  // this is what image_u8_destroy does (the image and its buffer are malloc'd).
  free(im->buf);
  free(im);
  return tag;
}

}  // namespace

cv::Mat sheetTexture(Kind kind, int id, int side_px) {
  cv::Mat marker;
  if (kind == Kind::AprilTag) {
    marker = aprilTagImage(id);
  } else {
    cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50)->drawMarker(id, 60, marker, 1);
  }
  cv::Mat sheet(side_px, side_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const int m0 = static_cast<int>(std::lround(side_px * layout::kPatternMin / layout::kUnits));
  const int m1 = static_cast<int>(std::lround(side_px * layout::kPatternMax / layout::kUnits));
  cv::Mat scaled, bgr;
  cv::resize(marker, scaled, {m1 - m0, m1 - m0}, 0, 0, cv::INTER_NEAREST);
  cv::cvtColor(scaled, bgr, cv::COLOR_GRAY2BGR);
  bgr.copyTo(sheet(cv::Rect(m0, m0, m1 - m0, m1 - m0)));
  return sheet;
}

struct Detector::Impl {
  Kind kind;
  apriltag_detector_t* td = nullptr;
  cv::Ptr<cv::aruco::Dictionary> dict;
  cv::Ptr<cv::aruco::DetectorParameters> params;
};

Detector::Detector(Kind kind) : impl_(std::make_unique<Impl>()) {
  impl_->kind = kind;
  if (kind == Kind::AprilTag) {
    impl_->td = apriltag_detector_create();
    apriltag_detector_add_family(impl_->td, family());
    impl_->td->nthreads = 1;  // quad_decimate stays at its default (2.0)
  } else {
    impl_->dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
    impl_->params = cv::aruco::DetectorParameters::create();
  }
}

Detector::~Detector() {
  if (impl_ && impl_->td) apriltag_detector_destroy(impl_->td);
}
Detector::Detector(Detector&&) noexcept = default;
Detector& Detector::operator=(Detector&& o) noexcept {
  if (this != &o) {
    if (impl_ && impl_->td) apriltag_detector_destroy(impl_->td);
    impl_ = std::move(o.impl_);
  }
  return *this;
}

Kind Detector::kind() const { return impl_->kind; }

std::vector<Found> Detector::detect(const cv::Mat& gray) {
  std::vector<Found> out;
  if (gray.empty() || gray.type() != CV_8UC1) return out;
  if (impl_->kind == Kind::AprilTag) {
    image_u8_t im{gray.cols, gray.rows, static_cast<int32_t>(gray.step), gray.data};
    zarray_t* dets = apriltag_detector_detect(impl_->td, &im);
    for (int k = 0; k < zarray_size(dets); ++k) {
      apriltag_detection_t* d;
      zarray_get(dets, k, &d);
      Found f{d->id, {}};
      // AprilTag's corners run counter-clockwise from the bottom left in
      // the tag's frame; ours clockwise from the top left. Its pixel
      // coordinates put a pixel's centre at +0.5 (AprilRobotics/apriltag
      // issue 121; measured here on ld-synth's renders: +0.50 px in x and y
      // on average); OpenCV's, ours, at the integer: half a pixel less.
      const int order[4] = {3, 2, 1, 0};
      for (int i = 0; i < 4; ++i)
        f.corners[static_cast<size_t>(i)] = {static_cast<float>(d->p[order[i]][0] - 0.5),
                                             static_cast<float>(d->p[order[i]][1] - 0.5)};
      out.push_back(f);
    }
    apriltag_detections_destroy(dets);
  } else {
    std::vector<std::vector<cv::Point2f>> corners;
    std::vector<int> ids;
    cv::aruco::detectMarkers(gray, impl_->dict, corners, ids, impl_->params);
    for (size_t k = 0; k < ids.size(); ++k) {
      Found f{ids[k], {}};
      for (size_t i = 0; i < 4; ++i) f.corners[i] = corners[k][i];
      out.push_back(f);
    }
  }
  return out;
}

bool matches(const Quad& quad, const std::array<cv::Point2d, 4>& truth) {
  cv::Point2d c(0, 0), tc(0, 0);
  for (const auto& p : quad) c += cv::Point2d(p) * 0.25;
  for (const auto& p : truth) tc += p * 0.25;
  return cv::norm(c - tc) < std::max(3.0, 0.1 * cv::norm(truth[1] - truth[0]));
}

}  // namespace ld::markers
