// AprilTag 3 and ArUco markers printed like our landmark: the texture puts
// the marker where our pattern is, and each detector finds its marker at the
// pose our landmark would have, with corners in our order.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"
#include "ld/markers.hpp"
#include "ld/synth.hpp"

TEST(Markers, TextureFillsThePatternSquare) {
  for (auto kind : {ld::markers::Kind::AprilTag, ld::markers::Kind::Aruco}) {
    const cv::Mat t = ld::markers::sheetTexture(kind, 3, 540);
    ASSERT_EQ(t.size(), cv::Size(540, 540));
    ASSERT_EQ(t.type(), CV_8UC3);
    // white margin (0.5u = 30 px), black border just inside the pattern square
    EXPECT_EQ(t.at<cv::Vec3b>(10, 270), cv::Vec3b(255, 255, 255));
    EXPECT_EQ(t.at<cv::Vec3b>(32, 270), cv::Vec3b(0, 0, 0));
    EXPECT_EQ(t.at<cv::Vec3b>(270, 32), cv::Vec3b(0, 0, 0));
    EXPECT_EQ(t.at<cv::Vec3b>(530, 530), cv::Vec3b(255, 255, 255));
  }
  EXPECT_THROW(ld::markers::parse("qr"), std::invalid_argument);
}

TEST(Markers, EachDetectorFindsItsMarkerAtOurPose) {
  const auto cam = ld::CameraModel::defaultVga();
  for (auto kind : {ld::markers::Kind::AprilTag, ld::markers::Kind::Aruco}) {
    ld::markers::Detector det(kind);
    for (double roll : {0.0, 30.0, 180.0}) {
      auto lm = ld::synth::placeLandmark(cam, 1.0, 20, 0, roll, 0.1, -0.1, 0.15);
      lm.texture = ld::markers::sheetTexture(kind, 7, 540);
      ld::synth::SceneSpec spec;
      spec.landmarks = {lm};
      spec.background = ld::synth::Background::Plain;
      spec.distractors = 0;
      const auto frame = ld::synth::render(spec);
      cv::Mat gray;
      cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
      const auto found = det.detect(gray);
      ASSERT_EQ(found.size(), 1u) << ld::markers::name(kind) << " roll " << roll;
      EXPECT_EQ(found[0].id, 7);
      EXPECT_TRUE(ld::markers::matches(found[0].corners, frame.truth[0].corners));
      // TL first, clockwise: the first corner is the truth's TL.
      EXPECT_LT(cv::norm(cv::Point2d(found[0].corners[0]) - frame.truth[0].corners[0]), 3.0)
          << ld::markers::name(kind) << " roll " << roll;
    }
    EXPECT_TRUE(det.detect(cv::Mat()).empty());
  }
}

// Corners in OpenCV's pixel convention (a pixel's centre at the integer), as
// ours are: AprilTag's own put it at +0.5, which the wrapper takes off. Over
// clean renders the mean signed error is near 0 in x and y for both (a
// wrapper that passed AprilTag's through would be half a pixel off in each).
TEST(Markers, CornersInOpenCvPixelConvention) {
  const auto cam = ld::CameraModel::defaultVga();
  for (auto kind : {ld::markers::Kind::AprilTag, ld::markers::Kind::Aruco}) {
    ld::markers::Detector det(kind);
    double dx = 0, dy = 0;
    int n = 0;
    for (int k = 0; k < 12; ++k) {
      auto lm = ld::synth::placeLandmark(cam, 1.2, -20 + 4.0 * k, 0, 30.0 * k, 0.2 * std::sin(k), 0.2 * std::cos(k),
                                         0.15);
      lm.texture = ld::markers::sheetTexture(kind, 0, 540);
      ld::synth::SceneSpec spec;
      spec.landmarks = {lm};
      spec.background = ld::synth::Background::Plain;
      spec.distractors = 0;
      spec.seed = 50 + static_cast<uint64_t>(k);
      const auto frame = ld::synth::render(spec);
      cv::Mat gray;
      cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
      for (const auto& f : det.detect(gray)) {
        if (f.id != 0 || !ld::markers::matches(f.corners, frame.truth[0].corners)) continue;
        for (int i = 0; i < 4; ++i) {
          dx += f.corners[static_cast<size_t>(i)].x - frame.truth[0].corners[static_cast<size_t>(i)].x;
          dy += f.corners[static_cast<size_t>(i)].y - frame.truth[0].corners[static_cast<size_t>(i)].y;
          ++n;
        }
      }
    }
    ASSERT_GE(n, 40) << ld::markers::name(kind);
    std::printf("%s corners: mean offset (%.3f, %.3f) px over %d\n", ld::markers::name(kind).c_str(), dx / n, dy / n,
                n);
    EXPECT_LT(std::abs(dx / n), 0.2) << ld::markers::name(kind);
    EXPECT_LT(std::abs(dy / n), 0.2) << ld::markers::name(kind);
  }
}
