// ld-synth's renderer: planar things (landmarks, cards, walls) through a
// pinhole camera into a canvas, then the camera's distortion, lighting in
// linear light, optics blur, sensor noise and JPEG.
//
// The frame is made in these steps (render() reads like this list):
//   1. the ideal canvas: a pinhole image with the camera's K, larger than the
//      image when the camera distorts (barrel distortion sees more);
//   2. the procedural background (wall, floor, furniture, posters, ...);
//   3. textured surfaces (walls and floor of a sequence's world);
//   4. colourful distractors and landmark-like cards, away from the landmarks;
//   5. the landmarks: each sheet texture warped into a supersampled patch and
//      box-filtered down, so edges are anti-aliased at any distance;
//   6. the camera's distortion (a remap);
//   7. lighting in linear light: gain, colour temperature, gradient, glare;
//   8. defocus and motion blur (in linear light, so glare blooms);
//   9. signal-dependent sensor noise;
//  10. a JPEG round trip.
#include "ld/synth.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"
#include "synth_detail.hpp"

namespace ld::synth {

using detail::Canvas;
using detail::Rand;

namespace detail {

uint64_t mix(uint64_t a, uint64_t b) {
  uint64_t z = a ^ (b * 0x9E3779B97F4A7C15ULL + 0x632BE59BD9B4E019ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double Rand::normal() {
  // Box-Muller; uni() is in [0, 1), so 1 - uni() is in (0, 1].
  const double a = 1.0 - uni(), b = uni();
  return std::sqrt(-2.0 * std::log(a)) * std::cos(2.0 * M_PI * b);
}

cv::Matx33d rotX(double deg) {
  const double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
  return {1, 0, 0, 0, c, -s, 0, s, c};
}
cv::Matx33d rotY(double deg) {
  const double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
  return {c, 0, s, 0, 1, 0, -s, 0, c};
}
cv::Matx33d rotZ(double deg) {
  const double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
  return {c, -s, 0, s, c, 0, 0, 0, 1};
}

cv::Matx33d fromRvec(const cv::Vec3d& r) {
  cv::Matx33d R;
  cv::Rodrigues(r, R);
  return R;
}

cv::Vec3d toRvec(const cv::Matx33d& R) {
  cv::Vec3d r;
  cv::Rodrigues(R, r);
  return r;
}

}  // namespace detail

namespace {

using detail::fromRvec;

constexpr double kNear = 0.02;  // near clipping plane, metres

// Iterations of undistortPoints: its default (5) is off by hundredths of a
// pixel in the corners of a strongly distorted image.
const cv::TermCriteria kUndistort(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12);

// ---------------------------------------------------------------------------
// Geometry helpers.

// The part of a convex polygon (camera frame) with z >= kNear.
std::vector<cv::Point3d> clipNear(const std::vector<cv::Point3d>& poly) {
  std::vector<cv::Point3d> out;
  const size_t n = poly.size();
  for (size_t i = 0; i < n; ++i) {
    const cv::Point3d& a = poly[i];
    const cv::Point3d& b = poly[(i + 1) % n];
    const bool ain = a.z >= kNear, bin = b.z >= kNear;
    if (ain) out.push_back(a);
    if (ain != bin) {
      const double f = (kNear - a.z) / (b.z - a.z);
      out.push_back(a + f * (b - a));
    }
  }
  return out;
}

cv::Point2d project(const cv::Matx33d& K, const cv::Point3d& p) {
  const cv::Vec3d q = K * cv::Vec3d(p.x, p.y, p.z);
  return {q[0] / q[2], q[1] / q[2]};
}

// Integer rectangle around points, grown by `grow` pixels, clipped to `bounds`.
cv::Rect boundingRect(const std::vector<cv::Point2d>& pts, double grow, const cv::Rect& bounds) {
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (const auto& p : pts) {
    x0 = std::min(x0, p.x);
    y0 = std::min(y0, p.y);
    x1 = std::max(x1, p.x);
    y1 = std::max(y1, p.y);
  }
  const auto clampd = [](double v, double lo, double hi) { return std::max(lo, std::min(hi, v)); };
  const double bx0 = bounds.x, by0 = bounds.y, bx1 = bounds.x + bounds.width,
               by1 = bounds.y + bounds.height;
  const int ix0 = static_cast<int>(std::floor(clampd(x0 - grow, bx0, bx1)));
  const int iy0 = static_cast<int>(std::floor(clampd(y0 - grow, by0, by1)));
  const int ix1 = static_cast<int>(std::ceil(clampd(x1 + grow + 1, bx0, bx1)));
  const int iy1 = static_cast<int>(std::ceil(clampd(y1 + grow + 1, by0, by1)));
  if (ix1 <= ix0 || iy1 <= iy0) return {};
  return {ix0, iy0, ix1 - ix0, iy1 - iy0};
}

// dst = src over dst with coverage mask (8-bit, 255 = src).
void blendInto(cv::Mat& dst, const cv::Mat& src, const cv::Mat& mask) {
  for (int y = 0; y < dst.rows; ++y) {
    auto* d = dst.ptr<uint8_t>(y);
    const auto* s = src.ptr<uint8_t>(y);
    const auto* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < dst.cols; ++x) {
      const int a = m[x];
      if (a == 0) continue;
      for (int c = 0; c < 3; ++c) {
        const int i = 3 * x + c;
        d[i] = static_cast<uint8_t>((s[i] * a + d[i] * (255 - a) + 127) / 255);
      }
    }
  }
}

int roundUp(double v, int multiple) {
  return static_cast<int>(std::ceil(v / multiple)) * multiple;
}

// ---------------------------------------------------------------------------
// Colours and procedural painting.

cv::Scalar rgb(double r, double g, double b) { return {b, g, r}; }

cv::Scalar scaled(const cv::Scalar& c, double f) {
  return {std::min(255.0, c[0] * f), std::min(255.0, c[1] * f), std::min(255.0, c[2] * f)};
}

// Wall paints, as a webcam sees them under white light.
cv::Scalar wallColour(Rand& r) {
  static constexpr double kWalls[][3] = {
      {232, 230, 222}, {226, 222, 210}, {214, 206, 190}, {205, 205, 202}, {218, 224, 226},
      {208, 222, 208}, {236, 226, 200}, {190, 190, 188}, {226, 214, 204}, {198, 210, 222}};
  const auto& w = kWalls[r.index(std::size(kWalls))];
  const double f = r.uni(0.93, 1.03);
  return scaled(rgb(w[0], w[1], w[2]), f);
}

enum class Hue { Blue, Red, Other };

// A colour of a thing in the room: saturated blues and reds (the distractors
// that matter) and everything else.
cv::Scalar objectColour(Rand& r, Hue hue) {
  static constexpr double kBlues[][3] = {{40, 60, 160}, {30, 80, 200}, {45, 50, 120},
                                         {20, 40, 110}, {60, 110, 220}, {10, 30, 230},
                                         {70, 60, 150}, {40, 120, 190}};
  static constexpr double kReds[][3] = {{200, 40, 40},  {215, 70, 50}, {170, 30, 50},
                                        {230, 60, 30},  {240, 30, 20}, {190, 60, 80},
                                        {220, 100, 60}, {150, 25, 30}};
  static constexpr double kOthers[][3] = {
      {60, 160, 70},  {230, 200, 40}, {240, 140, 30}, {120, 60, 140}, {40, 180, 200},
      {230, 130, 170}, {120, 80, 40}, {30, 30, 35},  {128, 128, 128}, {250, 250, 250},
      {90, 130, 60},  {200, 170, 120}, {60, 70, 90}};
  const double f = r.uni(0.85, 1.1);
  switch (hue) {
    case Hue::Blue: {
      const auto& c = kBlues[r.index(std::size(kBlues))];
      return scaled(rgb(c[0], c[1], c[2]), f);
    }
    case Hue::Red: {
      const auto& c = kReds[r.index(std::size(kReds))];
      return scaled(rgb(c[0], c[1], c[2]), f);
    }
    case Hue::Other: break;
  }
  const auto& c = kOthers[r.index(std::size(kOthers))];
  return scaled(rgb(c[0], c[1], c[2]), f);
}

Hue randomHue(Rand& r) {
  const double u = r.uni();
  return u < 0.35 ? Hue::Blue : u < 0.7 ? Hue::Red : Hue::Other;
}

// Smoothed Gaussian noise (CV_32F, about unit variance) with features of
// about `cell` pixels. Fine grain (small cells) is a seeded 256-pixel tile
// repeated (invisible at the amplitudes used); coarse noise is upsampled in
// two steps (cubic on a small grid, then linear), which is smooth and cheap.
cv::Mat smoothNoise(cv::Size size, double cell, Rand& r) {
  cell = std::max(1.0, cell);
  cv::RNG rng(r.next());
  const auto upsampled = [&](cv::Size out) {
    const int sw = static_cast<int>(std::ceil(out.width / cell)) + 1;
    const int sh = static_cast<int>(std::ceil(out.height / cell)) + 1;
    cv::Mat small(sh, sw, CV_32F);
    rng.fill(small, cv::RNG::NORMAL, 0, 1);
    cv::Mat big;
    if (cell > 8) {
      cv::Mat mid;
      cv::resize(small, mid, cv::Size(sw * 4, sh * 4), 0, 0, cv::INTER_CUBIC);
      cv::resize(mid, big, out, 0, 0, cv::INTER_LINEAR);
    } else {
      cv::resize(small, big, out, 0, 0, cv::INTER_CUBIC);
    }
    return big;
  };
  if (cell > 6 || (size.width <= 256 && size.height <= 256)) return upsampled(size);
  const cv::Mat tile = upsampled(cv::Size(256, 256));
  cv::Mat out;
  cv::repeat(tile, size.height / 256 + 1, size.width / 256 + 1, out);
  return out(cv::Rect(0, 0, size.width, size.height)).clone();
}

// img += amplitude * field on every channel (field CV_32F of img's size).
void addField(cv::Mat img, const cv::Mat& field, double amplitude) {
  cv::Mat d;
  field.convertTo(d, CV_16S, amplitude);
  for (int y = 0; y < img.rows; ++y) {
    auto* p = img.ptr<uint8_t>(y);
    const int16_t* f = d.ptr<int16_t>(y);
    for (int x = 0; x < img.cols; ++x)
      for (int c = 0; c < 3; ++c) p[3 * x + c] = cv::saturate_cast<uint8_t>(p[3 * x + c] + f[x]);
  }
}

// A texture of about `amp` levels with features of `cell` pixels over img.
void texture(cv::Mat img, double cell, double amp, Rand& r) {
  if (img.empty()) return;
  addField(img, smoothNoise(img.size(), cell, r), amp);
}

// Wood: stripes along x with wavy grain.
void wood(cv::Mat img, double ppm, Rand& r) {
  if (img.empty()) return;
  const cv::Scalar base = scaled(rgb(150, 100, 60), r.uni(0.7, 1.3));
  img.setTo(base);
  const cv::Mat wave = smoothNoise(img.size(), std::max(8.0, 0.3 * ppm), r);
  const double period = std::max(3.0, r.uni(0.008, 0.02) * ppm);
  std::array<float, 256> lut{};  // one period of the grain profile
  for (size_t i = 0; i < lut.size(); ++i)
    lut[i] = static_cast<float>(std::sin(2 * M_PI * static_cast<double>(i) / 256.0));
  const double bend = 0.8 * period;
  cv::Mat field(img.size(), CV_32F);
  for (int y = 0; y < img.rows; ++y) {
    const float* w = wave.ptr<float>(y);
    float* f = field.ptr<float>(y);
    for (int x = 0; x < img.cols; ++x) {
      const double phase = (y + bend * w[x]) / period;
      f[x] = lut[static_cast<size_t>(static_cast<int64_t>(std::floor(phase * 256)) & 255)];
    }
  }
  addField(img, field, r.uni(6, 14));
  texture(img, 2, 3, r);
}

const char* randomWord(Rand& r) {
  static const char* kWords[] = {"EXIT",   "Room 214", "MEETING", "Lab 3",   "FIRE",   "PUSH",
                                 "Kitchen", "No entry", "Printer", "QUIET",   "B-12",   "Welcome",
                                 "INFO",   "WC",       "2F",      "Office",  "Sale",   "Agenda",
                                 "Team",   "Q3 plan",  "STOP",    "Lift",    "Dock 4", "Storage"};
  return kWords[r.index(std::size(kWords))];
}

void text(cv::Mat& img, cv::Point org, double height_px, const cv::Scalar& colour, Rand& r) {
  const double scale = std::max(0.25, height_px / 22.0);
  const int thick = std::max(1, static_cast<int>(scale * r.uni(1.0, 2.5)));
  const int font = r.chance(0.5) ? cv::FONT_HERSHEY_SIMPLEX : cv::FONT_HERSHEY_DUPLEX;
  cv::putText(img, randomWord(r), org, font, scale, colour, thick, cv::LINE_AA);
}

// A filled polygon with sub-pixel vertices and anti-aliased edges.
void fillPoly(cv::Mat& img, const std::vector<cv::Point2d>& pts, const cv::Scalar& colour) {
  constexpr int kShift = 4;
  std::vector<cv::Point> q;
  for (const auto& p : pts)
    q.emplace_back(static_cast<int>(std::lround(p.x * (1 << kShift))),
                   static_cast<int>(std::lround(p.y * (1 << kShift))));
  cv::fillConvexPoly(img, q, colour, cv::LINE_AA, kShift);
}

std::vector<cv::Point2d> rotatedRect(cv::Point2d c, double w, double h, double deg) {
  const double a = deg * M_PI / 180, ca = std::cos(a), sa = std::sin(a);
  std::vector<cv::Point2d> out;
  for (const auto& [dx, dy] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}})
    out.emplace_back(c.x + ca * dx * w - sa * dy * h, c.y + sa * dx * w + ca * dy * h);
  return out;
}

cv::Rect rectAround(const std::vector<cv::Point2d>& pts) {
  return boundingRect(pts, 0, cv::Rect(-100000, -100000, 200000, 200000));
}

bool overlapsAny(const cv::Rect& r, const std::vector<cv::Rect>& avoid) {
  for (const auto& a : avoid)
    if ((r & a).area() > 0) return true;
  return false;
}

// A poster: a coloured panel with blocks, circles and lines of text.
void poster(cv::Mat& img, cv::Rect rc, double ppm, Rand& r) {
  rc &= cv::Rect(0, 0, img.cols, img.rows);
  if (rc.width < 4 || rc.height < 4) return;
  cv::Mat p = img(rc);
  p.setTo(r.chance(0.5) ? objectColour(r, Hue::Other) : scaled(rgb(245, 245, 240), r.uni(0.9, 1)));
  const int n = r.integer(2, 6);
  for (int i = 0; i < n; ++i) {
    const double w = r.uni(0.1, 0.7) * rc.width, h = r.uni(0.05, 0.4) * rc.height;
    const cv::Point2d c(r.uni(0, rc.width), r.uni(0, rc.height));
    const cv::Scalar col = objectColour(r, randomHue(r));
    if (r.chance(0.3))
      cv::circle(p, c, static_cast<int>(std::min(w, h) / 2), col, cv::FILLED, cv::LINE_AA);
    else
      fillPoly(p, rotatedRect(c, w, h, r.chance(0.7) ? 0 : r.uni(-30, 30)), col);
  }
  const int lines = r.integer(0, 4);
  for (int i = 0; i < lines; ++i)
    text(p, {static_cast<int>(r.uni(0.05, 0.3) * rc.width), static_cast<int>(r.uni(0.15, 0.95) * rc.height)},
         r.uni(0.03, 0.08) * ppm, r.chance(0.6) ? rgb(20, 20, 25) : objectColour(r, randomHue(r)), r);
  cv::rectangle(img, rc, scaled(rgb(60, 60, 60), r.uni(0.5, 2)), std::max(1, static_cast<int>(0.006 * ppm)),
                cv::LINE_AA);
}

// A shelf with books (thin vertical blocks of many colours, blues and reds among them).
void shelf(cv::Mat& img, cv::Rect rc, double ppm, Rand& r) {
  rc &= cv::Rect(0, 0, img.cols, img.rows);
  if (rc.width < 8 || rc.height < 8) return;
  cv::Mat s = img(rc);
  wood(s, ppm, r);
  const int boards = std::max(1, static_cast<int>(rc.height / (0.35 * ppm)));
  const double bh = static_cast<double>(rc.height) / boards;
  for (int b = 0; b < boards; ++b) {
    const double y1 = (b + 1) * bh - 0.025 * ppm;
    double x = 0.03 * ppm;
    while (x < rc.width - 0.05 * ppm) {
      const double w = r.uni(0.02, 0.06) * ppm, h = r.uni(0.5, 0.9) * bh;
      if (r.chance(0.15)) {
        x += w;
        continue;
      }
      cv::Mat roi = s(boundingRect({{x, y1 - h}, {x + w - 1, y1 - 1}}, 0, cv::Rect(0, 0, s.cols, s.rows)));
      if (!roi.empty()) roi.setTo(objectColour(r, randomHue(r)));
      x += w + 1;
    }
    cv::Mat board = s(boundingRect({{0, y1}, {static_cast<double>(s.cols), y1 + 0.025 * ppm}}, 0,
                                   cv::Rect(0, 0, s.cols, s.rows)));
    if (!board.empty()) board.setTo(scaled(rgb(120, 80, 50), r.uni(0.8, 1.2)));
  }
}

void door(cv::Mat& img, double x, double floor_y, double ppm, Rand& r) {
  const double w = 0.9 * ppm, h = 2.05 * ppm, frame = 0.06 * ppm;
  const cv::Rect outer = boundingRect({{x - frame, floor_y - h - frame}, {x + w + frame, floor_y}}, 0,
                                      cv::Rect(0, 0, img.cols, img.rows));
  const cv::Rect leaf = boundingRect({{x, floor_y - h}, {x + w, floor_y}}, 0, cv::Rect(0, 0, img.cols, img.rows));
  if (outer.area() == 0) return;
  img(outer).setTo(scaled(rgb(235, 235, 230), r.uni(0.7, 1.0)));
  if (leaf.area() == 0) return;
  if (r.chance(0.5))
    wood(img(leaf), ppm, r);
  else
    img(leaf).setTo(r.chance(0.5) ? objectColour(r, Hue::Other) : scaled(rgb(200, 200, 195), r.uni(0.8, 1.1)));
  texture(img(leaf), 3, 3, r);
  const cv::Point2d handle(x + 0.85 * w, floor_y - 1.0 * ppm);
  cv::circle(img, handle, std::max(2, static_cast<int>(0.03 * ppm)), rgb(190, 190, 185), cv::FILLED, cv::LINE_AA);
  if (r.chance(0.4))
    text(img, {static_cast<int>(x + 0.2 * w), static_cast<int>(floor_y - 1.6 * ppm)}, 0.06 * ppm,
         rgb(20, 20, 20), r);
}

void furniture(cv::Mat& img, double floor_y, double ppm, Rand& r) {
  const double x = r.uni(-0.3, 1.0) * img.cols;
  const int kind = r.integer(0, 2);
  if (kind == 0) {  // desk: a top and two legs
    const double w = r.uni(1.0, 1.6) * ppm, top = floor_y - 0.75 * ppm, th = 0.04 * ppm;
    const cv::Scalar c = r.chance(0.5) ? scaled(rgb(150, 105, 65), r.uni(0.7, 1.2)) : scaled(rgb(225, 225, 220), r.uni(0.8, 1));
    const cv::Scalar legs = scaled(rgb(70, 70, 75), r.uni(0.6, 1.4));
    const double lw = 0.05 * ppm;
    img(boundingRect({{x + 0.03 * ppm, top}, {x + 0.03 * ppm + lw, floor_y}}, 0, {0, 0, img.cols, img.rows})).setTo(legs);
    img(boundingRect({{x + w - 0.03 * ppm - lw, top}, {x + w - 0.03 * ppm, floor_y}}, 0, {0, 0, img.cols, img.rows})).setTo(legs);
    cv::Mat t = img(boundingRect({{x, top}, {x + w, top + th}}, 0, {0, 0, img.cols, img.rows}));
    if (!t.empty()) t.setTo(c);
    // Things on the desk: a monitor, a mug.
    if (r.chance(0.6)) {
      const double mw = 0.55 * ppm, mh = 0.35 * ppm, mx = x + r.uni(0.1, 0.5) * w;
      cv::Mat m = img(boundingRect({{mx, top - mh - 0.1 * ppm}, {mx + mw, top - 0.1 * ppm}}, 0, {0, 0, img.cols, img.rows}));
      if (!m.empty()) {
        m.setTo(rgb(25, 25, 30));
        texture(m, 0.1 * ppm, 6, r);
      }
      img(boundingRect({{mx + mw / 2 - 0.02 * ppm, top - 0.1 * ppm}, {mx + mw / 2 + 0.02 * ppm, top}}, 0, {0, 0, img.cols, img.rows}))
          .setTo(rgb(40, 40, 45));
    }
    if (r.chance(0.5)) {
      const double mx = x + r.uni(0.6, 0.9) * w;
      img(boundingRect({{mx, top - 0.1 * ppm}, {mx + 0.08 * ppm, top}}, 0, {0, 0, img.cols, img.rows}))
          .setTo(objectColour(r, randomHue(r)));
    }
  } else if (kind == 1) {  // cabinet with drawers
    const double w = r.uni(0.4, 0.9) * ppm, h = r.uni(0.6, 1.2) * ppm;
    const cv::Rect rc = boundingRect({{x, floor_y - h}, {x + w, floor_y}}, 0, {0, 0, img.cols, img.rows});
    if (rc.area() == 0) return;
    img(rc).setTo(r.chance(0.5) ? scaled(rgb(170, 170, 168), r.uni(0.7, 1.2)) : objectColour(r, Hue::Other));
    texture(img(rc), 4, 2, r);
    const int drawers = r.integer(2, 4);
    for (int d = 1; d < drawers; ++d) {
      const int y = static_cast<int>(floor_y - h + d * h / drawers);
      cv::line(img, {static_cast<int>(x), y}, {static_cast<int>(x + w), y}, rgb(60, 60, 60), 1, cv::LINE_AA);
    }
    for (int d = 0; d < drawers; ++d) {
      const double y = floor_y - h + (d + 0.3) * h / drawers;
      cv::line(img, cv::Point2d(x + 0.4 * w, y), cv::Point2d(x + 0.6 * w, y), rgb(40, 40, 40),
               std::max(1, static_cast<int>(0.012 * ppm)), cv::LINE_AA);
    }
  } else {  // bookshelf
    const double w = r.uni(0.6, 1.2) * ppm, h = r.uni(1.0, 1.9) * ppm;
    shelf(img, boundingRect({{x, floor_y - h}, {x + w, floor_y}}, 0, {0, 0, img.cols, img.rows}), ppm, r);
  }
}

// A colourful object of random kind; `fip_px` is the size a landmark's
// square has in this image, so some distractors are exactly that size.
void distractor(cv::Mat& img, cv::Point2d c, double fip_px, double ppm, Rand& r) {
  const Hue hue = randomHue(r);
  const cv::Scalar col = objectColour(r, hue);
  const int kind = r.integer(0, 9);
  switch (kind) {
    case 0:
    case 1:
    case 2: {  // a saturated blue or red square of landmark-square size
      const double s = fip_px * r.uni(0.6, 1.6);
      const cv::Scalar sq = objectColour(r, r.chance(0.5) ? Hue::Blue : Hue::Red);
      fillPoly(img, rotatedRect(c, s, s * r.uni(0.85, 1.15), r.uni(-45, 45)), sq);
      if (r.chance(0.3)) {  // a second one nearby, the way FIPs come in pairs
        const double a = r.uni(0, 2 * M_PI), d = s * r.uni(2, 4);
        fillPoly(img, rotatedRect(c + cv::Point2d(d * std::cos(a), d * std::sin(a)), s, s, r.uni(-45, 45)),
                 objectColour(r, Hue::Blue));
      }
      break;
    }
    case 3: {  // an upright block (a box, a binder)
      const double w = r.uni(0.05, 0.4) * ppm, h = r.uni(0.05, 0.4) * ppm;
      fillPoly(img, rotatedRect(c, w, h, 0), col);
      break;
    }
    case 4: {  // a disc or an ellipse
      const double a = r.uni(0.02, 0.12) * ppm, b = a * r.uni(0.5, 1.0);
      cv::ellipse(img, cv::RotatedRect(c, cv::Size2f(static_cast<float>(2 * a), static_cast<float>(2 * b)),
                                       static_cast<float>(r.uni(0, 180))),
                  col, cv::FILLED, cv::LINE_AA);
      break;
    }
    case 5: {  // a rotated rectangle
      fillPoly(img, rotatedRect(c, r.uni(0.03, 0.3) * ppm, r.uni(0.03, 0.3) * ppm, r.uni(0, 180)), col);
      break;
    }
    case 6: {  // stripes
      const int n = r.integer(3, 7);
      const double w = r.uni(0.005, 0.03) * ppm, gap = w * r.uni(1.5, 3), len = r.uni(0.1, 0.5) * ppm;
      const double a = r.uni(0, 180), ca = std::cos(a * M_PI / 180), sa = std::sin(a * M_PI / 180);
      for (int i = 0; i < n; ++i) {
        const double off = (i - n / 2.0) * gap;
        fillPoly(img, rotatedRect(c + cv::Point2d(-sa * off, ca * off), len, w, a), i % 2 && r.chance(0.5) ? objectColour(r, randomHue(r)) : col);
      }
      break;
    }
    case 7: {  // text
      text(img, c, r.uni(0.03, 0.12) * ppm, col, r);
      break;
    }
    case 8: {  // a ring or an outlined square
      const double s = fip_px * r.uni(1, 3);
      if (r.chance(0.5))
        cv::circle(img, c, static_cast<int>(s / 2), col, std::max(1, static_cast<int>(s / 6)), cv::LINE_AA);
      else
        cv::rectangle(img, cv::Rect(static_cast<int>(c.x), static_cast<int>(c.y), static_cast<int>(s), static_cast<int>(s)),
                      col, std::max(1, static_cast<int>(s / 6)), cv::LINE_AA);
      break;
    }
    default: {  // a triangle
      const double s = r.uni(0.03, 0.15) * ppm, a = r.uni(0, 2 * M_PI);
      std::vector<cv::Point2d> tri;
      for (int i = 0; i < 3; ++i)
        tri.emplace_back(c.x + s * std::cos(a + i * 2 * M_PI / 3), c.y + s * std::sin(a + i * 2 * M_PI / 3));
      fillPoly(img, tri, col);
    }
  }
}

}  // namespace

namespace detail {

void paintWall(cv::Mat& img, double ppm, Rand& r) {
  img.setTo(wallColour(r));
  // Slow light falloff and paint unevenness, then fine grain (one pass).
  cv::Mat field = smoothNoise(img.size(), std::max(8.0, 0.6 * ppm), r);
  field *= r.uni(3, 7);
  cv::scaleAdd(smoothNoise(img.size(), 2.0, r), r.uni(1, 2.5), field, field);
  addField(img, field, 1.0);
}

void paintFloor(cv::Mat& img, double ppm, Rand& r) {
  const int kind = r.integer(0, 2);
  if (kind == 0) {  // carpet
    img.setTo(scaled(rgb(110, 108, 104), r.uni(0.6, 1.3)));
    texture(img, 1.5, 10, r);
    texture(img, 0.3 * ppm, 5, r);
  } else if (kind == 1) {  // planks
    wood(img, ppm, r);
    const double plank = r.uni(0.12, 0.2) * ppm;
    for (double y = r.uni(0, plank); y < img.rows; y += plank)
      cv::line(img, cv::Point2d(0, y), cv::Point2d(img.cols, y), rgb(70, 45, 30), 1, cv::LINE_AA);
  } else {  // tiles
    img.setTo(scaled(rgb(200, 195, 185), r.uni(0.7, 1.1)));
    texture(img, 3, 4, r);
    const double tile = r.uni(0.3, 0.6) * ppm;
    for (double x = r.uni(0, tile); x < img.cols; x += tile)
      cv::line(img, cv::Point2d(x, 0), cv::Point2d(x, img.rows), rgb(120, 120, 115), 1, cv::LINE_AA);
    for (double y = r.uni(0, tile); y < img.rows; y += tile)
      cv::line(img, cv::Point2d(0, y), cv::Point2d(img.cols, y), rgb(120, 120, 115), 1, cv::LINE_AA);
  }
}

void paintBackground(cv::Mat& img, Background kind, double ppm, bool with_floor, Rand& r,
                     bool paint_wall) {
  if (paint_wall) paintWall(img, ppm, r);
  if (kind == Background::Plain) {
    // A gentle gradient across the wall.
    cv::Mat ramp(img.size(), CV_32F);
    const double a = r.uni(0, 2 * M_PI), ca = std::cos(a), sa = std::sin(a);
    const double L = std::abs(ca) * img.cols + std::abs(sa) * img.rows + 1;
    for (int y = 0; y < img.rows; ++y) {
      float* p = ramp.ptr<float>(y);
      for (int x = 0; x < img.cols; ++x)
        p[x] = static_cast<float>(((x - img.cols / 2.0) * ca + (y - img.rows / 2.0) * sa) / L);
    }
    addField(img, ramp, r.uni(5, 20));
    return;
  }
  const cv::Rect all(0, 0, img.cols, img.rows);
  // A corner of the room: the other wall is lit differently.
  if (paint_wall && r.chance(0.35)) {
    const int xc = static_cast<int>(r.uni(0.1, 0.9) * img.cols);
    cv::Mat other = img(cv::Rect(r.chance(0.5) ? 0 : xc, 0, r.chance(0.5) ? xc : img.cols - xc, img.rows) & all);
    if (!other.empty()) other.convertTo(other, -1, r.uni(0.78, 0.92));
  }
  const double floor_y = with_floor && r.chance(0.8) ? r.uni(0.6, 0.95) * img.rows : img.rows + 0.05 * ppm;
  // Textured areas: a cork board, a fabric panel.
  for (int i = r.integer(0, 2); i > 0; --i) {
    const cv::Rect rc = boundingRect({{r.uni(0, img.cols), r.uni(0, floor_y)}},
                                     r.uni(0.1, 0.4) * ppm, all);
    if (rc.area() == 0) continue;
    img(rc).setTo(r.chance(0.5) ? scaled(rgb(180, 140, 90), r.uni(0.8, 1.1)) : objectColour(r, Hue::Other));
    texture(img(rc), r.uni(1.5, 4), r.uni(6, 14), r);
  }
  if (r.chance(0.35)) door(img, r.uni(-0.2, 0.9) * img.cols, floor_y, ppm, r);
  // Posters, a whiteboard with marker scribbles.
  for (int i = r.integer(1, 3); i > 0; --i) {
    const double w = r.uni(0.3, 0.8) * ppm, h = r.uni(0.4, 1.0) * ppm;
    const double x = r.uni(-0.1, 1.0) * img.cols, y = r.uni(-0.1, 0.8) * floor_y;
    poster(img, cv::Rect(static_cast<int>(x), static_cast<int>(y), static_cast<int>(w), static_cast<int>(h)), ppm, r);
  }
  if (r.chance(0.3)) {
    const cv::Rect wb = cv::Rect(static_cast<int>(r.uni(-0.1, 0.8) * img.cols), static_cast<int>(r.uni(0, 0.5) * floor_y),
                                 static_cast<int>(r.uni(0.8, 1.5) * ppm), static_cast<int>(r.uni(0.6, 1.0) * ppm)) & all;
    if (wb.area() > 0) {
      img(wb).setTo(rgb(240, 242, 242));
      cv::rectangle(img, wb, rgb(150, 150, 155), std::max(1, static_cast<int>(0.015 * ppm)));
      for (int i = r.integer(2, 8); i > 0; --i) {
        const cv::Scalar pen = objectColour(r, r.chance(0.7) ? (r.chance(0.5) ? Hue::Blue : Hue::Red) : Hue::Other);
        cv::Point2d p(wb.x + r.uni(0.1, 0.8) * wb.width, wb.y + r.uni(0.1, 0.9) * wb.height);
        for (int k = r.integer(2, 6); k > 0; --k) {
          const cv::Point2d q = p + cv::Point2d(r.uni(-0.15, 0.15) * ppm, r.uni(-0.08, 0.08) * ppm);
          cv::line(img, p, q, pen, std::max(1, static_cast<int>(0.008 * ppm)), cv::LINE_AA);
          p = q;
        }
      }
    }
  }
  if (r.chance(0.35)) {
    const double w = r.uni(0.8, 1.5) * ppm, h = r.uni(0.4, 1.0) * ppm;
    shelf(img, cv::Rect(static_cast<int>(r.uni(-0.1, 0.9) * img.cols), static_cast<int>(r.uni(0.05, 0.4) * floor_y),
                        static_cast<int>(w), static_cast<int>(h)), ppm, r);
  }
  // Floor with a skirting board; furniture standing on it.
  if (floor_y < img.rows) {
    const cv::Rect fl = boundingRect({{0, floor_y}, {static_cast<double>(img.cols), static_cast<double>(img.rows)}}, 0, all);
    if (fl.area() > 0) {
      const int kind = r.integer(0, 2);
      if (kind == 0) {
        img(fl).setTo(scaled(rgb(110, 108, 104), r.uni(0.6, 1.3)));
        texture(img(fl), 1.5, 10, r);
        texture(img(fl), 0.3 * ppm, 5, r);
      } else if (kind == 1) {
        wood(img(fl), ppm, r);
      } else {
        img(fl).setTo(scaled(rgb(200, 195, 185), r.uni(0.7, 1.1)));
        texture(img(fl), 3, 4, r);
        const double tile = r.uni(0.3, 0.6) * ppm;
        for (double x = r.uni(0, tile); x < img.cols; x += tile)
          cv::line(img, cv::Point2d(x, floor_y), cv::Point2d(x + (x - img.cols / 2.0) * 0.5, img.rows), rgb(120, 120, 115), 1, cv::LINE_AA);
      }
      const double sk = 0.06 * ppm;
      cv::Mat skirt = img(boundingRect({{0, floor_y - sk}, {static_cast<double>(img.cols), floor_y}}, 0, all));
      if (!skirt.empty()) skirt.setTo(r.chance(0.5) ? scaled(rgb(240, 240, 236), 0.95) : scaled(rgb(70, 60, 55), r.uni(0.7, 1.3)));
    }
  }
  for (int i = r.integer(0, 3); i > 0; --i) furniture(img, floor_y, ppm, r);
  if (kind == Background::Clutter) {
    // Dense clutter: boxes, binders, bottles, cables, labels everywhere.
    const int n = r.integer(30, 70);
    for (int i = 0; i < n; ++i) {
      const cv::Point2d c(r.uni(0, img.cols), r.uni(0, img.rows));
      distractor(img, c, r.uni(0.01, 0.05) * ppm, ppm, r);
    }
  }
}

void paintDistractors(cv::Mat& img, int count, const std::vector<double>& fip_px,
                      const std::vector<cv::Rect>& avoid, double ppm, Rand& r) {
  for (int i = 0; i < count; ++i) {
    const double fip = fip_px.empty() ? r.uni(0.015, 0.04) * ppm : fip_px[r.index(fip_px.size())];
    // Try a few positions away from the landmarks.
    for (int attempt = 0; attempt < 20; ++attempt) {
      const cv::Point2d c(r.uni(0, img.cols), r.uni(0, img.rows));
      const double reach = std::max(3 * fip, 0.1 * ppm);
      if (overlapsAny(rectAround({c - cv::Point2d(reach, reach), c + cv::Point2d(reach, reach)}), avoid)) continue;
      distractor(img, c, fip, ppm, r);
      break;
    }
  }
}

cv::Mat cardTexture(int variant, int side, const artwork::Colours& ink, Rand& r) {
  cv::Mat card(side, side, CV_8UC3, cv::Scalar(ink.white[0], ink.white[1], ink.white[2]));
  const double u = side / layout::kUnits;
  const auto square = [&](double cx, double cy, const cv::Vec3b& c) {
    const double h = layout::kSquareSide / 2;
    cv::rectangle(card, cv::Point(static_cast<int>(std::lround((cx - h) * u)), static_cast<int>(std::lround((cy - h) * u))),
                  cv::Point(static_cast<int>(std::lround((cx + h) * u)) - 1, static_cast<int>(std::lround((cy + h) * u)) - 1),
                  cv::Scalar(c[0], c[1], c[2]), cv::FILLED);
  };
  const auto qrLike = [&]() {
    const int n = 21;
    const double m = (layout::kQrMax - layout::kQrMin) / (n + 2);
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const bool finder = (x < 7 && y < 7) || (x >= n - 7 && y < 7) || (x < 7 && y >= n - 7);
        bool dark = r.chance(0.5);
        if (finder) {
          const int fx = x < 7 ? x : x - (n - 7), fy = y < 7 ? y : y - (n - 7);
          const int d = std::max(std::abs(fx - 3), std::abs(fy - 3));
          dark = d != 2;
        }
        if (!dark) continue;
        const double x0 = (layout::kQrMin + (x + 1) * m) * u, y0 = (layout::kQrMin + (y + 1) * m) * u;
        cv::rectangle(card, cv::Point(static_cast<int>(std::lround(x0)), static_cast<int>(std::lround(y0))),
                      cv::Point(static_cast<int>(std::lround(x0 + m * u)) - 1, static_cast<int>(std::lround(y0 + m * u)) - 1),
                      cv::Scalar(ink.black[0], ink.black[1], ink.black[2]), cv::FILLED);
      }
  };
  const auto& c = layout::kCentresU;
  switch (variant % 3) {
    case 0:  // three FIPs and the red square in the middle (no QR), sometimes a fourth blue
      square(c[0][0], c[0][1], ink.blue);
      square(c[1][0], c[1][1], ink.blue);
      square(c[2][0], c[2][1], ink.blue);
      square(4.5, 4.5, ink.red);
      if (r.chance(0.5)) square(c[3][0], c[3][1], ink.blue);
      break;
    case 1:  // three FIPs, a QR-like block, and the red square next to TL
      square(c[0][0], c[0][1], ink.blue);
      square(c[1][0], c[1][1], ink.blue);
      square(c[2][0], c[2][1], ink.blue);
      qrLike();
      if (r.chance(0.5))
        square(c[0][0] + 2.3, c[0][1], ink.red);  // right of TL
      else
        square(c[0][0], c[0][1] + 2.3, ink.red);  // below TL
      break;
    default:  // colours swapped: three red squares and a blue one
      square(c[0][0], c[0][1], ink.red);
      square(c[1][0], c[1][1], ink.red);
      square(c[2][0], c[2][1], ink.red);
      square(c[3][0], c[3][1], ink.blue);
      qrLike();
  }
  return card;
}

}  // namespace detail

namespace {

// ---------------------------------------------------------------------------
// Planar things into the canvas.

// Draws the rectangle [-w/2, w/2] x [-h/2, h/2] of the plane with pose (R, t)
// (camera frame), textured with `tex` (covering it whole). ss > 1: through a
// patch supersampled ss times and box-filtered down (exact anti-aliasing for
// small sharp things); ss = 1: a plain warp (walls, floors). Returns false
// when nothing of it is in front of the camera and inside the canvas.
bool drawPlanar(Canvas& cv_, const cv::Matx33d& R, const cv::Vec3d& t, cv::Size2d size_m,
                const cv::Mat& tex, int ss) {
  const double w = size_m.width, h = size_m.height;
  std::vector<cv::Point3d> poly;
  bool clipped = false;
  for (const auto& [x, y] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) {
    const cv::Vec3d p = R * cv::Vec3d(x * w, y * h, 0) + t;
    poly.emplace_back(p[0], p[1], p[2]);
    clipped = clipped || p[2] < kNear;
  }
  if (clipped) poly = clipNear(poly);
  if (poly.size() < 3) return false;
  std::vector<cv::Point2d> img_poly;
  for (const auto& p : poly) img_poly.push_back(project(cv_.K, p));
  const cv::Rect roi = boundingRect(img_poly, 2, cv::Rect(0, 0, cv_.img.cols, cv_.img.rows));
  if (roi.area() == 0) return false;

  // Texture pixel (i, j) (centre) -> plane point -> canvas pixel.
  const cv::Matx33d A(w / tex.cols, 0, 0.5 * w / tex.cols - w / 2, 0, h / tex.rows,
                      0.5 * h / tex.rows - h / 2, 0, 0, 1);
  const cv::Matx33d M(R(0, 0), R(0, 1), t[0], R(1, 0), R(1, 1), t[1], R(2, 0), R(2, 1), t[2]);
  // Canvas pixel -> patch pixel: p = ss * (x - roi.x + 0.5) - 0.5.
  const cv::Matx33d P(ss, 0, ss * (0.5 - roi.x) - 0.5, 0, ss, ss * (0.5 - roi.y) - 0.5, 0, 0, 1);
  const cv::Matx33d H = P * cv_.K * M * A;
  const cv::Size psize(roi.width * ss, roi.height * ss);

  cv::Mat ptex, pmask;
  cv::warpPerspective(tex, ptex, cv::Mat(H), psize, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  if (ss > 1 && !clipped) {
    const cv::Mat white(tex.size(), CV_8U, cv::Scalar(255));
    cv::warpPerspective(white, pmask, cv::Mat(H), psize, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                        cv::Scalar(0));
  } else {
    pmask = cv::Mat::zeros(psize, CV_8U);
    std::vector<cv::Point2d> pp;
    for (const auto& q : img_poly) pp.emplace_back(ss * (q.x - roi.x + 0.5) - 0.5, ss * (q.y - roi.y + 0.5) - 0.5);
    // Far-away vertices (just past the near plane) are clamped: the polygon
    // is convex, so clamping to a big box keeps it right inside the patch.
    const double big = 4.0 * (psize.width + psize.height) + 1000;
    for (auto& q : pp) {
      q.x = std::max(-big, std::min(big, q.x));
      q.y = std::max(-big, std::min(big, q.y));
    }
    fillPoly(pmask, pp, cv::Scalar(255));
  }
  cv::Mat dst = cv_.img(roi);
  if (ss == 1) {
    blendInto(dst, ptex, pmask);
    return true;
  }
  cv::Mat up;
  cv::resize(dst, up, psize, 0, 0, cv::INTER_NEAREST);
  blendInto(up, ptex, pmask);
  cv::resize(up, dst, roi.size(), 0, 0, cv::INTER_AREA);
  return true;
}

// Side of the projected pattern in canvas pixels (largest edge), or 0.
double projectedSide(const Canvas& c, const cv::Matx33d& R, const cv::Vec3d& t, double side) {
  std::vector<cv::Point2d> q;
  for (const auto& p : layout::objectCorners(side)) {
    const cv::Vec3d v = R * cv::Vec3d(p.x, p.y, p.z) + t;
    if (v[2] < kNear) return 0;
    q.push_back(project(c.K, {v[0], v[1], v[2]}));
  }
  double s = 0;
  for (size_t i = 0; i < 4; ++i) s = std::max(s, cv::norm(q[i] - q[(i + 1) % 4]));
  return s * layout::kUnits / (layout::kPatternMax - layout::kPatternMin);
}

// Supersampling of a sheet's patch: finer for small sheets, where
// anti-aliasing matters; none for sheets filling much of the image.
int supersampling(double side_px) {
  return side_px < 48 ? 4 : side_px < 160 ? 3 : side_px < 480 ? 2 : 1;
}

// A square texture's side for a sheet of `side_px` canvas pixels: about twice
// the supersampled side, a multiple of 18 (so the artwork is exact to the pixel).
int textureSide(double side_px, int ss) {
  return std::max(144, std::min(1800, roundUp(2.0 * ss * side_px, 18)));
}

// The artwork at about n pixels (at least n). At 18 (N + 2) pixels for a QR
// of N modules every edge of the artwork falls on a pixel edge (u = 2 (N + 2),
// a module is 8 pixels), so a larger texture is that one scaled up by a whole
// factor with nearest neighbour: the same picture renderLandmark would draw,
// for a fraction of the time.
cv::Mat landmarkTexture(const std::string& payload, artwork::QrEcc ecc, int n, const artwork::Colours& ink) {
  const artwork::QrCode qr = artwork::encodeQr(payload, ecc);
  const int base = 18 * (qr.size + 2);
  if (n <= base) return artwork::renderLandmark(qr, n, ink);
  const cv::Mat small = artwork::renderLandmark(qr, base, ink);
  const int k = (n + base - 1) / base;
  cv::Mat big;
  cv::resize(small, big, cv::Size(base * k, base * k), 0, 0, cv::INTER_NEAREST);
  return big;
}

void drawLandmark(Canvas& c, const LandmarkPlacement& lm, const artwork::Colours& ink) {
  const cv::Matx33d R = fromRvec(lm.rvec);
  const double side_px = projectedSide(c, R, lm.tvec, lm.side_m);
  // A sheet crossing the near plane is huge anyway: coarse supersampling.
  const int ss = side_px > 0 ? supersampling(side_px) : 1;
  const int n = side_px > 0 ? textureSide(side_px, ss) : 1800;
  cv::Mat tex;
  if (!lm.texture.empty()) {
    tex = lm.texture;
    if (tex.channels() == 1) cv::cvtColor(tex, tex, cv::COLOR_GRAY2BGR);
    if (tex.channels() == 4) cv::cvtColor(tex, tex, cv::COLOR_BGRA2BGR);
    if (tex.cols > 2 * n) cv::resize(tex, tex, cv::Size(n, n), 0, 0, cv::INTER_AREA);
  } else {
    tex = landmarkTexture(lm.payload, lm.ecc, n, ink);
  }
  drawPlanar(c, R, lm.tvec, {lm.side_m, lm.side_m}, tex, ss);
}

// The surface's mip level whose texels are about one canvas pixel where the
// image centre's ray meets it (or, when that ray misses it, at its nearest
// visible corner); obliquely seen surfaces go a little coarser.
const cv::Mat& mipFor(const Canvas& c, const Surface& s, const cv::Matx33d& R) {
  if (s.mipmaps.empty()) return s.texture;
  const cv::Vec3d n(R(0, 2), R(1, 2), R(2, 2));  // plane normal
  cv::Vec3d ray = c.K.inv() * cv::Vec3d(c.img.cols / 2.0, c.img.rows / 2.0, 1.0);
  ray /= cv::norm(ray);
  double depth = -1, cos_view = 1;
  const double nd = n.dot(ray);
  if (std::abs(nd) > 1e-6) {
    const double lambda = n.dot(s.tvec) / nd;
    const cv::Vec3d p = lambda * ray;
    const cv::Vec3d local = R.t() * (p - s.tvec);
    if (lambda > 0 && std::abs(local[0]) <= s.size_m.width / 2 && std::abs(local[1]) <= s.size_m.height / 2) {
      depth = p[2];
      cos_view = std::abs(nd);
    }
  }
  if (depth <= 0) {
    depth = 1e18;
    for (const auto& [x, y] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) {
      const cv::Vec3d p = R * cv::Vec3d(x * s.size_m.width, y * s.size_m.height, 0) + s.tvec;
      if (p[2] > kNear) depth = std::min(depth, p[2]);
    }
    if (depth > 1e17) return s.mipmaps.front();
  }
  const double px_per_m = c.K(0, 0) / depth * std::sqrt(std::max(0.05, cos_view));
  const double texels_per_m = s.texture.cols / s.size_m.width;
  const int level = static_cast<int>(std::floor(std::log2(std::max(1.0, texels_per_m / px_per_m))));
  return s.mipmaps[static_cast<size_t>(std::min(level, static_cast<int>(s.mipmaps.size()) - 1))];
}

// ---------------------------------------------------------------------------
// The camera's distortion: output pixel -> ideal canvas position.

struct DistortionMap {
  cv::Mat map_x, map_y;  // CV_32F, output size
  cv::Rect2d ideal;      // ideal pixel positions the image covers
};

DistortionMap distortionMap(const CameraModel& cam) {
  const int W = cam.size.width, H = cam.size.height, g = 8;
  const int gw = (W - 1) / g + 2, gh = (H - 1) / g + 2;
  std::vector<cv::Point2d> grid;
  grid.reserve(static_cast<size_t>(gw * gh));
  for (int j = 0; j < gh; ++j)
    for (int i = 0; i < gw; ++i) grid.emplace_back(i * g, j * g);
  std::vector<cv::Point2d> und;
  cv::undistortPoints(grid, und, cv::Mat(cam.K), cam.dist, cv::noArray(), cv::Mat(cam.K), kUndistort);
  DistortionMap m;
  m.map_x.create(H, W, CV_32F);
  m.map_y.create(H, W, CV_32F);
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (int y = 0; y < H; ++y) {
    const int j = std::min(y / g, gh - 2);
    const double fy = (y - j * g) / static_cast<double>(g);
    float* mx = m.map_x.ptr<float>(y);
    float* my = m.map_y.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      const int i = std::min(x / g, gw - 2);
      const double fx = (x - i * g) / static_cast<double>(g);
      const auto& a = und[static_cast<size_t>(j * gw + i)];
      const auto& b = und[static_cast<size_t>(j * gw + i + 1)];
      const auto& c = und[static_cast<size_t>((j + 1) * gw + i)];
      const auto& d = und[static_cast<size_t>((j + 1) * gw + i + 1)];
      const cv::Point2d p = (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * c + fx * d);
      mx[x] = static_cast<float>(p.x);
      my[x] = static_cast<float>(p.y);
      x0 = std::min(x0, p.x);
      y0 = std::min(y0, p.y);
      x1 = std::max(x1, p.x);
      y1 = std::max(y1, p.y);
    }
  }
  // Extreme distortion models fold over far out: keep the canvas sane.
  x0 = std::max(x0, -1.0 * W);
  y0 = std::max(y0, -1.0 * H);
  x1 = std::min(x1, 2.0 * W);
  y1 = std::min(y1, 2.0 * H);
  m.ideal = cv::Rect2d(x0, y0, x1 - x0, y1 - y0);
  return m;
}

// ---------------------------------------------------------------------------
// Lighting and degradation.

// sRGB 8-bit -> linear.
const std::array<float, 256>& srgbToLinear() {
  static const std::array<float, 256> lut = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double v = i / 255.0;
      t[static_cast<size_t>(i)] =
          static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
    }
    return t;
  }();
  return lut;
}

constexpr int kLinLevels = 4096;

// Linear [0, 1] in kLinLevels steps -> sRGB 8-bit.
const std::array<uint8_t, kLinLevels + 1>& linearToSrgb() {
  static const std::array<uint8_t, kLinLevels + 1> lut = [] {
    std::array<uint8_t, kLinLevels + 1> t{};
    for (int i = 0; i <= kLinLevels; ++i) {
      const double v = static_cast<double>(i) / kLinLevels;
      const double s = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
      t[static_cast<size_t>(i)] = static_cast<uint8_t>(std::lround(std::min(1.0, s) * 255));
    }
    return t;
  }();
  return lut;
}

// Linear-light sRGB colour (R, G, B) of a black body at temperature K: its
// chromaticity on the Planckian locus (Kim et al.'s cubic fit of the CIE 1931
// locus, 1667-25000 K), as XYZ with Y = 1, through the sRGB (D65) matrix.
// Below ~1900 K the locus leaves the sRGB gamut (blue < 0): clamped.
cv::Vec3d blackBody(double kelvin) {
  const double T = std::max(1667.0, std::min(25000.0, kelvin));
  const double t1 = 1e3 / T, t2 = t1 * t1, t3 = t2 * t1;
  const double x = T < 4000 ? -0.2661239 * t3 - 0.2343589 * t2 + 0.8776956 * t1 + 0.179910
                            : -3.0258469 * t3 + 2.1070379 * t2 + 0.2226347 * t1 + 0.240390;
  const double x2 = x * x, x3 = x2 * x;
  const double y = T < 2222   ? -1.1063814 * x3 - 1.34811020 * x2 + 2.18555832 * x - 0.20219683
                   : T < 4000 ? -0.9549476 * x3 - 1.37418593 * x2 + 2.09137015 * x - 0.16748867
                              : 3.0817580 * x3 - 5.87338670 * x2 + 3.75112997 * x - 0.37001483;
  const double X = x / y, Z = (1 - x - y) / y;
  const double r = 3.2406 * X - 1.5372 - 0.4986 * Z;
  const double g = -0.9689 * X + 1.8758 + 0.0415 * Z;
  const double b = 0.0557 * X - 0.2040 + 1.0570 * Z;
  return {std::max(r, 1e-4), std::max(g, 1e-4), std::max(b, 1e-4)};
}

}  // namespace

namespace detail {

cv::Vec3d whiteBalance(double kelvin) {
  // Linear RGB of the illuminant relative to the 6500 K the camera is
  // balanced for. Cheap webcams' auto white balance undoes part of a colour
  // cast: keep 70% of it (in log terms). Normalised to keep luminance, so the
  // gain stays the brightness control. Returned in BGR order.
  const cv::Vec3d a = blackBody(kelvin), d = blackBody(6500);
  cv::Vec3d f;
  for (int i = 0; i < 3; ++i) f[i] = std::pow(a[i] / d[i], 0.7);
  const double y = 0.2126 * f[0] + 0.7152 * f[1] + 0.0722 * f[2];
  return {f[2] / y, f[1] / y, f[0] / y};
}

}  // namespace detail

namespace {

bool trivialLighting(const Lighting& l) {
  return l.gain == 1.0 && std::abs(l.colour_temp_k - 6500.0) < 1e-9 && l.gradient == 0.0 &&
         l.glare == 0.0;
}

// img (8-bit BGR, sRGB) -> linear light with the lighting applied (CV_32FC3).
cv::Mat lightLinear(const cv::Mat& img, const Lighting& l) {
  const auto& lut = srgbToLinear();
  const cv::Vec3d wb = detail::whiteBalance(l.colour_temp_k);
  const float f[3] = {static_cast<float>(wb[0] * l.gain), static_cast<float>(wb[1] * l.gain),
                      static_cast<float>(wb[2] * l.gain)};
  const float wbf[3] = {static_cast<float>(wb[0]), static_cast<float>(wb[1]), static_cast<float>(wb[2])};
  const int W = img.cols, H = img.rows;
  const double a = l.gradient_angle_deg * M_PI / 180, ca = std::cos(a), sa = std::sin(a);
  const double L = std::abs(ca) * W + std::abs(sa) * H + 1e-9;
  // Glare: a Gaussian spot of peak `glare` (linear, 1 = white) and sigma
  // glare_radius * width / 2, in the light's colour.
  const double gs = std::max(1.0, l.glare_radius * W / 2);
  const double gx = l.glare_centre.x * (W - 1), gy = l.glare_centre.y * (H - 1);
  const double greach = 3.5 * gs;
  cv::Mat out(img.size(), CV_32FC3);
  const double step = -l.gradient * ca / L;  // brightness change per pixel along x
  for (int y = 0; y < H; ++y) {
    const auto* p = img.ptr<uint8_t>(y);
    float* o = out.ptr<float>(y);
    const bool glare_row = l.glare > 0 && std::abs(y - gy) < greach;
    // 1 - gradient * t, t = 0..1 along the gradient's direction.
    double g = 1.0 - l.gradient * (((0 - W / 2.0) * ca + (y - H / 2.0) * sa) / L + 0.5);
    for (int x = 0; x < W; ++x, g += step) {
      const float gf = static_cast<float>(g);
      for (int c = 0; c < 3; ++c) o[3 * x + c] = lut[p[3 * x + c]] * gf * f[c];
    }
    if (!glare_row) continue;
    const int x0 = std::max(0, static_cast<int>(gx - greach)), x1 = std::min(W - 1, static_cast<int>(gx + greach));
    for (int x = x0; x <= x1; ++x) {
      const double d2 = (x - gx) * (x - gx) + (y - gy) * (y - gy);
      const float add = static_cast<float>(l.glare * std::exp(-0.5 * d2 / (gs * gs)));
      for (int c = 0; c < 3; ++c) o[3 * x + c] += add * wbf[c];
    }
  }
  return out;
}

void linearToImage(const cv::Mat& lin, cv::Mat& img) {
  const auto& lut = linearToSrgb();
  img.create(lin.size(), CV_8UC3);
  for (int y = 0; y < lin.rows; ++y) {
    const float* p = lin.ptr<float>(y);
    auto* o = img.ptr<uint8_t>(y);
    for (int x = 0; x < 3 * lin.cols; ++x) {
      const float v = std::max(0.0f, std::min(1.0f, p[x]));
      o[x] = lut[static_cast<size_t>(v * kLinLevels + 0.5f)];
    }
  }
}

void blur(cv::Mat& img, const Degradation& d) {
  if (d.defocus_sigma_px > 0.05) cv::GaussianBlur(img, img, cv::Size(), d.defocus_sigma_px);
  if (d.motion_px >= 0.5) {
    const int k = 2 * static_cast<int>(std::ceil(d.motion_px / 2)) + 1;
    cv::Mat kernel = cv::Mat::zeros(k * 4, k * 4, CV_32F);  // drawn at 4x, then area-reduced
    const double a = d.motion_angle_deg * M_PI / 180;
    const cv::Point2d c(2.0 * k - 0.5, 2.0 * k - 0.5);
    const cv::Point2d h(2.0 * d.motion_px * std::cos(a), 2.0 * d.motion_px * std::sin(a));
    cv::line(kernel, c - h, c + h, cv::Scalar(1), 4, cv::LINE_AA);
    cv::resize(kernel, kernel, cv::Size(k, k), 0, 0, cv::INTER_AREA);
    kernel /= cv::sum(kernel)[0];
    cv::filter2D(img, img, -1, kernel, cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
  }
}

// Shot noise grows with the signal: sigma = noise_sigma at mid grey,
// sqrt-shaped, with a floor for read noise in the dark. Gaussian samples come
// from a seeded table indexed by a xorshift generator: fast and deterministic.
void addNoise(cv::Mat& img, double sigma, uint64_t seed) {
  if (sigma <= 0) return;
  constexpr int kTable = 1 << 16;
  cv::Mat table(1, kTable, CV_32F);
  cv::RNG rng(seed);
  rng.fill(table, cv::RNG::NORMAL, 0, 1);
  const float* g = table.ptr<float>(0);
  std::array<float, 256> s{};
  for (int v = 0; v < 256; ++v)
    s[static_cast<size_t>(v)] = static_cast<float>(sigma * std::sqrt((v + 24.0) / (128.0 + 24.0)));
  uint64_t state = detail::mix(seed, 0x401) | 1;
  for (int y = 0; y < img.rows; ++y) {
    auto* p = img.ptr<uint8_t>(y);
    for (int x = 0; x < 3 * img.cols; x += 3) {
      state ^= state << 13;
      state ^= state >> 7;
      state ^= state << 17;
      for (int c = 0; c < 3; ++c) {
        const float n = g[(state >> (16 * c)) & (kTable - 1)];
        p[x + c] = cv::saturate_cast<uint8_t>(p[x + c] + n * s[p[x + c]]);
      }
    }
  }
}

void jpegRoundTrip(cv::Mat& img, int quality) {
  if (quality <= 0) return;
  std::vector<uint8_t> buf;
  cv::imencode(".jpg", img, buf, {cv::IMWRITE_JPEG_QUALITY, std::min(100, quality)});
  img = cv::imdecode(buf, cv::IMREAD_COLOR);
}

// ---------------------------------------------------------------------------
// Landmark-like cards and distractors placed in 3D / in the image.

struct Footprint {
  cv::Rect box;   // canvas pixels, grown
  double fip_px;  // a coloured square's side in canvas pixels
};

std::vector<Footprint> landmarkFootprints(const Canvas& c, const std::vector<LandmarkPlacement>& lms) {
  std::vector<Footprint> out;
  for (const auto& lm : lms) {
    const cv::Matx33d R = fromRvec(lm.rvec);
    std::vector<cv::Point2d> q;
    bool front = true;
    for (const auto& [x, y] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) {
      const cv::Vec3d p = R * cv::Vec3d(x * lm.side_m, y * lm.side_m, 0) + lm.tvec;
      if (p[2] < kNear) front = false;
      else q.push_back(project(c.K, {p[0], p[1], p[2]}));
    }
    if (!front) continue;
    const cv::Rect b = rectAround(q);
    const int g = std::max(4, static_cast<int>(0.25 * std::max(b.width, b.height)));
    out.push_back({cv::Rect(b.x - g, b.y - g, b.width + 2 * g, b.height + 2 * g),
                   c.K(0, 0) * lm.side_m * layout::kSquareSide / layout::kUnits / std::max(kNear, lm.tvec[2])});
  }
  return out;
}

void drawCards(Canvas& c, const SceneSpec& spec, const std::vector<Footprint>& avoid_lm,
               const artwork::Colours& ink, Rand& r) {
  std::vector<cv::Rect> avoid;
  for (const auto& f : avoid_lm) avoid.push_back(f.box);
  CameraModel ideal;
  ideal.K = c.K;
  ideal.size = c.img.size();
  for (int i = 0; i < spec.landmark_like_cards; ++i) {
    for (int attempt = 0; attempt < 40; ++attempt) {
      // Near the landmarks' distances and sizes when there are landmarks.
      double dist = r.uni(0.8, 2.5), side = r.uni(0.1, 0.2);
      if (!spec.landmarks.empty()) {
        const auto& lm = spec.landmarks[r.index(spec.landmarks.size())];
        dist = std::max(0.3, cv::norm(lm.tvec) * r.uni(0.7, 1.3));
        side = lm.side_m * r.uni(0.7, 1.2);
      }
      const LandmarkPlacement p = placeLandmark(ideal, dist, r.uni(-45, 45), r.uni(-10, 10),
                                                r.chance(0.5) ? r.uni(-20, 20) : r.uni(-180, 180),
                                                r.uni(-0.85, 0.85), r.uni(-0.85, 0.85), side);
      const cv::Matx33d R = fromRvec(p.rvec);
      std::vector<cv::Point2d> q;
      for (const auto& [x, y] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) {
        const cv::Vec3d v = R * cv::Vec3d(x * side, y * side, 0) + p.tvec;
        q.push_back(project(c.K, {v[0], v[1], v[2]}));
      }
      const cv::Rect box = rectAround(q);
      if (overlapsAny(box, avoid)) continue;
      const double side_px = projectedSide(c, R, p.tvec, side);
      const int ss = supersampling(side_px);
      const cv::Mat tex = detail::cardTexture(r.integer(0, 2), textureSide(side_px, ss), ink, r);
      drawPlanar(c, R, p.tvec, {side, side}, tex, ss);
      avoid.push_back(box);
      break;
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------
// Public functions.

artwork::Colours printedInk() {
  artwork::Colours c;
  c.blue = {120, 50, 45};    // sRGB (45, 50, 120)
  c.red = {50, 70, 215};     // sRGB (215, 70, 50)
  c.white = {228, 235, 235}; // sRGB (235, 235, 228)
  c.black = {40, 35, 35};    // sRGB (35, 35, 40)
  return c;
}

void makeMipmaps(Surface& s) {
  s.mipmaps.clear();
  if (s.texture.empty()) return;
  s.mipmaps.push_back(s.texture);
  while (s.mipmaps.back().cols > 32 && s.mipmaps.back().rows > 32 && s.mipmaps.size() < 8) {
    cv::Mat next;
    cv::pyrDown(s.mipmaps.back(), next);
    s.mipmaps.push_back(next);
  }
}

LandmarkPlacement placeLandmark(const CameraModel& camera, double distance, double yaw_deg,
                                double pitch_deg, double roll_deg, double nx, double ny,
                                double side_m, const std::string& payload, int id) {
  const cv::Point2d pix((camera.size.width - 1) / 2.0 * (1 + nx), (camera.size.height - 1) / 2.0 * (1 + ny));
  cv::Vec3d d;
  if (camera.hasDistortion()) {
    std::vector<cv::Point2d> in{pix}, out;
    cv::undistortPoints(in, out, cv::Mat(camera.K), camera.dist, cv::noArray(), cv::noArray(), kUndistort);
    d = {out[0].x, out[0].y, 1.0};
  } else {
    d = camera.K.inv() * cv::Vec3d(pix.x, pix.y, 1.0);
  }
  d /= cv::norm(d);
  // Face the camera along the ray, the sheet's x axis horizontal.
  const double pan = std::atan2(d[0], d[2]) * 180 / M_PI;
  const double tilt = -std::asin(std::max(-1.0, std::min(1.0, d[1]))) * 180 / M_PI;
  const cv::Matx33d R = detail::rotY(pan) * detail::rotX(tilt) * detail::rotY(yaw_deg) *
                        detail::rotX(pitch_deg) * detail::rotZ(roll_deg);
  LandmarkPlacement p;
  p.id = id;
  p.payload = payload;
  p.side_m = side_m;
  p.rvec = detail::toRvec(R);
  p.tvec = d * distance;
  return p;
}

LandmarkTruth truthFor(const CameraModel& camera, const LandmarkPlacement& lm) {
  LandmarkTruth t;
  t.id = lm.id;
  t.payload = lm.payload;
  t.t = lm.tvec;
  t.rvec = lm.rvec;
  t.distance = cv::norm(lm.tvec);
  std::vector<cv::Point3d> obj;
  for (const auto& p : layout::objectCentres(lm.side_m)) obj.push_back(p);
  for (const auto& p : layout::objectCorners(lm.side_m)) obj.push_back(p);
  std::vector<cv::Point2d> img;
  cv::projectPoints(obj, lm.rvec, lm.tvec, cv::Mat(camera.K), camera.dist, img);
  t.fip_tl = img[layout::kFipTl];
  t.fip_tr = img[layout::kFipTr];
  t.fip_bl = img[layout::kFipBl];
  t.ap = img[layout::kAp];
  for (size_t i = 0; i < 4; ++i) t.corners[i] = img[4 + i];

  const cv::Matx33d R = fromRvec(lm.rvec);
  bool in = true;
  std::vector<cv::Point2d> ideal;
  for (size_t i = 0; i < 4; ++i) {
    const cv::Point3d& p = obj[4 + i];
    const cv::Vec3d v = R * cv::Vec3d(p.x, p.y, p.z) + lm.tvec;
    if (v[2] <= 0) in = false;
    else ideal.push_back(project(camera.K, {v[0], v[1], v[2]}));
    const cv::Point2d& q = t.corners[i];
    if (!(q.x >= 0 && q.y >= 0 && q.x <= camera.size.width - 1 && q.y <= camera.size.height - 1)) in = false;
  }
  if (in && camera.hasDistortion()) {
    // Far outside the field of view a distortion polynomial folds back into
    // the image: the undistorted corners must lie where the image border's do.
    std::vector<cv::Point2d> border, und;
    const double W = camera.size.width - 1, H = camera.size.height - 1;
    for (int i = 0; i <= 16; ++i) {
      const double f = i / 16.0;
      border.insert(border.end(), {{f * W, 0}, {f * W, H}, {0, f * H}, {W, f * H}});
    }
    cv::undistortPoints(border, und, cv::Mat(camera.K), camera.dist, cv::noArray(), cv::Mat(camera.K), kUndistort);
    const cv::Rect2d box = cv::boundingRect(std::vector<cv::Point2f>(und.begin(), und.end()));
    const double m = 2.0;
    for (const auto& q : ideal)
      if (q.x < box.x - m || q.y < box.y - m || q.x > box.x + box.width + m || q.y > box.y + box.height + m)
        in = false;
  }
  t.in_view = in;
  return t;
}

Frame render(const SceneSpec& spec) {
  const CameraModel& cam = spec.camera;
  if (cam.size.width <= 0 || cam.size.height <= 0)
    throw std::invalid_argument("render: camera has no image size");
  const artwork::Colours ink = spec.printed_ink ? printedInk() : artwork::Colours{};

  // 1. The ideal canvas.
  Canvas canvas;
  canvas.K = cam.K;
  DistortionMap dmap;
  const bool distort = cam.hasDistortion();
  cv::Size csize = cam.size;
  if (distort) {
    dmap = distortionMap(cam);
    const int ox = static_cast<int>(std::ceil(-dmap.ideal.x)) + 2;
    const int oy = static_cast<int>(std::ceil(-dmap.ideal.y)) + 2;
    canvas.offset = {static_cast<double>(ox), static_cast<double>(oy)};
    csize = {static_cast<int>(std::ceil(dmap.ideal.x + dmap.ideal.width)) + ox + 3,
             static_cast<int>(std::ceil(dmap.ideal.y + dmap.ideal.height)) + oy + 3};
    canvas.K(0, 2) += ox;
    canvas.K(1, 2) += oy;
  }
  canvas.img.create(csize, CV_8UC3);
  // Objects are sized as if on a wall 2 m away.
  const double ppm = cam.K(0, 0) / 2.0;

  // 2. Background.
  Rand rbg(detail::mix(spec.seed, 1));
  detail::paintBackground(canvas.img, spec.background, ppm, true, rbg);

  // 3. Surfaces.
  for (const auto& s : spec.surfaces) {
    if (s.texture.empty()) continue;
    const cv::Matx33d R = fromRvec(s.rvec);
    drawPlanar(canvas, R, s.tvec, s.size_m, mipFor(canvas, s, R), 1);
  }

  // 4. Distractors and landmark-like cards, kept off the landmarks.
  const std::vector<Footprint> fps = landmarkFootprints(canvas, spec.landmarks);
  {
    Rand rd(detail::mix(spec.seed, 2));
    std::vector<double> fip;
    std::vector<cv::Rect> avoid;
    for (const auto& f : fps) {
      fip.push_back(f.fip_px);
      avoid.push_back(f.box);
    }
    detail::paintDistractors(canvas.img, spec.distractors, fip, avoid, ppm, rd);
    Rand rc(detail::mix(spec.seed, 3));
    drawCards(canvas, spec, fps, ink, rc);
  }

  // 5. Landmarks.
  for (const auto& lm : spec.landmarks) drawLandmark(canvas, lm, ink);

  // 6. Distortion.
  Frame frame;
  if (distort) {
    cv::Mat mx = dmap.map_x + canvas.offset.x, my = dmap.map_y + canvas.offset.y;
    cv::remap(canvas.img, frame.bgr, mx, my, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  } else {
    frame.bgr = canvas.img;
  }

  // 7-8. Lighting and optics blur in linear light.
  const Degradation& deg = spec.degradation;
  const bool blurs = deg.defocus_sigma_px > 0.05 || deg.motion_px >= 0.5;
  if (!trivialLighting(spec.lighting) || blurs) {
    cv::Mat lin = lightLinear(frame.bgr, spec.lighting);
    blur(lin, deg);
    linearToImage(lin, frame.bgr);
  }
  // 9-10. Sensor noise, JPEG.
  addNoise(frame.bgr, deg.noise_sigma, spec.noise_seed ? spec.noise_seed : detail::mix(spec.seed, 4));
  jpegRoundTrip(frame.bgr, deg.jpeg_quality);

  for (const auto& lm : spec.landmarks) frame.truth.push_back(truthFor(cam, lm));
  return frame;
}

SceneSpec randomConditions(const CameraModel& camera, std::vector<LandmarkPlacement> landmarks,
                           uint64_t seed) {
  Rand r(detail::mix(seed, 0x5eed));
  SceneSpec s;
  s.camera = camera;
  s.landmarks = std::move(landmarks);
  s.seed = seed;
  s.printed_ink = true;
  // Background: an office (60%) or dense clutter (40%), 3..10 distractors, no cards.
  s.background = r.chance(0.6) ? Background::Office : Background::Clutter;
  s.distractors = r.integer(3, 10);
  s.landmark_like_cards = 0;
  // Lighting: gain 0.7..1.3, 4000..7500 K, gradient 0..0.3 in any direction,
  // a small glare spot (peak 0.1..0.4, radius 5..15% of the width) one time in five.
  s.lighting.gain = r.uni(0.7, 1.3);
  s.lighting.colour_temp_k = r.uni(4000, 7500);
  s.lighting.gradient = r.uni(0, 0.3);
  s.lighting.gradient_angle_deg = r.uni(0, 360);
  if (r.chance(0.2)) {
    s.lighting.glare = r.uni(0.1, 0.4);
    s.lighting.glare_centre = {r.uni(0, 1), r.uni(0, 1)};
    s.lighting.glare_radius = r.uni(0.05, 0.15);
  }
  // Degradation: defocus sigma 0..0.8 px; motion blur 0.5..2 px in any
  // direction one time in three; noise 1..4; JPEG quality 75..95 four times in five.
  s.degradation.defocus_sigma_px = r.uni(0, 0.8);
  if (r.chance(1.0 / 3)) {
    s.degradation.motion_px = r.uni(0.5, 2);
    s.degradation.motion_angle_deg = r.uni(0, 180);
  }
  s.degradation.noise_sigma = r.uni(1, 4);
  s.degradation.jpeg_quality = r.chance(0.8) ? r.integer(75, 95) : 0;
  return s;
}

std::string truthJsonLine(const std::string& image, cv::Size size,
                          const std::vector<LandmarkTruth>& truth, int64_t seq, int64_t utime) {
  const auto px = [](double v) { return std::round(v * 1e4) / 1e4; };
  const auto m = [](double v) { return std::round(v * 1e6) / 1e6; };
  const auto pt = [&](const cv::Point2d& p) { return nlohmann::ordered_json::array({px(p.x), px(p.y)}); };
  nlohmann::ordered_json j;
  j["image"] = image;
  j["width"] = size.width;
  j["height"] = size.height;
  if (seq >= 0) j["seq"] = seq;
  if (utime >= 0) j["utime"] = utime;
  j["landmarks"] = nlohmann::ordered_json::array();
  for (const auto& t : truth) {
    nlohmann::ordered_json l;
    l["id"] = t.id;
    l["payload"] = t.payload;
    l["fip_tl"] = pt(t.fip_tl);
    l["fip_tr"] = pt(t.fip_tr);
    l["fip_bl"] = pt(t.fip_bl);
    l["ap"] = pt(t.ap);
    l["corners"] = nlohmann::ordered_json::array();
    for (const auto& c : t.corners) l["corners"].push_back(pt(c));
    l["pose"]["t"] = {m(t.t[0]), m(t.t[1]), m(t.t[2])};
    l["pose"]["rvec"] = {m(t.rvec[0]), m(t.rvec[1]), m(t.rvec[2])};
    l["pose"]["distance"] = m(t.distance);
    l["in_view"] = t.in_view;
    j["landmarks"].push_back(l);
  }
  // (a payload's bytes that are not UTF-8 as U+FFFD)
  return j.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

}  // namespace ld::synth
