// Adaptive lighting: the adapter's estimate and correction, and on ld-synth
// lighting sweeps that it holds detection where the fixed defaults drop,
// without more false landmarks.
#include <gtest/gtest.h>

#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "ld/adaptive.hpp"
#include "ld/eval.hpp"

TEST(LightingAdapter, NeutralWellLitFrameIsLeftAlone) {
  ld::LightingAdapter a;
  const cv::Mat frame(120, 160, CV_8UC3, cv::Scalar(205, 205, 205));
  const cv::Mat& out = a.correct(frame);
  EXPECT_EQ(out.data, frame.data);  // no copy, no change
  EXPECT_EQ(a.gains(), cv::Vec3d(1, 1, 1));
}

TEST(LightingAdapter, WarmAndDimWhiteBecomesNeutralAndBright) {
  ld::LightingAdapter a;
  // Tungsten-lit, dim paper with a saturated orange object that must not
  // pull the estimate (its weakest channel is dark).
  cv::Mat frame(120, 160, CV_8UC3, cv::Scalar(60, 100, 140));
  cv::rectangle(frame, cv::Rect(0, 0, 80, 120), cv::Scalar(20, 120, 250), cv::FILLED);
  const cv::Mat out = a.correct(frame).clone();
  const cv::Vec3b paper = out.at<cv::Vec3b>(60, 120);
  EXPECT_NEAR(paper[0], 200, 3);
  EXPECT_NEAR(paper[1], 200, 3);
  EXPECT_NEAR(paper[2], 200, 3);
  EXPECT_FALSE(a.fromLandmarks());
}

TEST(LightingAdapter, GainsAreBoundedAndBadFramesPassThrough) {
  ld::AdaptiveParams p;
  p.max_gain = 3;
  ld::LightingAdapter a(p);
  const cv::Mat frame(40, 40, CV_8UC3, cv::Scalar(2, 30, 40));
  a.correct(frame);
  for (int c = 0; c < 3; ++c) EXPECT_LE(a.gains()[c], 3.0 + 1e-9);
  const cv::Mat gray(10, 10, CV_8UC1, cv::Scalar(9));
  EXPECT_EQ(a.correct(gray).data, gray.data);
  EXPECT_TRUE(a.correct(cv::Mat()).empty());
}

TEST(LightingAdapter, ConfirmedLandmarkSheetIsTheWhiteReference) {
  ld::LightingAdapter a;
  // A frame whose whitest surface is a greenish wall, and a "landmark" whose
  // sheet (the area the corners span) is warm paper.
  cv::Mat frame(200, 200, CV_8UC3, cv::Scalar(180, 230, 180));
  cv::rectangle(frame, cv::Rect(50, 50, 100, 100), cv::Scalar(90, 130, 170), cv::FILLED);
  ld::Detection det;
  ld::Landmark lm;
  lm.corners = {cv::Point2f(55, 55), cv::Point2f(145, 55), cv::Point2f(145, 145), cv::Point2f(55, 145)};
  det.landmarks.push_back(lm);
  a.observe(frame, det);
  EXPECT_TRUE(a.fromLandmarks());
  a.correct(frame);
  // Gains from the paper (90, 130, 170), not from the wall.
  EXPECT_NEAR(a.gains()[0] / a.gains()[2], 170.0 / 90.0, 0.05);
  EXPECT_NEAR(a.gains()[1] / a.gains()[2], 170.0 / 130.0, 0.05);
}

namespace {

ld::eval::SweepOptions lit(double temp_k, double gain, bool adaptive) {
  ld::eval::SweepOptions o;
  o.side_m = 0.15;
  o.trials = 20;
  o.seed = 99;
  o.colour_temp_k = temp_k;
  o.gain = gain;
  o.adaptive = adaptive;
  return o;
}

}  // namespace

TEST(AdaptiveDetection, HoldsUnderTungstenWhereTheDefaultsDrop) {
  for (double temp : {2700.0, 3200.0}) {
    const auto fixed = ld::eval::measure(lit(temp, -1, false), 1.5, 0, 40);
    const auto adaptive = ld::eval::measure(lit(temp, -1, true), 1.5, 0, 40);
    std::printf("%.0f K: fixed %d/%d, adaptive %d/%d\n", temp, fixed.detected, fixed.trials,
                adaptive.detected, adaptive.trials);
    EXPECT_LE(fixed.detectRate(), 0.5);
    EXPECT_GE(adaptive.detectRate(), 0.95);
  }
}

TEST(AdaptiveDetection, NoLossInDaylightAndDimLight) {
  for (auto [temp, gain] : {std::pair{6500.0, 1.0}, {5000.0, 0.3}, {4000.0, 0.2}}) {
    const auto adaptive = ld::eval::measure(lit(temp, gain, true), 1.5, 0, 40);
    std::printf("%.0f K gain %.1f: adaptive %d/%d\n", temp, gain, adaptive.detected, adaptive.trials);
    EXPECT_GE(adaptive.detectRate(), 0.95);
  }
}

TEST(AdaptiveDetection, NoMoreFalseLandmarksOnDistractorScenes) {
  for (auto [temp, gain] : {std::pair{6500.0, 1.0}, {2700.0, 1.0}, {4000.0, 0.25}}) {
    const double fp = ld::eval::falsePositivesPerFrame(lit(temp, gain, true), 100);
    std::printf("%.0f K gain %.2f: %.3f false landmarks per frame\n", temp, gain, fp);
    EXPECT_LE(fp, 0.01);
  }
}
