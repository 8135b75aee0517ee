// AprilTag 3 and ArUco markers printed like our landmark: the texture puts
// the marker where our pattern is, and each detector finds its marker at the
// pose our landmark would have, with corners in our order.
#include <gtest/gtest.h>

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
