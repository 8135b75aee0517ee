// Adaptive lighting: the adapter's estimate and correction, and on ld-synth
// lighting sweeps that it holds detection where the fixed defaults drop,
// without more false landmarks.
#include <gtest/gtest.h>

#include <type_traits>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/adaptive.hpp"
#include "ld/eval.hpp"
#include "ld/synth.hpp"

TEST(LightingAdapter, NeutralWellLitFrameIsLeftAlone) {
  ld::LightingAdapter a;
  const cv::Mat frame(120, 160, CV_8UC3, cv::Scalar(205, 205, 205));
  const cv::Mat& out = a.correct(frame);
  EXPECT_EQ(out.data, frame.data);  // no copy, no change
  EXPECT_EQ(a.gains(), cv::Vec3d(1, 1, 1));
}

// Movable, not copyable: a copy shared the adapter's buffers, one's
// corrections written into the frames the other returned (an API audit).
// correct() returns the frame itself where nothing is corrected.
static_assert(!std::is_copy_constructible_v<ld::LightingAdapter> && !std::is_copy_assignable_v<ld::LightingAdapter>);
static_assert(std::is_move_constructible_v<ld::LightingAdapter> && std::is_move_assignable_v<ld::LightingAdapter>);
TEST(LightingAdapter, MovesWithItsStateAndGivesTheFrameItselfWhereNothingIsCorrected) {
  ld::LightingAdapter a;
  const cv::Mat gray(48, 64, CV_8UC1, cv::Scalar(90));
  EXPECT_EQ(&a.correct(gray), &gray);
  ld::LightingAdapter b = std::move(a);
  EXPECT_EQ(&b.correct(gray), &gray);
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
  // Parameters out of their range are refused, named (max_gain 0 made every
  // frame black and found nothing, without a word)
  const auto refused = [](void (*set)(ld::AdaptiveParams&), const std::string& says) {
    ld::AdaptiveParams bad;
    set(bad);
    try {
      ld::LightingAdapter refusing(bad);
      ADD_FAILURE() << "taken: " << says;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "AdaptiveParams: " + says);
    }
  };
  refused([](ld::AdaptiveParams& q) { q.max_gain = 0; }, "max_gain must be 1 to 64, not 0");
  refused([](ld::AdaptiveParams& q) { q.target_white = 1000; }, "target_white must be 1 to 255, not 1000");
  refused([](ld::AdaptiveParams& q) { q.glare_window = 0; }, "glare_window must be 1 to 4096, not 0");
  refused([](ld::AdaptiveParams& q) { q.smoothing = std::nan(""); }, "smoothing must be 0.001 to 1, not nan");
  EXPECT_THROW(ld::AdaptiveDetector({}, [] {
                 ld::AdaptiveParams q;
                 q.bright_fraction = 2;
                 return q;
               }()),
               std::invalid_argument);
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

// A frame of black and white 8 px squares (ink on paper everywhere), with a
// blue patch at the centre.
cv::Mat checkerWithBluePatch() {
  cv::Mat frame(240, 320, CV_8UC3);
  for (int y = 0; y < frame.rows; ++y)
    for (int x = 0; x < frame.cols; ++x)
      frame.at<cv::Vec3b>(y, x) = ((x / 8 + y / 8) % 2) ? cv::Vec3b(230, 232, 235) : cv::Vec3b(30, 30, 32);
  frame(cv::Rect(150, 110, 20, 20)).setTo(cv::Scalar(90, 45, 40));  // printed blue
  return frame;
}

double saturation(const cv::Vec3b& p) {
  const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
  return mx > 0 ? static_cast<double>(mx - mn) / mx : 0.0;
}

}  // namespace

TEST(LightingAdapter, GlareVeilIsSubtracted) {
  ld::LightingAdapter a;
  const cv::Mat clean = checkerWithBluePatch();
  // A veil of `level` on every channel over the middle (a lamp's hot spot).
  auto veiled = [&clean](double level) {
    cv::Mat frame = clean.clone();
    cv::Mat spot = frame(cv::Rect(100, 60, 120, 120));
    cv::add(spot, cv::Scalar::all(level), spot);
    return frame;
  };
  const cv::Mat frame = veiled(150);
  ASSERT_LT(saturation(frame.at<cv::Vec3b>(120, 160)), 0.25);  // the blue is washed out
  const cv::Mat out = a.correct(frame).clone();
  EXPECT_TRUE(a.glareCorrected());
  EXPECT_GT(saturation(out.at<cv::Vec3b>(120, 160)), 0.45);  // blue again
  EXPECT_EQ(out.at<cv::Vec3b>(120, 160)[0], std::max({out.at<cv::Vec3b>(120, 160)[0], out.at<cv::Vec3b>(120, 160)[1],
                                                        out.at<cv::Vec3b>(120, 160)[2]}));
  // Black under the veil is dark again; far from it nothing changed.
  EXPECT_LT(out.at<cv::Vec3b>(100 + 4, 104 + 8 * 4)[0], 90);
  EXPECT_EQ(out.at<cv::Vec3b>(4, 4), clean.at<cv::Vec3b>(4, 4));
  EXPECT_EQ(out.at<cv::Vec3b>(235, 315), clean.at<cv::Vec3b>(235, 315));
  // The stretch back to the full range, (255 - black) / (255 - veil): about
  // 3 under this veil of 150 over the checker's black; under one of 100 it
  // is not strong (AdaptiveParams::wide_hue_min_stretch 3) ...
  std::printf("veil 150: stretch %.2f\n", a.veilStretch());
  EXPECT_GT(a.veilStretch(), 2.5);
  a.correct(veiled(100));
  std::printf("veil 100: stretch %.2f, corrected %d\n", a.veilStretch(), a.glareCorrected());
  EXPECT_TRUE(a.glareCorrected());
  EXPECT_GT(a.veilStretch(), 1.5);
  EXPECT_LT(a.veilStretch(), 3.0);
  EXPECT_FALSE(a.strongVeil());
  // ... under one of 185, strong; and none without a veil.
  a.correct(veiled(185));
  std::printf("veil 185: stretch %.2f, corrected %d\n", a.veilStretch(), a.glareCorrected());
  EXPECT_TRUE(a.glareCorrected());
  EXPECT_GE(a.veilStretch(), 3.0);
  EXPECT_TRUE(a.strongVeil());
  a.correct(clean);
  EXPECT_EQ(a.veilStretch(), 1.0);
  EXPECT_FALSE(a.strongVeil());
}

// A warm lamp's hot spot lifts red most and blue least. Assumed neutral, the
// veil would be under-subtracted in red and the blue square would come out
// violet; measured on the veiled blocks, its colour is the lamp's and the
// square comes out blue.
TEST(LightingAdapter, VeilColourIsMeasuredOnTheVeil) {
  ld::LightingAdapter a;
  cv::Mat frame = checkerWithBluePatch();
  cv::Mat spot = frame(cv::Rect(100, 60, 120, 120));
  cv::add(spot, cv::Scalar(80, 125, 170), spot);  // B, G, R
  const cv::Mat out = a.correct(frame).clone();
  ASSERT_TRUE(a.glareCorrected());
  const cv::Vec3d colour = a.veilColour();
  EXPECT_NEAR(colour[2], 1.0, 0.02);  // red strongest
  EXPECT_NEAR(colour[1], 125.0 / 170, 0.05);
  EXPECT_NEAR(colour[0], 80.0 / 170, 0.05);
  const cv::Vec3b blue = out.at<cv::Vec3b>(120, 160);
  EXPECT_GT(saturation(blue), 0.45);
  EXPECT_GT(blue[0], 1.5 * blue[2]) << blue;  // blue, not violet
  std::printf("blue under a warm veil, corrected: %d %d %d\n", blue[0], blue[1], blue[2]);
  // black under the veil is black again in every channel
  const cv::Vec3b black = out.at<cv::Vec3b>(100 + 4, 104 + 8 * 4);
  EXPECT_LT(std::max({black[0], black[1], black[2]}), 60) << black;
}

TEST(LightingAdapter, PaleOrColouredSurfacesAreNotAVeil) {
  ld::AdaptiveParams p;
  ld::LightingAdapter a(p);
  cv::Mat frame = checkerWithBluePatch();
  // A plain pale wall (nothing dark on it) and an orange board (red and
  // green lifted, blue not): neither is glare.
  frame(cv::Rect(0, 0, 120, 120)).setTo(cv::Scalar(200, 205, 210));
  frame(cv::Rect(200, 120, 120, 120)).setTo(cv::Scalar(40, 150, 240));
  cv::rectangle(frame, cv::Rect(220, 140, 60, 60), cv::Scalar(230, 232, 235), 4);  // white lines on it
  const cv::Mat before = frame.clone();
  const cv::Mat& out = a.correct(frame);
  EXPECT_FALSE(a.glareCorrected());
  EXPECT_EQ(cv::norm(out, before, cv::NORM_INF), 0.0);
  // Off: nothing is even looked at.
  p.glare_min_lift = 0;
  ld::LightingAdapter off(p);
  cv::Mat veiled = checkerWithBluePatch();
  cv::add(veiled, cv::Scalar(150, 150, 150), veiled);
  off.correct(veiled);
  EXPECT_FALSE(off.glareCorrected());
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

// ld-eval lighting scores both detectors on one rendering of each scene:
// the same counts as measuring each on its own.
TEST(AdaptiveDetection, BothDetectorsOnOneRenderingCountAsApart) {
  auto o = lit(-1, -1, true);
  o.glare = 0.3;
  o.trials = 8;
  const auto [fixed, adaptive] = ld::eval::measureFixedAndAdaptive(o, 1.5, 0, 40);
  const auto alone = ld::eval::measure(o, 1.5, 0, 40);
  o.adaptive = false;
  const auto fixed_alone = ld::eval::measure(o, 1.5, 0, 40);
  EXPECT_EQ(fixed.trials, 8);
  EXPECT_EQ(adaptive.detected, alone.detected);
  EXPECT_EQ(fixed.detected, fixed_alone.detected);
  EXPECT_NE(fixed.detected, adaptive.detected);  // glare: the two differ, so the order is checked too
  // False landmarks: with the defaults both counts are 0 on so few frames,
  // so the sheet, QR and cover checks are switched off to let look-alike
  // cards through, at rates that differ between the two detectors.
  auto loose = lit(3200, -1, true);
  loose.params.sheet_max_saturation = 1;
  loose.params.sheet_min_value = 0;
  loose.params.sheet_uniformity = 0;
  loose.params.qr_max_brightness = 2;
  loose.params.cover_min = 0;
  loose.params.cover_max = 1;
  const auto fp = ld::eval::falsePositivesFixedAndAdaptive(loose, 20);
  const double adaptive_fp = ld::eval::falsePositivesPerFrame(loose, 20);
  loose.adaptive = false;
  EXPECT_DOUBLE_EQ(fp[0], ld::eval::falsePositivesPerFrame(loose, 20));
  EXPECT_DOUBLE_EQ(fp[1], adaptive_fp);
  EXPECT_NE(fp[0], fp[1]);
}

// Warm light: the adaptive detector keeps a candle's 2000 K, a household
// bulb's 2700 K and a halogen's 3200 K. The fixed defaults lose frames there
// (over 100 frames of ld-eval lighting: 75, 71 and 86 %; the faint look's
// windows, white-balanced by their own white, keep that many: without them
// 0, 0 and 74 %), fewer than before on this test's 20.
TEST(AdaptiveDetection, HoldsUnderWarmLight) {
  int fixed_all = 0, adaptive_all = 0;
  for (double temp : {2000.0, 2700.0, 3200.0}) {
    const auto [fixed, adaptive] = ld::eval::measureFixedAndAdaptive(lit(temp, -1, true), 1.5, 0, 40);
    std::printf("%.0f K: fixed %d/%d, adaptive %d/%d\n", temp, fixed.detected, fixed.trials,
                adaptive.detected, adaptive.trials);
    fixed_all += fixed.detected;
    adaptive_all += adaptive.detected;
    EXPECT_GE(adaptive.detected, fixed.detected);
    // (2000 K: 97 of 100 frames in ld-eval lighting --trials 100)
    EXPECT_GE(adaptive.detectRate(), temp < 2500 ? 0.9 : 0.95);
  }
  EXPECT_GT(adaptive_all, fixed_all);
}

// A BGRA frame is corrected as its BGR is: it went to the detector
// uncorrected, and taught the adapter nothing (2 landmarks in BGR, 1 in BGRA).
TEST(AdaptiveDetection, BgraFramesAreCorrectedAsBgr) {
  ld::AdaptiveDetector as_bgr, as_bgra;
  int found = 0;
  for (int k = 0; k < 6; ++k) {
    ld::synth::SceneSpec spec;
    spec.seed = 40 + k;
    spec.lighting.colour_temp_k = 2200;
    spec.lighting.gain = 0.7;
    spec.degradation.noise_sigma = 2;
    spec.landmarks = {ld::synth::placeLandmark(spec.camera, 1.2, 20, 0, 10 * k, -0.3, 0),
                      ld::synth::placeLandmark(spec.camera, 1.6, -10, 0, -15 * k, 0.3, 0.1, 0.15, "b", 1)};
    const cv::Mat bgr = ld::synth::render(spec).bgr;
    cv::Mat bgra;
    cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
    const auto a = as_bgr.detect(bgr).landmarks;
    const auto b = as_bgra.detect(bgra).landmarks;
    ASSERT_EQ(a.size(), b.size()) << "frame " << k;
    found += static_cast<int>(a.size());
    for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i].corners, b[i].corners);
    EXPECT_EQ(as_bgr.adapter().gains(), as_bgra.adapter().gains()) << "frame " << k;
  }
  EXPECT_GT(as_bgra.adapter().gains()[0], 1.2);  // (corrected: tungsten's weak blue raised)
  EXPECT_GE(found, 9);
}

// The correction's time is the detection's first stage, "adapt" (the stage
// timings of LANDMARKS said nothing of it), and in its total; without the
// adapter there is no such stage.
TEST(AdaptiveDetection, CorrectionIsTheFirstStage) {
  ld::synth::SceneSpec spec;
  spec.seed = 41;
  spec.lighting.colour_temp_k = 2200;
  spec.landmarks = {ld::synth::placeLandmark(spec.camera, 1.2, 20, 0, 10, -0.3, 0)};
  const cv::Mat bgr = ld::synth::render(spec).bgr;
  ld::AdaptiveDetector on;
  for (int k = 0; k < 3; ++k) {
    const ld::Detection& d = on.detect(bgr);
    ASSERT_FALSE(d.stages.empty());
    EXPECT_STREQ(d.stages.front().name, "adapt");
    EXPECT_GT(d.stageMs("adapt"), 0);
    double sum = 0;
    for (const auto& st : d.stages) sum += st.ms;
    EXPECT_GE(d.total_ms, sum - 1e-9);  // (the total holds every stage, the correction too, and the timer's own time)
    ld::Explanation why;
    EXPECT_STREQ(on.detect(bgr, why).stages.front().name, "adapt");
  }
  ld::AdaptiveDetector off(ld::Detector{}, false);
  EXPECT_EQ(off.detect(bgr).stageMs("adapt"), 0);
}

// Without the faint look the fixed defaults lose warm light altogether.
TEST(AdaptiveDetection, FixedDefaultsWithoutTheFaintLookDropUnderTungsten) {
  auto o = lit(2700, -1, false);
  o.params.faint_looks = 0;
  const auto fixed = ld::eval::measure(o, 1.5, 0, 40);
  std::printf("2700 K, no faint look: fixed %d/%d\n", fixed.detected, fixed.trials);
  EXPECT_LE(fixed.detectRate(), 0.5);
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

// A hot spot of glare on the landmark (peak 0.3 of white, in linear light,
// then 0.6, which clips the sheet): the fixed defaults lose half the frames or more, the
// adaptive detector's veil subtraction keeps most, and no false landmark
// appears under it.
TEST(AdaptiveDetection, HoldsUnderGlareOnTheLandmark) {
  auto glare = [](bool adaptive) {
    auto o = lit(-1, -1, adaptive);
    o.glare = 0.3;
    return o;
  };
  const auto [fixed, adaptive] = ld::eval::measureFixedAndAdaptive(glare(true), 1.5, 0, 40);
  std::printf("glare 0.3: fixed %d/%d, adaptive %d/%d\n", fixed.detected, fixed.trials, adaptive.detected,
              adaptive.trials);
  // (measured: fixed 9 of 20 since the faint look's steep round, at most 8
  // before; adaptive 20 of 20)
  EXPECT_LE(fixed.detectRate(), 0.5);
  EXPECT_GE(adaptive.detected, fixed.detected + 8);
  EXPECT_GE(adaptive.detectRate(), 0.8);
  const double fp = ld::eval::falsePositivesPerFrame(glare(true), 100);
  std::printf("glare 0.3: %.3f false landmarks per frame\n", fp);
  EXPECT_LE(fp, 0.01);
  // Twice as strong: the sheet clips to white, the squares keep a trace of colour.
  auto strong = glare(true);
  strong.glare = 0.6;
  const auto [fixed6, adaptive6] = ld::eval::measureFixedAndAdaptive(strong, 1.5, 0, 40);
  std::printf("glare 0.6: fixed %d/%d, adaptive %d/%d\n", fixed6.detected, fixed6.trials, adaptive6.detected,
              adaptive6.trials);
  // (measured: 0 and 20 of 20; 17 of 20 before the faint look took blue at
  // any hue under a subtracted veil, Detector::setGlareCorrected)
  EXPECT_GE(adaptive6.detected, fixed6.detected + 10);
  EXPECT_GE(adaptive6.detectRate(), 0.9);
}

namespace {

// The adaptive detector on the lighting sweep's glare point (`glare` on the
// landmark, 15 cm at 1.5 m, yaw within +-40 degrees): `trials` frames of
// `seed` as it is, and again with `off` applied to its parameters.
std::array<ld::eval::Point, 2> glareWithAndWithout(double glare, int trials, uint64_t seed,
                                                   const std::function<void(ld::DetectorParams&)>& off) {
  auto o = lit(-1, -1, true);
  o.glare = glare;
  o.trials = trials;
  o.seed = seed;
  const auto with = ld::eval::measure(o, 1.5, 0, 40);
  off(o.params);
  return {with, ld::eval::measure(o, 1.5, 0, 40)};
}

// The adaptive detector's finds in 100 frames of `seed` at the lighting
// sweep's glare point of strength `glare`, printed.
int foundUnderGlare(double glare, uint64_t seed) {
  auto o = lit(-1, -1, true);
  o.glare = glare;
  o.trials = 100;
  o.seed = seed;
  const int found = ld::eval::measure(o, 1.5, 0, 40).detected;
  std::printf("glare %g, 100 frames of seed %llu: %d\n", glare, static_cast<unsigned long long>(seed), found);
  return found;
}

}  // namespace

// Under glare 0.6 the veil's subtraction leaves a tint (a veil a few levels
// off in one channel, stretched back 4 times) that turns the blue squares
// violet, cyan or brown; the QR beside them, black on white, shows the same
// tint, and the faint look's veil round takes it out of its windows
// (DetectorParams::veil_looks). On the lighting sweep's glare point, seeds
// 1-12 of 100 frames each, it found 1171 of 1200 against 1140 without it
// (before the twenty-fifth session's ECI); on this seed 98 against 90.
TEST(AdaptiveDetection, VeilRoundTakesTheQrsTintOut) {
  const auto [with, without] = glareWithAndWithout(0.6, 100, 10, [](ld::DetectorParams& p) { p.veil_looks = 0; });
  std::printf("glare 0.6, 100 frames: veil round %d, without it %d\n", with.detected, without.detected);
  EXPECT_GE(with.detected, without.detected + 4);
  EXPECT_GE(with.detectRate(), 0.95);
}

// Glare 0.75 on the landmark: the hot spot's peak on the QR lifts it to the
// sheet's brightness and beyond, where no rule on its darkness holds; in
// the frames the adapter took a strong veil out of, the dips of its dark
// modules under its white ones count (DetectorParams::qr_washed_dip). On
// the lighting sweep's glare-0.75 point it found 92, 90 and 91 of 100
// frames (seeds 1-3) against 72, 72 and 73 when it came; here 37 of 40
// against 28 (34 against 25 before the veil round's order, below).
TEST(AdaptiveDetection, QrWashedOutByAHotSpotCountsByItsTexture) {
  const auto [with, without] = glareWithAndWithout(0.75, 40, 99, [](ld::DetectorParams& p) { p.qr_washed_dip = 0; });
  std::printf("glare 0.75, 40 frames: %d, without the washed-QR rule %d\n", with.detected, without.detected);
  EXPECT_GE(with.detected, without.detected + 6);
  EXPECT_GE(with.detectRate(), 0.75);
}

// A warm hot spot on the landmark makes red clutter of the frame once its
// veil is out (48-223 red squares no landmark took in the missed frames),
// and the veil round's budget (a quarter of the frame) covered only the
// few largest of them, the AP seldom among them; an AP inside a window
// looked at around another red square was skipped, though the round takes
// only its own square's landmark from each window. It now looks around
// the red squares with the brightest paper beside them first (a sheet the
// hot spot clipped reads near white once corrected), each in its own
// window. On the lighting sweep's glare-0.75 point, seeds 1-3: 94 / 91 /
// 93 of 100 against 92 / 89 / 91; at 0.9 41 / 45 / 42 against 39 / 44 / 39.
// This is seed 1 at 0.75 (94 of 100; 92 before, so a frame's margin; 95
// since the wider windows below).
TEST(AdaptiveDetection, VeilRoundLooksWhereThePaperIsBrightestFirst) { EXPECT_GE(foundUnderGlare(0.75, 1), 93); }

// The hot spot pales the AP's edges, and the thresholded square the veil
// round starts from reads shorter than printed (9.6 px for 14); its window,
// reaching 5 of those sides each way from it, left out the FIP diagonal
// from it (4.24 printed sides away), which the completion then could not
// measure (frames 71 and 87 of this seed). The round's windows now reach 6
// sides. On the lighting sweep's glare-0.75 point, seeds 1-6: 561 -> 570
// of 600; this seed 93 -> 97 (the other two frames gained not traced).
TEST(AdaptiveDetection, VeilRoundReachesTheFipBeyondAShrunkenAp) { EXPECT_GE(foundUnderGlare(0.75, 3), 96); }

// Where a veil window's look finds nothing, the round looks at the window
// again at thresholds raised by second_look_raise, as the second look
// does: the squares come out without the pale pixels around them. Of seed
// 2's 9 misses it finds 3: in frame 14 the pale look had all four squares,
// refused for other squares in the sheet; in 78 all four, refused for a
// saturated sheet or a side ratio; in 26 only BL and the AP whole, TL and
// TR in pieces. On the
// lighting sweep's glare-0.75 point, seeds 1-9: 857 -> 862 of 900; seeds
// 2 and 7 91 + 91 -> 94 + 93.
TEST(AdaptiveDetection, VeilRoundLooksAgainAtRaisedThresholds) {
  EXPECT_GE(foundUnderGlare(0.75, 2) + foundUnderGlare(0.75, 7), 185);
}

// The veil round takes the tint it measured on the QR out of its windows
// but not out of the pixels clipped in some channel (the sheet's white at
// the hot spot: the tint was measured without them). Taken out of them
// too, a tint of B -83 G +18 R +65 turned a clipped sheet pale blue, and
// the window around the landmark's AP showed 1 FIP and no AP (14 FIPs and
// 4 APs now). On the lighting sweep's glare point at 0.9, seeds 1-3: 133 ->
// 150 of 300; seeds 2 and 3 46 + 43 -> 53 + 51; at 0.75, seeds 1-15:
// 1432 -> 1453 of 1500.
TEST(AdaptiveDetection, VeilRoundLeavesTheClippedSheetAsItIs) {
  EXPECT_GE(foundUnderGlare(0.9, 2) + foundUnderGlare(0.9, 3), 100);
}

// The command line: `ld-detect --adaptive` on frames under tungsten light,
// and on frames with glare on the landmark, finds what the fixed defaults
// miss. (One folder per light: the adapter carries its estimate from frame
// to frame, as for a camera's video.)
TEST(AdaptiveCli, DetectAdaptiveOption) {
  const auto dir = std::filesystem::temp_directory_path() / ("test_adaptive_" + std::to_string(getpid()));
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  for (const std::string light : {"tungsten", "glare"}) {
    std::filesystem::create_directories(dir / light);
    for (int i = 0; i < 6; ++i) {
      auto spec = ld::synth::randomConditions(
          cam, {ld::synth::placeLandmark(cam, 1.5, -30 + 12 * i, 0, 60 * i, 0, 0, 0.15)}, 500 + i);
      spec.lighting.glare = 0;
      spec.lighting.colour_temp_k = 2700;
      if (light == "glare") {
        const auto t = ld::synth::truthFor(cam, spec.landmarks[0]);
        const cv::Point2d c = (t.fip_tl + t.ap) / 2;
        spec.lighting.colour_temp_k = 6000;
        spec.lighting.glare = 0.3;
        spec.lighting.glare_radius = 0.15;
        spec.lighting.glare_centre = {c.x / cam.size.width, c.y / cam.size.height};
      }
      ASSERT_TRUE(cv::imwrite((dir / light / ("f" + std::to_string(i) + ".png")).string(),
                              ld::synth::render(spec).bgr));
    }
  }
  auto found = [&](const std::string& light, const std::string& options) {
    const auto json = dir / "out.jsonl";
    const std::string cmd = std::string(LD_BIN_DIR) + "/ld-detect " + options + " " + (dir / light).string() +
                            " -o " + json.string() + " 2> " + (dir / "err.txt").string();
    const int rc = std::system(cmd.c_str());
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << cmd;
    std::ifstream in(json);
    int n = 0, lines = 0;
    for (std::string line; std::getline(in, line); ++lines) n += line.find("fip_tl") != std::string::npos;
    EXPECT_EQ(lines, 6);
    return n;
  };
  for (const std::string light : {"tungsten", "glare"}) {
    const int fixed = found(light, ""), adaptive = found(light, "--adaptive");
    std::printf("ld-detect on 6 %s frames: fixed %d, --adaptive %d\n", light.c_str(), fixed, adaptive);
    EXPECT_LE(fixed, 2) << light;
    EXPECT_GE(adaptive, 5) << light;
  }
  std::filesystem::remove_all(dir);
}
