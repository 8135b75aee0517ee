// Accuracy of the detector on ld-synth scenes (printed-ink colours, random
// lighting, blur, noise and JPEG; 640x480, f = 600 px), one default parameter
// set for all of them: detection-rate sweeps over yaw at any roll, false
// positives on scenes without a landmark, corner and pose accuracy. The
// measured figures are printed; the log of a run is the accuracy report.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <random>

#include <opencv2/calib3d.hpp>

#include "ld/detector.hpp"
#include "ld/eval.hpp"
#include "ld/synth.hpp"

namespace {

const ld::CameraModel kCam = ld::CameraModel::defaultVga();

std::array<cv::Point2d, 4> centres(const ld::synth::LandmarkTruth& t) {
  return {t.fip_tl, t.fip_tr, t.fip_bl, t.ap};
}

// The detection of `t` in `det`, or nullptr: its four centres each within
// max(2 px, 0.3 FIP sides) of the truth, in the right order.
const ld::Landmark* match(const ld::Detection& det, const ld::synth::LandmarkTruth& t) {
  for (const auto& lm : det.landmarks)
    if (ld::matchesTruth(lm, centres(t))) return &lm;
  return nullptr;
}

struct Sweep {
  std::map<int, std::pair<int, int>> per_yaw;  // yaw -> (found, frames)
  int found(double max_abs_yaw) const {
    int n = 0;
    for (const auto& [yaw, r] : per_yaw) n += std::abs(yaw) <= max_abs_yaw + 1e-9 ? r.first : 0;
    return n;
  }
  int frames(double max_abs_yaw) const {
    int n = 0;
    for (const auto& [yaw, r] : per_yaw) n += std::abs(yaw) <= max_abs_yaw + 1e-9 ? r.second : 0;
    return n;
  }
  double rate(double max_abs_yaw) const { return static_cast<double>(found(max_abs_yaw)) / frames(max_abs_yaw); }
  void print(const std::string& name) const {
    std::cout << name << " detection rate by yaw:";
    for (const auto& [yaw, r] : per_yaw) std::cout << " " << yaw << ":" << r.first << "/" << r.second;
    std::cout << "\n";
    for (double lim : {50.0, 60.0, 70.0, 80.0})
      if (frames(lim) > 0 && (lim <= per_yaw.rbegin()->first))
        std::printf("%s within +-%.0f deg: %d / %d = %.1f %%\n", name.c_str(), lim, found(lim), frames(lim),
                    100.0 * rate(lim));
  }
};

// `per_yaw` frames at each yaw from -max_yaw to max_yaw: any roll, pitch
// within +-10 degrees, anywhere in the middle of the image, random conditions.
Sweep sweep(double side_m, double distance, int max_yaw, int step, int per_yaw, uint64_t seed) {
  ld::Detector det;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  Sweep s;
  for (int yaw = -max_yaw; yaw <= max_yaw; yaw += step)
    for (int k = 0; k < per_yaw; ++k) {
      const double roll = U(rng) * 360 - 180, pitch = (U(rng) - 0.5) * 20;
      const double nx = U(rng) - 0.5, ny = U(rng) - 0.5;
      const auto lm = ld::synth::placeLandmark(kCam, distance, yaw, pitch, roll, nx, ny, side_m);
      const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, {lm}, rng()));
      auto& r = s.per_yaw[yaw];
      r.first += match(det.detect(frame.bgr), frame.truth[0]) != nullptr;
      ++r.second;
    }
  return s;
}

// A plain wall of `colour` (BGR), `side_m` square, just behind the sheet
// `lm` and in its plane.
ld::synth::Surface wallBehind(const ld::synth::LandmarkPlacement& lm, const cv::Scalar& colour, double side_m) {
  ld::synth::Surface wall;
  wall.texture = cv::Mat(8, 8, CV_8UC3, colour);
  wall.size_m = {side_m, side_m};
  wall.rvec = lm.rvec;
  cv::Matx33d R;
  cv::Rodrigues(lm.rvec, R);
  wall.tvec = lm.tvec + R * cv::Vec3d(0, 0, 0.002);
  return wall;
}

}  // namespace

// A 9 cm landmark at 1.5 m: FIPs of 8 px, 3 px wide at 70 degrees of yaw.
TEST(DetectionRate, Landmark9cmAt1m5) {
  const Sweep s = sweep(0.09, 1.5, 70, 10, 12, 9015);
  s.print("9 cm at 1.5 m");
  EXPECT_GE(s.rate(60), 0.95);
  EXPECT_GE(s.rate(70), 0.92);
}

// The issue's target for the 9 cm landmark: 95 % within +-70 degrees at
// 1.5 m, over 900 frames (the sweep above, 180 frames, has too few to hold
// it to). Met since the faint look's steep round: 866 of 900 (96.2 %; 95.1 %
// before it started from rounded APs and blue squares, 93.3 % before the
// round); ld-eval's 1500-frame sweeps of seeds 1-3 give 96.1, 96.4 and
// 96.1 % (docs/evaluation.md). At 70 degrees the FIPs are 3 px wide.
TEST(DetectionRate, IssueTargetAtExtremeYaw9cm) {
  const Sweep s = sweep(0.09, 1.5, 70, 10, 60, 9070);
  s.print("9 cm at 1.5 m, 60 frames per step");
  EXPECT_GE(s.rate(70), 0.95);
}

// A 15 cm landmark at 2.5 m: FIPs of 8 px, 1.4 px wide at 80 degrees.
TEST(DetectionRate, Landmark15cmAt2m5) {
  const Sweep s = sweep(0.15, 2.5, 80, 10, 12, 15025);
  s.print("15 cm at 2.5 m");
  EXPECT_GE(s.rate(60), 0.95);
  EXPECT_GE(s.rate(70), 0.92);
  EXPECT_GE(s.rate(80), 0.80);
}

// The issue's target for the 15 cm landmark (95 % within +-80 degrees at
// 2.5 m): not met yet at the extreme angles, where printed blue squares
// 1.4-3 px wide lose their colour to blur and JPEG chroma subsampling.
// Run with --gtest_also_run_disabled_tests.
TEST(DetectionRate, DISABLED_IssueTargetAtExtremeYaw15cm) {
  EXPECT_GE(sweep(0.15, 2.5, 80, 10, 12, 15025).rate(80), 0.95);
}

// The faint look's steep round (steep_looks): at 70 degrees of yaw a 9 cm
// landmark's blue squares at 1.5 m are 2-3 px wide, and the half-resolution
// colour of JPEG (4 frames in 5 of ld-synth's random conditions) spreads
// their blue over the paper, to grey; taken again from the sharp brightness
// in a window around the red square, it is blue again. The same JPEG
// colour rounds the thresholded AP: it starts from red squares whose axes
// differ by 1.3:1 or more, as thresholded, not the printed 3:1. On these
// 160 frames (the 15 cm landmark at 2.5 m is the same in pixels) the round
// finds at least 16 landmarks more (10 % of the frames) than the detector
// without it finds (117 against 97 when written; 112 when it started only
// from squares of 2:1 or more), and loses none that it finds.
TEST(DetectionRate, SteepRoundTakesTheColourFromTheBrightness) {
  ld::DetectorParams without;
  without.steep_looks = 0;
  ld::Detector det, plain(without);
  std::mt19937_64 rng(7070);
  std::uniform_real_distribution<double> U(0, 1);
  int found = 0, found_without = 0, lost = 0, frames = 0;
  for (const double yaw : {-70.0, 70.0})
    for (int k = 0; k < 80; ++k, ++frames) {
      const double roll = U(rng) * 360 - 180, pitch = (U(rng) - 0.5) * 20;
      const auto lm = ld::synth::placeLandmark(kCam, 1.5, yaw, pitch, roll, U(rng) - 0.5, U(rng) - 0.5, 0.09);
      const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, {lm}, rng()));
      const bool with = match(det.detect(frame.bgr), frame.truth[0]) != nullptr;
      const bool alone = match(plain.detect(frame.bgr), frame.truth[0]) != nullptr;
      found += with, found_without += alone, lost += alone && !with;
    }
  std::printf("9 cm at 1.5 m, yaw +-70: %d of %d found, %d without the steep round (%d of them lost with it)\n", found,
              frames, found_without, lost);
  EXPECT_GE(found, found_without + 16);
  EXPECT_EQ(lost, 0);
}

// The steep round around blue squares: a 9 cm landmark at 1.5 m, 60-70
// degrees of yaw, hung on a brown or red wall (just behind the sheet),
// every frame through JPEG. Half-resolution colour joins the AP, 1-2 px of
// margin from the sheet's edge, to the wall, so no red square is left to
// start from; where a FIP kept some blue, the round looks around it. Of
// these 120 frames 95 are found (88 when the round started only from red
// squares); at least 92 must be, and no landmark but the sheet's.
TEST(DetectionRate, SteepRoundAroundBlueSquaresWhenTheApJoinedTheWall) {
  ld::Detector det;
  std::mt19937_64 rng(6070);
  std::uniform_real_distribution<double> U(0, 1);
  constexpr int kFrames = 120;
  int found = 0, others = 0;
  for (int k = 0; k < kFrames; ++k) {
    const double yaw = (k % 2 ? 1 : -1) * (60 + 10 * U(rng));
    const double roll = U(rng) * 360 - 180, pitch = (U(rng) - 0.5) * 20;
    const auto lm = ld::synth::placeLandmark(kCam, 1.5, yaw, pitch, roll, U(rng) - 0.5, U(rng) - 0.5, 0.09);
    auto spec = ld::synth::randomConditions(kCam, {lm}, rng());
    // brown wood, orange, or red paint (BGR)
    const cv::Scalar colours[] = {{40, 90, 160}, {30, 110, 210}, {45, 45, 190}};
    spec.surfaces.push_back(wallBehind(lm, colours[k % 3], 2.0));
    spec.degradation.jpeg_quality = 75 + static_cast<int>(20 * U(rng));
    const auto frame = ld::synth::render(spec);
    const ld::Detection& d = det.detect(frame.bgr);
    found += match(d, frame.truth[0]) != nullptr;
    for (const auto& l : d.landmarks) others += !ld::matchesTruth(l, centres(frame.truth[0]));
  }
  std::printf("9 cm at 1.5 m, yaw 60-70, on a brown or red wall, JPEG: %d of %d found, %d other landmarks\n", found,
              kFrames, others);
  EXPECT_GE(found, 92);
  EXPECT_EQ(others, 0);
}

// Close range: a 15 cm landmark from 0.25 to 0.35 m at yaw within +-60
// degrees (strong perspective: the AP far from the affine prediction), in
// the middle of the image so that it stays in view.
TEST(DetectionRate, CloseAndSteep) {
  ld::Detector det;
  std::mt19937_64 rng(2530);
  std::uniform_real_distribution<double> U(0, 1);
  int found = 0, frames = 0;
  for (double distance : {0.25, 0.3, 0.35})
    for (int k = 0; k < 30; ++k) {
      const double yaw = (2 * U(rng) - 1) * 60, roll = U(rng) * 360 - 180, pitch = (U(rng) - 0.5) * 20;
      const auto lm = ld::synth::placeLandmark(kCam, distance, yaw, pitch, roll, 0, 0, 0.15);
      const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, {lm}, rng()));
      if (!frame.truth[0].in_view) continue;
      ++frames;
      found += match(det.detect(frame.bgr), frame.truth[0]) != nullptr;
    }
  std::printf("close and steep: %d / %d = %.1f %%\n", found, frames, 100.0 * found / frames);
  EXPECT_GE(frames, 80);
  EXPECT_GE(found, 0.95 * frames);
}

// Several landmarks per frame at ordinary angles.
TEST(DetectionRate, SeveralLandmarksPerFrame) {
  ld::Detector det;
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> U(0, 1);
  int truths = 0, found = 0, extra = 0;
  for (int i = 0; i < 40; ++i) {
    std::vector<ld::synth::LandmarkPlacement> lms;
    const int n = 2 + i % 3;
    for (int k = 0; k < n; ++k) {
      const double nx = -0.7 + 1.4 * (k + 0.5) / n;
      lms.push_back(ld::synth::placeLandmark(kCam, 1.0 + 1.5 * U(rng), (U(rng) - 0.5) * 100,
                                             (U(rng) - 0.5) * 20, U(rng) * 360, nx, (U(rng) - 0.5) * 0.8,
                                             0.15, "lm", k));
    }
    const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, lms, rng()));
    const auto& d = det.detect(frame.bgr);
    int matched = 0;
    for (const auto& t : frame.truth) {
      if (!t.in_view) continue;
      ++truths;
      matched += match(d, t) != nullptr;
    }
    found += matched;
    extra += static_cast<int>(d.landmarks.size()) - matched;
  }
  std::printf("several per frame: %d / %d found, %d extra\n", found, truths, extra);
  EXPECT_GE(found, 0.95 * truths);
  EXPECT_EQ(extra, 0);
}

// A camera turning or driving during the exposure: motion blur of 10 px
// (9 cm at 1-1.5 m, squares 8-12 px) and 15 px (15 cm at 1-2 m), along a
// direction drawn per frame, yaw within +-40 degrees. The blur mixes each
// square with the paper; printed blue, dark and only moderately saturated,
// falls under the first pass's blue threshold, while the red AP stays red.
// The faint look around that AP labels blue from faint_look_blue; with the
// first pass's threshold there, fewer are found.
TEST(DetectionRate, UnderMotionBlur) {
  ld::DetectorParams first_threshold;
  first_threshold.faint_look_blue = first_threshold.saturation_threshold_blue;
  ld::Detector det, at_first_threshold(first_threshold);
  struct Set { double side, near, far, blur, at_least; };  // (measured 2026-12-03: 55 % and 33 %)
  for (const Set& set : {Set{0.09, 1.0, 1.5, 10, 0.45}, Set{0.15, 1.0, 2.0, 15, 0.25}}) {
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> U(0, 1);
    int found = 0, found_at_first = 0, frames = 0;
    for (int k = 0; k < 60; ++k) {
      const double distance = set.near + (set.far - set.near) * U(rng), yaw = 80 * U(rng) - 40;
      const auto lm = ld::synth::placeLandmark(kCam, distance, yaw, (U(rng) - 0.5) * 20, 360 * U(rng) - 180,
                                               U(rng) - 0.5, U(rng) - 0.5, set.side);
      auto spec = ld::synth::randomConditions(kCam, {lm}, rng());
      spec.degradation.motion_px = set.blur;
      spec.degradation.motion_angle_deg = 180 * U(rng);
      const auto frame = ld::synth::render(spec);
      ++frames;
      found += match(det.detect(frame.bgr), frame.truth[0]) != nullptr;
      found_at_first += match(at_first_threshold.detect(frame.bgr), frame.truth[0]) != nullptr;
    }
    std::printf("%.0f cm at %.1f-%.1f m, blur %.0f px: %d / %d found; with the faint look at the first pass's "
                "blue threshold %d\n", 100 * set.side, set.near, set.far, set.blur, found, frames, found_at_first);
    EXPECT_GE(found, found_at_first + frames / 15) << set.side;
    EXPECT_GE(found, set.at_least * frames) << set.side;
  }
}

// Scenes without a landmark: colourful blue and red objects and
// landmark-like cards (red square in the middle, next to TL, colours swapped).
TEST(FalsePositives, DistractorScenesWithoutLandmarks) {
  ld::Detector det;
  const int frames = 300;
  int fp = 0;
  for (int i = 0; i < frames; ++i) {
    auto spec = ld::synth::randomConditions(kCam, {}, 50000 + static_cast<uint64_t>(i));
    spec.distractors = 6 + i % 7;
    spec.landmark_like_cards = 2 + i % 3;
    fp += static_cast<int>(det.detect(ld::synth::render(spec).bgr).landmarks.size());
  }
  std::printf("false positives: %d in %d frames (%.2f per 100 frames)\n", fp, frames, 100.0 * fp / frames);
  EXPECT_LE(fp * 100, frames);  // at most 1 per 100 frames
}

// Sheets hung in a 3 x 3 grid on a wall (15 cm, 1-3 m, yaw within +-40
// degrees, a plain wall of 0.35-0.95 of white just behind them), with gaps
// of `gap_lo`..`gap_hi` sheets between them: `frames` frames, the landmarks
// that match no sheet, the sheets in view and those found.
struct GridResult {
  int false_landmarks = 0, in_view = 0, found = 0;
};
GridResult gridOfSheets(double gap_lo, double gap_hi, int frames, uint64_t seed, uint64_t scene_seed) {
  ld::Detector det;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  GridResult r;
  for (int k = 0; k < frames; ++k) {
    const double S = 0.15, gap = (gap_lo + (gap_hi - gap_lo) * U(rng)) * S;
    const double dist = 1.0 + 2.0 * U(rng), yaw = (2 * U(rng) - 1) * 40;
    const double pitch = (2 * U(rng) - 1) * 10, roll = (2 * U(rng) - 1) * 10;
    const auto mid = ld::synth::placeLandmark(kCam, dist, yaw, pitch, roll, 0, 0, S, "room-105", 4);
    cv::Matx33d R;
    cv::Rodrigues(mid.rvec, R);
    std::vector<ld::synth::LandmarkPlacement> sheets;
    for (int j = -1; j <= 1; ++j)
      for (int i = -1; i <= 1; ++i) {
        auto lm = mid;
        lm.id = static_cast<int>(sheets.size());
        lm.payload = "room-" + std::to_string(101 + lm.id);
        lm.tvec = mid.tvec + R * cv::Vec3d(i * (S + gap), j * (S + gap), 0);
        sheets.push_back(lm);
      }
    auto spec = ld::synth::randomConditions(kCam, sheets, scene_seed + static_cast<uint64_t>(k));
    const double level = 255 * (0.35 + 0.6 * U(rng));
    spec.surfaces.push_back(wallBehind(mid, cv::Scalar(level, level, level), 3.0));
    spec.distractors = 0;
    const auto frame = ld::synth::render(spec);
    const ld::Detection& d = det.detect(frame.bgr);
    for (const auto& lm : d.landmarks) {
      bool real = false;
      for (const auto& t : frame.truth) real |= ld::matchesTruth(lm, centres(t));
      r.false_landmarks += !real;
    }
    for (const auto& t : frame.truth) {
      if (!t.in_view) continue;
      ++r.in_view;
      r.found += match(d, t) != nullptr;
    }
  }
  std::printf("grids of sheets with gaps of %.2f-%.2f S: %d of %d sheets in view found, %d false landmarks in %d "
              "frames\n", gap_lo, gap_hi, r.found, r.in_view, r.false_landmarks, frames);
  return r;
}

// Gaps of about a third of a sheet: the squares along two neighbouring
// sheets' facing edges (a blue and a red one of one sheet, two blue ones of
// the other) lie as a landmark's turned by 90 degrees, its middle the wall
// seen through the gap. Before verification compared such a "QR" with the
// band of wall across the "sheet", 14 of them came in these 60 frames, and
// each took the squares of real landmarks (513 of the 540 sheets in view
// found). None may come, and 98 % of the sheets in view are found.
TEST(FalsePositives, GridOfSheetsWithGapsMakesNoLandmarks) {
  const GridResult r = gridOfSheets(0.3, 0.37, 60, 2026, 70000);
  EXPECT_EQ(r.false_landmarks, 0);
  EXPECT_GE(r.found, r.in_view * 98 / 100);
}

// Gaps of about a sixth of a sheet: where four sheets' corners meet, the TL
// of one, the TR of its left neighbour, the BL of the one above and the AP
// of the one diagonally across lie as a smaller landmark's turned by 180
// degrees, the middle of each of its sides on the wall in a gap. Before
// verification looked for those four dips, 7 came in these 100 frames,
// each taking a real landmark's TL (881 of the 900 sheets in view found).
// None may come, and 98 % of the sheets in view are found.
TEST(FalsePositives, GridOfSheetsWithNarrowGapsMakesNoLandmarks) {
  const GridResult r = gridOfSheets(0.15, 0.2, 100, 2011, 71000);
  EXPECT_EQ(r.false_landmarks, 0);
  EXPECT_GE(r.found, r.in_view * 98 / 100);
}

// Clean frontal views at 1 m (15 cm, FIPs of 33 px): corners to a fraction
// of a pixel.
TEST(Corners, SubPixelOnCleanFrontalViews) {
  ld::Detector det;
  double sq = 0, worst = 0;
  int n = 0;
  for (int k = 0; k < 12; ++k) {
    ld::synth::SceneSpec spec;
    spec.camera = kCam;
    spec.landmarks = {ld::synth::placeLandmark(kCam, 1.0, 0, 0, k * 31.0, 0.6 * std::sin(k), 0.5 * std::cos(2 * k),
                                               0.15)};
    spec.seed = 100 + static_cast<uint64_t>(k);
    const auto frame = ld::synth::render(spec);
    const ld::Landmark* lm = match(det.detect(frame.bgr), frame.truth[0]);
    ASSERT_NE(lm, nullptr) << k;
    for (int i = 0; i < 4; ++i) {
      const double e = cv::norm(cv::Point2d(lm->corners[i]) - frame.truth[0].corners[i]);
      sq += e * e;
      worst = std::max(worst, e);
      ++n;
    }
  }
  const double rms = std::sqrt(sq / n);
  std::printf("corner error on clean frontal views at 1 m: RMS %.3f px, worst %.3f px\n", rms, worst);
  EXPECT_LT(rms, 0.5);
}

namespace {

// The corners' RMS error of detectors `a` and `b` on the same frames of a
// camera `cam`: 8 landmarks of 15 cm per distance, near the image's corners
// (where a lens distorts most), turned by 45 degrees each.
std::pair<double, double> cornerRms(ld::Detector& a, ld::Detector& b, const ld::CameraModel& cam,
                                    const std::vector<double>& distances, uint64_t seed) {
  double sq_a = 0, sq_b = 0;
  int n = 0;
  for (size_t k = 0; k < 8 * distances.size(); ++k) {
    ld::synth::SceneSpec spec;
    spec.camera = cam;
    spec.landmarks = {ld::synth::placeLandmark(cam, distances[k / 8], 0, 0, static_cast<double>(k) * 45.0,
                                               k % 2 ? 0.55 : -0.55, k % 4 < 2 ? 0.45 : -0.45, 0.15)};
    spec.seed = seed + k;
    const auto frame = ld::synth::render(spec);
    EXPECT_TRUE(frame.truth[0].in_view) << k;
    const ld::Landmark* da = match(a.detect(frame.bgr), frame.truth[0]);
    EXPECT_NE(da, nullptr) << k;
    if (!da) continue;
    const auto corners_a = da->corners;
    const ld::Landmark* db = match(b.detect(frame.bgr), frame.truth[0]);
    EXPECT_NE(db, nullptr) << k;
    if (!db) continue;
    for (int i = 0; i < 4; ++i) {
      sq_a += std::pow(cv::norm(cv::Point2d(corners_a[i]) - frame.truth[0].corners[i]), 2);
      sq_b += std::pow(cv::norm(cv::Point2d(db->corners[i]) - frame.truth[0].corners[i]), 2);
      ++n;
    }
  }
  return {std::sqrt(sq_a / std::max(1, n)), std::sqrt(sq_b / std::max(1, n))};
}

}  // namespace

// A barrel-distorting camera: with its calibration the corners follow the
// distortion (the sheet is a homography of the undistorted image only).
TEST(Corners, DistortingCameraWithItsCalibration) {
  ld::CameraModel cam = kCam;
  cam.dist = (cv::Mat_<double>(1, 5) << -0.3, 0.1, 0, 0, 0);
  ld::DetectorParams centroids;
  centroids.align_iterations = 0;  // (the calibration's effect alone: no sheet alignment)
  ld::Detector calibrated(centroids), plain;
  calibrated.setCamera(cam, 0.15);
  const auto [rms_cal, rms_plain] = cornerRms(calibrated, plain, cam, {0.8}, 200);
  std::printf("corner error with barrel distortion (k1 -0.3): RMS %.3f px with the calibration, %.3f px without\n",
              rms_cal, rms_plain);
  EXPECT_LT(rms_cal, 0.5);
  EXPECT_LT(rms_cal, rms_plain);
}

// Sheet alignment with a distorting camera: the sheet is a homography of the
// undistorted image only, so the crop is aligned through the distortion; the
// corners come out at least as good as the centroids' (aligned in the
// distorted image as it is, they were 2-3 times worse near the corners).
// At 0.6 m the sheet is a near one, read on every other pixel of the crop
// taken through the distortion.
TEST(Corners, SheetAlignmentThroughTheDistortion) {
  ld::CameraModel cam = kCam;
  cam.dist = (cv::Mat_<double>(1, 5) << -0.3, 0.1, 0, 0, 0);
  ld::DetectorParams centroids, aligned;
  centroids.align_iterations = 0;
  aligned.align_iterations = 10;
  ld::Detector plain(centroids), align(aligned);
  plain.setCamera(cam, 0.15);
  align.setCamera(cam, 0.15);
  const auto [rms_plain, rms_align] = cornerRms(plain, align, cam, {0.6, 1.2, 2.0}, 220);
  std::printf("corner error with barrel distortion (k1 -0.3), 0.6, 1.2 and 2 m near the image's corners: RMS %.3f px "
              "centroids, %.3f px sheet alignment\n",
              rms_plain, rms_align);
  EXPECT_LT(rms_align, rms_plain);
}

namespace {

using ld::eval::PoseErrors;
using ld::eval::quantile;

void print(const PoseErrors& e, const char* name) {
  std::printf("%s: corners median %.3f px, 90th pct %.3f px; rotation median %.2f deg, 90th pct %.2f deg; "
              "distance median %.2f %%, 90th pct %.2f %%\n",
              name, quantile(e.corner_px, 0.5), quantile(e.corner_px, 0.9), quantile(e.rotation_deg, 0.5),
              quantile(e.rotation_deg, 0.9), 100 * quantile(e.distance_frac, 0.5), 100 * quantile(e.distance_frac, 0.9));
}

// The default detector (it aligns the sheet when it computes a pose)
// against one with align_iterations 0, both with the camera, on `frames`
// random views of a 15 cm landmark at `distance` (yaw within +-40 degrees,
// pitch within +-10, any roll, within `spread` of the image's middle;
// scenes `scene_seed` on): each one's errors over the frames where it found
// the landmark. With `every_frame` both must find it in every frame;
// otherwise both in the same frames.
void alignedAgainstCentroids(double distance, double spread, int frames, uint64_t rng_seed, uint64_t scene_seed,
                             bool every_frame, PoseErrors& without, PoseErrors& with) {
  ld::DetectorParams centroids;
  centroids.align_iterations = 0;
  ld::Detector plain(centroids), align;
  plain.setCamera(kCam, 0.15);
  align.setCamera(kCam, 0.15);
  std::mt19937_64 rng(rng_seed);
  std::uniform_real_distribution<double> U(0, 1);
  for (int k = 0; k < frames; ++k) {
    const auto lm = ld::synth::placeLandmark(kCam, distance, -40 + 80 * U(rng), -10 + 20 * U(rng), 360 * U(rng),
                                             spread * (U(rng) - 0.5), spread * (U(rng) - 0.5), 0.15);
    const auto frame =
        ld::synth::render(ld::synth::randomConditions(kCam, {lm}, scene_seed + static_cast<uint64_t>(k)));
    const ld::Landmark* a = match(plain.detect(frame.bgr), frame.truth[0]);
    if (every_frame) {
      ASSERT_NE(a, nullptr) << k;
    }
    if (a) without.add(a->corners, a->pose, frame.truth[0]);
    const ld::Landmark* b = match(align.detect(frame.bgr), frame.truth[0]);
    if (every_frame) {
      ASSERT_NE(b, nullptr) << k;
    }
    ASSERT_EQ(b != nullptr, a != nullptr) << k;  // (the two differ in their corners alone)
    if (b) with.add(b->corners, b->pose, frame.truth[0]);
  }
}

}  // namespace

// Sheet alignment (DetectorParams::align_iterations) on far landmarks, 15 cm
// at 2.5 m (a sheet of about 36 px): the whole sheet's edges place the
// corners better than each square's centroid, and the pose's rotation with
// them (where four corners a few tenths of a pixel off let IPPE pick the
// wrong one of the two mirror poses). The aligned detector is the default
// one: it aligns because it computes a pose (align_iterations -1, auto).
TEST(Pose, SheetAlignmentSharpensFarLandmarks) {
  PoseErrors without, with;
  ASSERT_NO_FATAL_FAILURE(alignedAgainstCentroids(2.5, 1.0, 40, 41, 500, true, without, with));
  print(without, "15 cm at 2.5 m, centroids");
  print(with, "15 cm at 2.5 m, sheet alignment");
  ASSERT_EQ(with.rotation_deg.size(), without.rotation_deg.size());
  EXPECT_LT(quantile(with.corner_px, 0.5), 0.6 * quantile(without.corner_px, 0.5));
  EXPECT_LT(quantile(with.corner_px, 0.9), 0.6 * quantile(without.corner_px, 0.9));
  EXPECT_LT(quantile(with.rotation_deg, 0.9), 0.5 * quantile(without.rotation_deg, 0.9));
  EXPECT_LT(quantile(with.rotation_deg, 0.9), 3.0);
}

// ... and on near ones, 15 cm at 0.5 m (sheets of about 180 px, fitted to
// a finer model on every third pixel): the centroids, from many pixels,
// place the corners about as well, but the rotation still gains.
TEST(Pose, SheetAlignmentSteadiesNearLandmarks) {
  PoseErrors without, with;
  ASSERT_NO_FATAL_FAILURE(alignedAgainstCentroids(0.5, 0.5, 30, 45, 800, false, without, with));
  ASSERT_GE(with.corner_px.size(), 25u);
  print(without, "15 cm at 0.5 m, centroids");
  print(with, "15 cm at 0.5 m, sheet alignment");
  EXPECT_LT(quantile(with.corner_px, 0.9), 1.1 * quantile(without.corner_px, 0.9));
  EXPECT_LT(quantile(with.rotation_deg, 0.9), 0.75 * quantile(without.rotation_deg, 0.9));
  EXPECT_LT(quantile(with.rotation_deg, 0.9), 1.0);
}

// ... and what it leaves alone: steeply seen landmarks (55-70 degrees of
// yaw), whose squares are a few pixels wide, are found as often (the fit
// does not slide them off the truth: SheetAlignment.* in test_detector
// tests the guard against a slide).
TEST(Pose, SheetAlignmentLeavesSteepLandmarks) {
  ld::DetectorParams aligned;
  aligned.align_iterations = 10;
  ld::Detector plain, align(aligned);
  std::mt19937_64 rng(43);
  std::uniform_real_distribution<double> U(0, 1);
  for (int k = 0; k < 6; ++k) (void)U(rng), (void)U(rng);  // (the draws of the near half this test had)
  int found_plain = 0, found_aligned = 0;
  for (int k = 0; k < 40; ++k) {
    const double yaw = (k % 2 ? 1 : -1) * (55 + 15 * U(rng));
    const auto lm = ld::synth::placeLandmark(kCam, 2.5, yaw, 0, 360 * U(rng), U(rng) - 0.5, U(rng) - 0.5, 0.15);
    const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, {lm}, 700 + static_cast<uint64_t>(k)));
    found_plain += match(plain.detect(frame.bgr), frame.truth[0]) != nullptr;
    found_aligned += match(align.detect(frame.bgr), frame.truth[0]) != nullptr;
  }
  std::printf("15 cm at 2.5 m, yaw 55-70 deg: %d of 40 found with centroids, %d with sheet alignment\n", found_plain,
              found_aligned);
  EXPECT_GT(found_plain, 10);
  EXPECT_GE(found_aligned, found_plain);
}

// Pose of a 15 cm landmark at 1.5 m under random conditions and angles.
TEST(Pose, DistanceWithinTwoPercentAt1m5) {
  ld::Detector det;
  det.setCamera(kCam, 0.15);
  PoseErrors errors;
  for (int k = 0; k < 30; ++k) {
    const auto lm = ld::synth::placeLandmark(kCam, 1.5, -45 + 3.0 * k, 0, k * 37.0, 0.5 * std::sin(k),
                                             0.4 * std::cos(3 * k), 0.15);
    const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, {lm}, 300 + static_cast<uint64_t>(k)));
    const ld::Landmark* d = match(det.detect(frame.bgr), frame.truth[0]);
    ASSERT_NE(d, nullptr) << k;
    ASSERT_TRUE(d->pose.has_value());
    errors.add(d->corners, d->pose, frame.truth[0]);
  }
  const std::vector<double>& errs = errors.distance_frac;
  const double worst_angle = *std::max_element(errors.rotation_deg.begin(), errors.rotation_deg.end());
  double mean = 0, worst = 0;
  for (double e : errs) mean += e / errs.size(), worst = std::max(worst, e);
  std::printf("pose distance error at 1.5 m: mean %.2f %%, worst %.2f %%; worst rotation error %.1f deg\n",
              100 * mean, 100 * worst, worst_angle);
  EXPECT_LT(worst, 0.02);
}

// Two 15 cm landmarks side by side at 2.5 m, 45 px apart, both seen at 60-70
// degrees of yaw (one sign a frame, the other the next), each at any roll:
// pair k of the sequence drawn from seed 9001.
namespace {
struct SteepPair {
  std::vector<ld::synth::LandmarkPlacement> landmarks;
  uint64_t conditions;
};
SteepPair steepPair(std::mt19937_64& rng, int k) {
  std::uniform_real_distribution<double> U(0, 1);
  const double yaw = (k % 2 ? 1 : -1) * (60 + 10 * U(rng));
  const double roll0 = U(rng) * 360 - 180, roll1 = U(rng) * 360 - 180, ny = (U(rng) - 0.5) * 0.2;
  const uint64_t conditions = rng();
  return {{ld::synth::placeLandmark(kCam, 2.5, yaw, 0, roll0, -0.07, ny, 0.15, "lm", 0),
           ld::synth::placeLandmark(kCam, 2.5, yaw, 0, roll1, 0.07, ny, 0.15, "lm", 1)},
          conditions};
}
}  // namespace

// A steep window that finds its neighbour's landmark too leaves it out (not
// its own square's), and the neighbour's square, inside that window, then
// gets a window of its own: of these 300 pairs both landmarks are found in
// 257 frames; 252 when the neighbour's square was skipped as inside a
// window looked at. At least 255: room for two frames of drift from other
// changes, none for losing the rule.
TEST(DetectionRate, SteepNeighboursEachGetTheirOwnWindow) {
  ld::Detector det;
  std::mt19937_64 rng(9001);
  int both = 0, others = 0;
  constexpr int kPairs = 300;
  for (int k = 0; k < kPairs; ++k) {
    const SteepPair pair = steepPair(rng, k);
    const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, pair.landmarks, pair.conditions));
    const ld::Detection& d = det.detect(frame.bgr);
    const bool a = match(d, frame.truth[0]) != nullptr, b = match(d, frame.truth[1]) != nullptr;
    both += a && b;
    others += static_cast<int>(d.landmarks.size()) - a - b;
  }
  std::printf("steep neighbours, 15 cm at 2.5 m, yaw 60-70: both found in %d of %d frames, %d other landmarks\n",
              both, kPairs, others);
  EXPECT_GE(both, 255);
}

// Pair 89 of that sequence: a steep round's window finds a landmark that
// is not around its own square and leaves it out (--explain's "left out");
// that landmark's square, inside the window, gets a window of its own later
// in the round, which finds and keeps it. Both landmarks are found.
TEST(DetectionRate, LeftOutNeighbourIsFoundInItsOwnWindow) {
  std::mt19937_64 rng(9001);
  SteepPair pair{};
  for (int k = 0; k <= 89; ++k) pair = steepPair(rng, k);
  const auto frame = ld::synth::render(ld::synth::randomConditions(kCam, pair.landmarks, pair.conditions));
  ld::Detector det;
  ld::Explanation why;
  const ld::Detection& d = det.detect(frame.bgr, why);
  EXPECT_NE(match(d, frame.truth[0]), nullptr);
  EXPECT_NE(match(d, frame.truth[1]), nullptr);
  // A square of landmark i near p (the window's square).
  const auto near = [&](int i, const cv::Point2f& p) {
    for (const auto& c : centres(frame.truth[static_cast<size_t>(i)]))
      if (std::hypot(c.x - p.x, c.y - p.y) < 3) return true;
    return false;
  };
  bool left_then_own = false;
  for (size_t a = 0; a < why.looks.size(); ++a) {
    const auto& first = why.looks[a];
    if (first.dropped < 1) continue;
    for (size_t b = a + 1; b < why.looks.size(); ++b) {
      const auto& own = why.looks[b];
      const cv::Point around(static_cast<int>(std::lround(own.around.x)), static_cast<int>(std::lround(own.around.y)));
      for (int i = 0; i < 2; ++i)
        left_then_own |= own.round == first.round && near(i, own.around) && first.window.contains(around) &&
                         own.landmarks == 1 && own.dropped == 0;
    }
  }
  EXPECT_TRUE(left_then_own) << ld::describe(why, ld::DetectorParams());
}
