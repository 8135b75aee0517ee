// ld-synth: the ground truth is where the rendered landmark is (to a fraction
// of a pixel, at steep angles and upside down, with and without distortion),
// the pose conventions are the documented ones, rendering is deterministic,
// lighting and degradation do what they say, and the sequence writer makes a
// readable LCM log with the right timestamps and sequence numbers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <tuple>

#include <unistd.h>

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/image_convert.hpp"
#include "ld/landmark_layout.hpp"
#include "ld/synth.hpp"

#include "../tools/synth/src/synth_detail.hpp"

namespace fs = std::filesystem;
using namespace ld::synth;
namespace layout = ld::layout;

namespace {

enum class Colour { Blue, Red, White, Other };

// Classification by channel dominance (BGR pixel).
Colour classify(const cv::Vec3b& p) {
  const int b = p[0], g = p[1], r = p[2];
  if (b > r + 25 && b > g + 25) return Colour::Blue;
  if (r > g + 40 && r > b + 40) return Colour::Red;
  if (std::min({b, g, r}) >= 200 && std::max({b, g, r}) - std::min({b, g, r}) <= 20) return Colour::White;
  return Colour::Other;
}

const char* name(Colour c) {
  switch (c) {
    case Colour::Blue: return "blue";
    case Colour::Red: return "red";
    case Colour::White: return "white";
    case Colour::Other: break;
  }
  return "other";
}

// A clean scene: plain wall, no distractors, no lighting change, no degradation.
SceneSpec cleanScene(const ld::CameraModel& cam, std::vector<LandmarkPlacement> lms, uint64_t seed = 1) {
  SceneSpec s;
  s.camera = cam;
  s.landmarks = std::move(lms);
  s.background = Background::Plain;
  s.distractors = 0;
  s.landmark_like_cards = 0;
  s.seed = seed;
  return s;
}

// Image points of sheet points given in units u (sheet frame, top-left origin).
std::vector<cv::Point2f> project(const ld::CameraModel& cam, const LandmarkPlacement& lm,
                                 const std::vector<std::array<double, 2>>& pts_u) {
  std::vector<cv::Point3d> obj;
  for (const auto& p : pts_u) obj.push_back(layout::objectPoint(p, lm.side_m));
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, lm.rvec, lm.tvec, cv::Mat(cam.K), cam.dist, img);
  return {img.begin(), img.end()};
}

// The image quadrilateral of coloured square k (TL, TR, BL, AP).
std::vector<cv::Point2f> squareQuad(const ld::CameraModel& cam, const LandmarkPlacement& lm, int k) {
  const auto& c = layout::kCentresU[static_cast<size_t>(k)];
  const double h = layout::kSquareSide / 2;
  return project(cam, lm, {{c[0] - h, c[1] - h}, {c[0] + h, c[1] - h}, {c[0] + h, c[1] + h}, {c[0] - h, c[1] + h}});
}

// Centroid of the ink of square k, each pixel within 1.5 px of the projected
// square weighted by how much ink it holds (a linear measure: blue by B - R,
// red by R - B, between paper and ink of the printed colours).
cv::Point2d inkCentroid(const cv::Mat& img, const std::vector<cv::Point2f>& quad, bool red) {
  const cv::Rect box = cv::boundingRect(quad) + cv::Size(4, 4) - cv::Point(2, 2);
  const auto ink = printedInk();
  const double paper = red ? ink.white[2] - ink.white[0] : ink.white[0] - ink.white[2];
  const double full = red ? ink.red[2] - ink.red[0] : ink.blue[0] - ink.blue[2];
  double sw = 0, sx = 0, sy = 0;
  for (int y = std::max(0, box.y); y < std::min(img.rows, box.br().y); ++y)
    for (int x = std::max(0, box.x); x < std::min(img.cols, box.br().x); ++x) {
      if (cv::pointPolygonTest(quad, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), true) < -1.5) continue;
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      const double v = red ? p[2] - p[0] : p[0] - p[2];
      const double w = std::clamp((v - paper) / (full - paper), 0.0, 1.0);
      sw += w;
      sx += w * x;
      sy += w * y;
    }
  return sw > 0 ? cv::Point2d(sx / sw, sy / sw) : cv::Point2d(-1, -1);
}

cv::Vec3b at(const cv::Mat& img, cv::Point2d p) {
  return img.at<cv::Vec3b>(static_cast<int>(std::lround(p.y)), static_cast<int>(std::lround(p.x)));
}

struct Checked {
  int corners = 0;
};

// Every check of the ground truth against the rendered frame.
// tol: how far the ink centroid of each square may be from the image of its
// centre (perspective alone moves it a few tenths of a pixel at 0.6 m); it
// must be within tol / 4 of the exact area centroid of the projected square.
void expectTruthMatchesPixels(const ld::CameraModel& cam, const LandmarkPlacement& lm, const cv::Mat& img,
                              const LandmarkTruth& t, double tol, Checked& checked, const std::string& what,
                              double area_tol = -1) {
  if (area_tol < 0) area_tol = tol / 4;
  SCOPED_TRACE(what);
  ASSERT_TRUE(t.in_view);
  const cv::Point2d centres[4] = {t.fip_tl, t.fip_tr, t.fip_bl, t.ap};
  for (int k = 0; k < 4; ++k) {
    const bool red = k == layout::kAp;
    const Colour c = classify(at(img, centres[k]));
    EXPECT_EQ(c, red ? Colour::Red : Colour::Blue) << "square " << k << " centre pixel is " << name(c);
    const auto quad = squareQuad(cam, lm, k);
    const cv::Point2d m = inkCentroid(img, quad, red);
    EXPECT_LT(cv::norm(m - centres[k]), tol) << "square " << k << " ink centroid " << m << " vs truth " << centres[k];
    const cv::Moments mo = cv::moments(quad);
    const cv::Point2d area_centroid(mo.m10 / mo.m00, mo.m01 / mo.m00);
    EXPECT_LT(cv::norm(m - area_centroid), area_tol) << "square " << k << " ink centroid " << m << " vs area centroid " << area_centroid;
  }
  // Corners: just inside along the diagonal is the square's ink, just outside
  // is paper (checked where both points are clear of every edge by 1.2 px).
  const int corner_square[4] = {layout::kFipTl, layout::kFipTr, layout::kAp, layout::kFipBl};
  const auto sheet = project(cam, lm, {{0, 0}, {9, 0}, {9, 9}, {0, 9}});
  for (size_t i = 0; i < 4; ++i) {
    const auto& cu = layout::kCornersU[i];
    const double dx = cu[0] < 4.5 ? 1 : -1, dy = cu[1] < 4.5 ? 1 : -1, d = 0.25;
    const auto pts = project(cam, lm, {cu, {cu[0] + d * dx, cu[1] + d * dy}, {cu[0] - d * dx, cu[1] - d * dy}});
    EXPECT_LT(cv::norm(cv::Point2d(pts[0]) - t.corners[i]), 1e-3);
    const auto quad = squareQuad(cam, lm, corner_square[i]);
    const bool in_ok = cv::pointPolygonTest(quad, pts[1], true) >= 1.2;
    const bool out_ok = cv::pointPolygonTest(quad, pts[2], true) <= -1.2 && cv::pointPolygonTest(sheet, pts[2], true) >= 1.2;
    const cv::Rect inside(1, 1, img.cols - 2, img.rows - 2);
    if (!in_ok || !out_ok || !inside.contains(pts[1]) || !inside.contains(pts[2])) continue;
    ++checked.corners;
    const Colour ink = corner_square[i] == layout::kAp ? Colour::Red : Colour::Blue;
    EXPECT_EQ(classify(at(img, pts[1])), ink) << "inside corner " << i;
    EXPECT_EQ(classify(at(img, pts[2])), Colour::White) << "outside corner " << i << " " << at(img, pts[2]);
  }
}

ld::CameraModel distortedVga() {
  ld::CameraModel cam = ld::CameraModel::defaultVga();
  cam.dist = (cv::Mat_<double>(1, 5) << -0.28, 0.09, 0.0005, -0.0004, 0.0);
  return cam;
}

}  // namespace

// ---------------------------------------------------------------------------
// Pose conventions and truthFor.

TEST(SynthTruth, FrontalDistancesFollowFocalLength) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  for (double d : {0.5, 1.5, 3.0}) {
    const LandmarkPlacement lm = placeLandmark(cam, d, 0, 0, 0, 0, 0, 0.15, "x", 7);
    EXPECT_LT(cv::norm(lm.rvec), 1e-12);
    EXPECT_NEAR(lm.tvec[2], d, 1e-12);
    const LandmarkTruth t = truthFor(cam, lm);
    EXPECT_EQ(t.id, 7);
    EXPECT_EQ(t.payload, "x");
    EXPECT_NEAR(t.distance, d, 1e-12);
    const double f = cam.K(0, 0), u = 0.15 / 9;
    EXPECT_NEAR(cv::norm(t.fip_tr - t.fip_tl), f * 6 * u / d, 1e-9);
    EXPECT_NEAR(cv::norm(t.fip_bl - t.fip_tl), f * 6 * u / d, 1e-9);
    EXPECT_NEAR(cv::norm(t.ap - t.fip_tl), f * 6 * u / d * std::sqrt(2.0), 1e-9);
    EXPECT_NEAR(cv::norm(t.corners[1] - t.corners[0]), f * 8 * u / d, 1e-9);
    // Upright: TR to the right of TL, BL below it; the sheet centre on the axis.
    EXPECT_GT(t.fip_tr.x, t.fip_tl.x);
    EXPECT_NEAR(t.fip_tr.y, t.fip_tl.y, 1e-9);
    EXPECT_GT(t.fip_bl.y, t.fip_tl.y);
    EXPECT_NEAR((t.fip_tl.x + t.ap.x) / 2, cam.K(0, 2), 1e-9);
    EXPECT_TRUE(t.in_view);
  }
}

TEST(SynthTruth, AngleSignsAreTheDocumentedOnes) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  // + yaw: the right edge comes towards the camera, so the right column is taller.
  LandmarkTruth t = truthFor(cam, placeLandmark(cam, 1.0, 40, 0, 0));
  EXPECT_GT(cv::norm(t.ap - t.fip_tr), cv::norm(t.fip_bl - t.fip_tl) * 1.05);
  EXPECT_LT(cv::norm(t.fip_tr - t.fip_tl), 0.9 * 600 * 0.1);  // foreshortened
  // + pitch: the top edge comes towards the camera, so the top row is wider.
  t = truthFor(cam, placeLandmark(cam, 1.0, 0, 30, 0));
  EXPECT_GT(cv::norm(t.fip_tr - t.fip_tl), cv::norm(t.ap - t.fip_bl) * 1.05);
  // + roll: clockwise in the image (TR moves below TL at 90 degrees).
  t = truthFor(cam, placeLandmark(cam, 1.0, 0, 0, 90));
  EXPECT_NEAR(t.fip_tr.x, t.fip_tl.x, 1e-6);
  EXPECT_GT(t.fip_tr.y, t.fip_tl.y + 50);
  // Upside down: the AP is top-left of TL.
  t = truthFor(cam, placeLandmark(cam, 1.0, 0, 0, 180));
  EXPECT_LT(t.ap.x, t.fip_tl.x);
  EXPECT_LT(t.ap.y, t.fip_tl.y);
}

TEST(SynthTruth, RayThroughNormalisedImagePosition) {
  for (const ld::CameraModel& cam : {ld::CameraModel::defaultVga(), distortedVga()}) {
    for (const auto& [nx, ny] : {std::pair{1.0, 0.0}, {-1.0, 1.0}, {0.5, -0.25}}) {
      const LandmarkPlacement lm = placeLandmark(cam, 2.0, 10, 5, 30, nx, ny);
      std::vector<cv::Point2d> img;
      cv::projectPoints(std::vector<cv::Point3d>{{0, 0, 0}}, lm.rvec, lm.tvec, cv::Mat(cam.K), cam.dist, img);
      EXPECT_NEAR(img[0].x, (cam.size.width - 1) / 2.0 * (1 + nx), 1e-3);
      EXPECT_NEAR(img[0].y, (cam.size.height - 1) / 2.0 * (1 + ny), 1e-3);
      EXPECT_NEAR(cv::norm(lm.tvec), 2.0, 1e-12);
    }
  }
  // Off axis, yaw = 0 faces the camera: the sheet's normal points back along the ray.
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  const LandmarkPlacement lm = placeLandmark(cam, 2.0, 0, 0, 0, 0.8, -0.6);
  cv::Matx33d R;
  cv::Rodrigues(lm.rvec, R);
  const cv::Vec3d normal(R(0, 2), R(1, 2), R(2, 2));
  EXPECT_NEAR(normal.dot(lm.tvec / cv::norm(lm.tvec)), 1.0, 1e-12);
  EXPECT_NEAR(R(1, 0), 0.0, 1e-12);  // the sheet's x axis stays horizontal
}

TEST(SynthTruth, InViewOnlyWhenAllCornersAreInsideAndInFront) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  EXPECT_TRUE(truthFor(cam, placeLandmark(cam, 1.5, 0, 0, 0, 0.7, 0.5)).in_view);
  EXPECT_FALSE(truthFor(cam, placeLandmark(cam, 1.5, 0, 0, 0, 1.0, 0)).in_view);   // half out
  EXPECT_FALSE(truthFor(cam, placeLandmark(cam, 0.05, 0, 0, 0)).in_view);           // bigger than the view
  LandmarkPlacement behind = placeLandmark(cam, 1.5, 0, 0, 0);
  behind.tvec = {0, 0, -1.5};
  EXPECT_FALSE(truthFor(cam, behind).in_view);
  // Rendering them is fine, and their truth is reported (not in view).
  SceneSpec s = cleanScene(cam, {behind, placeLandmark(cam, 1.5, 0, 0, 0, 1.0, 0)});
  s.background = Background::Office;
  const Frame f = render(s);
  ASSERT_EQ(f.truth.size(), 2u);
  EXPECT_FALSE(f.truth[0].in_view);
  EXPECT_FALSE(f.truth[1].in_view);
  // The visible half of the second one is there: its TL FIP is blue.
  EXPECT_EQ(classify(at(f.bgr, f.truth[1].fip_tl)), Colour::Blue);
}

// ---------------------------------------------------------------------------
// The rendered landmark is where the truth says.

TEST(SynthRender, TruthMatchesPixelsAtSteepAnglesAndAnyRoll) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  const double yaws[] = {0, 25, -45, 60, -70, 80, -80};
  const double rolls[] = {0, 33, 90, 180, -120};
  const double pitches[] = {0, 7, -9};
  Checked checked;
  int n = 0;
  for (double yaw : yaws)
    for (double roll : rolls)
      for (double d : {0.6, 1.0, 1.6}) {
        if (std::abs(yaw) >= 70 && d > 1.2) continue;  // squares narrower than 2 px
        const double pitch = pitches[n++ % 3];
        const LandmarkPlacement lm = placeLandmark(cam, d, yaw, pitch, roll, 0, 0, 0.15, "room-214/door");
        const Frame f = render(cleanScene(cam, {lm}, static_cast<uint64_t>(n)));
        const bool frontal = std::abs(yaw) <= 30;
        expectTruthMatchesPixels(cam, lm, f.bgr, f.truth[0], frontal ? 0.5 : 1.0, checked,
                                 "yaw " + std::to_string(yaw) + " pitch " + std::to_string(pitch) +
                                     " roll " + std::to_string(roll) + " d " + std::to_string(d));
      }
  EXPECT_GT(checked.corners, n * 2);  // most corners were clear enough to check
}

TEST(SynthRender, TruthMatchesPixelsCloseUp) {
  // Sheets filling most of the frame take the coarser rendering paths.
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  Checked checked;
  for (const auto& [d, yaw, roll] : {std::tuple{0.17, 0.0, 0.0}, {0.19, 15.0, 180.0}, {0.3, -40.0, 60.0}}) {
    const LandmarkPlacement lm = placeLandmark(cam, d, yaw, 0, roll);
    const Frame f = render(cleanScene(cam, {lm}));
    // Squares of 70-100 px: perspective moves their centroids by pixels.
    expectTruthMatchesPixels(cam, lm, f.bgr, f.truth[0], yaw == 0 ? 0.5 : 3.0, checked,
                             "d " + std::to_string(d), yaw == 0 ? 0.1 : 0.3);
  }
  EXPECT_GE(checked.corners, 6);
}

TEST(SynthRender, TruthMatchesPixelsWithDistortion) {
  const ld::CameraModel cam = distortedVga();
  Checked checked;
  for (const auto& [nx, ny] : {std::pair{0.0, 0.0}, {0.7, 0.6}, {-0.75, -0.65}, {0.75, -0.6}}) {
    for (double roll : {0.0, 135.0}) {
      const LandmarkPlacement lm = placeLandmark(cam, 1.0, 20, 0, roll, nx, ny);
      const Frame f = render(cleanScene(cam, {lm}));
      expectTruthMatchesPixels(cam, lm, f.bgr, f.truth[0], 1.0, checked,
                               "nx " + std::to_string(nx) + " ny " + std::to_string(ny));
    }
  }
  EXPECT_GT(checked.corners, 16);
}

TEST(SynthRender, TruthMatchesPixelsAt1080p) {
  const ld::CameraModel cam = ld::CameraModel::pinhole({1920, 1080}, 1800);
  Checked checked;
  const LandmarkPlacement a = placeLandmark(cam, 2.5, -35, 5, 160, -0.5, 0.2, 0.15, "a", 0);
  const LandmarkPlacement b = placeLandmark(cam, 0.9, 50, -5, -30, 0.4, -0.1, 0.15, "b", 1);
  SceneSpec s = cleanScene(cam, {a, b});
  s.landmark_like_cards = 3;  // kept off the landmarks
  const Frame f = render(s);
  ASSERT_EQ(f.bgr.size(), cv::Size(1920, 1080));
  expectTruthMatchesPixels(cam, a, f.bgr, f.truth[0], 1.0, checked, "a");
  expectTruthMatchesPixels(cam, b, f.bgr, f.truth[1], 1.0, checked, "b");
}

TEST(SynthRender, PrintedAndNominalColours) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  const LandmarkPlacement lm = placeLandmark(cam, 0.8, 0, 0, 0);
  SceneSpec s = cleanScene(cam, {lm});
  Frame f = render(s);
  const auto ink = printedInk();
  EXPECT_EQ(at(f.bgr, f.truth[0].fip_tl), ink.blue);
  EXPECT_EQ(at(f.bgr, f.truth[0].ap), ink.red);
  // Paper between TL and TR.
  const auto paper = project(cam, lm, {{4.5, 1.5}});
  EXPECT_EQ(at(f.bgr, paper[0]), ink.white);
  s.printed_ink = false;
  f = render(s);
  EXPECT_EQ(at(f.bgr, f.truth[0].fip_tl), cv::Vec3b(255, 0, 0));
  EXPECT_EQ(at(f.bgr, f.truth[0].ap), cv::Vec3b(0, 0, 255));
}

TEST(SynthRender, CustomTextureCoversTheSheet) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  LandmarkPlacement lm = placeLandmark(cam, 1.0, 20, 0, 10);
  lm.texture = cv::Mat(90, 90, CV_8UC3, cv::Scalar(40, 200, 60));
  const Frame f = render(cleanScene(cam, {lm}));
  for (const auto& p : {f.truth[0].fip_tl, f.truth[0].ap, (f.truth[0].fip_tr + f.truth[0].fip_bl) / 2})
    EXPECT_EQ(at(f.bgr, p), cv::Vec3b(40, 200, 60));
}

// ---------------------------------------------------------------------------
// Determinism, backgrounds, distractors, lighting, degradation.

TEST(SynthRender, SameSeedSameBytesOtherSeedOtherPicture) {
  for (const ld::CameraModel& cam : {ld::CameraModel::defaultVga(), distortedVga()}) {
    const std::vector<LandmarkPlacement> lms{placeLandmark(cam, 1.2, 30, 5, 45, -0.3, 0.1),
                                             placeLandmark(cam, 2.0, -20, 0, 0, 0.5, -0.2, 0.15, "b", 1)};
    SceneSpec s = randomConditions(cam, lms, 42);
    s.landmark_like_cards = 3;
    s.degradation.jpeg_quality = 85;
    s.degradation.motion_px = 1.5;
    s.lighting.glare = 0.3;
    const Frame a = render(s), b = render(s);
    ASSERT_EQ(a.bgr.size(), cam.size);
    EXPECT_EQ(cv::norm(a.bgr, b.bgr, cv::NORM_INF), 0.0);
    SceneSpec s2 = randomConditions(cam, lms, 43);
    const Frame c = render(s2);
    cv::Mat diff;
    cv::absdiff(a.bgr, c.bgr, diff);
    cv::cvtColor(diff, diff, cv::COLOR_BGR2GRAY);
    EXPECT_GT(cv::countNonZero(diff > 20), static_cast<int>(diff.total() / 10));
    // The truth does not depend on the conditions.
    EXPECT_EQ(a.truth[1].fip_tl, c.truth[1].fip_tl);
  }
}

TEST(SynthRender, RandomConditionsStayInTheirRanges) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  int glare = 0, jpeg = 0;
  std::set<int> backgrounds;
  for (uint64_t seed = 1; seed <= 200; ++seed) {
    const SceneSpec s = randomConditions(cam, {}, seed);
    EXPECT_GE(s.lighting.gain, 0.7);
    EXPECT_LE(s.lighting.gain, 1.3);
    EXPECT_GE(s.lighting.colour_temp_k, 4000);
    EXPECT_LE(s.lighting.colour_temp_k, 7500);
    EXPECT_LE(s.lighting.gradient, 0.3);
    EXPECT_LE(s.degradation.defocus_sigma_px, 0.8);
    EXPECT_LE(s.degradation.motion_px, 2.0);
    EXPECT_GE(s.degradation.noise_sigma, 1.0);
    EXPECT_LE(s.degradation.noise_sigma, 4.0);
    EXPECT_TRUE(s.degradation.jpeg_quality == 0 ||
                (s.degradation.jpeg_quality >= 75 && s.degradation.jpeg_quality <= 95));
    EXPECT_NE(s.background, Background::Plain);
    backgrounds.insert(static_cast<int>(s.background));
    glare += s.lighting.glare > 0;
    jpeg += s.degradation.jpeg_quality > 0;
  }
  EXPECT_EQ(backgrounds.size(), 2u);
  EXPECT_GT(glare, 10);
  EXPECT_LT(glare, 100);
  EXPECT_GT(jpeg, 120);
}

namespace {

int countColour(const cv::Mat& img, Colour c) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) n += classify(img.at<cv::Vec3b>(y, x)) == c;
  return n;
}

}  // namespace

TEST(SynthRender, CardsAndDistractorsBringBlueAndRed) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  SceneSpec s = cleanScene(cam, {});
  const Frame empty = render(s);
  EXPECT_EQ(countColour(empty.bgr, Colour::Blue), 0);
  EXPECT_EQ(countColour(empty.bgr, Colour::Red), 0);
  s.landmark_like_cards = 3;
  const Frame cards = render(s);
  EXPECT_GT(countColour(cards.bgr, Colour::Blue), 100);
  EXPECT_GT(countColour(cards.bgr, Colour::Red), 30);
  s.landmark_like_cards = 0;
  int blue = 0, red = 0;
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    s.distractors = 12;
    s.seed = seed;
    const Frame d = render(s);
    blue += countColour(d.bgr, Colour::Blue);
    red += countColour(d.bgr, Colour::Red);
  }
  EXPECT_GT(blue, 200);
  EXPECT_GT(red, 200);
  // Office and clutter backgrounds are busy pictures, not flat walls.
  for (Background b : {Background::Office, Background::Clutter}) {
    s.background = b;
    s.distractors = 0;
    cv::Mat gray, edges;
    cv::cvtColor(render(s).bgr, gray, cv::COLOR_BGR2GRAY);
    cv::Canny(gray, edges, 40, 100);
    EXPECT_GT(cv::countNonZero(edges), 2000);
  }
}

// The light of a colour temperature is a black body's: undo the camera's
// partial white balance (70 % of the cast kept, relative to 6500 K) and the
// illuminant's chromaticity must be the CIE 1931 Planckian locus' (reference
// values from CIE tables, not from the fit the renderer uses). The old fit of
// display colours had 2.8 times too little blue at 2000 K.
TEST(SynthLighting, IlluminantIsOnThePlanckianLocus) {
  const auto rgbOf = [](double x, double y) {  // linear sRGB of chromaticity (x, y), Y = 1
    const double X = x / y, Z = (1 - x - y) / y;
    return cv::Vec3d(3.2406 * X - 1.5372 - 0.4986 * Z, -0.9689 * X + 1.8758 + 0.0415 * Z,
                     0.0557 * X - 0.2040 + 1.0570 * Z);
  };
  const cv::Vec3d d65 = rgbOf(0.3135, 0.3237);  // the 6500 K black body
  const struct { double k, x, y; } locus[] = {
      {2000, 0.5267, 0.4133}, {2700, 0.4599, 0.4106}, {4000, 0.3805, 0.3768}, {10000, 0.2807, 0.2884}};
  for (const auto& p : locus) {
    const cv::Vec3d wb = ld::synth::detail::whiteBalance(p.k);  // BGR
    EXPECT_NEAR(0.2126 * wb[2] + 0.7152 * wb[1] + 0.0722 * wb[0], 1.0, 1e-9) << p.k;
    cv::Vec3d rgb;
    for (int c = 0; c < 3; ++c) rgb[c] = d65[c] * std::pow(wb[2 - c], 1 / 0.7);
    const double X = 0.4124 * rgb[0] + 0.3576 * rgb[1] + 0.1805 * rgb[2];
    const double Y = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
    const double Z = 0.0193 * rgb[0] + 0.1192 * rgb[1] + 0.9505 * rgb[2];
    EXPECT_NEAR(X / (X + Y + Z), p.x, 0.002) << p.k;
    EXPECT_NEAR(Y / (X + Y + Z), p.y, 0.002) << p.k;
  }
  const cv::Vec3d d = ld::synth::detail::whiteBalance(6500);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(d[c], 1.0, 1e-9);
}

TEST(SynthRender, LightingAndDegradation) {
  const ld::CameraModel cam = ld::CameraModel::defaultVga();
  const LandmarkPlacement lm = placeLandmark(cam, 0.8, 0, 0, 0);
  const cv::Point2d paper = project(cam, lm, {{4.5, 1.5}})[0];
  SceneSpec s = cleanScene(cam, {lm});
  const cv::Vec3b white = at(render(s).bgr, paper);

  s.lighting.colour_temp_k = 2700;  // tungsten: clearly yellow/orange
  cv::Vec3b p = at(render(s).bgr, paper);
  EXPECT_GT(p[2], p[0] + 60) << p;
  EXPECT_GT(p[1], p[0] + 20) << p;
  s.lighting.colour_temp_k = 9000;  // shade: bluish
  p = at(render(s).bgr, paper);
  EXPECT_GT(p[0], p[2] + 5) << p;

  s.lighting = Lighting{};
  s.lighting.gain = 0.4;  // dim: paper is grey
  p = at(render(s).bgr, paper);
  for (int c = 0; c < 3; ++c) EXPECT_LT(p[c], white[c] * 0.8);

  s.lighting = Lighting{};
  s.lighting.glare = 1.5;  // a saturating spot
  s.lighting.glare_centre = {paper.x / (cam.size.width - 1), paper.y / (cam.size.height - 1)};
  const Frame g = render(s);
  EXPECT_EQ(at(g.bgr, paper), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(at(g.bgr, {5, 5}), at(render(cleanScene(cam, {lm})).bgr, {5, 5}));  // far from the spot

  s.lighting = Lighting{};
  s.lighting.gradient = 0.5;  // darker towards +x
  const Frame gr = render(s);
  EXPECT_GT(cv::mean(gr.bgr.colRange(0, 50))[1], cv::mean(gr.bgr.colRange(590, 640))[1] + 40);

  // Noise: the paper's spread grows; defocus: edges soften; JPEG: bytes change.
  s.lighting = Lighting{};
  s.degradation.noise_sigma = 4;
  const Frame nz = render(s);
  const cv::Rect patch(static_cast<int>(paper.x) - 8, static_cast<int>(paper.y) - 4, 16, 8);
  cv::Scalar mean, sd;
  cv::meanStdDev(nz.bgr(patch).reshape(1), mean, sd);
  EXPECT_GT(sd[0], 2.0);
  EXPECT_LT(sd[0], 8.0);
  s.degradation = Degradation{};
  s.degradation.defocus_sigma_px = 1.5;
  s.degradation.motion_px = 3;
  const Frame bl = render(s);
  const auto maxGradient = [](const cv::Mat& img) {
    cv::Mat gray, gx;
    cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
    cv::Sobel(gray, gx, CV_32F, 1, 0);
    double mx = 0;
    cv::minMaxLoc(cv::abs(gx), nullptr, &mx);
    return mx;
  };
  EXPECT_LT(maxGradient(bl.bgr), 0.6 * maxGradient(render(cleanScene(cam, {lm})).bgr));
  s.degradation = Degradation{};
  s.degradation.jpeg_quality = 60;
  const Frame jp = render(s);
  EXPECT_GT(cv::norm(jp.bgr, render(cleanScene(cam, {lm})).bgr, cv::NORM_INF), 3.0);
}

// ---------------------------------------------------------------------------
// Sequences.

TEST(SynthSequence, LandmarksEnterAndLeaveTheView) {
  SequenceOptions o;
  o.frames = 120;
  o.landmarks = 3;
  o.seed = 11;
  const Sequence seq(o);
  std::vector<int> seen(3, 0);
  int with_any = 0;
  for (int i = 0; i < seq.frames(); ++i) {
    const SceneSpec s = seq.scene(i);
    ASSERT_EQ(s.landmarks.size(), 3u);
    bool any = false;
    for (size_t k = 0; k < 3; ++k) {
      EXPECT_EQ(s.landmarks[k].id, static_cast<int>(k));
      EXPECT_EQ(s.landmarks[k].payload, "room-" + std::to_string(101 + k));
      const LandmarkTruth t = truthFor(s.camera, s.landmarks[k]);
      if (t.in_view) {
        ++seen[k];
        any = true;
        EXPECT_GT(t.distance, 1.0);
        EXPECT_LT(t.distance, 3.5);
      }
    }
    with_any += any;
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(seen[k], 10) << "landmark " << k;
    EXPECT_LT(seen[k], seq.frames()) << "landmark " << k << " never leaves the view";
  }
  EXPECT_GE(with_any, seq.frames() * 2 / 3);
  // Frames are deterministic, and consecutive frames move smoothly.
  const Frame a = render(seq.scene(30)), b = render(Sequence(o).scene(30));
  EXPECT_EQ(cv::norm(a.bgr, b.bgr, cv::NORM_INF), 0.0);
  const LandmarkTruth t0 = truthFor(o.camera, seq.scene(60).landmarks[1]);
  const LandmarkTruth t1 = truthFor(o.camera, seq.scene(61).landmarks[1]);
  EXPECT_LT(cv::norm(t1.fip_tl - t0.fip_tl), 20.0);
  EXPECT_GT(cv::norm(t1.fip_tl - t0.fip_tl), 0.5);
}

TEST(SynthSequence, WritesReadableLcmLogFramesAndTruth) {
  const fs::path dir = fs::temp_directory_path() / ("ld_test_synth_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  SequenceOptions o;
  o.out_dir = (dir / "seq").string();
  o.log_path = (dir / "seq.lcmlog").string();
  o.frames = 12;
  o.fps = 15;
  o.landmarks = 2;
  o.pixel_format = "yuyv";
  o.seed = 5;
  const SequenceStats st = writeSequence(o);
  EXPECT_EQ(st.frames, 12);
  EXPECT_GE(st.frames_with_landmark_in_view, 8);

  lcm::LogFile log(o.log_path, "r");
  ASSERT_TRUE(log.good());
  int n = 0;
  int64_t last = -1;
  for (const lcm::LogEvent* ev = log.readNextEvent(); ev; ev = log.readNextEvent(), ++n) {
    EXPECT_EQ(ev->channel, "IMAGE");
    ld::image_t msg;
    ASSERT_EQ(msg.decode(ev->data, 0, ev->datalen), ev->datalen);
    EXPECT_EQ(msg.utime, ev->timestamp);
    EXPECT_EQ(msg.utime, o.start_utime + std::llround(n * 1e6 / o.fps));
    if (last >= 0) {
      EXPECT_NEAR(static_cast<double>(msg.utime - last), 1e6 / o.fps, 1.0);
    }
    last = msg.utime;
    EXPECT_EQ(ld::imageSeq(msg), std::optional<int64_t>(n));
    EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_YUYV);
    const cv::Mat bgr = ld::imageToBgr(msg);
    EXPECT_EQ(bgr.size(), cv::Size(640, 480));
    // The PNG of the same frame is the same picture (up to YUYV's chroma).
    const cv::Mat png = cv::imread((fs::path(o.out_dir) / cv::format("%06d.png", n)).string());
    ASSERT_FALSE(png.empty());
    cv::Mat a, b;
    cv::cvtColor(png, a, cv::COLOR_BGR2GRAY);
    cv::cvtColor(bgr, b, cv::COLOR_BGR2GRAY);
    EXPECT_LT(cv::norm(a, b, cv::NORM_L1) / static_cast<double>(a.total()), 3.0);
  }
  EXPECT_EQ(n, 12);

  std::ifstream truth(fs::path(o.out_dir) / "truth.jsonl");
  std::string line;
  int lines = 0;
  while (std::getline(truth, line)) {
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["image"], cv::format("%06d.png", lines));
    EXPECT_EQ(j["seq"], lines);
    EXPECT_EQ(j["utime"], o.start_utime + std::llround(lines * 1e6 / o.fps));
    EXPECT_EQ(j["width"], 640);
    ASSERT_EQ(j["landmarks"].size(), 2u);
    for (int k = 0; k < 2; ++k) {
      const auto& l = j["landmarks"][static_cast<size_t>(k)];
      EXPECT_EQ(l["id"], k);
      EXPECT_EQ(l["payload"], "room-" + std::to_string(101 + k));
      for (const char* key : {"fip_tl", "fip_tr", "fip_bl", "ap"}) EXPECT_EQ(l[key].size(), 2u);
      EXPECT_EQ(l["corners"].size(), 4u);
      EXPECT_EQ(l["pose"]["t"].size(), 3u);
      EXPECT_EQ(l["pose"]["rvec"].size(), 3u);
      EXPECT_TRUE(l["in_view"].is_boolean());
    }
    ++lines;
  }
  EXPECT_EQ(lines, 12);

  // The same options write the same log, byte for byte.
  SequenceOptions o2 = o;
  o2.out_dir.clear();
  o2.log_path = (dir / "again.lcmlog").string();
  writeSequence(o2);
  std::ifstream f1(o.log_path, std::ios::binary), f2(o2.log_path, std::ios::binary);
  const std::string b1((std::istreambuf_iterator<char>(f1)), {}), b2((std::istreambuf_iterator<char>(f2)), {});
  EXPECT_EQ(b1, b2);

  // Bad options and unwritable places are one clear exception.
  o2.log_path = "/nonexistent-dir/x.lcmlog";
  EXPECT_THROW(writeSequence(o2), std::runtime_error);
  o2.log_path.clear();
  o2.out_dir = "/proc/ld-synth-cannot-be-here";
  EXPECT_THROW(writeSequence(o2), std::runtime_error);
  o2.out_dir = (dir / "x").string();
  o2.pixel_format = "nv12";
  EXPECT_THROW(writeSequence(o2), std::runtime_error);
  fs::remove_all(dir);
}
