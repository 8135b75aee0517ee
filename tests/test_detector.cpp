// Unit tests of the detector's stages and of the Detector on landmarks
// rendered here from the artwork at known poses (exact ground truth).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numeric>
#include <random>
#include <set>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <unistd.h>

#include "../detector/src/filters.hpp"
#include "../detector/src/stages.hpp"
#include "ld/adaptive.hpp"
#include "ld/artwork.hpp"
#include "ld/config_file.hpp"
#include "ld/detector.hpp"
#include "ld/qr_reader.hpp"
#include "ld/landmark_layout.hpp"

namespace {

using ld::detail::Region;
namespace layout = ld::layout;

const ld::detail::MaskThresholds kMt{0.35, 0.35, 25};

// ------------------------------------------------------------------ rendering

// Printed-ink looking colours (BGR).
ld::artwork::Colours inkColours() {
  ld::artwork::Colours c;
  c.blue = {150, 60, 40};
  c.red = {45, 60, 215};
  c.white = {225, 228, 230};
  c.black = {30, 30, 30};
  return c;
}

cv::Matx33d rotation(double yaw_deg, double pitch_deg, double roll_deg) {
  const double y = yaw_deg * CV_PI / 180, p = pitch_deg * CV_PI / 180, r = roll_deg * CV_PI / 180;
  const cv::Matx33d Ry(std::cos(y), 0, std::sin(y), 0, 1, 0, -std::sin(y), 0, std::cos(y));
  const cv::Matx33d Rx(1, 0, 0, 0, std::cos(p), -std::sin(p), 0, std::sin(p), std::cos(p));
  const cv::Matx33d Rz(std::cos(r), -std::sin(r), 0, std::sin(r), std::cos(r), 0, 0, 0, 1);
  return Ry * Rx * Rz;
}

struct Placed {
  cv::Matx33d R = cv::Matx33d::eye();
  cv::Vec3d t{0, 0, 1};
  double side_m = 0.15;
  cv::Mat artwork;  // sheet texture (square BGR)
};

struct Truth {
  std::array<cv::Point2d, 4> centres;  // TL, TR, BL, AP
  std::array<cv::Point2d, 4> corners;  // TL, TR, BR, BL
};

cv::Point2d project(const ld::CameraModel& cam, const Placed& p, const cv::Point3d& X) {
  const cv::Vec3d c = p.R * cv::Vec3d(X.x, X.y, X.z) + p.t;
  return {cam.K(0, 0) * c[0] / c[2] + cam.K(0, 2), cam.K(1, 1) * c[1] / c[2] + cam.K(1, 2)};
}

Truth truthOf(const ld::CameraModel& cam, const Placed& p) {
  Truth t;
  const auto cs = layout::objectCentres(p.side_m);
  const auto cn = layout::objectCorners(p.side_m);
  for (int i = 0; i < 4; ++i) {
    t.centres[i] = project(cam, p, cs[i]);
    t.corners[i] = project(cam, p, cn[i]);
  }
  return t;
}

// Draws the sheet into `img` (supersampled 4x, then area-averaged).
void drawSheet(cv::Mat& img, const ld::CameraModel& cam, const Placed& p) {
  const int ss = 4;
  const cv::Mat& art = p.artwork;
  const double n = art.cols, s = p.side_m;
  // texture pixel (i, j) -> object point (x, y, 1) -> camera -> supersampled image
  const cv::Matx33d A(s / n, 0, s / (2 * n) - s / 2, 0, s / n, s / (2 * n) - s / 2, 0, 0, 1);
  const cv::Matx33d Rt(p.R(0, 0), p.R(0, 1), p.t[0], p.R(1, 0), p.R(1, 1), p.t[1], p.R(2, 0),
                       p.R(2, 1), p.t[2]);
  const cv::Matx33d S(ss, 0, (ss - 1) / 2.0, 0, ss, (ss - 1) / 2.0, 0, 0, 1);
  const cv::Matx33d H = S * cam.K * Rt * A;
  const cv::Size big(img.cols * ss, img.rows * ss);
  cv::Mat warped, mask;
  cv::warpPerspective(art, warped, H, big, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::warpPerspective(cv::Mat(art.size(), CV_8UC1, cv::Scalar(255)), mask, H, big, cv::INTER_LINEAR,
                      cv::BORDER_CONSTANT);
  cv::Mat small, small_mask;
  cv::resize(warped, small, img.size(), 0, 0, cv::INTER_AREA);
  cv::resize(mask, small_mask, img.size(), 0, 0, cv::INTER_AREA);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const double a = small_mask.at<uint8_t>(y, x) / 255.0;
      if (a <= 0) continue;
      auto& d = img.at<cv::Vec3b>(y, x);
      const auto& sv = small.at<cv::Vec3b>(y, x);
      for (int c = 0; c < 3; ++c) d[c] = cv::saturate_cast<uint8_t>(sv[c] + (1 - a) * d[c]);  // premultiplied
    }
}

cv::Mat background(cv::Size size, uint64_t seed, bool plain = false) {
  cv::Mat bg(size, CV_8UC3, cv::Scalar(120, 125, 130));
  if (plain) return bg;
  cv::RNG rng(seed);
  cv::Mat noise(size / 16 + cv::Size(1, 1), CV_8UC3);
  rng.fill(noise, cv::RNG::UNIFORM, 60, 200);
  cv::Mat gray;
  cv::cvtColor(noise, gray, cv::COLOR_BGR2GRAY);  // grey texture: no saturation
  cv::cvtColor(gray, noise, cv::COLOR_GRAY2BGR);
  cv::resize(noise, bg, size, 0, 0, cv::INTER_CUBIC);
  return bg;
}

const cv::Mat& artworkImage() {
  static const cv::Mat art = ld::artwork::renderLandmark("room-214/door", 720, inkColours());
  return art;
}

Placed place(double distance, double yaw, double roll, double side_m = 0.15, double x = 0, double y = 0) {
  Placed p;
  p.R = rotation(yaw, 0, roll);
  p.t = {x, y, distance};
  p.side_m = side_m;
  p.artwork = artworkImage();
  return p;
}

void addNoise(cv::Mat& img, double sigma, uint64_t seed) {
  cv::Mat n(img.size(), CV_16SC3);
  cv::RNG rng(seed);
  rng.fill(n, cv::RNG::NORMAL, 0, sigma);
  cv::Mat f;
  img.convertTo(f, CV_16SC3);
  f += n;
  f.convertTo(img, CV_8UC3);
}

const ld::CameraModel kCam = ld::CameraModel::defaultVga();

bool found(const ld::Detection& det, const Truth& t) {
  for (const auto& lm : det.landmarks)
    if (ld::matchesTruth(lm, t.centres)) return true;
  return false;
}

// Exactly one landmark, and it is `t`.
::testing::AssertionResult onlyLandmark(const ld::Detection& det, const Truth& t) {
  if (det.landmarks.size() != 1) return ::testing::AssertionFailure() << det.landmarks.size() << " landmarks, not 1";
  if (!ld::matchesTruth(det.landmarks[0], t.centres)) return ::testing::AssertionFailure() << "not the landmark";
  return ::testing::AssertionSuccess();
}

// Regions of a layout: TL, TR, BL, AP squares of `side` px, rotated by `roll`
// degrees about `c`.
std::array<Region, 4> layoutRegions(double side, double roll_deg, cv::Point2d c) {
  const double r = roll_deg * CV_PI / 180, co = std::cos(r), si = std::sin(r);
  std::array<Region, 4> out;
  const double s2 = side * side / 12.0;
  for (int i = 0; i < 4; ++i) {
    const double ux = (layout::kCentresU[i][0] - 4.5) * side / 2, uy = (layout::kCentresU[i][1] - 4.5) * side / 2;
    Region& g = out[i];
    g.cx = c.x + co * ux - si * uy;
    g.cy = c.y + si * ux + co * uy;
    g.sxx = s2, g.syy = s2, g.sxy = 0;  // a square's moments are rotation invariant
    g.area = static_cast<int>(side * side);
    g.colour = i == 3 ? ld::detail::kRed : ld::detail::kBlue;
  }
  return out;
}

}  // namespace

// ====================================================================== saturation

TEST(Saturation, LabelsBlueRedAndNothingElse) {
  cv::Mat img(8, 40, CV_8UC3, cv::Scalar(128, 128, 128));
  img.at<cv::Vec3b>(1, 1) = {200, 40, 30};   // blue
  img.at<cv::Vec3b>(1, 2) = {60, 80, 210};   // red (orange-ish)
  img.at<cv::Vec3b>(1, 3) = {160, 60, 90};   // purplish blue
  img.at<cv::Vec3b>(1, 11) = {160, 60, 140};  // violet: not blue
  img.at<cv::Vec3b>(1, 12) = {200, 170, 40};  // teal: not blue
  img.at<cv::Vec3b>(1, 4) = {250, 250, 250};  // white
  img.at<cv::Vec3b>(1, 5) = {20, 5, 5};      // saturated but too dark
  img.at<cv::Vec3b>(1, 6) = {200, 170, 160};  // pale blue: S = 0.2
  img.at<cv::Vec3b>(1, 7) = {40, 200, 50};   // green
  img.at<cv::Vec3b>(1, 10) = {40, 180, 210};  // yellow: not red
  img.at<cv::Vec3b>(1, 35) = {200, 40, 30};  // in the scalar tail / second vector
  cv::Mat labels;
  ld::detail::saturationMask(img, kMt, labels);
  ASSERT_EQ(labels.size(), img.size());
  EXPECT_EQ(labels.at<uint8_t>(1, 1), ld::detail::kBlue);
  EXPECT_EQ(labels.at<uint8_t>(1, 2), ld::detail::kRed);
  EXPECT_EQ(labels.at<uint8_t>(1, 3), ld::detail::kBlue);
  EXPECT_EQ(labels.at<uint8_t>(1, 4), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 5), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 6), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 7), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 10), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 11), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 12), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 35), ld::detail::kBlue);
  EXPECT_EQ(cv::countNonZero(labels), 4);
  // Default thresholds: blue lower than red. Warm-lit white paper stays unlabelled.
  img.at<cv::Vec3b>(1, 8) = {180, 225, 255};  // white paper under 4000 K light: S = 0.29
  img.at<cv::Vec3b>(1, 9) = {150, 120, 110};  // faint blue: S = 0.27
  ld::detail::saturationMask(img, ld::detail::MaskThresholds{}, labels);
  EXPECT_EQ(labels.at<uint8_t>(1, 8), ld::detail::kNone);
  EXPECT_EQ(labels.at<uint8_t>(1, 9), ld::detail::kBlue);
}

// The vectorised loop and the scalar rule agree on every pixel, with the
// blue hue window and without it (MaskThresholds::wide_blue, the faint look
// under a subtracted glare veil).
TEST(Saturation, VectorAndScalarAgree) {
  cv::Mat img(37, 101, CV_8UC3);
  cv::RNG(7).fill(img, cv::RNG::UNIFORM, 0, 256);
  // hue ties, in vector lanes and in the scalar tail: cyan (b = g > r),
  // magenta (b = r > g), grey
  const cv::Vec3b ties[] = {{200, 200, 60}, {200, 60, 200}, {150, 150, 150}};
  for (int k = 0; k < 3; ++k) img.at<cv::Vec3b>(0, k) = img.at<cv::Vec3b>(0, img.cols - 1 - k) = ties[k];
  int blue_narrow = 0;
  for (const bool wide : {false, true}) {
    cv::Mat labels;
    ld::detail::MaskThresholds t{0.2, 0.35, 25};
    t.wide_blue = wide;
    ld::detail::saturationMask(img, t, labels);
    const int qb = static_cast<int>(std::lround(t.blue * 256)), qr = static_cast<int>(std::lround(t.red * 256));
    int mismatches = 0, blue = 0, red = 0;
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const auto p = img.at<cv::Vec3b>(y, x);
        const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
        int want = 0;
        const int b = p[0], g = p[1], r = p[2];
        // blue: hue 210..270 degrees (wide: wherever blue is the largest); red: hue -60..30 degrees
        if (mx >= 25 && b == mx)
          want = (mx - mn) > ((mx * qb) >> 8) && (wide ? b > r : b - g > std::max(0, g - r) && b - r > std::max(0, r - g))
                     ? 1 : 0;
        else if (mx >= 25 && r == mx)
          want = (mx - mn) > ((mx * qr) >> 8) && r - g > std::max(0, g - b) ? 2 : 0;
        mismatches += labels.at<uint8_t>(y, x) != want;
        blue += want == 1;
        red += want == 2;
      }
    EXPECT_EQ(mismatches, 0) << "wide " << wide;
    for (const int x : {0, img.cols - 1}) {  // cyan blue only when wide; magenta and grey never
      EXPECT_EQ(labels.at<uint8_t>(0, x), wide ? ld::detail::kBlue : ld::detail::kNone) << x;
      EXPECT_EQ(labels.at<uint8_t>(0, x == 0 ? 1 : x - 1), ld::detail::kNone) << x;
      EXPECT_EQ(labels.at<uint8_t>(0, x == 0 ? 2 : x - 2), ld::detail::kNone) << x;
    }
    EXPECT_GT(blue, 100);
    EXPECT_GT(red, 100);
    if (!wide) blue_narrow = blue;
    else EXPECT_GT(blue, blue_narrow + 100);  // teal and violet too
  }
}

// ====================================================================== colour from brightness

// The vectorised loops and the scalar tail agree with the rule written out
// (within a level: float rounding), at widths that leave tails of every
// length and on a 1-pixel-wide and a 1-pixel-high window.
TEST(ColourFromBrightness, VectorAndScalarAgreeWithTheRule) {
  std::vector<float> scratch;
  for (const cv::Size size : {cv::Size(1, 9), cv::Size(9, 1), cv::Size(37, 5), cv::Size(16, 3), cv::Size(50, 7)}) {
    cv::Mat img(size, CV_8UC3);
    cv::RNG(size.width * 31 + size.height).fill(img, cv::RNG::UNIFORM, 0, 256);
    const double white = 200;
    cv::Mat out;
    ld::detail::colourFromBrightness(img, white, out, scratch);
    const int w = img.cols, h = img.rows;
    const auto at = [&](int y, int x) { return img.at<cv::Vec3b>(std::clamp(y, 0, h - 1), std::clamp(x, 0, w - 1)); };
    const auto luma = [](const cv::Vec3b& p) { return 0.114 * p[0] + 0.587 * p[1] + 0.299 * p[2]; };
    int off = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        double sd = 0, sb = 0, sr = 0;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const cv::Vec3b q = at(y + dy, x + dx);
            const double yy = luma(q);
            sd += std::max(white - yy, 0.0), sb += q[0] - yy, sr += q[2] - yy;
          }
        const double yy = luma(at(y, x)), f = std::max(white - yy, 0.0) / std::max(sd, 0.05 * 9 * white);
        const double cb = f * sb, cr = f * sr;
        const cv::Vec3b want(cv::saturate_cast<uint8_t>(yy + cb),
                             cv::saturate_cast<uint8_t>(yy - (0.114 * cb + 0.299 * cr) / 0.587),
                             cv::saturate_cast<uint8_t>(yy + cr));
        const cv::Vec3b got = out.at<cv::Vec3b>(y, x);
        for (int c = 0; c < 3; ++c) off += std::abs(got[c] - want[c]) > 1;
      }
    EXPECT_EQ(off, 0) << size;
  }
}

// ====================================================================== window colour

// The faint and veil looks' per-channel gain and tint give cv::multiply's and
// cv::subtract's values exactly (they replace them: both allocate a buffer
// at each call), on views into a larger buffer as the looks use them.
// (and pixels at the clip, for the veil round, kept as they are)
TEST(WindowColour, ScaleAndSubtractAreOpenCvsValues) {
  cv::RNG rng(7);
  cv::Mat buffer(40, 60, CV_8UC3, cv::Scalar::all(0));
  int kept = 0;
  for (int t = 0; t < 200; ++t) {
    const cv::Size size(1 + rng.uniform(0, 50), 1 + rng.uniform(0, 30));
    cv::Mat img(size, CV_8UC3);
    rng.fill(img, cv::RNG::UNIFORM, 0, 256);
    cv::Vec3d gain(rng.uniform(1.0, 4.0), rng.uniform(1.0, 4.0), rng.uniform(1.0, 4.0));
    if (t % 4 == 0) gain[t % 3] = 1.0;
    if (t % 7 == 0) gain = {1.5, 2.5, 0.5};  // (products on halves: rounded as OpenCV rounds them)
    if (t % 9 == 0) gain[t % 3] = 1e6;
    cv::Scalar tint(rng.uniform(-60.0, 60.0), rng.uniform(-60.0, 60.0), rng.uniform(-60.0, 60.0));
    if (t % 5 == 0) tint[1] = std::floor(tint[1]) + 0.5;
    if (t % 6 == 0) tint = {300, -300, 255.5};
    if (t % 11 == 0) tint = {-1e6, 1e6, -255.5};
    cv::Mat want, out = buffer(cv::Rect(0, 0, size.width, size.height));
    cv::multiply(img, cv::Scalar(gain[0], gain[1], gain[2]), want);
    ld::detail::scaleChannels(img, gain, out);
    EXPECT_EQ(cv::norm(out, want, cv::NORM_INF), 0) << "gain " << gain << " at " << size;
    cv::subtract(img, tint, want);
    ld::detail::subtractChannels(img, tint, out);
    EXPECT_EQ(cv::norm(out, want, cv::NORM_INF), 0) << "tint " << tint << " at " << size;
    EXPECT_EQ(out.data, buffer.data);
    // Pixels whose largest channel is keep_from or more stay as they are.
    const int keep_from = t % 3 == 0 ? 256 : rng.uniform(200, 256);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const cv::Vec3b v = img.at<cv::Vec3b>(y, x);
        if (std::max({v[0], v[1], v[2]}) >= keep_from) {
          want.at<cv::Vec3b>(y, x) = v;
          ++kept;
        }
      }
    ld::detail::subtractChannels(img, tint, out, keep_from);
    EXPECT_EQ(cv::norm(out, want, cv::NORM_INF), 0) << "tint " << tint << ", keep_from " << keep_from << " at " << size;
  }
  EXPECT_GT(kept, 100);  // (the keeping was tried)
}

// ====================================================================== regions

TEST(Regions, SmallSquaresStayWhole) {
  cv::Mat img(30, 40, CV_8UC3, cv::Scalar(220, 220, 220));
  img(cv::Rect(5, 5, 4, 4)).setTo(cv::Scalar(160, 50, 40));    // 4x4 blue
  img(cv::Rect(20, 10, 3, 8)).setTo(cv::Scalar(40, 60, 200));  // 3x8 red
  img(cv::Rect(30, 20, 1, 1)).setTo(cv::Scalar(160, 50, 40));  // one pixel of noise
  cv::Mat labels;
  ld::detail::saturationMask(img, kMt, labels);
  ld::detail::RunScratch scratch;
  std::vector<Region> regions;
  ld::detail::extractRegions(labels, img, kMt, 3, 1000, 0.0, scratch, regions);
  ASSERT_EQ(regions.size(), 2u);
  const Region& b = regions[0].colour == ld::detail::kBlue ? regions[0] : regions[1];
  const Region& r = regions[0].colour == ld::detail::kBlue ? regions[1] : regions[0];
  EXPECT_EQ(b.area, 16);
  EXPECT_EQ(b.width(), 4);
  EXPECT_EQ(b.height(), 4);
  EXPECT_NEAR(b.cx, 6.5, 1e-9);
  EXPECT_NEAR(b.cy, 6.5, 1e-9);
  EXPECT_NEAR(b.side(), 4.0, 1e-9);
  EXPECT_EQ(r.area, 24);
  EXPECT_EQ(r.width(), 3);
  EXPECT_EQ(r.height(), 8);
  EXPECT_NEAR(r.cx, 21.0, 1e-9);
  EXPECT_NEAR(r.cy, 13.5, 1e-9);
  EXPECT_NEAR(r.sxx, 9.0 / 12, 1e-9);
  EXPECT_NEAR(r.syy, 64.0 / 12, 1e-9);
  EXPECT_GT(b.sum_b, 1.3 * b.sum_r);
}

// Regions are 4-connected: a square touching a blue background only at a
// corner pixel stays apart from it; a 2-pixel-wide diagonal strip is one
// region; two colours touching are two regions.
TEST(Regions, FourConnectedAndPerColour) {
  cv::Mat img(30, 30, CV_8UC3, cv::Scalar(220, 220, 220));
  for (int i = 2; i < 12; ++i) img(cv::Rect(i, i, 2, 1)).setTo(cv::Scalar(160, 50, 40));  // 20 px
  img(cv::Rect(14, 2, 3, 3)).setTo(cv::Scalar(160, 50, 40));
  img(cv::Rect(14, 5, 3, 3)).setTo(cv::Scalar(40, 60, 200));
  img(cv::Rect(20, 20, 4, 4)).setTo(cv::Scalar(160, 50, 40));
  img(cv::Rect(24, 24, 6, 6)).setTo(cv::Scalar(160, 50, 40));  // corner to corner
  cv::Mat labels;
  ld::detail::saturationMask(img, kMt, labels);
  ld::detail::RunScratch scratch;
  std::vector<Region> regions;
  ld::detail::extractRegions(labels, img, kMt, 1, 1000, 0.0, scratch, regions);
  ASSERT_EQ(regions.size(), 5u);
  std::multiset<int> areas;
  for (const auto& r : regions) areas.insert(r.area);
  EXPECT_EQ(areas, (std::multiset<int>{9, 9, 16, 20, 36}));
}

// Rings and bent strokes fill little of the square their moments describe:
// dropped at min_fill; a solid square (or any parallelogram) fills it all.
TEST(Regions, FillDropsRingsAndBentStrokes) {
  cv::Mat img(40, 60, CV_8UC3, cv::Scalar(220, 220, 220));
  cv::rectangle(img, cv::Rect(2, 2, 16, 16), cv::Scalar(160, 50, 40), 2);  // ring
  img(cv::Rect(22, 20, 30, 2)).setTo(cv::Scalar(160, 50, 40));              // an L
  img(cv::Rect(22, 20, 2, 18)).setTo(cv::Scalar(160, 50, 40));
  img(cv::Rect(40, 2, 8, 8)).setTo(cv::Scalar(160, 50, 40));                // square
  cv::Mat labels;
  ld::detail::saturationMask(img, kMt, labels);
  ld::detail::RunScratch scratch;
  std::vector<Region> regions;
  ld::detail::extractRegions(labels, img, kMt, 1, 1000, 0.0, scratch, regions);
  EXPECT_EQ(regions.size(), 3u);
  ld::detail::extractRegions(labels, img, kMt, 1, 1000, 0.5, scratch, regions);
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_EQ(regions[0].area, 64);
  EXPECT_NEAR(ld::detail::fill(regions[0]), 1.0, 1e-9);
}

// U shapes and spirals merge through later rows (union-find).
TEST(Regions, MergesThroughLaterRows) {
  cv::Mat img(20, 20, CV_8UC3, cv::Scalar(220, 220, 220));
  img(cv::Rect(2, 2, 2, 10)).setTo(cv::Scalar(160, 50, 40));
  img(cv::Rect(8, 2, 2, 10)).setTo(cv::Scalar(160, 50, 40));
  img(cv::Rect(14, 2, 2, 10)).setTo(cv::Scalar(160, 50, 40));
  img(cv::Rect(2, 12, 14, 2)).setTo(cv::Scalar(160, 50, 40));
  cv::Mat labels;
  ld::detail::saturationMask(img, kMt, labels);
  ld::detail::RunScratch scratch;
  std::vector<Region> regions;
  ld::detail::extractRegions(labels, img, kMt, 1, 1000, 0.0, scratch, regions);
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_EQ(regions[0].area, 3 * 20 + 28);
}

// Every region of a random image (runs of every length, at both edges of
// the rows, in blocks of coloured noise) against OpenCV's own 4-connected
// components of each colour: the same area and bounding box, and the
// channel sums and saturation-weighted centroid summed pixel by pixel here
// (extractRegions sums whole vectors of a run at once where it can).
TEST(Regions, SumsAndCentroidsAreThoseOfThePixels) {
  cv::Mat img(61, 203, CV_8UC3);
  cv::RNG rng(11);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  // long runs too: coloured bars of random lengths, some to the row's end
  for (int k = 0; k < 60; ++k) {
    const int y = rng.uniform(0, img.rows), x0 = rng.uniform(0, img.cols - 2);
    const int len = rng.uniform(2, 90), x1 = std::min(img.cols, x0 + len);
    const cv::Scalar ink = k % 2 ? cv::Scalar(rng.uniform(150, 256), rng.uniform(0, 60), rng.uniform(0, 50))
                                 : cv::Scalar(rng.uniform(0, 60), rng.uniform(0, 50), rng.uniform(150, 256));
    img(cv::Range(y, std::min(img.rows, y + rng.uniform(1, 4))), cv::Range(x0, x1)).setTo(ink);
  }
  const ld::detail::MaskThresholds t{0.3, 0.4, 25};
  cv::Mat labels;
  ld::detail::saturationMask(img, t, labels);
  ld::detail::RunScratch scratch;
  std::vector<Region> regions;
  ld::detail::extractRegions(labels, img, t, 1, 1 << 30, 0.0, scratch, regions);
  const int thr[3] = {0, static_cast<int>(std::lround(t.blue * 256)), static_cast<int>(std::lround(t.red * 256))};
  size_t expected = 0, long_rows = 0;
  for (uint8_t colour : {ld::detail::kBlue, ld::detail::kRed}) {
    cv::Mat comp;
    const int n = cv::connectedComponents(labels == colour, comp, 4, CV_32S);
    for (int c = 1; c < n; ++c) {
      int area = 0, x0 = INT32_MAX, y0 = INT32_MAX, x1 = -1, y1 = -1;
      int64_t w = 0, wx = 0, wy = 0, sb = 0, sg = 0, sr = 0;
      for (int y = 0; y < img.rows; ++y) {
        int run = 0;
        for (int x = 0; x < img.cols; ++x) {
          if (comp.at<int>(y, x) != c) {
            run = 0;
            continue;
          }
          long_rows += ++run == 20;
          const auto p = img.at<cv::Vec3b>(y, x);
          const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
          const int wt = std::max(1, (mx - mn) - ((mx * thr[colour]) >> 8));
          ++area, w += wt, wx += int64_t(wt) * x, wy += int64_t(wt) * y;
          sb += p[0], sg += p[1], sr += p[2];
          x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
      }
      ++expected;
      int found = 0;
      for (const Region& r : regions) {
        if (r.colour != colour || r.x0 != x0 || r.y0 != y0 || r.x1 != x1 || r.y1 != y1 || r.area != area) continue;
        ++found;
        EXPECT_EQ(r.sum_b, double(sb));
        EXPECT_EQ(r.sum_g, double(sg));
        EXPECT_EQ(r.sum_r, double(sr));
        EXPECT_NEAR(r.cx, double(wx) / double(w), 1e-9);
        EXPECT_NEAR(r.cy, double(wy) / double(w), 1e-9);
      }
      EXPECT_EQ(found, 1) << "component at " << x0 << "," << y0 << " of " << area << " pixels";
    }
  }
  EXPECT_EQ(regions.size(), expected);
  EXPECT_GT(expected, 500u);
  EXPECT_GT(long_rows, 20u);  // runs long enough for whole vectors
}

// ====================================================================== colour

TEST(Colour, PaperRatioRule) {
  Region r;
  r.sum_b = 150, r.sum_g = 60, r.sum_r = 40;
  EXPECT_TRUE(ld::detail::isFip(r, 1.3, 1.3));
  EXPECT_FALSE(ld::detail::isAp(r, 1.3, 1.3));
  r.sum_b = 150, r.sum_g = 120, r.sum_r = 40;  // cyan-ish: blue not 1.3x green
  EXPECT_FALSE(ld::detail::isFip(r, 1.3, 1.3));
  EXPECT_TRUE(ld::detail::isFip(r, 1.2, 1.2));
  r.sum_b = 40, r.sum_g = 70, r.sum_r = 210;
  EXPECT_TRUE(ld::detail::isAp(r, 1.3, 1.3));
  EXPECT_FALSE(ld::detail::isFip(r, 1.3, 1.3));
  r.sum_b = 120, r.sum_g = 110, r.sum_r = 130;  // greyish
  EXPECT_FALSE(ld::detail::isAp(r, 1.3, 1.3));
  EXPECT_FALSE(ld::detail::isFip(r, 1.3, 1.3));
}

// ====================================================================== graph

TEST(Graph, EdgesByDistanceAndSize) {
  const ld::DetectorParams p;
  auto sq = [](double x, double y, double w, double h) {
    Region r;
    r.cx = x, r.cy = y, r.sxx = w * w / 12, r.syy = h * h / 12;
    return r;
  };
  const Region a = sq(100, 100, 8, 8);
  EXPECT_TRUE(ld::detail::fipEdge(a, sq(124, 100, 8, 8), p));      // neighbour: 3 sides
  EXPECT_TRUE(ld::detail::fipEdge(a, sq(124, 124, 8, 8), p));      // diagonal: 4.24
  EXPECT_NEAR(ld::detail::normalisedDistance(a, sq(124, 124, 8, 8)), 3 * std::sqrt(2.0), 1e-9);
  EXPECT_FALSE(ld::detail::fipEdge(a, sq(108, 100, 8, 8), p));     // touching: 1 side
  EXPECT_FALSE(ld::detail::fipEdge(a, sq(200, 100, 8, 8), p));     // 12.5 sides
  EXPECT_FALSE(ld::detail::fipEdge(a, sq(124, 100, 28, 28), p));   // 3.5 times larger
  EXPECT_FALSE(ld::detail::fipEdge(a, sq(124, 100, 8, 28), p));    // 3.5 times taller
  // Foreshortened 3x (yaw): widths and x distances shrink together.
  EXPECT_TRUE(ld::detail::fipEdge(sq(100, 100, 2.7, 8), sq(108, 100, 2.7, 8), p));
  // Rolled 45 degrees: the moments of a square do not change, the distance neither.
  EXPECT_NEAR(ld::detail::normalisedDistance(a, sq(100 + 24 / std::sqrt(2.0), 100 + 24 / std::sqrt(2.0), 8, 8)),
              3.0, 1e-9);
}

TEST(Graph, ThreeCycles) {
  // 0-1-2 triangle, 2-3-4 triangle, 4-5 edge, 1-3 edge (no extra triangle).
  const int n = 6;
  std::vector<uint8_t> adj(n * n, 0);
  auto edge = [&](int a, int b) { adj[a * n + b] = adj[b * n + a] = 1; };
  edge(0, 1), edge(1, 2), edge(0, 2), edge(2, 3), edge(3, 4), edge(2, 4), edge(4, 5), edge(1, 3);
  std::vector<std::array<int, 3>> cycles;
  ld::detail::threeCycles(adj, n, cycles);
  std::vector<std::array<int, 3>> want{{0, 1, 2}, {1, 2, 3}, {2, 3, 4}};
  EXPECT_EQ(cycles, want);
}

// ====================================================================== AP choice and ordering

class ApChoice : public ::testing::TestWithParam<double> {};

TEST_P(ApChoice, FindsTlAtAnyRoll) {
  const double roll = GetParam();
  const auto sq = layoutRegions(10, roll, {200, 150});
  const ld::DetectorParams p;
  // FIPs in a scrambled order, with a decoy FIP and a decoy AP elsewhere.
  std::vector<Region> fips{sq[2], sq[0], sq[1]};
  Region decoy = sq[0];
  decoy.cx += 300;
  fips.push_back(decoy);
  Region decoy_ap = sq[3];
  decoy_ap.cx -= 150;
  std::vector<Region> aps{decoy_ap, sq[3]};
  for (const auto& cyc : std::vector<std::array<int, 3>>{{0, 1, 2}, {2, 0, 1}, {1, 2, 0}}) {
    ld::detail::Candidate c;
    ASSERT_TRUE(ld::detail::chooseAp(cyc, fips, aps, p, c)) << roll;
    EXPECT_EQ(c.tl, 1) << roll;
    EXPECT_EQ(c.tr, 2) << roll;
    EXPECT_EQ(c.bl, 0) << roll;
    EXPECT_EQ(c.ap, 1) << roll;
    EXPECT_LT(c.error, 1e-6);
  }
}

INSTANTIATE_TEST_SUITE_P(Rolls, ApChoice, ::testing::Values(0.0, 45.0, 90.0, 135.0, 180.0, -120.0, 11.0, -30.0));

TEST(ApChoiceRule, NoApNoCandidate) {
  const auto sq = layoutRegions(10, 0, {200, 150});
  std::vector<Region> fips{sq[0], sq[1], sq[2]};
  Region far = sq[3];
  far.cx += 40;  // 4 sides off the prediction
  std::vector<Region> aps{far};
  ld::detail::Candidate c;
  EXPECT_FALSE(ld::detail::chooseAp({0, 1, 2}, fips, aps, ld::DetectorParams{}, c));
  // An AP in the middle of the landmark (a look-alike card) is no AP either.
  Region mid = sq[3];
  mid.cx = 200, mid.cy = 150;
  aps = {mid};
  EXPECT_FALSE(ld::detail::chooseAp({0, 1, 2}, fips, aps, ld::DetectorParams{}, c));
  // Nor is one of three times the size.
  Region big = sq[3];
  big.sxx *= 9, big.syy *= 9;
  aps = {big};
  EXPECT_FALSE(ld::detail::chooseAp({0, 1, 2}, fips, aps, ld::DetectorParams{}, c));
}

// Every AP in the gate is a choice, nearest first; sizes that show
// perspective (TR and BL larger than TL: the AP's corner nearer the camera)
// move the second prediction, and an AP there is a choice too.
TEST(ApChoiceRule, EveryApInTheGatesNearestFirst) {
  const auto sq = layoutRegions(10, 0, {200, 150});
  std::vector<Region> fips{sq[0], sq[1], sq[2]};
  Region near = sq[3], nearer = sq[3];
  near.cx += 5;    // half a side off the prediction
  nearer.cx -= 2;  // a fifth
  std::vector<Region> aps{near, nearer};
  std::vector<ld::detail::Candidate> choices;
  ld::detail::apChoices({0, 1, 2}, fips, aps, ld::DetectorParams{}, choices);
  ASSERT_EQ(choices.size(), 2u);
  EXPECT_EQ(choices[0].ap, 1);
  EXPECT_EQ(choices[1].ap, 0);
  EXPECT_LT(choices[0].error, choices[1].error);
  ld::detail::apChoices({0, 1, 2}, fips, aps, ld::DetectorParams{}, choices, nullptr, 1);
  EXPECT_EQ(choices.size(), 1u);
  // Perspective: TR and BL 1.4 times TL's side. w = side^(-2/3) puts the AP
  // beyond TR + BL - TL, out of the affine gate.
  for (int k : {1, 2}) {
    fips[k].sxx *= 1.96, fips[k].syy *= 1.96, fips[k].sxy *= 1.96;
  }
  const double wtl = std::pow(fips[0].side(), -2.0 / 3), wtr = std::pow(fips[1].side(), -2.0 / 3),
               wbl = std::pow(fips[2].side(), -2.0 / 3), w = wtr + wbl - wtl;
  Region beyond = sq[3];
  beyond.cx = (wtr * fips[1].cx + wbl * fips[2].cx - wtl * fips[0].cx) / w;
  beyond.cy = (wtr * fips[1].cy + wbl * fips[2].cy - wtl * fips[0].cy) / w;
  beyond.sxx *= 1.96 * 1.96, beyond.syy *= 1.96 * 1.96, beyond.sxy *= 1.96 * 1.96;  // nearer still: larger
  ASSERT_GT(std::hypot(beyond.cx - sq[3].cx, beyond.cy - sq[3].cy), 10.0);  // more than the affine gate
  aps = {beyond};
  ld::detail::apChoices({0, 1, 2}, fips, aps, ld::DetectorParams{}, choices);
  ASSERT_EQ(choices.size(), 1u);
  EXPECT_EQ(choices[0].tl, 0);
  EXPECT_LT(choices[0].error, 1e-6);
}

namespace {

// A landmark at 0.8 m on a plain background, labelled and cut into regions
// as the first pass does: its three FIPs and its AP, and which FIP is which.
struct LabelledLandmark {
  cv::Mat img;
  ld::DetectorParams p;
  std::vector<Region> fips, aps;
  int tl = -1, tr = -1, bl = -1;
};

void labelLandmark(LabelledLandmark& l) {
  l.img = background(kCam.size, 29, true);
  const Placed placed = place(0.8, 0, 20);
  drawSheet(l.img, kCam, placed);
  const Truth t = truthOf(kCam, placed);
  cv::Mat labels;
  const ld::DetectorParams& p = l.p;
  ld::detail::saturationMask(l.img, {p.saturation_threshold_blue, p.saturation_threshold, p.value_min}, labels);
  ld::detail::RunScratch scratch;
  std::vector<Region> regions;
  ld::detail::extractRegions(labels, l.img, kMt, 3, 100000, 0.0, scratch, regions);
  for (const Region& r : regions) (r.colour == ld::detail::kBlue ? l.fips : l.aps).push_back(r);
  ASSERT_EQ(l.fips.size(), 3u);
  ASSERT_EQ(l.aps.size(), 1u);
  auto nearest = [&](cv::Point2d c) {
    int best = 0;
    for (int i = 1; i < 3; ++i)
      if (std::hypot(l.fips[i].cx - c.x, l.fips[i].cy - c.y) < std::hypot(l.fips[best].cx - c.x, l.fips[best].cy - c.y))
        best = i;
    return best;
  };
  l.tl = nearest(t.centres[0]), l.tr = nearest(t.centres[1]), l.bl = nearest(t.centres[2]);
}

}  // namespace

// Of several APs in the gates the nearest is tried first, but the one kept
// is the one whose landmark verifies: here a bar (three times as long as
// wide, the AP's area) lies exactly where TR + BL - TL predicts, nearer than
// the real AP, and verification refuses it.
TEST(ApChoiceRule, TheApWhoseLandmarkVerifiesIsKept) {
  LabelledLandmark lm;
  ASSERT_NO_FATAL_FAILURE(labelLandmark(lm));
  const cv::Mat& img = lm.img;
  const ld::DetectorParams& p = lm.p;
  std::vector<Region>& fips = lm.fips;
  std::vector<Region>& aps = lm.aps;
  const int tl = lm.tl, tr = lm.tr, bl = lm.bl;
  Region bar = aps[0];
  bar.cx = fips[tr].cx + fips[bl].cx - fips[tl].cx;
  bar.cy = fips[tr].cy + fips[bl].cy - fips[tl].cy;
  // the same determinant (so the same side()), three times as long as wide
  const double l = std::sqrt(bar.sxx * bar.syy - bar.sxy * bar.sxy);
  bar.sxx = 3 * l, bar.syy = l / 3, bar.sxy = 0;
  aps.insert(aps.begin(), bar);  // index 0: the bar, 1: the real AP

  std::vector<ld::detail::Candidate> choices;
  ld::detail::apChoices({tl, tr, bl}, fips, aps, p, choices);
  ASSERT_EQ(choices.size(), 2u);
  ASSERT_EQ(choices[0].ap, 0) << "the bar is not the nearest choice: the test does not test the rule";
  ld::detail::Check why = ld::detail::Check::kNoAp;
  EXPECT_FALSE(ld::detail::verify(choices[0], fips, aps, img, p, &why));
  ld::detail::Candidate kept;
  ASSERT_TRUE(ld::detail::bestVerifiedChoice({tl, tr, bl}, fips, aps, img, p, choices, kept));
  EXPECT_EQ(kept.ap, 1) << "the bar was refused by: " << ld::detail::checkName(why);
  EXPECT_EQ(kept.tl, tl);
}

// A coloured square in the QR beside the centre, as large as the landmark's
// squares (a look-alike card's square, where pale fragments made a landmark
// around it: their small measured size shrinks the circle the centre's
// check looks in), is refused; a small coloured piece there (a module's
// edge tinted by warm light or JPEG) is tolerated, as before.
TEST(Verification, ASquareInTheQrAsLargeAsTheLandmarksIsRefused) {
  LabelledLandmark lm;
  ASSERT_NO_FATAL_FAILURE(labelLandmark(lm));
  const cv::Mat& img = lm.img;
  const ld::DetectorParams& p = lm.p;
  std::vector<Region>& fips = lm.fips;
  std::vector<Region>& aps = lm.aps;
  ld::detail::Candidate c;
  c.tl = lm.tl, c.tr = lm.tr, c.bl = lm.bl, c.ap = 0;
  ld::detail::Check why = ld::detail::Check::kCount;
  ld::detail::Candidate plain = c;
  ASSERT_TRUE(ld::detail::verify(plain, fips, aps, img, p, &why)) << ld::detail::checkName(why);
  // In the QR, beside the centre: 1.05 square sides from it, a quarter of
  // the way from the TL-BL side to TR-AP (the centres 3 sides apart).
  const Region& tl = fips[c.tl];
  const Region& tr = fips[c.tr];
  const Region& bl = fips[c.bl];
  // Sized against the printed square's side (a third of the centres' distance).
  const double printed = std::hypot(tr.cx - tl.cx, tr.cy - tl.cy) / 3;
  for (double scale : {1.1, 0.7}) {
    Region extra = tl;
    extra.cx = tl.cx + (tr.cx - tl.cx) * (0.45 / 3) + (bl.cx - tl.cx) * 0.5;
    extra.cy = tl.cy + (tr.cy - tl.cy) * (0.45 / 3) + (bl.cy - tl.cy) * 0.5;
    const double f = scale * printed / tl.side();
    extra.sxx *= f * f, extra.syy *= f * f, extra.sxy *= f * f;
    ASSERT_NEAR(extra.side(), scale * printed, 0.01 * printed);
    std::vector<Region> more = fips;
    more.push_back(extra);
    ld::detail::Candidate k = c;
    why = ld::detail::Check::kCount;
    const bool ok = ld::detail::verify(k, more, aps, img, p, &why);
    if (scale > 1) {
      EXPECT_FALSE(ok);
      EXPECT_EQ(why, ld::detail::Check::kOtherSquares) << ld::detail::checkName(why);
    } else {
      EXPECT_TRUE(ok) << "a small piece in the QR refused by: " << ld::detail::checkName(why);
    }
  }
}

TEST(Overlaps, BestScoreWinsGreedily) {
  std::vector<ld::detail::Candidate> c(3);
  c[0] = {0, 1, 2, 0, 0.5, 0};
  c[1] = {0, 3, 4, 1, 0.1, 0};  // shares FIP 0 with c[0], better
  c[2] = {5, 6, 7, 0, 0.2, 0};  // shares the AP with c[0]
  std::vector<uint8_t> used;
  ld::detail::resolveOverlaps(c, 8, 2, used);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].tr, 3);
  EXPECT_EQ(c[1].tl, 5);
}

TEST(Geometry, RightIsoscelesFindsTheCorner) {
  for (double roll : {0.0, 70.0, 200.0}) {
    const auto sq = layoutRegions(9, roll, {150, 120});
    const std::vector<Region> fips{sq[1], sq[2], sq[0]};  // TR, BL, TL
    int corner = -1;
    EXPECT_TRUE(ld::detail::rightIsosceles({0, 1, 2}, fips, 1.35, &corner)) << roll;
    EXPECT_EQ(corner, 2) << roll;
  }
  auto sq = layoutRegions(9, 0, {150, 120});
  sq[2].cx = sq[0].cx + 2 * (sq[1].cx - sq[0].cx);  // three in a row
  sq[2].cy = sq[0].cy;
  EXPECT_FALSE(ld::detail::rightIsosceles({0, 1, 2}, std::vector<Region>{sq[0], sq[1], sq[2]}, 1.35));
}

// A square of the landmark's frame (from the centres) fits it; a bar does not.
TEST(Geometry, SquareConsistencyWithTheFrame) {
  const auto sq = layoutRegions(10, 30, {200, 200});
  const cv::Point2d e1(sq[1].cx - sq[0].cx, sq[1].cy - sq[0].cy), e2(sq[2].cx - sq[0].cx, sq[2].cy - sq[0].cy);
  double scale = 0, aniso = 0;
  ASSERT_TRUE(ld::detail::squareConsistency(sq[3], e1, e2, scale, aniso));
  EXPECT_NEAR(scale, 1.0, 1e-9);
  EXPECT_NEAR(aniso, 1.0, 1e-9);
  Region bar = sq[3];
  bar.sxx = 30.0 * 30 / 12, bar.syy = 10.0 * 10 / 12, bar.sxy = 0;  // 30 x 10
  ASSERT_TRUE(ld::detail::squareConsistency(bar, e1, e2, scale, aniso));
  EXPECT_NEAR(aniso, 3.0, 1e-6);
  EXPECT_NEAR(scale, std::sqrt(3.0), 1e-6);
  // Under foreshortening the frame squeezes with the squares.
  const cv::Point2d f1(e1.x * 0.3, e1.y), f2(e2.x * 0.3, e2.y);
  Region squeezed = sq[3];
  const double c = std::cos(30 * CV_PI / 180), s = std::sin(30 * CV_PI / 180), v = 100.0 / 12;
  // R diag(v) R' squeezed in x by 0.3: moments of the projected square.
  squeezed.sxx = 0.09 * v * (c * c + s * s), squeezed.syy = v, squeezed.sxy = 0;
  ASSERT_TRUE(ld::detail::squareConsistency(squeezed, f1, f2, scale, aniso));
  EXPECT_NEAR(aniso, 1.0, 1e-6);
}

// Along any side of a landmark the two squares cover a third of the
// distance between their centres; between a card's corner square and one
// in its middle, two thirds.
TEST(Geometry, CoverFractionOfTheSides) {
  cv::Mat img = background(kCam.size, 15, true);
  const Placed p = place(0.8, 25, 30);
  drawSheet(img, kCam, p);
  const Truth t = truthOf(kCam, p);
  const cv::Point2d P[4] = {t.centres[0], t.centres[1], t.centres[3], t.centres[2]};  // TL, TR, AP, BL
  const uint8_t C[4] = {ld::detail::kBlue, ld::detail::kBlue, ld::detail::kRed, ld::detail::kBlue};
  for (int i = 0; i < 4; ++i)
    EXPECT_NEAR(ld::detail::coverFraction(img, P[i], C[i], P[(i + 1) % 4], C[(i + 1) % 4]), 1.0 / 3, 0.05) << i;
  // A card with its red square in the middle: TL to the middle.
  cv::Mat card = background(kCam.size, 15, true);
  Placed pc = p;
  pc.artwork = ld::artwork::renderLandmark("x", 720, inkColours());
  const int u = 80;
  pc.artwork(cv::Rect(7 * u / 2, 7 * u / 2, 2 * u, 2 * u)).setTo(cv::Scalar(45, 60, 215));
  drawSheet(card, kCam, pc);
  const cv::Point2d mid = (t.centres[0] + t.centres[3]) * 0.5;
  EXPECT_NEAR(ld::detail::coverFraction(card, t.centres[0], ld::detail::kBlue, mid, ld::detail::kRed), 2.0 / 3, 0.07);
  // The light the inks absorb gives the same.
  const auto absorbed = ld::detail::CoverProfile::kAbsorbed;
  for (int i = 0; i < 4; ++i)
    EXPECT_NEAR(ld::detail::coverFraction(img, P[i], C[i], P[(i + 1) % 4], C[(i + 1) % 4], absorbed), 1.0 / 3, 0.05)
        << i;
  // (more: the QR's black modules between them absorb too)
  EXPECT_GT(ld::detail::coverFraction(card, t.centres[0], ld::detail::kBlue, mid, ld::detail::kRed, absorbed),
            ld::detail::kAbsorbedCoverMax);
}

// Colour at a fraction of the brightness's resolution (JPEG's and the
// sensor mosaic's, strong here, on squares 8 px across): the squares'
// colour spreads over the sheet and its profile covers more of the sides
// than a landmark's squares can; the light the inks absorb keeps the
// brightness's edges, and verification takes that.
TEST(Geometry, CoverOfSmearedColourFromTheAbsorbedLight) {
  cv::Mat img = background(kCam.size, 15, true);
  const Placed p = place(2.5, 10, 20);
  drawSheet(img, kCam, p);
  cv::Mat ycc;
  cv::cvtColor(img, ycc, cv::COLOR_BGR2YCrCb);
  std::vector<cv::Mat> ch;
  cv::split(ycc, ch);
  for (int k : {1, 2}) cv::GaussianBlur(ch[k], ch[k], cv::Size(), 6.0);
  cv::merge(ch, ycc);
  cv::cvtColor(ycc, img, cv::COLOR_YCrCb2BGR);
  const Truth t = truthOf(kCam, p);
  const cv::Point2d P[4] = {t.centres[0], t.centres[1], t.centres[3], t.centres[2]};  // TL, TR, AP, BL
  const uint8_t C[4] = {ld::detail::kBlue, ld::detail::kBlue, ld::detail::kRed, ld::detail::kBlue};
  const ld::DetectorParams params;
  int out_of_bounds = 0;
  for (int i = 0; i < 4; ++i) {
    const double colour = ld::detail::coverFraction(img, P[i], C[i], P[(i + 1) % 4], C[(i + 1) % 4]);
    out_of_bounds += colour < params.cover_min || colour > params.cover_max;
    const double absorbed = ld::detail::coverFraction(img, P[i], C[i], P[(i + 1) % 4], C[(i + 1) % 4],
                                                      ld::detail::CoverProfile::kAbsorbed);
    std::printf("side %d: colour's cover %.3f, absorbed light's %.3f\n", i, colour, absorbed);
    EXPECT_NEAR(absorbed, 1.0 / 3, 0.06) << i;
  }
  ASSERT_GT(out_of_bounds, 0) << "the colour's cover is within bounds: the test does not test the rule";
  ld::Detector det(params);
  const auto& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 1u);
  EXPECT_LT(cv::norm(cv::Point2d(d.landmarks[0].fip_tl) - t.centres[0]), 1.5);
}

// ====================================================================== corners

TEST(Corners, HomographyExact) {
  const std::array<cv::Point2d, 4> src{{{0, 0}, {1, 0}, {1, 1}, {0, 1}}};
  const std::array<cv::Point2d, 4> dst{{{10, 20}, {110, 25}, {105, 140}, {5, 118}}};
  cv::Matx33d H;
  ASSERT_TRUE(ld::detail::homography4(src, dst, H));
  for (int i = 0; i < 4; ++i) EXPECT_LT(cv::norm(ld::detail::applyH(H, src[i]) - dst[i]), 1e-9);
  const std::array<cv::Point2d, 4> line{{{0, 0}, {1, 1}, {2, 2}, {3, 3}}};
  EXPECT_FALSE(ld::detail::homography4(line, dst, H));
}

// Centroids of projected squares, corrected, give the exact projected centres
// and corners under strong perspective.
TEST(Corners, PerspectiveCentroidCorrection) {
  const Placed p = place(0.5, 55, 20, 0.3);
  const Truth t = truthOf(kCam, p);
  // Measured centres: the centroids of the projected squares.
  std::array<cv::Point2d, 4> centroids;
  const double u = p.side_m / 9;
  for (int i = 0; i < 4; ++i) {
    std::vector<cv::Point2f> poly;
    for (auto [dx, dy] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
      const double x = (layout::kCentresU[i][0] + dx - 4.5) * u, y = (layout::kCentresU[i][1] + dy - 4.5) * u;
      poly.emplace_back(project(kCam, p, {x, y, 0}));
    }
    const cv::Moments m = cv::moments(poly);
    centroids[i] = {m.m10 / m.m00, m.m01 / m.m00};
  }
  double before = 0;
  for (int i = 0; i < 4; ++i) before = std::max(before, cv::norm(centroids[i] - t.centres[i]));
  EXPECT_GT(before, 0.1);  // the centroid is not the projected centre
  std::array<cv::Point2d, 4> corrected, corners;
  ASSERT_TRUE(ld::detail::fitCorners(centroids, 3, corrected, corners));
  for (int i = 0; i < 4; ++i) {
    EXPECT_LT(cv::norm(corrected[i] - t.centres[i]), 0.01) << i;
    EXPECT_LT(cv::norm(corners[i] - t.corners[i]), 0.02) << i;
  }
}

// ====================================================================== detector on rendered frames

class Roll : public ::testing::TestWithParam<double> {};

TEST_P(Roll, FindsLandmarkWithRightOrientation) {
  const double roll = GetParam();
  cv::Mat img = background(kCam.size, 3);
  const Placed p = place(1.0, 0, roll, 0.15, 0.05, -0.03);
  drawSheet(img, kCam, p);
  const Truth t = truthOf(kCam, p);
  ld::Detector det;
  const auto& d = det.detect(img);
  ASSERT_TRUE(onlyLandmark(d, t)) << roll;
  for (int i = 0; i < 4; ++i) EXPECT_LT(cv::norm(cv::Point2d(d.landmarks[0].corners[i]) - t.corners[i]), 1.0);
}

INSTANTIATE_TEST_SUITE_P(Rolls, Roll, ::testing::Values(0.0, 11.0, 30.0, 45.0, 90.0, 135.0, 180.0, -120.0, -60.0));

TEST(Detector, SmallAndSteep) {
  // 9 cm at 1.5 m: FIPs of 8 px; at 60 degrees of yaw, 4 px wide.
  for (double yaw : {0.0, 40.0, -60.0}) {
    cv::Mat img = background(kCam.size, 4);
    const Placed p = place(1.5, yaw, 25, 0.09);
    drawSheet(img, kCam, p);
    addNoise(img, 3, 5);
    ld::Detector det;
    EXPECT_TRUE(found(det.detect(img), truthOf(kCam, p))) << yaw;
  }
}

// A frame cluttered with more blue squares than max_candidates keeps (400),
// each larger than a far landmark's: the landmark is still found (its FIPs
// have a red square of their size within reach and are kept first), and the
// explanation says that the cap was reached. Kept by size alone, the
// clutter pushed every square of the landmark out.
TEST(Detector, ClutterOverTheCandidateCapKeepsTheLandmark) {
  cv::Mat img = background(kCam.size, 4);
  const Placed p = place(1.5, 0, 0, 0.09);  // FIPs of 8 px
  drawSheet(img, kCam, p);
  const Truth t = truthOf(kCam, p);
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const auto& c : t.corners) x0 = std::min(x0, c.x), y0 = std::min(y0, c.y), x1 = std::max(x1, c.x), y1 = std::max(y1, c.y);
  const cv::Rect2d sheet(x0, y0, x1 - x0, y1 - y0);
  int drawn = 0;
  for (int y = 4; y + 12 < img.rows; y += 19)
    for (int x = 4; x + 12 < img.cols; x += 19) {
      const cv::Rect r(x, y, 12, 12);  // 144 px, over twice a FIP's 64
      if ((cv::Rect2d(r) & cv::Rect2d(sheet.x - 20, sheet.y - 20, sheet.width + 40, sheet.height + 40)).area() > 0)
        continue;
      cv::rectangle(img, r, cv::Scalar(150, 35, 25), cv::FILLED);
      ++drawn;
    }
  ASSERT_GT(drawn, 500);
  ld::Detector det;
  ld::Explanation why;
  const auto& d = det.detect(img, why);
  EXPECT_TRUE(found(d, t)) << ld::describe(why, det.params());
  EXPECT_GT(why.fips_over_cap, 0);
  EXPECT_NE(ld::describe(why, det.params()).find("max_candidates, 400, kept the FIPs near a red square first"),
            std::string::npos)
      << ld::describe(why, det.params());
}

TEST(Detector, TwoLandmarksSideBySide) {
  cv::Mat img = background(kCam.size, 5);
  const Placed a = place(1.0, 0, 0, 0.15, -0.085, 0);
  const Placed b = place(1.0, 0, 0, 0.15, 0.085, 0);  // 2 cm gap between the sheets
  drawSheet(img, kCam, a);
  drawSheet(img, kCam, b);
  ld::Detector det;
  const auto& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 2u);
  EXPECT_TRUE(found(d, truthOf(kCam, a)));
  EXPECT_TRUE(found(d, truthOf(kCam, b)));
}

TEST(Detector, OneUprightOneUpsideDownTouching) {
  cv::Mat img = background(kCam.size, 6);
  const Placed a = place(1.2, 0, 0, 0.15, -0.076, 0);
  const Placed b = place(1.2, 0, 180, 0.15, 0.076, 0);
  drawSheet(img, kCam, a);
  drawSheet(img, kCam, b);
  ld::Detector det;
  const auto& d = det.detect(img);
  EXPECT_EQ(d.landmarks.size(), 2u);
  EXPECT_TRUE(found(d, truthOf(kCam, a)));
  EXPECT_TRUE(found(d, truthOf(kCam, b)));
}

namespace {

// Landmark-like cards: the three FIPs with the red square in the middle or
// next to TL instead of at BR.
cv::Mat lookAlike(int kind) {
  cv::Mat art = artworkImage().clone();
  const int u = art.cols / 9;
  const cv::Scalar white(225, 228, 230), red(45, 60, 215);
  art(cv::Rect(13 * u / 2, 13 * u / 2, 2 * u, 2 * u)).setTo(white);  // no AP at BR
  if (kind == 0) art(cv::Rect(7 * u / 2, 7 * u / 2, 2 * u, 2 * u)).setTo(red);  // red in the middle
  if (kind == 1) art(cv::Rect(7 * u / 2, u / 2, 2 * u, 2 * u)).setTo(red);      // red next to TL
  if (kind == 2) art(cv::Rect(u / 2, 7 * u / 2, 2 * u, 2 * u)).setTo(red);      // red under TL
  return art;
}

}  // namespace

TEST(Detector, RejectsLookAlikeCards) {
  ld::Detector det;
  for (int kind = 0; kind < 3; ++kind)
    for (double roll : {0.0, 90.0, 200.0}) {
      cv::Mat img = background(kCam.size, 7);
      Placed p = place(0.8, 20, roll, 0.15);
      p.artwork = lookAlike(kind);
      drawSheet(img, kCam, p);
      EXPECT_TRUE(det.detect(img).landmarks.empty()) << kind << " " << roll;
    }
}

// Under a warm light the QR's black-on-white edges at the landmark's centre
// come out saturated orange (in the sheet's own hue): still a landmark. A
// red or blue square there (a card's) is not one.
TEST(Detector, CentreInTheSheetsHueIsNoColouredSquare) {
  ld::Detector det;
  for (int kind = 0; kind < 3; ++kind) {
    cv::Mat img = background(kCam.size, 22, true);
    Placed p = place(1.0, 0, 0, 0.15);
    const int u = p.artwork.cols / 9;
    if (kind > 0) {
      p.artwork = p.artwork.clone();
      p.artwork(cv::Rect(7 * u / 2, 7 * u / 2, 2 * u, 2 * u))
          .setTo(kind == 1 ? cv::Scalar(45, 60, 215) : cv::Scalar(150, 60, 40));
    }
    drawSheet(img, kCam, p);
    cv::multiply(img, cv::Scalar(0.76, 0.88, 1.0), img);  // warm light: the sheet's red chroma about 0.14
    const Truth t = truthOf(kCam, p);
    const cv::Point2d c = (t.centres[0] + t.centres[1] + t.centres[2] + t.centres[3]) * 0.25;
    if (kind == 0)  // saturation 0.47, red chroma 0.36: a dark edge in the sheet's hue
      img(cv::Rect(static_cast<int>(c.x) - 1, static_cast<int>(c.y) - 1, 3, 3)).setTo(cv::Scalar(45, 62, 85));
    const auto& d = det.detect(img);
    if (kind == 0) {
      EXPECT_TRUE(onlyLandmark(d, t));
    } else {
      EXPECT_TRUE(d.landmarks.empty()) << kind;
    }
  }
}

// The real landmark next to a look-alike card: only the real one.
TEST(Detector, RealLandmarkBesideLookAlike) {
  cv::Mat img = background(kCam.size, 8);
  Placed card = place(1.0, 0, 0, 0.15, -0.09, 0);
  card.artwork = lookAlike(1);
  const Placed real = place(1.0, 0, 0, 0.15, 0.09, 0);
  drawSheet(img, kCam, card);
  drawSheet(img, kCam, real);
  ld::Detector det;
  const auto& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 1u);
  EXPECT_TRUE(found(d, truthOf(kCam, real)));
}

// A FIP touching a blue object beside the sheet merges with it in the mask:
// the other three squares put it where it is.
TEST(Detector, SquareMergedWithTheBackgroundIsCompleted) {
  cv::Mat img = background(kCam.size, 16, true);
  const Placed p = place(1.0, 0, 0, 0.15, 0, 0);
  const Truth t = truthOf(kCam, p);
  // A blue object overlapping the sheet's left margin next to TL.
  const int x = static_cast<int>(t.corners[0].x), y = static_cast<int>(t.corners[0].y);
  img(cv::Rect(x - 60, y - 10, 60, 40)).setTo(cv::Scalar(150, 60, 40));
  drawSheet(img, kCam, p);
  img(cv::Rect(x - 60, y + 2, 61, 10)).setTo(cv::Scalar(150, 60, 40));  // bridging the margin
  ld::DetectorParams q;
  q.complete_missing = false;
  ld::Detector without(q), with;
  EXPECT_FALSE(found(without.detect(img), t));
  EXPECT_TRUE(onlyLandmark(with.detect(img), t));
}

// The same where the blue object is a large one (a wall, a poster: beyond
// max_area_frac_1000 once the square joins it) and the frame has no other
// blue: two FIPs and the AP are all that is left, and still enough.
TEST(Detector, SquareMergedWithALargeObjectIsCompletedFromTwoFips) {
  cv::Mat img = background(kCam.size, 16, true);
  const Placed p = place(1.0, 0, 0, 0.15, 0.25, 0);
  const Truth t = truthOf(kCam, p);
  const int x = static_cast<int>(t.corners[0].x), y = static_cast<int>(t.corners[0].y);
  img(cv::Rect(x - 240, y - 100, 240, 200)).setTo(cv::Scalar(150, 60, 40));  // 48000 px of blue
  drawSheet(img, kCam, p);
  img(cv::Rect(x - 60, y + 2, 61, 10)).setTo(cv::Scalar(150, 60, 40));  // bridging the margin
  ld::Detector det;
  EXPECT_TRUE(onlyLandmark(det.detect(img), t));
}

// The AP missing from three FIPs is completed from red ink only. A sheet
// drawn without its AP, its blue pale (as glare leaves it), gets in the
// AP's square: red ink joined to a red object beside the sheet (found);
// a quarter of its pixels orange, scattered (the colour speckle that the
// adaptive glare pass's stretch leaves around a hot spot, in a frame it
// took a strong veil out of); or a warm tint (red 23 levels over green on
// white paper, a chroma of 0.097). Before a completed AP had to fill its
// square (in such frames) and be red for its brightness, both made a
// landmark, as on look-alike cards under glare (seeds 7 and 9-12 of
// `ld-synth scene --no-landmark --cards 5 --lighting glare`). Red ink on a
// sixth of the square (covering 0.26 of it once completed, as a steeply
// seen AP a few pixels wide may) is taken in frames the glare pass did not
// correct, not in those it did.
TEST(Detector, CompletesAnApOnlyFromRedInk) {
  ld::artwork::Colours ink = inkColours();
  ink.blue = {205, 160, 150};  // blue excess 45, saturation 0.27
  ink.red = ink.white;
  Placed p = place(1.0, 0, 0, 0.15, 0, 0);
  p.artwork = ld::artwork::renderLandmark("room-214/door", 720, ink);
  const Truth t = truthOf(kCam, p);
  cv::Mat base = background(kCam.size, 21, true);
  drawSheet(base, kCam, p);
  // The AP's square in the image: [6.5u, 8.5u]^2 of the sheet, projected.
  const double u = p.side_m / 9;
  std::vector<cv::Point> square;
  for (const auto& [x, y] : {std::pair{6.5, 6.5}, {8.5, 6.5}, {8.5, 8.5}, {6.5, 8.5}}) {
    const cv::Point2d q = project(kCam, p, {x * u - p.side_m / 2, y * u - p.side_m / 2, 0});
    square.emplace_back(static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y)));
  }
  cv::Mat inside(kCam.size, CV_8UC1, cv::Scalar(0));
  cv::fillConvexPoly(inside, square, cv::Scalar(255));
  const cv::Rect box = cv::boundingRect(square);
  // ... and a square of 0.4 of its side in its middle
  std::vector<cv::Point> middle;
  for (const auto& [x, y] : {std::pair{7.1, 7.1}, {7.9, 7.1}, {7.9, 7.9}, {7.1, 7.9}}) {
    const cv::Point2d q = project(kCam, p, {x * u - p.side_m / 2, y * u - p.side_m / 2, 0});
    middle.emplace_back(static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y)));
  }
  for (int kind = 0; kind < 4; ++kind) {
    cv::Mat img = base.clone();
    cv::RNG rng(5);
    for (int y = box.y; y < box.br().y; ++y)
      for (int x = box.x; x < box.br().x; ++x) {
        if (!inside.at<uint8_t>(y, x)) continue;
        auto& px = img.at<cv::Vec3b>(y, x);
        if (kind == 0) px = {45, 60, 215};
        if (kind == 1 && rng.uniform(0, 4) == 0) px = {120, 170, 250};  // red excess 80
        if (kind == 2) px = {228, 231, 254};
      }
    if (kind == 0) {  // a red object beside the sheet, joined to the AP across its margin
      img(cv::Rect(box.br().x + 8, box.y - 10, 60, 50)).setTo(cv::Scalar(45, 60, 215));
      img(cv::Rect(box.br().x - 2, box.y + 4, 12, 8)).setTo(cv::Scalar(45, 60, 215));
    }
    if (kind == 3) {  // red ink on a sixth of the square, joined to the object by a thin line
      cv::fillConvexPoly(img, middle, cv::Scalar(45, 60, 215));
      img(cv::Rect(box.br().x + 8, box.y - 10, 60, 50)).setTo(cv::Scalar(45, 60, 215));
      const cv::Rect m = cv::boundingRect(middle);
      img(cv::Rect(m.br().x - 1, m.y + m.height / 2 - 1, box.br().x + 10 - m.br().x, 3)).setTo(cv::Scalar(45, 60, 215));
    }
    // as the fixed defaults see a frame, and as the adaptive detector's
    // glare pass leaves one (the speckle only there: the cover rule holds
    // in such frames alone)
    for (bool glare_corrected : {false, true}) {
      if (kind == 1 && !glare_corrected) continue;
      ld::Detector det;
      det.setGlareCorrected(glare_corrected);
      const auto& d = det.detect(img);
      if (kind == 0 || (kind == 3 && !glare_corrected)) {
        EXPECT_TRUE(onlyLandmark(d, t)) << kind << " " << glare_corrected;
      } else {
        EXPECT_TRUE(d.landmarks.empty()) << kind << " " << glare_corrected;
      }
    }
  }
}

namespace {

// Two FIPs joined to a blue object behind the sheet through a faintly
// tinted margin (as JPEG's half-resolution colour and blur make it): one FIP
// and the AP are left, too few for the completion.
cv::Mat joinedToAnObject(Truth& t) {
  cv::Mat img = background(kCam.size, 18, true);
  // squares of 12.5 px, a margin of 3 px
  const Placed p = place(1.6, 0, 0, 0.15, 0, 0);
  t = truthOf(kCam, p);
  const int x0 = static_cast<int>(t.corners[0].x), x1 = static_cast<int>(t.corners[1].x);
  const int y = static_cast<int>(t.corners[0].y);
  img(cv::Rect(x0 - 40, y - 50, x1 - x0 + 80, 45)).setTo(cv::Scalar(150, 60, 40));  // above the sheet
  drawSheet(img, kCam, p);
  const cv::Scalar tint(150, 112, 106);  // saturation 0.29: above the blue threshold (0.25), under 0.35
  for (const auto& c : {t.centres[0], t.centres[1]})
    img(cv::Rect(static_cast<int>(c.x) - 3, y - 6, 6, 8)).setTo(tint);
  return img;
}

}  // namespace

// The second look around the pair left (joinedToAnObject), at raised
// thresholds, parts the squares from the object.
TEST(Detector, SecondLookPartsSquaresJoinedToAnObject) {
  Truth t;
  const cv::Mat img = joinedToAnObject(t);
  ld::DetectorParams once;
  once.second_looks = 0;
  EXPECT_TRUE(ld::Detector(once).detect(img).landmarks.empty());
  ld::Detector det;
  EXPECT_TRUE(onlyLandmark(det.detect(img), t));
}

// A blue and a red card beside a landmark the first pass found, and a
// larger blue object (as a merge would leave): the second look around the
// cards sees that landmark again, and reports it once.
TEST(Detector, SecondLookReportsALandmarkOnce) {
  cv::Mat img = background(kCam.size, 19);
  const Placed p = place(1.6, 20, 10, 0.15, 0, 0);
  drawSheet(img, kCam, p);
  const Truth t = truthOf(kCam, p);
  const int x = static_cast<int>(t.corners[1].x) + 10, y = static_cast<int>(t.corners[1].y);
  img(cv::Rect(x, y, 10, 10)).setTo(cv::Scalar(150, 60, 40));
  img(cv::Rect(x + 8, y + 30, 10, 10)).setTo(cv::Scalar(40, 60, 200));
  img(cv::Rect(x + 30, y, 30, 30)).setTo(cv::Scalar(150, 60, 40));
  ld::Detector det;
  EXPECT_TRUE(onlyLandmark(det.detect(img), t));
}

namespace {

// Warm light: blue and green fall off (2000-2500 K after a camera's partial
// white balance).
void warmLight(cv::Mat& img) {
  std::vector<cv::Mat> ch;
  cv::split(img, ch);
  ch[0] *= 0.5;
  ch[1] *= 0.8;
  cv::merge(ch, img);
}

}  // namespace

// A steeply seen 9 cm landmark (68 degrees of yaw) under warm light: blue
// and green fall off, the paper turns orange and the blue squares, 3 px
// wide and mixed with the paper, violet; the first pass finds nothing. The
// faint look around the red square white-balances its window by the
// window's own white and finds the landmark (without it, faint_looks: 0,
// nothing is found).
TEST(Detector, FaintLookFindsBlueSquaresTheLightTurnedViolet) {
  int found = 0, found_without = 0, tried = 0;
  for (double roll : {0.0, 60.0, 150.0, -100.0}) {
    cv::Mat img = background(kCam.size, 25, true);
    const Placed p = place(1.5, 68, roll, 0.09, 0, 0);
    drawSheet(img, kCam, p);
    cv::GaussianBlur(img, img, cv::Size(), 0.7);
    const Truth t = truthOf(kCam, p);
    warmLight(img);
    for (int blur : {-1, 3}) {  // the front end's own (none), and a blurred frame to label
      ld::DetectorParams with, without;
      with.blur_kernel = without.blur_kernel = blur;
      without.faint_looks = 0;
      ld::Detector plain(without), det(with);
      ++tried;
      found_without += onlyLandmark(plain.detect(img), t);
      found += onlyLandmark(det.detect(img), t);
    }
  }
  std::printf("found %d of %d, without the faint look %d\n", found, tried, found_without);
  EXPECT_LT(found_without, tried) << "the first pass finds them all: the test does not test the faint look";
  EXPECT_GT(found, found_without);
  EXPECT_GE(found, tried - 1);
}

// Inside a faint look's window the completion measures the square the
// window's labels miss where the other three put it, with the window's own
// labels (in the window's coordinates). TR printed in a cyan-leaning blue
// (a printer short of magenta): after the window's white balance the mask
// takes it for cyan, not blue, yet its blue stands out where the layout puts
// it. A red poster in the frame's top-left corner, where the window's
// coordinates would fall in the frame's labels, does not stop it (with the
// frame's labels nothing is found). Without the completion, or without the
// faint look, nothing is found.
TEST(Detector, FaintLookCompletesACyanSquareInItsWindow) {
  cv::Mat art = artworkImage().clone();
  const int u = art.cols / 9;
  art(cv::Rect(13 * u / 2, u / 2, 2 * u, 2 * u)).setTo(cv::Scalar(230, 170, 60));  // TR: sRGB (60, 170, 230)
  int found = 0, found_without_completion = 0, found_without_faint = 0, tried = 0;
  for (double roll : {0.0, 60.0, 150.0, -100.0}) {
    cv::Mat img = background(kCam.size, 25, true);
    img(cv::Rect(0, 0, 200, 200)).setTo(cv::Scalar(40, 60, 210));  // the red poster
    Placed p = place(1.5, 68, roll, 0.09, 0.35, 0.2);  // the frame's lower right
    p.artwork = art;
    drawSheet(img, kCam, p);
    cv::GaussianBlur(img, img, cv::Size(), 0.7);
    const Truth t = truthOf(kCam, p);
    warmLight(img);
    ld::DetectorParams no_completion, no_faint;
    no_completion.complete_missing = false;
    no_faint.faint_looks = 0;
    ++tried;
    found += onlyLandmark(ld::Detector().detect(img), t);
    found_without_completion += onlyLandmark(ld::Detector(no_completion).detect(img), t);
    found_without_faint += onlyLandmark(ld::Detector(no_faint).detect(img), t);
  }
  std::printf("found %d of %d; without the completion %d, without the faint look %d\n", found, tried,
              found_without_completion, found_without_faint);
  EXPECT_EQ(found_without_faint, 0) << "the first pass finds it: the test does not test the faint look";
  EXPECT_EQ(found_without_completion, 0) << "the faint look finds all four squares: the test does not test the completion";
  EXPECT_GE(found, tried - 1);
}

// A landmark stuck on a blue door or a red poster smaller than the frame:
// the coloured surface around the sheet is one region whose centre lies on
// the sheet. It is no square of the landmark's size and stops nothing (it
// was taken for a square at the sheet's centre, or elsewhere on it).
TEST(Detector, LandmarkOnAColouredPosterAroundIt) {
  for (const cv::Scalar& poster : {cv::Scalar(150, 60, 40), cv::Scalar(40, 50, 190)}) {
    for (double roll : {0.0, 35.0, 160.0}) {
      for (double yaw : {0.0, 40.0}) {
        cv::Mat img = background(kCam.size, 31, true);
        const Placed p = place(1.5, yaw, roll, 0.15, 0, 0);
        const Truth t = truthOf(kCam, p);
        const cv::Point2d c = (t.corners[0] + t.corners[2]) / 2;
        cv::rectangle(img, cv::Rect(cvRound(c.x) - 75, cvRound(c.y) - 75, 150, 150), poster, cv::FILLED);
        drawSheet(img, kCam, p);
        EXPECT_TRUE(onlyLandmark(ld::Detector().detect(img), t)) << poster << " roll " << roll << " yaw " << yaw;
      }
    }
  }
}

// A hard shadow across the sheet (a lamp's light cut by a door frame or by
// the robot itself), at 0.3 and 0.45 of the light, its edge at four angles
// and three places: each part of the sheet is white in its own light. The
// sheet's samples come in two even parts, the darker a run around the
// sheet, and the paper check compares the shaded paper with the shaded
// squares (all 24 were refused before, as an uneven or dark sheet). The
// same squares on a two-tone board (only the paper darkened there, the
// squares left in full light: a look-alike) are refused. The adaptive
// detector, whose gains clip the lit paper, finds them too. Deeper shadows
// (0.2) lose the shaded squares in the mask (value_min).
TEST(Detector, ShadowAcrossTheSheet) {
  int found = 0, found_adaptive = 0, found_painted = 0, tried = 0;
  for (double depth : {0.3, 0.45}) {
    for (double edge_deg : {0.0, 50.0, 100.0, 150.0}) {
      for (double offset : {-0.25, 0.0, 0.3}) {
        cv::Mat img = background(kCam.size, 43, true);
        const Placed p = place(1.5, 20, 30, 0.15, 0, 0);
        drawSheet(img, kCam, p);
        const Truth t = truthOf(kCam, p);
        const cv::Point2d c = (t.corners[0] + t.corners[2]) / 2;
        const double half = cv::norm(t.corners[2] - t.corners[0]) / 2;  // the pattern square's half diagonal
        const double a = edge_deg * CV_PI / 180;
        const cv::Point2d n(std::cos(a), std::sin(a));  // in the shadow: (x - c) . n < offset * half
        cv::Mat shadow = img.clone(), painted = img.clone();
        for (int y = 0; y < img.rows; ++y)
          for (int x = 0; x < img.cols; ++x) {
            if ((cv::Point2d(x, y) - c).dot(n) >= offset * half) continue;
            auto& s = shadow.at<cv::Vec3b>(y, x);
            auto& q = painted.at<cv::Vec3b>(y, x);
            const int mx = std::max({q[0], q[1], q[2]}), mn = std::min({q[0], q[1], q[2]});
            const bool paper = mx > 150 && mn > 0.7 * mx;
            for (int k = 0; k < 3; ++k) {
              s[k] = cv::saturate_cast<uint8_t>(s[k] * depth);
              if (paper) q[k] = cv::saturate_cast<uint8_t>(q[k] * depth);
            }
          }
        addNoise(shadow, 2, 7);
        addNoise(painted, 2, 7);
        ++tried;
        const bool ok = onlyLandmark(ld::Detector().detect(shadow), t);
        found += ok;
        ld::AdaptiveDetector adaptive(ld::Detector(), true);
        found_adaptive += onlyLandmark(adaptive.detect(shadow), t);
        EXPECT_TRUE(ok) << "depth " << depth << ", edge at " << edge_deg << " deg, offset " << offset;
        const bool look_alike = !ld::Detector().detect(painted).landmarks.empty();
        found_painted += look_alike;
        EXPECT_FALSE(look_alike) << "two-tone board: depth " << depth << ", edge at " << edge_deg << " deg, offset " << offset;
      }
    }
  }
  std::printf("found %d of %d (adaptive %d); on the two-tone board %d\n", found, tried, found_adaptive, found_painted);
  // (the adaptive gains clip the lit paper: there it need only be brighter than the ink at all)
  EXPECT_GE(found_adaptive, tried - 2);
}

// A band of shadow across the sheet's middle (the shadow of a pole or a
// cable between the lamp and the sheet): light (0.75-0.8 of the light) it
// leaves the sheet even by sheet_uniformity; deep (0.3-0.55) it crosses the
// sheet's outline four times, two runs of shaded samples: across the
// middle two opposite sides darker than the other two, at a slant (45 and
// 135 degrees) a run near the end of each of two opposite sides (both
// refused as uneven before the band rules; the slant at 0.45 and 0.55 was
// found only by the second look's other centres, or not at all). Either
// way the QR is as much darker than the band's paper as a QR is. Such a
// sheet is a landmark; a grid of sheets' wall through a gap
// (test_detector_accuracy: GridOfSheetsWithGapsMakesNoLandmarks) is not.
// (Bands of 0.65 fall between the two and are found at 45 and 135 degrees
// only: along a side the sheet's darkest samples are too dark for an even
// sheet.)
TEST(Detector, BandOfShadowAcrossTheSheet) {
  int found_here = 0, tried = 0;
  for (double depth : {0.3, 0.45, 0.55, 0.75, 0.8})
    for (double band_deg : {0.0, 45.0, 90.0, 135.0})
      for (double dist : {0.8, 1.5}) {
        cv::Mat img = background(kCam.size, 43, true);
        const Placed p = place(dist, 20, 10, 0.15, 0, 0);
        drawSheet(img, kCam, p);
        const Truth t = truthOf(kCam, p);
        const cv::Point2d c = (t.corners[0] + t.corners[2]) / 2;
        const double half_width = 0.3 * cv::norm(t.corners[2] - t.corners[0]) / 2;  // over the QR
        const double a = band_deg * CV_PI / 180;
        const cv::Point2d n(std::cos(a), std::sin(a));
        for (int y = 0; y < img.rows; ++y)
          for (int x = 0; x < img.cols; ++x) {
            if (std::abs((cv::Point2d(x, y) - c).dot(n)) > half_width) continue;
            auto& q = img.at<cv::Vec3b>(y, x);
            for (int k = 0; k < 3; ++k) q[k] = cv::saturate_cast<uint8_t>(q[k] * depth);
          }
        cv::GaussianBlur(img, img, {0, 0}, 0.7);
        addNoise(img, 2, 7 + tried);
        const bool ok = onlyLandmark(ld::Detector().detect(img), t);
        found_here += ok;
        ++tried;
        EXPECT_TRUE(ok) << "band of " << depth << " of the light at " << band_deg << " deg, " << dist << " m";
      }
  std::printf("bands of shadow across the sheet: found %d of %d\n", found_here, tried);
}

namespace {

// A landmark at 0.8 and 1.2 m, yaw 15, three rolls, one square (each of
// `squares` in turn) damaged by `damage(img, truth, square)`: that square's
// centre as detected lies within 1 px of the truth (the detector told a
// glare veil was subtracted when `tinted`). Returns the worst error.
double damagedSquareCentres(std::initializer_list<int> squares, uint64_t background_seed, int noise_seed, bool tinted,
                            const std::function<void(cv::Mat&, const Truth&, int)>& damage) {
  double worst = 0;
  int n = 0;
  for (double dist : {0.8, 1.2})
    for (double roll : {0.0, 25.0, 60.0})
      for (int which : squares) {
        cv::Mat img = background(kCam.size, background_seed, true);
        const Placed p = place(dist, 15, roll, 0.15, 0, 0);
        drawSheet(img, kCam, p);
        const Truth t = truthOf(kCam, p);
        damage(img, t, which);
        addNoise(img, 1.5, noise_seed + n);
        ++n;
        ld::Detector det;
        det.setGlareCorrected(tinted);
        const auto& d = det.detect(img);
        EXPECT_EQ(d.landmarks.size(), 1u) << dist << " m, roll " << roll << ", square " << which;
        if (d.landmarks.size() != 1) continue;
        const auto& lm = d.landmarks[0];
        const cv::Point2f got[4] = {lm.fip_tl, lm.fip_tr, lm.fip_bl, lm.ap};
        const cv::Point2d c = t.centres[which];
        const double err = cv::norm(cv::Point2d(got[which]) - c);
        worst = std::max(worst, err);
        EXPECT_LT(err, 1.0) << dist << " m, roll " << roll << ", square " << which << ": " << got[which] << " vs " << c;
      }
  return worst;
}

}  // namespace

// A square the mask splits (a lamp's hot spot or JPEG's colour leaves a
// row of it under the threshold): its pieces are joined, and its centre is
// the whole square's, not the larger piece's (an eighth of a side off).
TEST(Detector, SquareSplitByAPaleRowKeepsItsCentre) {
  const double worst = damagedSquareCentres({0, 1, 3}, 51, 3, false, [](cv::Mat& img, const Truth& t, int which) {
    const cv::Point2d c = t.centres[which];
    const cv::Point2d ex = (t.centres[1] - t.centres[0]) / 3, ey = (t.centres[2] - t.centres[0]) / 3;
    // paper between TL and TR, and a row of it across the square, a
    // quarter of a side below its centre
    const cv::Vec3b paper = img.at<cv::Vec3b>(cv::Point((t.centres[0] + t.centres[1]) / 2));
    const cv::Point2d a = c + 0.25 * ey - 0.7 * ex, b = c + 0.25 * ey + 0.7 * ex;
    cv::line(img, a, b, cv::Scalar(paper[0], paper[1], paper[2]), 1, cv::LINE_8);
  });
  std::printf("squares split by a pale row: worst centre error %.2f px\n", worst);
}

// A blue square half of whose ink has lost its blue under a glare veil's
// tint (the outer half grey-violet, as dark; in glare the parts have any
// shape), in a frame the adaptive detector tells the detector had a strong
// veil subtracted: its centre is the whole square's (measured where a
// square of the printed size is darkest against the margin's paper:
// detail::joinPieces), not the blue half's (a quarter of a side off), and
// not pulled out over the sheet's edge by a dark background there.
TEST(Detector, SquareHalfTintedKeepsItsCentre) {
  const double worst = damagedSquareCentres({0, 1, 2}, 53, 7, true, [](cv::Mat& img, const Truth& t, int which) {
    const cv::Point2d c = t.centres[which];
    // from the square's centre: outwards along the sheet's side (away from
    // the QR), and along the other side; half a side each way
    const cv::Point2d ex = (t.centres[1] - t.centres[0]) / 6, ey = (t.centres[2] - t.centres[0]) / 6;
    const cv::Point2d out = which == 1 ? ex : -ex;
    const cv::Vec3b ink = img.at<cv::Vec3b>(cv::Point(c));
    const double m = std::max({ink[0], ink[1], ink[2]});
    const std::vector<cv::Point> half = {cv::Point(c + out - ey), cv::Point(c - ey), cv::Point(c + ey),
                                         cv::Point(c + out + ey)};
    cv::fillConvexPoly(img, half, cv::Scalar(m, 0.8 * m, 1.05 * m), cv::LINE_8);
    // the background dark right up to the sheet's edge beyond it
    const cv::Point2d edge = c + 2.0 * out;
    cv::circle(img, edge + 1.5 * out, static_cast<int>(cv::norm(1.5 * out)), cv::Scalar(40, 40, 40), cv::FILLED);
  });
  std::printf("squares half tinted: worst centre error %.2f px\n", worst);
}

// Close up, at an angle, perspective moves the AP well off TR + BL - TL,
// where a red thing just off the sheet can lie nearer: it is not taken for
// the AP (the perspective prediction and, where both are in the gate, the
// better verification choose the AP; either alone passes this test, neither
// does not).
TEST(Detector, RedThingBesideTheApCloseUpIsNotTakenForIt) {
  for (double roll : {-34.0, 56.0, 146.0}) {
    cv::Mat img = background(kCam.size, 21, true);
    const Placed p = place(0.3, -29, roll, 0.15, 0, 0);
    drawSheet(img, kCam, p);
    const Truth t = truthOf(kCam, p);
    const cv::Point2d predicted = t.centres[1] + t.centres[2] - t.centres[0], d = predicted - t.centres[3];
    ASSERT_GT(cv::norm(d), 15.0) << roll;  // the perspective's shift, in px
    const double fip_side = cv::norm(t.centres[1] - t.centres[0]) / 3;
    cv::circle(img, t.centres[3] + 1.75 * d, static_cast<int>(0.3 * fip_side), cv::Scalar(40, 60, 210), cv::FILLED);
    ld::Detector det;
    EXPECT_TRUE(onlyLandmark(det.detect(img), t)) << roll;
  }
}

// Closer still and steeper, the AP lies beyond the gate around TR + BL - TL
// (the near squares look larger, the far ones smaller): the squares' sizes
// give the perspective, and the AP's place with it.
TEST(Detector, ApPredictedWithThePerspectiveOfTheSquaresSizes) {
  ld::Detector det;
  for (double roll : {-46.0, 44.0, 134.0, -136.0}) {
    cv::Mat img = background(kCam.size, 23, true);
    const Placed p = place(0.25, 38, roll, 0.15, 0, 0);
    drawSheet(img, kCam, p);
    const Truth t = truthOf(kCam, p);
    EXPECT_TRUE(onlyLandmark(det.detect(img), t)) << roll;
  }
}

// Parallel blue stripes and an orange one: squares' centres may lie like a
// landmark's, the squares themselves are bars.
TEST(Detector, RejectsStripes) {
  ld::Detector det;
  for (double angle : {0.0, 30.0, 60.0}) {
    cv::Mat img(kCam.size, CV_8UC3, cv::Scalar(200, 220, 235));
    const cv::Point2d c(320, 240), d(std::cos(angle * CV_PI / 180), std::sin(angle * CV_PI / 180)), n(-d.y, d.x);
    for (int k = -3; k <= 3; ++k) {
      const cv::Point2d o = c + n * (k * 14.0);
      cv::line(img, o - d * 120, o + d * 120, k == 1 ? cv::Scalar(40, 110, 230) : cv::Scalar(140, 50, 60), 6);
    }
    EXPECT_TRUE(det.detect(img).landmarks.empty()) << angle;
  }
}

// The QR is part of the landmark: a sheet with the four squares and a blank
// middle is not one (cards with squares only are common).
TEST(Detector, BlankMiddleIsNoLandmark) {
  cv::Mat img = background(kCam.size, 17);
  Placed p = place(1.0, 10, 20);
  p.artwork = artworkImage().clone();
  const int u = p.artwork.cols / 9;
  p.artwork(cv::Rect(5 * u / 2, 5 * u / 2, 4 * u, 4 * u)).setTo(cv::Scalar(225, 228, 230));
  drawSheet(img, kCam, p);
  ld::Detector det;
  EXPECT_TRUE(det.detect(img).landmarks.empty());
}

// Glare clips a sheet's white: the QR's white modules clip with it, its dark
// ones turn light grey where the veil is strongest and stay darker at its
// edge, so the QR's mean is nearly the sheet's. Its grey modules still count
// as a QR on a clipped sheet (the mean rule alone rejects it); a blank
// middle on the same sheet still does not.
TEST(Detector, WashedOutQrOnAClippedSheetStillCounts) {
  auto washed = [](bool blank) {
    cv::Mat art = artworkImage().clone();
    const int u = art.cols / 9;
    if (blank) art(cv::Rect(5 * u / 2, 5 * u / 2, 4 * u, 4 * u)).setTo(cv::Scalar(255, 255, 255));
    art.forEach<cv::Vec3b>([&](cv::Vec3b& px, const int* pos) {
      const int mx = std::max({px[0], px[1], px[2]}), mn = std::min({px[0], px[1], px[2]});
      if (mx - mn > 40) return;  // the coloured squares keep their colour
      // what is left of the ink's darkness: a veil strong on the right, weaker on the left
      const int keep = pos[1] < art.cols / 2 ? 45 : 8;
      for (int c = 0; c < 3; ++c) px[c] = cv::saturate_cast<uint8_t>(255 - (255 - px[c]) * keep / 100 + 4);
    });
    return art;
  };
  cv::Mat img = background(kCam.size, 23);
  Placed p = place(0.6, 10, 20);
  p.artwork = washed(false);
  drawSheet(img, kCam, p);
  ld::Detector det;
  EXPECT_TRUE(onlyLandmark(det.detect(img), truthOf(kCam, p)));
  ld::DetectorParams mean_only;
  mean_only.qr_dark_samples = 26;
  mean_only.qr_clipped_max_brightness = mean_only.qr_max_brightness;
  ld::Detector strict(mean_only);
  EXPECT_TRUE(strict.detect(img).landmarks.empty()) << "the QR's mean passes: the test does not test the rule";

  cv::Mat blank = background(kCam.size, 23);
  p.artwork = washed(true);
  drawSheet(blank, kCam, p);
  EXPECT_TRUE(det.detect(blank).landmarks.empty());
}

namespace {

// A landmark at 0.6 m whose paper reads `paper` on every channel (glare at
// the sensor's clip), its QR square painted by `paint` (and the whole
// artwork then by `paint_sheet`), on background `seed`.
struct ClippedSheet {
  cv::Mat img;
  Truth truth;
};
ClippedSheet clippedSheet(uint8_t paper, const std::function<void(cv::Mat&)>& paint, uint64_t seed,
                          const std::function<void(cv::Mat&)>& paint_sheet = {}) {
  Placed p = place(0.6, 10, 20);
  p.artwork = artworkImage().clone();
  cv::Mat white;
  cv::inRange(p.artwork, inkColours().white, inkColours().white, white);
  p.artwork.setTo(cv::Scalar(paper, paper, paper), white);
  const int u = p.artwork.cols / 9;
  cv::Mat qr = p.artwork(cv::Rect(5 * u / 2, 5 * u / 2, 4 * u, 4 * u));
  paint(qr);
  if (paint_sheet) paint_sheet(p.artwork);
  ClippedSheet s{background(kCam.size, seed), truthOf(kCam, p)};
  drawSheet(s.img, kCam, p);
  return s;
}

}  // namespace

// Farther off the QR's modules are a pixel or less and blur to a light grey:
// under glare on a clipped sheet that grey reads 0.88-0.92 of the sheet
// (whose true brightness lies above the clip), with no point dark enough
// for the dark-point rule. It counts as a QR up to 0.93 of the sheet when
// its points are grey; a lighter grey, a blank middle, and a yellow patch on
// white as dark on the average (the mean of the grey points counts) do not.
TEST(Detector, LightGreyQrOnAClippedSheetCounts) {
  const auto with_qr = [](const std::function<void(cv::Mat&)>& paint) {
    const ClippedSheet s = clippedSheet(252, paint, 29);
    ld::Detector det;
    return onlyLandmark(det.detect(s.img), s.truth);
  };
  EXPECT_TRUE(with_qr([](cv::Mat& qr) { qr.setTo(cv::Scalar(227, 227, 227)); }));   // 0.90
  EXPECT_TRUE(with_qr([](cv::Mat& qr) { qr.setTo(cv::Scalar(214, 232, 236)); }));   // 0.90, tinted as under a veil
  EXPECT_FALSE(with_qr([](cv::Mat& qr) { qr.setTo(cv::Scalar(242, 242, 242)); }));  // 0.96
  EXPECT_FALSE(with_qr([](cv::Mat& qr) { qr.setTo(cv::Scalar(252, 252, 252)); }));  // blank
  EXPECT_FALSE(with_qr([](cv::Mat& qr) {  // a yellow patch off the centre, as dark on the average
    qr.setTo(cv::Scalar(252, 252, 252));
    qr(cv::Rect(qr.cols / 10, qr.rows / 10, qr.cols / 2, qr.rows * 3 / 10)).setTo(cv::Scalar(40, 220, 230));
  }));
}

// A hot spot's peak on the QR of a sheet it clipped all round: the QR's
// white modules read at the clip, above the sheet's margins, and its dark
// ones only a few levels under them, so its mean is the sheet's or more.
// In a frame the adapter took a strong glare veil out of
// (setGlareCorrected), the modules' dips count as a QR
// (DetectorParams::qr_washed_dip); a blank middle at the clip, a flat grey
// and the same frame without the correction do not.
TEST(Detector, QrWashedPastTheSheetCountsByItsTextureUnderGlare) {
  const auto detect = [](const std::function<void(cv::Mat&)>& paint, bool corrected, double dip,
                          const std::function<void(cv::Mat&)>& paint_sheet = {}) {
    const ClippedSheet s = clippedSheet(250, paint, 31, paint_sheet);
    ld::DetectorParams params;
    params.qr_washed_dip = dip;
    ld::Detector det(params);
    det.setGlareCorrected(corrected);
    return onlyLandmark(det.detect(s.img), s.truth);
  };
  // the QR's modules: white at the clip, black 14 levels under it
  const auto washed = [](cv::Mat& qr) {
    cv::Mat dark;
    cv::inRange(qr, cv::Scalar(0, 0, 0), cv::Scalar(120, 120, 120), dark);
    qr.setTo(cv::Scalar(255, 255, 255));
    qr.setTo(cv::Scalar(241, 241, 241), dark);
  };
  const double dip = ld::DetectorParams{}.qr_washed_dip;
  EXPECT_TRUE(detect(washed, true, dip));
  EXPECT_FALSE(detect(washed, false, dip)) << "the other QR rules pass it: the test does not test the rule";
  EXPECT_FALSE(detect(washed, true, 0));
  EXPECT_FALSE(detect(washed, true, 20));  // dips of 14 levels
  EXPECT_FALSE(detect([](cv::Mat& qr) { qr.setTo(cv::Scalar(255, 255, 255)); }, true, dip));  // blank, at the clip
  EXPECT_FALSE(detect([](cv::Mat& qr) { qr.setTo(cv::Scalar(250, 250, 250)); }, true, dip));  // blank, as the sheet
  EXPECT_FALSE(detect([](cv::Mat& qr) { qr.setTo(cv::Scalar(247, 247, 247)); }, true, dip));  // a flat grey
  // a blank middle with three green dots where points are sampled: coloured
  // points are not a QR's modules
  EXPECT_FALSE(detect(
      [](cv::Mat& qr) {
        qr.setTo(cv::Scalar(250, 250, 250));
        const double u = qr.cols / 4.0;  // the QR square spans 2.5u..6.5u of the sheet
        for (const cv::Point2d at : {cv::Point2d(3.1, 3.8), {5.9, 5.2}, {3.8, 5.9}})
          cv::circle(qr, (at - cv::Point2d(2.5, 2.5)) * u, static_cast<int>(0.3 * u), cv::Scalar(60, 170, 60), -1);
      },
      true, dip));
  // The sheet clipped all round: with its top margin (between TL and TR) at
  // 237 the QR counts, at 228 it does not.
  const auto top_margin = [&](uint8_t level) {
    return detect(washed, true, dip, [level](cv::Mat& art) {
      const int u = art.cols / 9;
      cv::Mat strip = art(cv::Rect(5 * u / 2, u / 2, 4 * u, 2 * u)), paper;
      cv::inRange(strip, cv::Scalar(250, 250, 250), cv::Scalar(250, 250, 250), paper);
      strip.setTo(cv::Scalar(level, level, level), paper);
    });
  };
  EXPECT_TRUE(top_margin(237));
  EXPECT_FALSE(top_margin(228));
}

// Hundreds of small blue and red dots: the graph is dense, the work bounded
// (max_candidates, max_cycles), and the landmark's larger squares come first.
TEST(Detector, DenseClutterStillFindsTheLandmark) {
  cv::Mat img(kCam.size, CV_8UC3, cv::Scalar(215, 215, 215));
  int k = 0;
  for (int y = 3; y < img.rows; y += 11)
    for (int x = 3; x < img.cols; x += 11, ++k)
      img(cv::Rect(x, y, 4, 4)).setTo(k % 5 ? cv::Scalar(150, 50, 40) : cv::Scalar(40, 60, 210));
  const Placed p = place(0.7, 15, 40);
  drawSheet(img, kCam, p);
  ld::Detector det;
  const auto& d = det.detect(img);
  EXPECT_EQ(d.landmarks.size(), 1u);
  EXPECT_TRUE(found(d, truthOf(kCam, p)));
}

TEST(Detector, GrayAndDegenerateImagesGiveNothing) {
  ld::Detector det;
  EXPECT_TRUE(det.detect(cv::Mat()).landmarks.empty());
  EXPECT_TRUE(det.detect(cv::Mat(1, 1, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
  EXPECT_TRUE(det.detect(cv::Mat(2, 5, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
  EXPECT_TRUE(det.detect(cv::Mat(7, 3, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
  EXPECT_TRUE(det.detect(cv::Mat(480, 640, CV_8UC3, cv::Scalar(255, 0, 0))).landmarks.empty());
  // Other types are the caller's mistake, said (a 16-bit PNG read with
  // IMREAD_UNCHANGED found nothing, without a word).
  for (int type : {CV_32FC3, CV_16UC3, CV_16UC1, CV_8UC2, CV_8SC3}) {
    const cv::Mat odd(48, 64, type, cv::Scalar(1, 0, 0));
    try {
      det.detect(odd);
      ADD_FAILURE() << "a " << cv::typeToString(type) << " image was taken";
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), "Detector::detect: a " + cv::typeToString(type) +
                                           " image: it reads 8-bit BGR, BGRA or gray (CV_8UC3, CV_8UC4, CV_8UC1)");
    }
    ld::Explanation why;
    EXPECT_THROW(det.detect(odd, why), std::invalid_argument);
  }
  // ... and a matrix of 3 dimensions (it gave no landmarks without a word)
  const int dims[] = {4, 48, 64};
  const cv::Mat cube(3, dims, CV_8UC3, cv::Scalar(1, 0, 0));
  try {
    det.detect(cube);
    ADD_FAILURE() << "a 3-dimensional matrix was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "Detector::detect: a matrix of 3 dimensions: it reads 2-dimensional 8-bit BGR, BGRA or gray images");
  }
  // A frame with a landmark, in gray: no colour, no landmark.
  cv::Mat img = background(kCam.size, 9);
  drawSheet(img, kCam, place(1.0, 0, 0));
  cv::Mat gray;
  cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
  EXPECT_TRUE(det.detect(gray).landmarks.empty());
  cv::Mat gray3;
  cv::cvtColor(gray, gray3, cv::COLOR_GRAY2BGR);
  EXPECT_TRUE(det.detect(gray3).landmarks.empty());
  // Random noise.
  cv::Mat noise(480, 640, CV_8UC3);
  cv::RNG(3).fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_TRUE(det.detect(noise).landmarks.empty());
  // BGRA works like BGR.
  cv::Mat bgra;
  cv::cvtColor(img, bgra, cv::COLOR_BGR2BGRA);
  EXPECT_EQ(det.detect(bgra).landmarks.size(), 1u);
  // A sub-image (non-continuous) works too.
  EXPECT_EQ(det.detect(img(cv::Rect(100, 50, 440, 380))).landmarks.size(), 1u);
}

// The artwork itself, as ld-generate writes it (pure #0000FF and #FF0000 on
// #FFFFFF: as bright as the paper), turned and scaled onto white: a user's
// first check of a printed landmark is often its own PNG, a scan or a
// screenshot. The paper by a square read 254 against the ink's 255 and the
// sheet was refused as dark in 6 of 40 such views (a user audit).
TEST(Detector, NominalArtworkTurnedOnWhiteIsFound) {
  const cv::Mat art = ld::artwork::renderLandmark("room-214/door", 900);
  ld::Detector det;
  int missed = 0;
  std::string which;
  for (double side : {300.0, 600.0, 1000.0})
    for (double turn : {0.0, 8.0, 10.0, 17.0, 33.0, 45.0, 100.0}) {
      cv::Mat page(1300, 1700, CV_8UC3, cv::Scalar(255, 255, 255));
      cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(450, 450), turn, side / art.cols);
      m.at<double>(0, 2) += 850 - 450;
      m.at<double>(1, 2) += 650 - 450;
      cv::warpAffine(art, page, m, page.size(), cv::INTER_LINEAR, cv::BORDER_TRANSPARENT);
      const ld::Detection d = det.detect(page);
      if (d.landmarks.size() != 1) {
        ++missed;
        which += " " + std::to_string(static_cast<int>(side)) + " px at " + std::to_string(static_cast<int>(turn)) +
                 " deg (" + std::to_string(d.landmarks.size()) + " found)";
      }
    }
  EXPECT_EQ(missed, 0) << which;
}

TEST(Detector, StagesAreNamedAndTimed) {
  cv::Mat img = background(kCam.size, 10);
  drawSheet(img, kCam, place(1.0, 0, 0));
  ld::Detector fast;
  fast.setCamera(kCam, 0.15);
  const auto& d = fast.detect(img);
  std::vector<std::string> names;
  for (const auto& s : d.stages) names.push_back(s.name);
  EXPECT_EQ(names, (std::vector<std::string>{"saturation", "contours", "colour", "geometry", "second look",
                                             "faint look", "corners", "pose"}));
  EXPECT_GT(d.total_ms, 0);
  EXPECT_GE(d.total_ms, d.stageMs("saturation"));
  EXPECT_EQ(d.stageMs("edges"), 0);

  ld::Detector paper(ld::DetectorParams::paper());
  const auto& dp = paper.detect(img);
  names.clear();
  for (const auto& s : dp.stages) names.push_back(s.name);
  EXPECT_EQ(names, (std::vector<std::string>{"blur", "saturation", "edges", "contours", "colour", "geometry", "corners"}));
}

// The paper's front end finds a large, frontal landmark.
TEST(Detector, PaperFrontEndFindsFrontalLandmark) {
  for (const auto& p : {ld::DetectorParams::paper(), [] {
                          ld::DetectorParams q;
                          q.front_end = "paper";
                          return q;
                        }()}) {
    cv::Mat img = background(kCam.size, 11);
    const Placed pl = place(0.6, 10, 0);
    drawSheet(img, kCam, pl);
    ld::Detector det(p);
    const auto& d = det.detect(img);
    EXPECT_TRUE(found(d, truthOf(kCam, pl)));
  }
}

TEST(Detector, CornersSubPixelOnFrontalViews) {
  ld::Detector det;
  double sq = 0;
  int n = 0;
  for (int k = 0; k < 6; ++k) {
    cv::Mat img = background(kCam.size, 20 + k, true);
    const Placed p = place(1.0, 0, k * 37.0, 0.15, 0.03 * k - 0.08, 0.011 * k - 0.03);
    drawSheet(img, kCam, p);
    const Truth t = truthOf(kCam, p);
    const auto& d = det.detect(img);
    ASSERT_EQ(d.landmarks.size(), 1u);
    for (int i = 0; i < 4; ++i) {
      sq += std::pow(cv::norm(cv::Point2d(d.landmarks[0].corners[i]) - t.corners[i]), 2);
      ++n;
    }
  }
  const double rms = std::sqrt(sq / n);
  std::cout << "corner RMS on rendered frontal views at 1 m: " << rms << " px\n";
  EXPECT_LT(rms, 0.5);
}

// ====================================================================== explanation

namespace {

// The explanation's refused group that is the landmark `t` (its three FIPs
// and, when tried, its AP, within 2 px), or null.
const ld::Explanation::Refused* refusedAt(const ld::Explanation& e, const Truth& t) {
  auto near = [](const cv::Point2f& a, const cv::Point2d& b) { return cv::norm(cv::Point2d(a) - b) < 2.0; };
  for (const auto& r : e.refused)
    if (near(r.fips[0], t.centres[0]) && near(r.fips[1], t.centres[1]) && near(r.fips[2], t.centres[2]) &&
        (!r.ap || near(*r.ap, t.centres[3])))
      return &r;
  return nullptr;
}

// `img` detected with an explanation into `why`: whether it gave the
// landmark `t` alone, as detect() without one gives it.
::testing::AssertionResult explainedAlone(const cv::Mat& img, const Truth& t, ld::Explanation& why) {
  ld::Detector det;
  const std::vector<ld::Landmark> alone = det.detect(img).landmarks;
  const auto& d = det.detect(img, why);
  if (auto found = onlyLandmark(d, t); !found) return found;
  if (alone.size() != 1 || alone[0].corners != d.landmarks[0].corners)
    return ::testing::AssertionFailure() << "not what detect() alone gives";
  return ::testing::AssertionSuccess();
}

}  // namespace

// A landmark found: the explanation counts its squares and refuses none of
// them, and the detection is the one detect() alone gives.
TEST(Explain, FoundLandmarkIsCountedNotRefused) {
  cv::Mat img = background(kCam.size, 31);
  const Placed p = place(1.0, 20, 35);
  drawSheet(img, kCam, p);
  const Truth t = truthOf(kCam, p);
  ld::Explanation why;
  ASSERT_TRUE(explainedAlone(img, t, why));
  EXPECT_GE(why.blue_regions, 3);
  EXPECT_GE(why.fips, 3);
  EXPECT_GE(why.aps, 1);
  EXPECT_GE(why.fip_pairs, 3);
  EXPECT_GE(why.right_isosceles, 1);
  EXPECT_EQ(refusedAt(why, t), nullptr);
  EXPECT_GT(why.ms, 0.0);
}

// Each way of losing a landmark is named: a blank middle by the QR check,
// a look-alike card's centre, a tightened cover range by the cover check,
// colour ratios out of reach by the off-colour count, with the parameters
// that decide them in the text.
TEST(Explain, NamesTheCheckThatRefusedTheLandmark) {
  const Placed plain = place(1.0, 10, 20);
  const Truth t = truthOf(kCam, plain);
  auto explain = [&](const cv::Mat& artwork, const ld::DetectorParams& params) {
    cv::Mat img = background(kCam.size, 17);
    Placed p = plain;
    p.artwork = artwork;
    drawSheet(img, kCam, p);
    ld::Detector det(params);
    ld::Explanation why;
    EXPECT_TRUE(det.detect(img, why).landmarks.empty());
    return why;
  };
  {  // blank middle
    cv::Mat art = artworkImage().clone();
    const int u = art.cols / 9;
    art(cv::Rect(5 * u / 2, 5 * u / 2, 4 * u, 4 * u)).setTo(cv::Scalar(225, 228, 230));
    const auto why = explain(art, {});
    const auto* r = refusedAt(why, t);
    ASSERT_NE(r, nullptr) << ld::describe(why, {});
    ASSERT_TRUE(r->ap.has_value());
    EXPECT_EQ(r->check, "no QR");
    EXPECT_NE(ld::describe(why, {}).find("no QR (qr_max_brightness"), std::string::npos) << ld::describe(why, {});
  }
  {  // a card with red in the middle and none at BR: no AP where the layout puts it
    const auto why = explain(lookAlike(0), {});
    const auto* r = refusedAt(why, t);
    ASSERT_NE(r, nullptr) << ld::describe(why, {});
    EXPECT_FALSE(r->ap.has_value());
    EXPECT_EQ(r->check, "no AP");
  }
  {  // a cover range a landmark cannot meet
    ld::DetectorParams q;
    q.cover_max = 0.2;
    const auto why = explain(artworkImage(), q);
    const auto* r = refusedAt(why, t);
    ASSERT_NE(r, nullptr) << ld::describe(why, q);
    EXPECT_EQ(r->check, "cover");
    bool counted = false;
    for (const auto& [check, n] : why.refusals) counted |= check == "cover" && n >= 1;
    EXPECT_TRUE(counted);
    EXPECT_NE(ld::describe(why, q).find("cover (cover_min, cover_max; where the colour is smeared, the absorbed light's 0.25-0.42)"), std::string::npos) << ld::describe(why, q);
  }
  {  // a fifth blue square on the sheet, between TL and TR (off the line
     // between their centres that the cover check follows): a pattern, not
     // a landmark
    cv::Mat art = artworkImage().clone();
    const int u = art.cols / 9;
    const cv::Vec3b blue = art.at<cv::Vec3b>(3 * u / 2, 3 * u / 2);
    art(cv::Rect(cvRound(3.95 * u), cvRound(0.3 * u), cvRound(1.1 * u), cvRound(1.1 * u)))
        .setTo(cv::Scalar(blue[0], blue[1], blue[2]));
    const auto why = explain(art, {});
    const auto* r = refusedAt(why, t);
    ASSERT_NE(r, nullptr) << ld::describe(why, {});
    EXPECT_EQ(r->check, "other squares");
    EXPECT_NE(ld::describe(why, {}).find("other squares (a coloured square on the sheet"), std::string::npos)
        << ld::describe(why, {});
  }
  {  // hollow squares (rings): labelled, then too sparse for min_fill
    cv::Mat art = artworkImage().clone();
    const int u = art.cols / 9;
    for (const cv::Point2d c : {cv::Point2d(1.5, 1.5), cv::Point2d(7.5, 1.5), cv::Point2d(1.5, 7.5), cv::Point2d(7.5, 7.5)})
      art(cv::Rect(cvRound((c.x - 0.6) * u), cvRound((c.y - 0.6) * u), cvRound(1.2 * u), cvRound(1.2 * u)))
          .setTo(cv::Scalar(225, 228, 230));
    const ld::DetectorParams q;
    const auto why = explain(art, q);
    EXPECT_GE(why.blue_sparse, 3);
    EXPECT_GE(why.red_sparse, 1);
    EXPECT_NE(ld::describe(why, q).find("sparse, under min_fill 0.5: "), std::string::npos) << ld::describe(why, q);
  }
  {  // colour ratios no ink meets: the squares are labelled, then off colour
    ld::DetectorParams q;
    q.color_ratio_a = q.color_ratio_b = 20;
    const auto why = explain(artworkImage(), q);
    EXPECT_GE(why.blue_off_colour, 3);
    EXPECT_GE(why.red_off_colour, 1);
    EXPECT_EQ(why.fips, 0);
    EXPECT_TRUE(why.refused.empty());
    EXPECT_NE(ld::describe(why, q).find("off colour (color_ratio_a 20, color_ratio_b 20): "), std::string::npos)
        << ld::describe(why, q);
  }
}

namespace {

const ld::Explanation::Round* roundNamed(const ld::Explanation& e, const std::string& name) {
  for (const auto& r : e.rounds)
    if (r.round == name) return &r;
  return nullptr;
}

int skipped(const ld::Explanation::Round& r, const std::string& why) {
  for (const auto& [reason, n] : r.skipped)
    if (reason == why) return n;
  return 0;
}

bool inside(const cv::Rect& r, const cv::Point2d& q) { return r.contains(cv::Point(cvRound(q.x), cvRound(q.y))); }

// Each round's squares are each either looked around or not, with a reason.
void expectRoundsAddUp(const ld::Explanation& e) {
  for (const auto& r : e.rounds) {
    int not_looked = 0;
    for (const auto& [reason, n] : r.skipped) not_looked += n;
    EXPECT_EQ(r.windows + not_looked, r.anchors) << r.round;
  }
}

}  // namespace

// The landmark the second look found (joinedToAnObject): the explanation
// lists the look's window, around the pair the first pass left, with its
// squares and its raised thresholds; only that look counts the landmark;
// and the detection is the one detect() alone gives.
TEST(Explain, ListsTheLookThatFoundTheLandmark) {
  Truth t;
  const cv::Mat img = joinedToAnObject(t);
  ld::Explanation why;
  ASSERT_TRUE(explainedAlone(img, t, why));
  const std::string text = ld::describe(why, {});
  const auto* second = roundNamed(why, "second look");
  ASSERT_NE(second, nullptr) << text;
  EXPECT_GE(second->anchors, 1);
  EXPECT_GE(second->windows, 1);
  const ld::Explanation::Look* found = nullptr;
  int finding = 0;
  for (const auto& l : why.looks)
    if (l.landmarks > 0) found = &l, ++finding;
  ASSERT_EQ(finding, 1) << text;
  expectRoundsAddUp(why);
  EXPECT_EQ(found->round, "second look");
  // (around the midpoint of the pair the first pass left: two of its squares)
  bool midpoint = false;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      midpoint |= cv::norm(cv::Point2d(found->around) - (t.centres[i] + t.centres[j]) / 2) < 1.5;
  EXPECT_TRUE(midpoint) << text;
  EXPECT_EQ(found->how, "raised by second_look_raise");
  EXPECT_EQ(found->landmarks, 1);
  EXPECT_EQ(found->dropped, 0);
  for (const auto& c : t.centres) EXPECT_TRUE(inside(found->window, c)) << text;
  EXPECT_GE(found->fips, 3);
  EXPECT_GE(found->aps, 1);
  EXPECT_GE(found->right_isosceles, 1);
  EXPECT_TRUE(found->refused.empty()) << text;
  EXPECT_NE(text.find("\nlooks after the first pass:\n  second look (second_looks 8): "), std::string::npos) << text;
  EXPECT_NE(text.find(", raised by second_look_raise: "), std::string::npos) << text;
  EXPECT_NE(text.find("shaped as a landmark's; 1 landmark found"), std::string::npos) << text;
}

// A steeply seen landmark under warm light whose middle is blank: the faint
// look's white-balanced window sees its violet blue squares and refuses them
// as no QR, and says so. The group's positions are the frame's (the
// window's own coordinates moved back).
TEST(Explain, LooksNameTheCheckThatRefusedInTheirWindow) {
  cv::Mat art = artworkImage().clone();
  const int u = art.cols / 9;
  art(cv::Rect(5 * u / 2, 5 * u / 2, 4 * u, 4 * u)).setTo(cv::Scalar(225, 228, 230));
  int named = 0, tried = 0;
  for (double roll : {0.0, 60.0, 150.0}) {
    cv::Mat img = background(kCam.size, 25, true);
    Placed p = place(1.5, 68, roll, 0.09, 0, 0);
    p.artwork = art;
    drawSheet(img, kCam, p);
    cv::GaussianBlur(img, img, cv::Size(), 0.7);
    const Truth t = truthOf(kCam, p);
    warmLight(img);
    ld::Detector det;
    ld::Explanation why;
    EXPECT_TRUE(det.detect(img, why).landmarks.empty());
    expectRoundsAddUp(why);
    ++tried;
    auto near = [](const cv::Point2f& a, const cv::Point2d& b) { return cv::norm(cv::Point2d(a) - b) < 2.0; };
    for (const auto& l : why.looks) {
      if (l.round != "faint look") continue;
      for (const auto& r : l.refused)
        if (near(r.fips[0], t.centres[0]) && near(r.fips[1], t.centres[1]) && near(r.fips[2], t.centres[2]) &&
            r.ap && near(*r.ap, t.centres[3]) && r.check == "no QR" && inside(l.window, t.centres[3]) &&
            l.how == "white-balanced") {
          ++named;
          const std::string text = ld::describe(why, {});
          EXPECT_NE(text.find("refused: 1 no QR\n      FIPs "), std::string::npos) << text;
        }
    }
  }
  std::printf("the faint look named no QR in %d of %d\n", named, tried);
  EXPECT_GE(named, tried - 1);
}

// A round's squares it did not look around are counted with the reason: a
// red card larger than the AP takes the faint look's only window
// (faint_looks 1; the larger squares go first), and the AP's is left,
// "faint_looks spent".
TEST(Explain, RoundsCountTheSquaresTheyDidNotLookAround) {
  cv::Mat img = background(kCam.size, 25, true);
  const Placed p = place(1.5, 68, 0, 0.09, 0, 0);
  drawSheet(img, kCam, p);
  cv::GaussianBlur(img, img, cv::Size(), 0.7);
  const Truth t = truthOf(kCam, p);
  img(cv::Rect(60, 60, 14, 14)).setTo(cv::Scalar(40, 50, 200));  // the red card, far from the landmark
  warmLight(img);
  ld::DetectorParams q;
  q.faint_looks = 1;
  ld::Detector det(q);
  ld::Explanation why;
  det.detect(img, why);
  const std::string text = ld::describe(why, q);
  expectRoundsAddUp(why);
  const auto* faint = roundNamed(why, "faint look");
  ASSERT_NE(faint, nullptr) << text;
  EXPECT_GE(faint->anchors, 2) << text;
  EXPECT_EQ(faint->windows, 1) << text;
  EXPECT_EQ(skipped(*faint, "faint_looks spent"), faint->anchors - 1) << text;
  bool card = false;
  for (const auto& l : why.looks)
    if (l.round == "faint look") {
      card |= inside(l.window, {67, 67});
      EXPECT_FALSE(inside(l.window, t.centres[3])) << text;
    }
  EXPECT_TRUE(card) << text;
  EXPECT_NE(text.find("  faint look (faint_looks 1): "), std::string::npos) << text;
  EXPECT_NE(text.find(cv::format("1 window looked at; %d not: faint_looks spent", faint->anchors - 1)),
            std::string::npos)
      << text;
  // The paper's front end has no looks, and says nothing of them.
  ld::Detector paper(ld::DetectorParams::paper());
  ld::Explanation none;
  paper.detect(img, none);
  EXPECT_TRUE(none.rounds.empty());
  EXPECT_TRUE(none.looks.empty());
  EXPECT_EQ(ld::describe(none, ld::DetectorParams::paper()).find("looks after"), std::string::npos);
}

// Confetti of small blue and red squares over a large frame, the looks'
// limits raised: more looks than an explanation lists (48; the rest
// counted), and more pairs of squares than the second look takes (256).
TEST(Explain, ListsAtMost48LooksAndCountsTheRest) {
  cv::Mat img(960, 1280, CV_8UC3, cv::Scalar(200, 205, 210));
  cv::RNG rng(5);
  for (int k = 0; k < 600; ++k) {
    const cv::Point at(rng.uniform(4, 1276), rng.uniform(4, 956));
    img(cv::Rect(at.x - 2, at.y - 2, 5, 5)).setTo(k % 2 ? cv::Scalar(160, 50, 40) : cv::Scalar(40, 60, 200));
  }
  ld::DetectorParams q;
  q.faint_looks = q.second_looks = 64;
  ld::Detector det(q);
  ld::Explanation why;
  det.detect(img, why);
  const std::string text = ld::describe(why, q);
  expectRoundsAddUp(why);
  int windows = 0;  // (one look each: no veil round here)
  for (const auto& r : why.rounds) windows += r.windows;
  EXPECT_EQ(why.looks.size(), ld::Explanation::kMaxLooks) << text;
  EXPECT_GT(why.looks_more, 0) << text;
  EXPECT_EQ(static_cast<int>(why.looks.size()) + why.looks_more, windows) << text;
  EXPECT_NE(text.find(cv::format("\n  %d more look", why.looks_more)), std::string::npos) << text;
  const auto* second = roundNamed(why, "second look");
  ASSERT_NE(second, nullptr) << text;
  EXPECT_GT(second->anchors, 256) << text;
  EXPECT_EQ(skipped(*second, "beyond the first kMaxAnchors (256), the AP pairs and the smaller windows first"),
            second->anchors - 256)
      << text;
}

// The veil round (frames with a glare veil taken out) around a lone red
// square says why it took no tint out: on a sheet clipped white, none
// measured (the discs where the QR would lie hold no unclipped pixel); on
// an even grey, none to take out (the tint is 0).
TEST(Explain, VeilRoundSaysWhyItTookNoTintOut) {
  for (const bool clipped : {true, false}) {
    cv::Mat img(480, 640, CV_8UC3, clipped ? cv::Scalar(255, 255, 255) : cv::Scalar(180, 180, 180));
    img(cv::Rect(300, 220, 10, 10)).setTo(cv::Scalar(40, 50, 200));
    ld::Detector det;
    det.setGlareCorrected(true);
    ld::Explanation why;
    EXPECT_TRUE(det.detect(img, why).landmarks.empty());
    const std::string text = ld::describe(why, {});
    expectRoundsAddUp(why);
    const auto* veil = roundNamed(why, "veil round");
    ASSERT_NE(veil, nullptr) << text;
    EXPECT_EQ(veil->anchors, 1) << text;
    EXPECT_EQ(veil->windows, 0) << text;
    const char* reason = clipped ? "no tint measured (the QR's discs off the frame or clipped)"
                                 : "no tint to take out (under kVeilMinTint)";
    EXPECT_EQ(skipped(*veil, reason), 1) << text;
    EXPECT_NE(text.find(std::string("1 not: ") + reason), std::string::npos) << text;
  }
}

// Gray and empty images: nothing counted, nothing refused.
TEST(Explain, ImagesWithoutColourExplainNothing) {
  ld::Detector det;
  for (const cv::Mat& img : {cv::Mat(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(128))}) {
    ld::Explanation why;
    why.fips = 7;  // cleared
    EXPECT_TRUE(det.detect(img, why).landmarks.empty());
    EXPECT_EQ(why.fips, 0);
    EXPECT_EQ(why.blue_regions, 0);
    EXPECT_TRUE(why.refused.empty());
  }
}

// Every check has a name of its own (explanations count refusals by it and
// describe() finds each check's hint by it).
TEST(Explain, EveryCheckHasItsOwnName) {
  std::set<std::string> names;
  for (int i = 0; i < ld::detail::kNumChecks; ++i) {
    const std::string name = ld::detail::checkName(static_cast<ld::detail::Check>(i));
    EXPECT_FALSE(name.empty() || name == "?") << "check " << i;
    EXPECT_TRUE(names.insert(name).second) << "two checks are called '" << name << "'";
  }
}

// ====================================================================== pose

TEST(Pose, FrontalSheetHasZeroRotation) {
  cv::Mat img = background(kCam.size, 12);
  const Placed p = place(1.2, 0, 0, 0.15, 0.02, 0.01);
  drawSheet(img, kCam, p);
  ld::Detector det;
  det.setCamera(kCam, 0.15);
  const auto& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 1u);
  ASSERT_TRUE(d.landmarks[0].pose.has_value());
  const ld::Pose& pose = *d.landmarks[0].pose;
  EXPECT_LT(cv::norm(pose.rvec), 0.03);
  EXPECT_NEAR(pose.distance, cv::norm(p.t), 0.01 * cv::norm(p.t));
  EXPECT_NEAR(pose.t[0], 0.02, 0.005);
  EXPECT_NEAR(pose.t[1], 0.01, 0.005);
}

// A calibration turned with its images (CameraModel::turned: a phone's
// portrait photo turned upright by its Exif orientation) projects every point
// where the image's own turn puts its projection, distortion included: the
// point's camera-frame coordinates turn as the image does (a quarter
// clockwise: x' = -y, y' = x; mirrored: x' = -x).
TEST(Pose, CalibrationTurnsWithTheImage) {
  ld::CameraModel cam;
  cam.size = {1920, 1080};
  cam.K = cv::Matx33d(1012.5, 0, 951.25, 0, 1009.0, 547.75, 0, 0, 1);
  cam.dist = (cv::Mat_<double>(1, 12) << -0.21, 0.08, 0.0013, -0.0021, -0.01, 0.002, 0.001, -0.003, 0.0011,
              -0.0004, 0.0017, 0.0006);
  cv::RNG rng(5);
  std::vector<cv::Point3d> points;
  for (int i = 0; i < 40; ++i)
    points.emplace_back(rng.uniform(-0.7, 0.7), rng.uniform(-0.4, 0.4), rng.uniform(0.8, 3.0));
  const auto project = [](const ld::CameraModel& c, const std::vector<cv::Point3d>& pts) {
    std::vector<cv::Point2d> px;
    cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), c.K, c.dist, px);
    return px;
  };
  const std::vector<cv::Point2d> raw = project(cam, points);
  for (bool mirrored : {false, true})
    for (int k = 0; k < 4; ++k) {
      ld::CameraModel turned;
      ASSERT_EQ(cam.turned(k, mirrored, turned), "");
      EXPECT_EQ(turned.size, k % 2 ? cv::Size(1080, 1920) : cv::Size(1920, 1080));
      std::vector<cv::Point3d> pts = points;
      std::vector<cv::Point2d> want = raw;
      cv::Size size = cam.size;
      if (mirrored)
        for (size_t i = 0; i < pts.size(); ++i) pts[i].x = -pts[i].x, want[i].x = size.width - 1 - want[i].x;
      for (int q = 0; q < k; ++q) {
        for (size_t i = 0; i < pts.size(); ++i) {
          pts[i] = {-pts[i].y, pts[i].x, pts[i].z};
          want[i] = {size.height - 1 - want[i].y, want[i].x};
        }
        size = {size.height, size.width};
      }
      const std::vector<cv::Point2d> got = project(turned, pts);
      for (size_t i = 0; i < pts.size(); ++i)
        ASSERT_LT(cv::norm(got[i] - want[i]), 1e-6) << "turn " << k << (mirrored ? " mirrored" : "") << ", point " << i;
    }
  // What does not turn is said.
  ld::CameraModel skewed = cam, out;
  skewed.K(0, 1) = 0.5;
  EXPECT_NE(skewed.turned(1, false, out).find("skew"), std::string::npos);
  EXPECT_EQ(skewed.turned(2, true, out), "");
  ld::CameraModel tilted = cam;
  tilted.dist = cv::Mat::zeros(1, 14, CV_64F);
  tilted.dist.at<double>(12) = 0.01;
  EXPECT_NE(tilted.turned(1, false, out).find("tilted"), std::string::npos);
  ld::CameraModel sizeless = cam;  // (its principal point turns about the image's middle)
  sizeless.size = {};
  EXPECT_NE(sizeless.turned(2, false, out).find("size is not known"), std::string::npos);
}

TEST(Pose, TurnedSheet) {
  cv::Mat img = background(kCam.size, 13);
  const Placed p = place(1.5, 35, 120, 0.15);
  drawSheet(img, kCam, p);
  ld::Detector det;
  det.setCamera(kCam, 0.15);
  const auto& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 1u);
  ASSERT_TRUE(d.landmarks[0].pose.has_value());
  cv::Matx33d R;
  cv::Rodrigues(d.landmarks[0].pose->rvec, R);
  const cv::Matx33d dR = R.t() * p.R;
  const double angle = std::acos(std::clamp((cv::trace(dR) - 1) / 2, -1.0, 1.0)) * 180 / CV_PI;
  EXPECT_LT(angle, 3.0);
  EXPECT_NEAR(d.landmarks[0].pose->distance, 1.5, 0.03);
}

// A camera for another frame size is scaled to the frame.
TEST(Pose, ScaledCamera) {
  const ld::CameraModel big = ld::CameraModel::pinhole({1280, 960}, 1200);
  cv::Mat img = background(kCam.size, 14);
  const Placed p = place(1.0, 0, 0);
  drawSheet(img, kCam, p);
  ld::Detector det;
  det.setCamera(big, 0.15);
  const auto& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 1u);
  ASSERT_TRUE(d.landmarks[0].pose.has_value());
  EXPECT_NEAR(d.landmarks[0].pose->distance, 1.0, 0.01);
}

// A calibration of another aspect ratio (a 16:9 mode's, on 4:3 frames) is
// another crop of the sensor: no pose, and the detection says why; the
// landmarks are found as ever, and a frame that fits gets its pose again.
TEST(Pose, CalibrationOfAnotherAspectRatioGivesNoPose) {
  const ld::CameraModel wide = ld::CameraModel::pinhole({1280, 720}, 1200);
  EXPECT_FALSE(wide.fits(kCam.size));
  EXPECT_TRUE(wide.fits({640, 360}));
  EXPECT_TRUE(ld::CameraModel::pinhole({1280, 960}, 1200).fits(kCam.size));
  EXPECT_EQ(ld::CameraModel::pinhole({1280, 960}, 1200).misfit(kCam.size), "");
  cv::Mat img = background(kCam.size, 14);
  drawSheet(img, kCam, place(1.0, 0, 0));
  ld::Detector det;
  det.setCamera(wide, 0.15);
  const ld::Detection& d = det.detect(img);
  ASSERT_EQ(d.landmarks.size(), 1u);
  EXPECT_FALSE(d.landmarks[0].pose.has_value());
  EXPECT_NE(d.pose_error.find("1280x720"), std::string::npos) << d.pose_error;
  EXPECT_NE(d.pose_error.find("640x480"), std::string::npos) << d.pose_error;
  det.setCamera(ld::CameraModel::pinhole({1280, 960}, 1200), 0.15);
  // What gives no pose at all is refused, said (an infinite side, or a
  // focal length of 0 or NaN, gave landmarks no pose and no pose_error)
  ld::Detector refusing;
  for (double side : {0.0, -0.15, std::numeric_limits<double>::infinity(), std::numeric_limits<double>::quiet_NaN()})
    EXPECT_THROW(refusing.setCamera(kCam, side), std::invalid_argument) << side;
  ld::CameraModel flat = kCam;
  flat.K(0, 0) = 0;
  EXPECT_THROW(refusing.setCamera(flat, 0.15), std::invalid_argument);
  flat.K(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(refusing.setCamera(flat, 0.15), std::invalid_argument);
  for (double f : {-600.0, 0.0, std::numeric_limits<double>::quiet_NaN()})
    EXPECT_THROW(ld::CameraModel::pinhole({640, 480}, f), std::invalid_argument) << f;
  EXPECT_THROW(ld::CameraModel::pinhole({-640, 480}, 600), std::invalid_argument);
  const ld::Detection& d2 = det.detect(img);
  ASSERT_EQ(d2.landmarks.size(), 1u);
  EXPECT_TRUE(d2.landmarks[0].pose.has_value());
  EXPECT_EQ(d2.pose_error, "");
}

// ====================================================================== parameters

namespace {

std::string tempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("ld_test_detector_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

}  // namespace

// Sheet alignment (detail::alignSheet) from a start off the truth: a start
// a tenth of a square off is fitted back to within a few hundredths of a
// pixel; from starts 0.6 of a square off, an alignment is either refused or
// moves no centre by more than a quarter of its square (the guard), and it
// is refused at least once (the fit slid back that far).
TEST(SheetAlignment, RecoversANearStartAndRefusesALongSlide) {
  const cv::Size size(640, 480);
  cv::Mat img = background(size, 5);
  const Placed p = place(2.0, 20, 30);
  drawSheet(img, kCam, p);
  addNoise(img, 2.0, 6);
  const Truth t = truthOf(kCam, p);
  ld::detail::SheetModel model;
  ld::detail::sheetModel(8, model);
  ld::detail::AlignScratch scratch;
  const double side = cv::norm(t.centres[1] - t.centres[0]) / 3;  // a square's side, px
  std::array<cv::Point2d, 4> pattern;
  for (int i = 0; i < 4; ++i) pattern[i] = {layout::kCornersU[i][0], layout::kCornersU[i][1]};
  // The truth moved by `shift` square sides in direction `angle`, centres
  // from its corners.
  const auto start = [&](double shift, double angle, std::array<cv::Point2d, 4>& centres,
                         std::array<cv::Point2d, 4>& corners) {
    const cv::Point2d d = shift * side * cv::Point2d(std::cos(angle), std::sin(angle));
    for (int i = 0; i < 4; ++i) corners[i] = t.corners[i] + d;
    cv::Matx33d H;
    ASSERT_TRUE(ld::detail::homography4(pattern, corners, H));
    for (int i = 0; i < 4; ++i) {
      const cv::Vec3d q = H * cv::Vec3d(layout::kCentresU[i][0], layout::kCentresU[i][1], 1);
      centres[i] = {q[0] / q[2], q[1] / q[2]};
    }
  };
  std::array<cv::Point2d, 4> centres, corners;
  for (int k = 0; k < 4; ++k) {
    start(0.1, k * CV_PI / 2 + 0.3, centres, corners);
    ASSERT_TRUE(ld::detail::alignSheet(img, nullptr, model, 10, centres, corners, scratch)) << k;
    for (int i = 0; i < 4; ++i) {
      EXPECT_LT(cv::norm(centres[i] - t.centres[i]), 0.1) << k << " centre " << i;
      EXPECT_LT(cv::norm(corners[i] - t.corners[i]), 0.15) << k << " corner " << i;
    }
  }
  int refused = 0;
  for (int k = 0; k < 8; ++k) {
    start(0.6, k * CV_PI / 4, centres, corners);
    const auto before = centres;
    if (!ld::detail::alignSheet(img, nullptr, model, 10, centres, corners, scratch)) {
      ++refused;
      for (int i = 0; i < 4; ++i) EXPECT_EQ(centres[i], before[i]) << k;  // left as they were
      continue;
    }
    for (int i = 0; i < 4; ++i) EXPECT_LE(cv::norm(centres[i] - before[i]), 0.25 * side * 1.1) << k << " centre " << i;
  }
  EXPECT_GT(refused, 0);
  // off: nothing
  start(0.1, 0, centres, corners);
  const auto before = centres;
  EXPECT_FALSE(ld::detail::alignSheet(img, nullptr, model, 0, centres, corners, scratch));
  EXPECT_EQ(centres, before);
}

// The size gates: a sheet over 120 px is fitted only to a near model (and
// then placed as well as a far one is), and none over 480 px.
TEST(SheetAlignment, NearSheetsTakeTheNearModelUpTo480Px) {
  ld::detail::SheetModel far_model, near_model;
  ld::detail::sheetModel(8, far_model);
  ld::detail::sheetModel(16, near_model);
  ld::detail::AlignScratch scratch;
  for (const double distance : {0.6, 0.17}) {
    cv::Mat img = background(kCam.size, 9);
    const Placed p = place(distance, 15, 20);
    drawSheet(img, kCam, p);
    addNoise(img, 2.0, 10);
    const Truth t = truthOf(kCam, p);
    std::array<cv::Point2d, 4> centres, corners;
    for (int i = 0; i < 4; ++i) {  // (a start off the truth by a third of a pixel)
      corners[i] = t.corners[i] + cv::Point2d(0.3, -0.2);
      centres[i] = t.centres[i] + cv::Point2d(0.3, -0.2);
    }
    const auto start_centres = centres, start_corners = corners;
    EXPECT_FALSE(ld::detail::alignSheet(img, nullptr, far_model, 10, centres, corners, scratch)) << distance;
    EXPECT_EQ(centres, start_centres);
    const bool aligned = ld::detail::alignSheet(img, nullptr, far_model, 10, centres, corners, scratch, &near_model);
    if (distance > 0.5) {
      ASSERT_TRUE(aligned);
      for (int i = 0; i < 4; ++i) {
        EXPECT_LT(cv::norm(corners[i] - t.corners[i]), 0.15) << "corner " << i;
        EXPECT_LT(cv::norm(centres[i] - t.centres[i]), 0.15) << "centre " << i;
      }
    } else {
      EXPECT_FALSE(aligned);  // (a sheet of about 530 px)
      EXPECT_EQ(corners, start_corners);
    }
  }
}

// align_iterations' default (-1, auto): a detector that computes poses
// aligns the sheet (its corners are align_iterations 10's, not the
// centroids'), one without a camera does not (its corners are
// align_iterations 0's), and the paper's settings never do.
TEST(SheetAlignment, OnByDefaultWhenAPoseIsComputed) {
  cv::Mat img = background(kCam.size, 7);
  drawSheet(img, kCam, place(2.0, 25, 40));
  addNoise(img, 2.0, 8);
  ld::DetectorParams off, ten;
  off.align_iterations = 0;
  ten.align_iterations = ld::DetectorParams::kAutoAlignIterations;
  EXPECT_EQ(ld::DetectorParams().align_iterations, -1);
  EXPECT_EQ(ld::DetectorParams::paper().align_iterations, 0);
  const auto corners = [&img](const ld::DetectorParams& params, bool with_camera) {
    ld::Detector det(params);
    if (with_camera) det.setCamera(kCam, 0.15);
    const auto& d = det.detect(img);
    EXPECT_EQ(d.landmarks.size(), 1u);
    EXPECT_EQ(d.landmarks.empty() ? false : d.landmarks[0].pose.has_value(), with_camera);
    return d.landmarks.empty() ? std::array<cv::Point2f, 4>{} : d.landmarks[0].corners;
  };
  const auto centroids = corners(off, true), aligned = corners(ten, true);
  ASSERT_NE(centroids, aligned);  // (the alignment moves them at 2 m)
  EXPECT_EQ(corners(ld::DetectorParams(), true), aligned);
  EXPECT_EQ(corners(ld::DetectorParams(), false), corners(off, false));
  EXPECT_EQ(corners(ld::DetectorParams(), false), centroids);
}

TEST(Params, SaveLoadRoundTrip) {
  ld::DetectorParams p;
  p.front_end = "paper";
  p.blur_kernel = 5;
  p.saturation_threshold = 0.41;
  p.value_min = 33;
  p.d_max = 6.25;
  p.max_candidates = 99;
  p.centre_iterations = 1;
  p.complete_missing = false;
  p.qr_washed_dip = 9;
  p.align_iterations = 7;
  const std::string path = tempPath("params.yaml");
  p.save(path);
  const ld::DetectorParams q = ld::DetectorParams::load(path);
  EXPECT_EQ(q.front_end, "paper");
  EXPECT_EQ(q.blur_kernel, 5);
  EXPECT_DOUBLE_EQ(q.saturation_threshold, 0.41);
  EXPECT_EQ(q.value_min, 33);
  EXPECT_DOUBLE_EQ(q.d_max, 6.25);
  EXPECT_EQ(q.max_candidates, 99);
  EXPECT_EQ(q.centre_iterations, 1);
  EXPECT_FALSE(q.complete_missing);
  EXPECT_DOUBLE_EQ(q.qr_washed_dip, 9);
  EXPECT_EQ(q.align_iterations, 7);
  EXPECT_DOUBLE_EQ(q.color_ratio_a, p.color_ratio_a);
  EXPECT_DOUBLE_EQ(q.sheet_min_value, p.sheet_min_value);
  std::remove(path.c_str());
  // true and false, as the tracker's file takes them (it was "must be 0 or 1")
  std::ofstream(path) << "complete_missing: false\n";
  const ld::DetectorParams b = ld::DetectorParams::load(path);
  EXPECT_FALSE(b.complete_missing);
  std::remove(path.c_str());
}

TEST(Params, PartialFileKeepsDefaults) {
  const std::string path = tempPath("partial.yaml");
  std::ofstream(path) << "%YAML:1.0\n---\nsaturation_threshold: 0.3\nd_min: 2\n";
  const ld::DetectorParams q = ld::DetectorParams::load(path);
  EXPECT_DOUBLE_EQ(q.saturation_threshold, 0.3);
  EXPECT_DOUBLE_EQ(q.d_min, 2.0);
  EXPECT_EQ(q.front_end, ld::DetectorParams{}.front_end);
  std::remove(path.c_str());
}

namespace {

std::string loadError(const std::string& content) {
  const std::string path = tempPath("bad.yaml");
  std::ofstream(path) << content;
  std::string msg;
  try {
    ld::DetectorParams::load(path);
  } catch (const std::runtime_error& e) {
    msg = e.what();
  }
  std::remove(path.c_str());
  return msg;
}

}  // namespace

TEST(Params, BadFilesGiveClearErrors) {
  EXPECT_NE(loadError("%YAML:1.0\n---\nsaturation_treshold: 0.3\n").find("unknown key 'saturation_treshold'"),
            std::string::npos);
  EXPECT_NE(loadError("%YAML:1.0\n---\nvalue_min: 2.5\n").find("'value_min' must be an integer"),
            std::string::npos);
  EXPECT_NE(loadError("%YAML:1.0\n---\nd_min: fast\n").find("'d_min' must be a number"), std::string::npos);
  EXPECT_NE(loadError("%YAML:1.0\n---\nfront_end: 3\n").find("'front_end' must be a string"), std::string::npos);
  EXPECT_NE(loadError("%YAML:1.0\n---\ncomplete_missing: 2\n").find("'complete_missing' must be 0 or 1"),
            std::string::npos);
  EXPECT_NE(loadError("%YAML:1.0\n---\n{ [ unbalanced").find("detector params"), std::string::npos);
  EXPECT_THROW(ld::DetectorParams::load("/nonexistent/dir/params.yaml"), std::runtime_error);
  // Values are checked on loading, with the file's name and the value read.
  const std::string bad_front_end = loadError("%YAML:1.0\n---\nfront_end: papr\n");
  EXPECT_NE(bad_front_end.find("detector params "), std::string::npos) << bad_front_end;
  EXPECT_NE(bad_front_end.find(".yaml: front_end must be \"fast\" or \"paper\", not \"papr\""), std::string::npos)
      << bad_front_end;
  EXPECT_NE(loadError("%YAML:1.0\n---\nd_min: -5\n").find(".yaml: d_min must be > 0"), std::string::npos);
  // integers beyond 32 bits are refused by line (OpenCV wrapped 4294967299 to 3)
  EXPECT_NE(loadError("%YAML:1.0\n---\nd_min: 1.5 # 99999999999\nmax_candidates: 4294967299\n")
                .find("line 4: the integer 4294967299 is out of range"),
            std::string::npos);
  EXPECT_NE(loadError("max_cycles: -99999999999\n").find("line 1: the integer -99999999999 is out of range"),
            std::string::npos);
  // a leading 0 is octal to OpenCV (value_min: 040 loaded as 32)
  EXPECT_NE(loadError("value_min: 040\n").find("line 1: the integer 040 has a leading 0, and OpenCV reads it as octal (32)"),
            std::string::npos)
      << loadError("value_min: 040\n");
  EXPECT_NE(loadError("value_min: 09\n").find("line 1: the integer 09 has a leading 0, and OpenCV reads no octal"),
            std::string::npos);
  EXPECT_NE(loadError("max_cycles: 037777777777\n")
                .find("the integer 037777777777 has a leading 0, and OpenCV reads it as octal, out of range"),
            std::string::npos)
      << loadError("max_cycles: 037777777777\n");
  // not in quoted text, a time's minutes, nor 00 (0 either way): the key's own check says what is wrong
  EXPECT_NE(loadError("front_end: \"fast 01\"\n").find("front_end must be"), std::string::npos)
      << loadError("front_end: \"fast 01\"\n");
  EXPECT_EQ(loadError("front_end: 10:05\n").find("leading 0"), std::string::npos) << loadError("front_end: 10:05\n");
  EXPECT_EQ(loadError("value_min: 00\n"), "");
  // booleans as the tracker's file takes them, true and false, besides 1 and 0
  EXPECT_NE(loadError("complete_missing: yes\n").find("'complete_missing' must be 0 or 1 (or false or true)"),
            std::string::npos);
  // bounds that keep a frame's time and memory bounded: no infinite number
  // (d_max .inf let the FIP graph take every pair), max_cycles up to 1e6
  EXPECT_NE(loadError("d_max: .inf\n").find(".yaml: d_max must be a finite number"), std::string::npos);
  EXPECT_NE(loadError("w_max: .Inf\n").find(".yaml: w_max must be a finite number"), std::string::npos);
  EXPECT_NE(loadError("max_cycles: 2000000000\n").find(".yaml: max_cycles must be in [1, 1000000]"), std::string::npos);
  EXPECT_EQ(loadError("max_cycles: 1000000\n"), "");
  // a UTF-8 byte order mark is no part of the first key ("unknown key 'd_min'" before)
  EXPECT_EQ(loadError("\xEF\xBB\xBF" "d_min: 1.5\n"), "");
}

// A comment after a string value is a comment (OpenCV's parser keeps it in
// the string), as after a number.
TEST(Params, CommentsAfterValues) {
  const std::string path = tempPath("comments.yaml");
  std::ofstream(path) << "front_end: paper          # fast (default) | paper\n"
                         "backend: cpu\t# cpu | gles | auto\n"
                         "d_min: 1.7   # centre distance\n";
  const ld::DetectorParams q = ld::DetectorParams::load(path);
  EXPECT_EQ(q.front_end, "paper");
  EXPECT_EQ(q.backend, "cpu");
  EXPECT_DOUBLE_EQ(q.d_min, 1.7);
  std::remove(path.c_str());
}

// Every configuration reader opens its file the same way (openConfigFile):
// a missing file names itself, and plain YAML without OpenCV's "%YAML:1.0"
// line is read like the tracker's parameters always were.
TEST(Params, FilesOpenLikeEveryConfigFile) {
  try {
    ld::DetectorParams::load("/nonexistent/dir/params.yaml");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("detector params /nonexistent/dir/params.yaml: cannot open: No such file or directory"), std::string::npos)
        << e.what();
  }
  try {
    ld::CameraModel::load("/nonexistent/dir/camera.yaml");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera file /nonexistent/dir/camera.yaml: cannot open"), std::string::npos)
        << e.what();
  }
  // (a file that never ends, /dev/zero, was read for ever)
  for (const auto& [file, why] : {std::pair{std::string("/tmp"), std::string("is a directory")},
                                  {tempPath("empty.yaml"), std::string("is empty")},
                                  {std::string("/dev/zero"), std::string("is larger than 16 MiB: not a configuration file")}}) {
    if (why == "is empty") std::ofstream(file) << "  \n";
    try {
      ld::DetectorParams::load(file);
      ADD_FAILURE() << file << ": no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(file + ": " + why), std::string::npos) << e.what();
    }
  }
  std::remove(tempPath("empty.yaml").c_str());
  const std::string path = tempPath("plain.yaml");
  std::ofstream(path) << "# no header\nsecond_looks: 2\nd_min: 2.0\n";
  const ld::DetectorParams q = ld::DetectorParams::load(path);
  EXPECT_EQ(q.second_looks, 2);
  EXPECT_DOUBLE_EQ(q.d_min, 2.0);
  std::remove(path.c_str());
}

// Malformed YAML on which OpenCV 4.6's parser never returns (found by
// fuzzing, tests/fuzz/opencv-hangs) is refused with one line, after the
// child process that tried it is given up, in the parameter and calibration
// readers; the process goes on and reads a good file after it.
TEST(Params, FileOpenCvLoopsOnIsRefused) {
  const std::string path = tempPath("loops.yml");
  {
    const std::string text = "%YAML:1.0\n   rows: 1\nows-02 ]\nx";  // (tests/fuzz/opencv-hangs/yaml-hang-memory.yml)
    std::ofstream(path) << text;
    for (const std::string& what : {std::string("detector params"), std::string("camera file")}) {
      try {
        if (what == "camera file")
          ld::CameraModel::load(path);
        else
          ld::DetectorParams::load(path);
        ADD_FAILURE() << what << ": no error for " << text;
      } catch (const std::runtime_error& e) {
        EXPECT_EQ(std::string(e.what()), what + " " + path +
                                             ": OpenCV's parser does not finish on it (given up after 5 s: "
                                             "malformed YAML?)");
      }
    }
  }
  std::ofstream(path) << "%YAML:1.0\n---\nd_min: 2.5\n";
  EXPECT_DOUBLE_EQ(ld::DetectorParams::load(path).d_min, 2.5);
  std::remove(path.c_str());
}

// A file OpenCV's parser takes or refuses in its own time is told apart from
// one it loops on, and leaves no child behind.
TEST(Params, ParserFailureOnlyForLoops) {
  EXPECT_EQ(ld::parserFailure("%YAML:1.0\n---\na: 1\n"), std::nullopt);
  EXPECT_EQ(ld::parserFailure("%YAML:1.0\n---\na: [1\n"), std::nullopt);  // (OpenCV throws: the caller says so)
  EXPECT_EQ(ld::parserFailure("<?xml version=\"1.0\"?>\n<opencv_storage><a>1</a></opencv_storage>\n"), std::nullopt);
  const auto loops = ld::parserFailure("%YAML:1.0\n   rows: 1\nows-02 ]\nx", std::chrono::seconds(1));
  ASSERT_TRUE(loops.has_value());
  EXPECT_EQ(*loops, "OpenCV's parser does not finish on it (given up after 1 s: malformed YAML?)");
  const pid_t left = ::waitpid(-1, nullptr, WNOHANG);
  const int why = errno;
  EXPECT_EQ(left, -1);  // no child left (ECHILD)
  EXPECT_EQ(why, ECHILD);
}

// A key given twice (cv::FileStorage would read the first and ignore the
// second without a word) is refused, in any format and at any depth, naming
// the key; a file without one reads as before.
TEST(Params, KeyGivenTwiceIsRefused) {
  const std::string path = tempPath("twice.yaml");
  for (const auto& [text, key] :
       {std::pair{std::string("align_iterations: 5\nd_min: 2.0\nalign_iterations: 6\n"), std::string("align_iterations")},
        {"{\"d_min\": 2.0, \"d_min\": 2.5}", "d_min"},
        {"<?xml version=\"1.0\"?>\n<opencv_storage>\n<d_max>9</d_max>\n<d_max>8</d_max>\n</opencv_storage>\n", "d_max"},
        {"camera_matrix:\n  rows: 3\n  rows: 3\n", "camera_matrix.rows"},
        {"views:\n  - { a: 1, b: 2 }\n  - { a: 3, a: 4 }\n", "views.[1].a"}}) {
    std::ofstream(path) << text;
    try {
      ld::DetectorParams::load(path);
      ADD_FAILURE() << text << ": no error";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": key '" + key + "' is given twice"), std::string::npos) << e.what();
    }
  }
  // (every reader: a calibration too)
  std::ofstream(path) << "image_width: 640\nimage_height: 480\nimage_width: 320\n";
  try {
    ld::CameraModel::load(path);
    ADD_FAILURE() << "camera file: no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("camera file " + path + ": key 'image_width' is given twice"),
              std::string::npos) << e.what();
  }
  // the same keys in a sequence's maps, each once, are no repeat
  std::ofstream(path) << "%YAML:1.0\n---\nd_min: 2.0\nviews:\n  - { a: 1, b: 2 }\n  - { a: 3, b: 4 }\n";
  EXPECT_FALSE(ld::duplicateKey(cv::FileStorage(path, cv::FileStorage::READ).root()).has_value());
  std::ofstream(path) << "align_iterations: 5\nd_min: 2.0\n";
  EXPECT_EQ(ld::DetectorParams::load(path).align_iterations, 5);
  std::remove(path.c_str());
}

TEST(Params, ValidateNamesTheField) {
  auto err = [](auto&& mutate) {
    ld::DetectorParams p;
    mutate(p);
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(err([](auto&) {}), "");
  EXPECT_NE(err([](auto& p) { p.front_end = "gpu"; }).find("front_end"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.blur_kernel = 4; }).find("blur_kernel"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.blur_kernel = 33; }).find("blur_kernel must be -1, 0 or an odd number from 1 to 31"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.saturation_threshold = 1.5; }).find("saturation_threshold"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.d_max = p.d_min; }).find("d_max"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.canny_high = 1; }).find("canny_high"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.ap_size_min = 0; }).find("ap_size_min"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.faint_look_blue = 0; }).find("faint_look_blue"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.qr_washed_dip = -1; }).find("qr_washed_dip"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.align_iterations = 101; }).find("align_iterations"), std::string::npos);
  EXPECT_NE(err([](auto& p) { p.align_iterations = -2; }).find("align_iterations"), std::string::npos);
  // a sigma where the fast front end has no blur (it was taken, and nothing blurred)
  EXPECT_NE(err([](auto& p) { p.blur_sigma = 20; }).find("blur_sigma is for a blur, and the fast front end has none"),
            std::string::npos);
  EXPECT_EQ(err([](auto& p) { p.blur_sigma = 2; p.blur_kernel = 5; }), "");
  ld::DetectorParams paper;
  paper.front_end = "paper";
  EXPECT_EQ(ld::detail::FilterSettings::from(paper).blur_sigma, 3.0);  // (the paper's own)
  paper.blur_sigma = 1.5;  // its own kernel takes a sigma given (it was dropped for 3)
  EXPECT_EQ(ld::detail::FilterSettings::from(paper).blur_kernel, 9);
  EXPECT_EQ(ld::detail::FilterSettings::from(paper).blur_sigma, 1.5);
  ld::DetectorParams bad;
  bad.front_end = "x";
  EXPECT_THROW(ld::Detector{bad}, std::invalid_argument);
}

// A sticker on the sheet (an inventory label, a highlighter's mark) where
// the sheet is sampled between two squares: one spot of a colour that no
// ink, poster or look-alike shows here (yellow to cyan) is let through; a
// red or blue one (the colours look-alikes bring onto the "sheet") and two
// spots are refused, as before.
TEST(Detector, ASpotOfColourOnTheSheet) {
  const auto withSpots = [](std::initializer_list<std::pair<cv::Point2d, cv::Scalar>> spots) {
    cv::Mat art = artworkImage().clone();
    const double u = art.cols / 9.0;
    for (const auto& [at, colour] : spots)
      cv::circle(art, at * u, static_cast<int>(0.7 * u), colour, -1, cv::LINE_AA);
    return art;
  };
  const cv::Point2d top(4.5, 1.5), left(1.5, 4.5);  // between TL and TR, between TL and BL
  const cv::Scalar yellow(40, 200, 230), green(60, 170, 60), red(50, 60, 210), blue(170, 90, 40);
  struct Case {
    const char* what;
    cv::Mat art;
    bool found;
  };
  const Case cases[] = {{"yellow", withSpots({{top, yellow}}), true},
                        {"green", withSpots({{top, green}}), true},
                        {"red", withSpots({{top, red}}), false},
                        {"blue", withSpots({{top, blue}}), false},
                        {"two yellow", withSpots({{top, yellow}, {left, yellow}}), false}};
  for (const Case& c : cases) {
    int found = 0, n = 0;
    for (double dist : {1.0, 1.5})
      for (double yaw : {-40.0, 0.0, 40.0})
        for (double roll : {0.0, 120.0}) {
          cv::Mat img = background(kCam.size, 11 + n);
          Placed p = place(dist, yaw, roll, 0.15, 0.05, -0.02);
          p.artwork = c.art;
          drawSheet(img, kCam, p);
          cv::GaussianBlur(img, img, {0, 0}, 0.7);
          addNoise(img, 2, 5 + n);
          ++n;
          found += onlyLandmark(ld::Detector().detect(img), truthOf(kCam, p));
        }
    EXPECT_EQ(found, c.found ? n : 0) << c.what << " spot";
  }
  // The adaptive detector's white balance is learnt on the same samples: the
  // sticker's colour is not taken for the light's (it pulled blue up by a
  // quarter, kept over frames).
  cv::Mat img = background(kCam.size, 3);
  Placed p = place(1.0, 20, 0, 0.15, 0.05, -0.02);
  p.artwork = cases[0].art;
  drawSheet(img, kCam, p);
  addNoise(img, 2, 5);
  ld::AdaptiveDetector adaptive(ld::Detector(), true);
  for (int frame = 0; frame < 10; ++frame) EXPECT_TRUE(onlyLandmark(adaptive.detect(img), truthOf(kCam, p))) << frame;
  const cv::Vec3d g = adaptive.adapter().gains();
  EXPECT_LT(std::max({g[0], g[1], g[2]}) / std::min({g[0], g[1], g[2]}), 1.08) << g;
}

// A landmark wrapped round a pillar (its vertical axis along the sheet's y):
// the sheet is no longer a plane and the squares' layout bends, more the
// thinner the pillar. Rendered by casting each (supersampled) pixel's ray
// on to the cylinder. Found on pillars down to 20 cm across; the QR read
// from close by down to 30 cm.
namespace {
cv::Point3d onPillar(double xf, double yf, double R) {
  if (R <= 0) return {xf, yf, 0};
  const double th = xf / R;
  return {R * std::sin(th), yf, R * (1 - std::cos(th))};
}
// A lamp to one side, `light_deg` off the sheet's normal (round its
// vertical axis, + to its right), shades the paper by Lambert's law over
// an `ambient` share of light that comes from everywhere (1: no lamp).
struct SideLight {
  double light_deg = 0, ambient = 1;
};
void drawPillarSheet(cv::Mat& img, const ld::CameraModel& cam, const Placed& p, double R, SideLight light = {}) {
  const int ss = 3;
  const cv::Mat& art = p.artwork;
  const double n = art.cols, S = p.side_m;
  const cv::Matx33d Kinv = cam.K.inv(), Rt = p.R.t();
  const cv::Vec3d C = -(Rt * p.t);
  const double phi = light.light_deg * CV_PI / 180;
  cv::Mat mapx(img.rows * ss, img.cols * ss, CV_32F, cv::Scalar(-1)), mapy = mapx.clone();
  cv::Mat shade(mapx.size(), CV_32F, cv::Scalar(1));
  for (int v = 0; v < mapx.rows; ++v)
    for (int u = 0; u < mapx.cols; ++u) {
      const cv::Vec3d ray = Rt * (Kinv * cv::Vec3d((u + 0.5) / ss - 0.5, (v + 0.5) / ss - 0.5, 1.0));
      double lam;
      if (R <= 0) {
        if (std::abs(ray[2]) < 1e-12) continue;
        lam = -C[2] / ray[2];
      } else {
        // (Cx + l dx)^2 + (Cz + l dz - R)^2 = R^2
        const double a = ray[0] * ray[0] + ray[2] * ray[2];
        const double b = 2 * (C[0] * ray[0] + (C[2] - R) * ray[2]);
        const double c = C[0] * C[0] + (C[2] - R) * (C[2] - R) - R * R;
        const double disc = b * b - 4 * a * c;
        if (disc < 0) continue;
        lam = (-b - std::sqrt(disc)) / (2 * a);
      }
      if (lam <= 0) continue;
      const cv::Vec3d X = C + lam * ray;
      const double s = R <= 0 ? X[0] : R * std::atan2(X[0], R - X[2]);
      const double tx = (s / S + 0.5) * n - 0.5, ty = (X[1] / S + 0.5) * n - 0.5;
      if (tx < 0 || ty < 0 || tx > n - 1 || ty > n - 1) continue;
      mapx.at<float>(v, u) = static_cast<float>(tx);
      mapy.at<float>(v, u) = static_cast<float>(ty);
      const double th = R <= 0 ? 0 : s / R;  // the surface's normal turns by th
      const double lambert = std::max(0.0, std::sin(th) * std::sin(phi) + std::cos(th) * std::cos(phi));
      shade.at<float>(v, u) = static_cast<float>(light.ambient + (1 - light.ambient) * lambert);
    }
  cv::Mat big;
  cv::remap(art, big, mapx, mapy, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  if (light.ambient < 1) {
    big.convertTo(big, CV_32FC3);
    cv::Mat shade3;
    cv::merge(std::vector<cv::Mat>{shade, shade, shade}, shade3);
    big = big.mul(shade3);
    big.convertTo(big, CV_8UC3);
  }
  cv::Mat inside = (mapx >= 0);
  cv::Mat bg;
  cv::resize(img, bg, big.size(), 0, 0, cv::INTER_NEAREST);
  big.copyTo(bg, inside);
  cv::resize(bg, img, img.size(), 0, 0, cv::INTER_AREA);
}
}  // namespace

TEST(Detector, LandmarkWrappedRoundAPillar) {
  ld::QrReader reader;
  for (double R : {0.3, 0.15, 0.1}) {  // pillars of 60, 30 and 20 cm across, for a 15 cm sheet
    int found_here = 0, n = 0, read_close = 0;
    for (double dist : {0.5, 1.0, 1.5})
      for (double yaw : {-30.0, 0.0, 30.0})
        for (double roll : {0.0, 10.0}) {
          cv::Mat img = background(kCam.size, 11 + n);
          const Placed p = place(dist, yaw, roll, 0.15, 0.05, -0.02);
          drawPillarSheet(img, kCam, p, R);
          cv::GaussianBlur(img, img, {0, 0}, 0.7);
          addNoise(img, 2, 5 + n);
          Truth t;
          const auto cs = layout::objectCentres(0.15);
          for (int i = 0; i < 4; ++i) t.centres[i] = project(kCam, p, onPillar(cs[i].x, cs[i].y, R));
          const ld::Detection det = ld::Detector().detect(img);
          found_here += found(det, t);
          if (dist == 0.5 && !det.landmarks.empty()) {
            const auto r = reader.decode(img, det.landmarks[0].corners);
            read_close += r && r->payload == "room-214/door";
          }
          ++n;
        }
    EXPECT_EQ(found_here, n) << "pillar radius " << R;
    // The QR, from close by: through the flat sheet's homography its middle
    // is off by up to two modules at 30 degrees (4 of 6 on the 30 cm pillar);
    // the reader's bent-sheet path follows the QR's own finders and timing.
    if (R >= 0.15) {
      EXPECT_EQ(read_close, 6) << "QR on a pillar of radius " << R << " at 0.5 m";
    }
  }
}

// A glossy (laminated) sheet's reflection lying on the QR alone: a soft
// band of white light across the QR square, the four squares untouched.
// The QR's white modules clip and its mean comes near the sheet's, as under
// glare over the whole sheet; here the sheet is not at the clip, but points
// of the QR brighter than any of the sheet tell the reflection, and the
// QR's dark modules are the evidence. (Before: 21 of 24 found.)
TEST(Detector, AReflectionOnTheQrAlone) {
  int found_n = 0, n = 0;
  for (double dist : {0.6, 1.0})
    for (double yaw : {-25.0, 25.0})
      for (double band_deg : {20.0, 75.0, 130.0})
        for (double strength : {0.5, 0.8}) {
          cv::Mat img = background(kCam.size, 7 + n, true);
          const Placed p = place(dist, yaw, 15, 0.15, 0, 0);
          drawSheet(img, kCam, p);
          const Truth t = truthOf(kCam, p);
          // image -> sheet units (the pattern square is [0.5, 8.5] u)
          const std::vector<cv::Point2f> img_pts(t.corners.begin(), t.corners.end());
          const std::vector<cv::Point2f> sheet_pts{{0.5f, 0.5f}, {8.5f, 0.5f}, {8.5f, 8.5f}, {0.5f, 8.5f}};
          const cv::Matx33d H = cv::getPerspectiveTransform(img_pts, sheet_pts);
          const double a = band_deg * CV_PI / 180;
          for (int y = 0; y < img.rows; ++y)
            for (int x = 0; x < img.cols; ++x) {
              const cv::Vec3d q = H * cv::Vec3d(x, y, 1);
              const double u = q[0] / q[2], v = q[1] / q[2];
              if (u < 2.5 || u > 6.5 || v < 2.5 || v > 6.5) continue;  // the QR square only
              const double across = std::abs((u - 4.5) * std::cos(a) + (v - 4.5) * std::sin(a));  // from the band's middle
              const double light = strength * 255 * std::exp(-across * across / (2 * 0.6 * 0.6));
              auto& px = img.at<cv::Vec3b>(y, x);
              for (int k = 0; k < 3; ++k) px[k] = cv::saturate_cast<uint8_t>(px[k] + light);
            }
          cv::GaussianBlur(img, img, {0, 0}, 0.6);
          addNoise(img, 2, 3 + n);
          ++n;
          found_n += onlyLandmark(ld::Detector().detect(img), t);
        }
  std::printf("a reflection on the QR alone: found %d of %d\n", found_n, n);
  // (the one left: at 1 m the strongest band leaves under 4 dark points in
  // the QR's middle)
  EXPECT_GE(found_n, n - 1);
}

// A light falling off across the sheet: a lamp to one side of a pillar the
// landmark is wrapped round (the far side in little more than the room's
// ambient light), and a flat sheet close to a lamp (the paper three times
// as bright at one edge as at the other). The paper is neither even nor a
// shadow's two parts; verification takes its light for a plane over the
// image and holds the paper where each FIP lies brighter than the FIP.
// (Before: none found on the 30 and 20 cm pillars, 32 of 36 flat sheets.)
TEST(Detector, LightFallingOffAcrossTheSheet) {
  for (double R : {0.3, 0.15, 0.1}) {
    int found_here = 0, n = 0;
    for (double light : {-50.0, 50.0})
      for (double dist : {0.5, 1.0})
        for (double yaw : {-30.0, 0.0, 30.0}) {
          cv::Mat img = background(kCam.size, 17 + n);
          const Placed p = place(dist, yaw, 10, 0.15, 0.05, -0.02);
          drawPillarSheet(img, kCam, p, R, {light, 0.25});
          cv::GaussianBlur(img, img, {0, 0}, 0.7);
          addNoise(img, 2, 5 + n);
          Truth t;
          const auto cs = layout::objectCentres(0.15);
          for (int i = 0; i < 4; ++i) t.centres[i] = project(kCam, p, onPillar(cs[i].x, cs[i].y, R));
          const bool ok = found(ld::Detector().detect(img), t);
          found_here += ok;
          EXPECT_TRUE(ok) << "pillar radius " << R << ", light " << light << " deg, " << dist << " m, yaw " << yaw;
          ++n;
        }
    std::printf("pillar radius %.2f m lit from the side: found %d of %d\n", R, found_here, n);
  }
  int found_flat = 0, n = 0;
  for (double dist : {0.6, 1.0, 1.5})
    for (double towards_deg : {0.0, 45.0, 90.0, 135.0, 200.0, 290.0})
      for (double yaw : {0.0, 30.0}) {
        cv::Mat img = background(kCam.size, 43, true);
        const Placed p = place(dist, yaw, 20, 0.15, 0, 0);
        drawSheet(img, kCam, p);
        const Truth t = truthOf(kCam, p);
        const cv::Point2d c = (t.corners[0] + t.corners[2]) / 2;
        const double reach = 0.6 * cv::norm(t.corners[2] - t.corners[0]);
        const double a = towards_deg * CV_PI / 180;
        const cv::Point2d dir(std::cos(a), std::sin(a));
        for (int y = 0; y < img.rows; ++y)
          for (int x = 0; x < img.cols; ++x) {
            const double s = std::clamp((cv::Point2d(x, y) - c).dot(dir) / reach, -1.0, 1.0);
            auto& q = img.at<cv::Vec3b>(y, x);
            for (int k = 0; k < 3; ++k) q[k] = cv::saturate_cast<uint8_t>(q[k] * (1.0 - 0.7 * (s + 1) / 2));
          }
        addNoise(img, 2, 7);
        const bool ok = onlyLandmark(ld::Detector().detect(img), t);
        found_flat += ok;
        EXPECT_TRUE(ok) << "flat sheet, " << dist << " m, yaw " << yaw << ", lit from " << towards_deg << " deg";
        ++n;
      }
  std::printf("flat sheets three times as bright at one edge: found %d of %d\n", found_flat, n);
}
