// The landmark detector: the orchestration of the stages of stages.cpp, in
// the order of the paper's Fig. 2, on either backend's filters (filters.hpp),
// and the parameter file.
#include "ld/detector.hpp"

#include <errno.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iostream>
#include <numeric>
#include <stdexcept>
#include <tuple>
#include <type_traits>

#include <opencv2/imgproc.hpp>

#include "filters.hpp"
#include "ld/config_file.hpp"
#include "ld/input_checks.hpp"
#include "stages.hpp"

namespace ld {

// ====================================================================== parameters

namespace {

// Every field once: name, member. Drives load, save and the unknown-key check.
template <typename F>
void forEachField(DetectorParams& p, F&& f) {
  f("front_end", p.front_end);
  f("backend", p.backend);
  f("blur_kernel", p.blur_kernel);
  f("blur_sigma", p.blur_sigma);
  f("saturation_threshold", p.saturation_threshold);
  f("saturation_threshold_blue", p.saturation_threshold_blue);
  f("value_min", p.value_min);
  f("canny_low", p.canny_low);
  f("canny_high", p.canny_high);
  f("min_area_px", p.min_area_px);
  f("max_area_frac_1000", p.max_area_frac_1000);
  f("color_ratio_a", p.color_ratio_a);
  f("color_ratio_b", p.color_ratio_b);
  f("min_fill", p.min_fill);
  f("d_min", p.d_min);
  f("d_max", p.d_max);
  f("w_min", p.w_min);
  f("w_max", p.w_max);
  f("h_min", p.h_min);
  f("h_max", p.h_max);
  f("ap_max_offset", p.ap_max_offset);
  f("ap_size_min", p.ap_size_min);
  f("ap_size_max", p.ap_size_max);
  f("shape_tolerance", p.shape_tolerance);
  f("max_anisotropy", p.max_anisotropy);
  f("square_scale_min", p.square_scale_min);
  f("square_scale_max", p.square_scale_max);
  f("sheet_max_saturation", p.sheet_max_saturation);
  f("sheet_min_value", p.sheet_min_value);
  f("sheet_uniformity", p.sheet_uniformity);
  f("qr_max_brightness", p.qr_max_brightness);
  f("qr_dark_samples", p.qr_dark_samples);
  f("qr_dark_sample", p.qr_dark_sample);
  f("qr_clipped_max_brightness", p.qr_clipped_max_brightness);
  f("qr_washed_dip", p.qr_washed_dip);
  f("cover_min", p.cover_min);
  f("cover_max", p.cover_max);
  f("complete_missing", p.complete_missing);
  f("second_looks", p.second_looks);
  f("second_look_raise", p.second_look_raise);
  f("faint_looks", p.faint_looks);
  f("faint_look_blue", p.faint_look_blue);
  f("steep_looks", p.steep_looks);
  f("veil_looks", p.veil_looks);
  f("max_candidates", p.max_candidates);
  f("max_cycles", p.max_cycles);
  f("centre_iterations", p.centre_iterations);
  f("align_iterations", p.align_iterations);
}

[[noreturn]] void badFile(const std::string& path, const std::string& what) {
  throw std::runtime_error("detector params " + path + ": " + what);
}

void readField(const std::string& path, const cv::FileNode& n, const char* key, std::string& v) {
  if (!n.isString()) badFile(path, std::string("key '") + key + "' must be a string");
  v = configString(n);
}
void readField(const std::string& path, const cv::FileNode& n, const char* key, int& v) {
  if (!n.isInt()) badFile(path, std::string("key '") + key + "' must be an integer");
  v = static_cast<int>(n);
}
void readField(const std::string& path, const cv::FileNode& n, const char* key, bool& v) {
  // (true and false as well, as the tracker's file takes them)
  if (n.isString() && (configString(n) == "true" || configString(n) == "false")) {
    v = configString(n) == "true";
    return;
  }
  if (!n.isInt() || (static_cast<int>(n) != 0 && static_cast<int>(n) != 1))
    badFile(path, std::string("key '") + key + "' must be 0 or 1 (or false or true)");
  v = static_cast<int>(n) != 0;
}
void readField(const std::string& path, const cv::FileNode& n, const char* key, double& v) {
  if (!n.isInt() && !n.isReal()) badFile(path, std::string("key '") + key + "' must be a number");
  v = static_cast<double>(n);
}

}  // namespace

DetectorParams DetectorParams::paper() {
  DetectorParams p;
  p.front_end = "paper";
  p.blur_kernel = 9;
  p.blur_sigma = 3.0;
  p.align_iterations = 0;  // (the paper's corners: the centres' homography)
  return p;
}

namespace {

// Every value in its range, else `Error(prefix + "<field> <why>")`.
template <class Error>
void checkValues(const DetectorParams& p, const std::string& prefix) {
  auto bad = [&prefix](const char* field, const std::string& why) { throw Error(prefix + field + " " + why); };
  // (an upper bound of .inf let the FIP graph take every pair: gigabytes)
  DetectorParams fields = p;
  forEachField(fields, [&](const char* field, const auto& v) {
    if constexpr (std::is_same_v<std::decay_t<decltype(v)>, double>)
      if (!std::isfinite(v)) bad(field, "must be a finite number");
  });
  if (p.front_end != "fast" && p.front_end != "paper")
    bad("front_end", "must be \"fast\" or \"paper\", not \"" + p.front_end + "\"");
  if (p.backend != "cpu" && p.backend != "gles" && p.backend != "auto")
    bad("backend", "must be \"cpu\", \"gles\" or \"auto\", not \"" + p.backend + "\"");
  if (p.blur_kernel != -1 && p.blur_kernel != 0 && (p.blur_kernel < 1 || p.blur_kernel % 2 == 0 || p.blur_kernel > 31))
    bad("blur_kernel", "must be -1, 0 or an odd number from 1 to 31");
  if (!(p.blur_sigma >= 0 && p.blur_sigma <= 20)) bad("blur_sigma", "must be in [0, 20]");
  // (a sigma for a blur that is not there: taken, and nothing blurred)
  if (p.blur_sigma > 0 && p.blur_kernel == -1 && p.front_end == "fast")
    bad("blur_sigma", "is for a blur, and the fast front end has none unless blur_kernel is set (an odd number "
                      "from 3 to 31)");
  if (!(p.saturation_threshold > 0 && p.saturation_threshold < 1)) bad("saturation_threshold", "must be in (0, 1)");
  if (!(p.saturation_threshold_blue > 0 && p.saturation_threshold_blue < 1))
    bad("saturation_threshold_blue", "must be in (0, 1)");
  if (p.value_min < 0 || p.value_min > 255) bad("value_min", "must be in [0, 255]");
  if (!(p.canny_low >= 0)) bad("canny_low", "must be >= 0");
  if (!(p.canny_high >= p.canny_low)) bad("canny_high", "must be >= canny_low");
  if (p.min_area_px < 1) bad("min_area_px", "must be >= 1");
  if (p.max_area_frac_1000 < 1 || p.max_area_frac_1000 > 1000) bad("max_area_frac_1000", "must be in [1, 1000]");
  if (!(p.color_ratio_a > 0)) bad("color_ratio_a", "must be > 0");
  if (!(p.color_ratio_b > 0)) bad("color_ratio_b", "must be > 0");
  if (!(p.min_fill >= 0 && p.min_fill <= 1)) bad("min_fill", "must be in [0, 1]");
  if (!(p.d_min > 0)) bad("d_min", "must be > 0");
  if (!(p.d_max > p.d_min)) bad("d_max", "must be > d_min");
  if (!(p.w_min > 0 && p.w_min <= 1)) bad("w_min", "must be in (0, 1]");
  if (!(p.w_max >= 1)) bad("w_max", "must be >= 1");
  if (!(p.h_min > 0 && p.h_min <= 1)) bad("h_min", "must be in (0, 1]");
  if (!(p.h_max >= 1)) bad("h_max", "must be >= 1");
  if (!(p.ap_max_offset > 0)) bad("ap_max_offset", "must be > 0");
  if (!(p.ap_size_min > 0 && p.ap_size_min <= 1)) bad("ap_size_min", "must be in (0, 1]");
  if (!(p.ap_size_max >= 1)) bad("ap_size_max", "must be >= 1");
  if (!(p.shape_tolerance > 0 && p.shape_tolerance <= 1)) bad("shape_tolerance", "must be in (0, 1]");
  if (!(p.max_anisotropy >= 1)) bad("max_anisotropy", "must be >= 1");
  if (!(p.square_scale_min > 0 && p.square_scale_min <= 1)) bad("square_scale_min", "must be in (0, 1]");
  if (!(p.square_scale_max >= 1)) bad("square_scale_max", "must be >= 1");
  if (!(p.sheet_max_saturation > 0 && p.sheet_max_saturation <= 1)) bad("sheet_max_saturation", "must be in (0, 1]");
  if (!(p.sheet_min_value >= 0 && p.sheet_min_value <= 2)) bad("sheet_min_value", "must be in [0, 2]");
  if (!(p.cover_min >= 0 && p.cover_min < 1)) bad("cover_min", "must be in [0, 1)");
  if (!(p.cover_max > p.cover_min && p.cover_max <= 1)) bad("cover_max", "must be in (cover_min, 1]");
  if (!(p.sheet_uniformity >= 0 && p.sheet_uniformity <= 1)) bad("sheet_uniformity", "must be in [0, 1]");
  if (!(p.qr_max_brightness > 0 && p.qr_max_brightness <= 2)) bad("qr_max_brightness", "must be in (0, 2]");
  if (p.qr_dark_samples < 1 || p.qr_dark_samples > 26) bad("qr_dark_samples", "must be in [1, 26]");
  if (!(p.qr_dark_sample > 0 && p.qr_dark_sample <= 1)) bad("qr_dark_sample", "must be in (0, 1]");
  if (!(p.qr_clipped_max_brightness > 0 && p.qr_clipped_max_brightness <= 2))
    bad("qr_clipped_max_brightness", "must be in (0, 2]");
  if (!(p.qr_washed_dip >= 0 && p.qr_washed_dip <= 255)) bad("qr_washed_dip", "must be in [0, 255]");
  if (p.second_looks < 0 || p.second_looks > 64) bad("second_looks", "must be in [0, 64]");
  if (!(p.second_look_raise > 0 && p.second_look_raise < 1)) bad("second_look_raise", "must be in (0, 1)");
  if (p.faint_looks < 0 || p.faint_looks > 64) bad("faint_looks", "must be in [0, 64]");
  if (!(p.faint_look_blue > 0 && p.faint_look_blue < 1)) bad("faint_look_blue", "must be in (0, 1)");
  if (p.steep_looks < 0 || p.steep_looks > 64) bad("steep_looks", "must be in [0, 64]");
  if (p.veil_looks < 0 || p.veil_looks > 64) bad("veil_looks", "must be in [0, 64]");
  if (p.max_candidates < 3 || p.max_candidates > 4096) bad("max_candidates", "must be in [3, 4096]");
  // (2e9 cycles of a frame of 3600 small squares took 1.4 GB and more than 30 s)
  if (p.max_cycles < 1 || p.max_cycles > 1000000) bad("max_cycles", "must be in [1, 1000000]");
  if (p.centre_iterations < 0 || p.centre_iterations > 10) bad("centre_iterations", "must be in [0, 10]");
  if (p.align_iterations < -1 || p.align_iterations > 100) bad("align_iterations", "must be -1 (auto) or in [0, 100]");
}

}  // namespace

DetectorParams DetectorParams::load(const std::string& path) {
  const cv::FileStorage fs = openConfigFile(path, "detector params");
  const cv::FileNode root = fs.root();
  if (!root.isMap()) badFile(path, "not a map of parameter names to values");
  DetectorParams p;
  for (const cv::FileNode& n : root) {
    const std::string key = n.name();
    bool known = false;
    forEachField(p, [&](const char* name, auto& field) {
      if (key != name) return;
      known = true;
      readField(path, n, name, field);
    });
    if (!known) badFile(path, "unknown key '" + key + "'");
  }
  checkValues<std::runtime_error>(p, "detector params " + path + ": ");  // named with the file
  return p;
}

void DetectorParams::save(const std::string& path) const {
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::WRITE);
  } catch (const cv::Exception& e) {
    badFile(path, "cannot write (" + e.err + ")");
  }
  if (!fs.isOpened()) badFile(path, "cannot write");
  DetectorParams copy = *this;
  forEachField(copy, [&](const char* name, const auto& field) {
    if constexpr (std::is_same_v<std::decay_t<decltype(field)>, bool>) fs << name << static_cast<int>(field);
    else fs << name << field;
  });
}

void DetectorParams::validate() const { checkValues<std::invalid_argument>(*this, "detector params: "); }

// ====================================================================== results

double Detection::stageMs(const std::string& name) const {
  for (const auto& s : stages)
    if (name == s.name) return s.ms;
  return 0.0;
}

std::optional<Pose> poseFromCorners(const std::array<cv::Point2f, 4>& corners, const CameraModel& camera,
                                    double side_m) {
  Pose pose;
  if (!(side_m > 0) || !detail::estimatePose(corners, camera, side_m, pose)) return std::nullopt;
  return pose;
}

bool matchesTruth(const Landmark& d, const std::array<cv::Point2d, 4>& truth, double min_tol_px,
                  double tol_frac) {
  const double size = cv::norm(truth[1] - truth[0]) / 3.0;
  const double tol = std::max(min_tol_px, tol_frac * size);
  const cv::Point2f got[4] = {d.fip_tl, d.fip_tr, d.fip_bl, d.ap};
  for (int i = 0; i < 4; ++i)
    if (!(cv::norm(cv::Point2d(got[i]) - truth[i]) < tol)) return false;
  return true;
}

namespace {

// What decides each check (detail::Check), for people: the parameters, or
// what the refusal means.
const char* checkHint(detail::Check check) {
  using detail::Check;
  switch (check) {
    case Check::kNoAp: return "no red square where TR + BL - TL puts it: ap_max_offset, ap_size_min, ap_size_max";
    case Check::kSideLength: return "d_min, d_max";
    case Check::kSideRatio:
    case Check::kAngle: return "shape_tolerance";
    case Check::kSquareAnisotropic: return "max_anisotropy";
    case Check::kSquareScale: return "square_scale_min, square_scale_max";
    case Check::kSquareSize: return "ap_size_min, ap_size_max";
    case Check::kOutsideImage: return "part of the sheet is outside the image";
    case Check::kSheetSaturated: return "sheet_max_saturation";
    case Check::kSheetDark: return "sheet_min_value";
    case Check::kSheetUneven: return "sheet_uniformity";
    case Check::kNoQr: return "qr_max_brightness, qr_dark_samples, qr_dark_sample, qr_clipped_max_brightness, qr_washed_dip";
    case Check::kCentreSaturated:
    case Check::kCentreColoured: return "colour at the centre: a look-alike card";
    case Check::kCover: return "cover_min, cover_max; where the colour is smeared, the absorbed light's 0.25-0.42";
    case Check::kSquareAtCentre: return "a coloured square at the centre: a look-alike card";
    case Check::kOtherSquares: return "a coloured square on the sheet besides the four: a pattern, not a landmark";
    case Check::kNotConvex:
    case Check::kDegenerateMoments:
    case Check::kDegenerateSquare:
    case Check::kCount: return "";
  }
  return "";
}

// A check's place in detail::Check by its name (kNumChecks for a name not there).
int checkIndex(const std::string& name) {
  for (int i = 0; i < detail::kNumChecks; ++i)
    if (name == detail::checkName(static_cast<detail::Check>(i))) return i;
  return detail::kNumChecks;
}

}  // namespace

namespace {

// The rounds of looks after the first pass, as explanations name them: the
// parameter that limits their windows (and the reason for the squares left
// once it is spent), and what they look around.
struct LookRound {
  const char* name;
  const char* limit;           // the parameter's name ...
  int DetectorParams::*looks;  // ... and the parameter
  const char* spent;
  const char *one, *many, *which;
};
constexpr LookRound kLookRounds[] = {
    {"second look", "second_looks", &DetectorParams::second_looks, "second_looks spent", "pair of squares",
     "pairs of squares", " no landmark took"},
    {"faint look", "faint_looks", &DetectorParams::faint_looks, "faint_looks spent", "red square", "red squares",
     " no landmark took"},
    {"steep round", "steep_looks", &DetectorParams::steep_looks, "steep_looks spent", "red square", "red squares",
     " shaped as a steeply seen AP"},
    {"steep round (around blue squares)", "steep_looks", &DetectorParams::steep_looks, "steep_looks spent",
     "blue square", "blue squares", " shaped as a steeply seen FIP"},
    {"veil round", "veil_looks", &DetectorParams::veil_looks, "veil_looks spent", "red square", "red squares",
     " no landmark took"},
};
constexpr const LookRound& kSecondLookRound = kLookRounds[0];

// The looks after the first pass, as describe() gives them.
template <typename Pt>
std::string describeLooks(const Explanation& e, const DetectorParams& p, const Pt& pt) {
  if (p.front_end == "paper") return "";  // (the paper's front end has no looks)
  if (e.rounds.empty()) return "\nlooks after the first pass: none ran";
  auto plural = [](int n, const char* one, const char* many) { return cv::format("%d %s", n, n == 1 ? one : many); };
  std::string s = "\nlooks after the first pass:";
  for (const auto& r : e.rounds) {
    const LookRound* k = std::find_if(std::begin(kLookRounds), std::end(kLookRounds),
                                      [&](const LookRound& q) { return r.round == q.name; });
    if (k == std::end(kLookRounds)) continue;  // (not one of the detector's)
    s += "\n  " + r.round + cv::format(" (%s %d): ", k->limit, p.*(k->looks)) + plural(r.anchors, k->one, k->many) +
         k->which + ", " + plural(r.windows, "window", "windows") + " looked at";
    for (const auto& [why, n] : r.skipped) s += cv::format("; %d not: ", n) + why;
    for (const auto& l : e.looks) {
      if (l.round != r.round) continue;
      s += cv::format("\n    window %dx%d at (%d, %d) around ", l.window.width, l.window.height, l.window.x, l.window.y) +
           pt(l.around) + ", " + l.how + ": " + plural(l.fips, "FIP", "FIPs") + ", " + plural(l.aps, "AP", "APs") +
           ", " + plural(l.right_isosceles, "group of three FIPs", "groups of three FIPs") + " shaped as a landmark's; " +
           plural(l.landmarks, "landmark", "landmarks") + " found";
      if (l.dropped > 0) s += cv::format(" (%d not around its square: left out)", l.dropped);
      if (!l.refusals.empty()) {
        std::string by;
        for (const auto& [check, n] : l.refusals) by += cv::format("%s%d %s", by.empty() ? "" : ", ", n, check.c_str());
        s += "; refused: " + by;
      }
      for (const auto& g : l.refused) {
        s += "\n      FIPs " + pt(g.fips[0]) + " " + pt(g.fips[1]) + " " + pt(g.fips[2]);
        if (g.ap) s += ", AP " + pt(*g.ap);
        s += ": " + g.check;
      }
    }
  }
  if (e.looks_more > 0) s += "\n  " + plural(e.looks_more, "more look", "more looks") + " not listed";
  return s;
}

}  // namespace

std::string describe(const Explanation& e, const DetectorParams& p, const std::string& indent) {
  auto num = [](double v) { return cv::format("%g", v); };
  auto pt = [](const cv::Point2f& q) { return cv::format("(%.1f, %.1f)", q.x, q.y); };
  std::string s = cv::format("regions: %d blue, %d red (min_area_px %d, max_area_frac_1000 %d)", e.blue_regions,
                             e.red_regions, p.min_area_px, p.max_area_frac_1000);
  if (e.blue_sparse + e.red_sparse > 0)
    s += cv::format("\n  sparse, under min_fill %s: %d blue, %d red", num(p.min_fill).c_str(), e.blue_sparse, e.red_sparse);
  if (e.blue_off_colour + e.red_off_colour > 0)
    s += "\n  off colour (color_ratio_a " + num(p.color_ratio_a) + ", color_ratio_b " + num(p.color_ratio_b) +
         cv::format("): %d blue, %d red", e.blue_off_colour, e.red_off_colour);
  s += cv::format("\nsquares: %d FIP%s, %d AP%s", e.fips, e.fips == 1 ? "" : "s", e.aps, e.aps == 1 ? "" : "s");
  if (e.fips_over_cap > 0 || e.aps_over_cap > 0)
    s += cv::format(" (of %d and %d: max_candidates, %d, kept %s)", e.fips + e.fips_over_cap,
                    e.aps + e.aps_over_cap, p.max_candidates,
                    e.fips_over_cap > 0 ? "the FIPs near a red square first, then the largest" : "the largest");
  s += "\nFIP graph (d_min " + num(p.d_min) + ", d_max " + num(p.d_max) + ", w " + num(p.w_min) + ".." +
       num(p.w_max) + ", h " + num(p.h_min) + ".." + num(p.h_max) +
       cv::format("): %d pair%s, %d triangle%s, %d right isosceles", e.fip_pairs, e.fip_pairs == 1 ? "" : "s",
                  e.triangles, e.triangles == 1 ? "" : "s", e.right_isosceles);
  if (!e.refusals.empty()) {
    int total = 0;
    std::string by;
    for (const auto& [check, n] : e.refusals) {
      total += n;
      by += cv::format("%s%d %s", by.empty() ? "" : ", ", n, check.c_str());
    }
    s += cv::format("\nrefused: %d group%s of three FIPs (%s)", total, total == 1 ? "" : "s", by.c_str());
    if (static_cast<size_t>(total) > e.refused.size())
      s += cv::format("; the %zu that came furthest:", e.refused.size());
  }
  for (const auto& r : e.refused) {
    s += "\n  FIPs " + pt(r.fips[0]) + " " + pt(r.fips[1]) + " " + pt(r.fips[2]);
    if (r.ap) s += ", AP " + pt(*r.ap);
    s += ": " + r.check;
    const int i = checkIndex(r.check);
    const bool first = &r == &e.refused.front() || (&r)[-1].check != r.check;  // each check's hint once
    const char* hint = i < detail::kNumChecks ? checkHint(static_cast<detail::Check>(i)) : "";
    if (first && *hint) s += std::string(" (") + hint + ")";
  }
  s += describeLooks(e, p, pt);
  if (indent.empty()) return s;
  s.insert(0, indent);
  for (size_t at = s.find('\n'); at != std::string::npos; at = s.find('\n', at + 1)) s.insert(at + 1, indent);
  return s;
}

// ====================================================================== detector

namespace {

using detail::StageTimer;

// Three FIPs of a landmark: two sides alike and the third sqrt(2) longer,
// within this ratio (the squares' moments, which measure the sides, are
// unreliable for tiny blurred squares).
constexpr double kTriangleTolerance = 1.5;

// Sheet alignment (align_iterations): the sheet drawn at this many px per
// unit u (72 px across). Measured at 1 and 2.5 m (with OpenCV's ECC, before
// the Gauss-Newton fit): 16, sharper than the far landmarks' blurred edges,
// placed the corners of 15 cm sheets at 2.5 m worse (median 0.11 px against
// 0.07), and gained little at 1 m.
constexpr int kAlignPerUnit = 8;
// ... and for sheets over 120 px (nearer than about 0.75 m for 15 cm),
// fitted on about 60 of their pixels each way: at 8 px per unit the model
// is coarser than their image, and placed their corners worse than the
// centroids (0.5 m: median 0.166 px against 0.116); at 16, 0.121 px, and
// the rotation's 90th percentile 0.27 degrees against 1.30.
constexpr int kAlignNearPerUnit = 16;

// Missing squares measured, and (FIP pair, AP) triples looked at, per frame
// at most: what bounds the completion's cost in cluttered frames.
constexpr int kMaxCompletionTrials = 400;
constexpr int kMaxCompletionPairs = 20000;

// A completed AP is a square of red ink. In frames the adaptive glare pass
// took a strong veil out of (setGlareCorrected), its pixels over half its
// peak cover at least this share of the square the three FIPs predict (of
// its part in the image: a look's window may cut it): the colour speckle
// the pass's stretch leaves around a hot spot peaks in scattered pixels
// (about a quarter of such a square), a printed square, whole or clipped in
// part by the hot spot, 0.34 or more (the lighting sweep's glare points).
// Not in other frames: a steeply seen AP, a few pixels wide, may cover
// less (0.297 in one frame of DetectionRate.IssueTargetAtExtremeYaw9cm) ...
constexpr double kCompletedApMinFill = 0.3;
// ... and red for its brightness: their mean red excess at least this share
// of their mean level. A warm tint left on white paper is 0.03-0.07 of it;
// printed red, under every light of the lighting sweep, 0.13 or more.
constexpr double kCompletedApMinChroma = 0.1;

// Squares the second look starts from are at most this long (pixels, the
// longest axis): a landmark with larger ones has a sheet margin of 4 px or
// more, which neither blur nor JPEG's colour tints across. The faint look
// starts from red squares up to this long too: larger landmarks' blue
// squares are wide enough to keep their colour.
constexpr double kSecondLookMaxSide = 16.0;
// Pairs of unused squares the second look ranks, at most (its windows are
// fewer still: second_looks, an eighth of the frame).
constexpr size_t kMaxAnchors = 256;
// Red squares the faint look starts from cover at least this many pixels
// (a 9 cm landmark's AP at 1.5 m and 70 degrees of yaw covers about 20).
constexpr int kFaintLookMinArea = 6;
// ... and windows whose white is this much stronger in one channel than in
// another (a colour cast) are looked at.
constexpr double kFaintLookMinCast = 1.08;
// Red squares up to kSteepMaxSide long whose moments' axes differ by
// kSteepAxisRatio or more, of kSteepMinArea pixels or more, with paper
// beside them (paperBeside()), may be a steeply seen landmark's AP (printed
// 2:1 at 60 degrees of yaw, 3:1 at 70) whose blue squares, a few pixels
// wide, lost their colour to the camera's or JPEG's half-resolution colour:
// the faint look's steep round looks around them again, further (the
// thresholded square comes out shorter than printed: 5 px long for 8 at 70
// degrees), with the window's colour taken from its brightness
// (detail::colourFromBrightness). The same half-resolution colour rounds
// the thresholded AP too: at 70 degrees a 9 cm AP at 1.5 m, 8 x 2.7 px
// printed, often comes out 4-5 px by 2.5-3.5 (axes 1.3:1 to 1.8:1) and
// 4-14 px in all, so the bounds are those, not the printed shape's (2:1
// and the faint look's 6 px found 1420 of ld-eval yaw's 1500 frames for
// 9 cm at 1.5 m within +-70 degrees; these 1434). Longer squares have blue
// squares wide enough to keep their colour; the limit keeps the round's
// windows (and time) from red clutter.
constexpr double kSteepAxisRatio = 1.3, kSteepMaxSide = 10.0;
constexpr int kSteepMinArea = 4;
// Paper beside such a square reads at least this much of its red.
constexpr double kSteepApPaperOverInk = 0.8;
// Where the AP is lost (JPEG's colour joined it, 1-2 px of margin from the
// sheet's edge, to a red or brown background behind) but a FIP kept some
// blue, the steep round looks around the blue squares too: up to
// kSteepMaxSide long, of kSteepMinArea pixels or more, axes differing by
// kSteepFipAxisRatio or more (1.3, as for the AP, let a striped blue and
// white surface in a dim frame make a landmark of its recoloured stripes),
// with paper beside them, taking only a landmark one of whose FIPs is the
// window's blue square. On ld-eval yaw --trials 100, 9 cm at 1.5 m within
// +-70 degrees, 1434 -> 1441 of 1500 (seeds 2, 3: 1440 -> 1446, 1432 ->
// 1441); 15 cm at 2.5 m within +-80, 1461 -> 1478 of 1700.
constexpr double kSteepFipAxisRatio = 1.6;
// ... and paper beside them brighter than their blue by this much (0.8 of
// it, as beside an AP, started the round around blue clutter on ld-bench's
// scenes: +0.1 ms a 640x480 frame; printed blue is dark, its blue channel
// under the paper's even mixed with it at a steep angle).
constexpr double kSteepFipPaperOverInk = 1.1;
constexpr int64_t kSteepMaxPixels = 640 * 480 / 8;  // the steep round's windows in all, at most
constexpr double kFaintLookReach = 5.0, kSteepReach = 6.5;  // the windows' radius, in the square's longest axes
// The veil round (DetectorParams::veil_looks): the QR's centre lies 2.12 of
// the AP's sides from the AP's (4.24 u); its texture is measured over a
// disc of half a side there, its tint over the middle 0.4 (inside the
// modules, 1.8 u each way), in kVeilDirections directions, from pixels
// under kVeilClipped in every channel (kVeilMinTintPixels of them at
// least); a tint under kVeilMinTint levels in every channel is none.
constexpr int kVeilDirections = 8;
constexpr double kVeilQrReach = 2.12, kVeilTextureDisc = 0.5, kVeilTintDisc = 0.4, kVeilMinTint = 6;
constexpr int kVeilClipped = 250, kVeilMinTintPixels = 6;
// The veil round looks first around the red squares with the brightest
// paper beside them: the hot spot that washed a landmark's blue out clipped
// its sheet, which reads near white once the veil is out (244-252), where
// the red clutter of a strongly corrected frame mostly lies on darker
// things. The paper's brightness: the mean of the kVeilPaperKept brightest
// of kVeilPaperPoints points one side from the square's centre, each
// point's weakest channel (around an AP, the points towards TR, BL and the
// QR lie on the sheet's paper; those on its outer sides are just past the
// sheet's edge). On the lighting sweep's glare point, seeds 1-3, with each
// anchor's own window (below): 0.75 272 -> 278 of 300 found, 0.9 122 ->
// 128, 0.6 296 -> 298; ordered by the QR's texture instead, 0.75 gave 272.
constexpr int kVeilPaperPoints = 16, kVeilPaperKept = 6;
// The veil round's windows reach this many of the red square's longest
// axes each way from it (the faint look's window, kFaintLookReach, at
// least): the hot spot shrinks the thresholded AP as it pales its edges (a
// 14 px AP read 9.6 px long), and the FIP diagonal from it lies 4.24
// printed sides away (3 along each of the image's axes for a landmark
// upright in the image, up to 4.24 along one turned by 45 degrees): 4.4-6.2
// of the shrunken sides, outside a window of 5 for most turns, where the
// completion cannot measure it (2 of the misses traced at glare 0.75). The
// reach is the sweep's best, on the glare point of the lighting sweep at
// 0.75, seeds 1-6 (100 frames each): 5 561 of 600 found, 5.5 566, 6 570,
// 6.5 569.
constexpr double kVeilReach = 6.0;

// `mask` with its colour thresholds raised by `raise` (second_look_raise):
// the second look's, and the veil round's look again.
detail::MaskThresholds raisedMask(detail::MaskThresholds mask, double raise) {
  mask.blue = std::min(0.95, mask.blue + raise);
  mask.red = std::min(0.95, mask.red + raise);
  return mask;
}

// One warning per process about the GPU not being used (whether it could
// not be started or failed later).
std::atomic<bool> g_backend_warned{false};

void warnBackend(const std::string& what) {
  if (g_backend_warned.exchange(true)) return;
  // (named as the program that runs the detector: ld-detector, ld-detect, ...)
  std::cerr << program_invocation_short_name << ": warning: " << what << "\n";
}

}  // namespace

void detail::resetBackendWarning() { g_backend_warned = false; }

namespace {
// LD_GLES_AUTO_FORCE: "gles", "cpu", or nullptr (unset, empty, or another
// value, which is said once a process: it was ignored without a word).
const char* autoForce() {
  const char* env = std::getenv("LD_GLES_AUTO_FORCE");  // (tests: both outcomes on any machine)
  if (!env || !*env) return nullptr;
  if (std::strcmp(env, "cpu") == 0) return "cpu";
  if (std::strcmp(env, "gles") == 0) return "gles";
  static std::atomic<bool> said{false};
  if (!said.exchange(true))
    std::cerr << program_invocation_short_name << ": warning: LD_GLES_AUTO_FORCE=" << env
              << " is neither gles nor cpu: ignored (the medians choose)\n";
  return nullptr;
}
}  // namespace

struct Detector::Impl {
  DetectorParams params;
  bool paper = false;
  detail::FilterSettings filter_settings;
  std::unique_ptr<detail::Filters> filters;
  std::string fallback_why;  // why the CPU runs where the GPU was asked for
  // Backend "auto" with a GPU: while `rival` (the CPU's filters) is held,
  // frames run on the GPU's filters and the CPU's in blocks of kChoiceBlock,
  // the first of each block a warm-up after the switch, the others timed
  // with their transfers; after kChoiceBlocks blocks of each, the one with
  // the smaller median stays for good, decided as the next frame begins
  // (this frame's filtered image may be the other's). The two give the same
  // label and edge images (with a blur, all but a few pixels), so the
  // landmarks do not change with the backend.
  static constexpr int kChoiceBlock = 4, kChoiceBlocks = 3;
  static constexpr int kChoiceFrames = 2 * kChoiceBlock * kChoiceBlocks;
  std::unique_ptr<detail::Filters> rival;
  const char* force = nullptr;  // LD_GLES_AUTO_FORCE's choice for "auto" (autoForce)
  cv::Mat rival_labels, rival_edges;  // the CPU's outputs while it is the rival
  int trial = 0;
  std::vector<double> gpu_ms, cpu_ms;
  std::string choice;          // what the choice measured, once the GPU won
  const char* ran = nullptr;   // the backend of the last frame's filters
  bool glare_corrected = false;  // setGlareCorrected()

  std::optional<CameraModel> camera;  // as given
  CameraModel scaled;                 // for the current frame size
  double side_m = 0;
  // why frames of misfit_size get no pose (CameraModel::misfit), made once a size
  std::string misfit;
  cv::Size misfit_size;

  // Buffers kept between frames.
  cv::Mat converted, labels, edges;
  std::vector<std::vector<cv::Point>> contours;
  detail::RunScratch runs;
  std::vector<detail::Region> regions, fips, aps;
  // classify()'s scratch over the cap (kept: no allocation per frame)
  std::vector<detail::Region> kept_fips;
  std::vector<std::pair<double, size_t>> aps_by_x;
  std::vector<double> near_score;
  std::vector<size_t> near_order;
  int fips_found = 0, aps_found = 0;                // classify()'s candidates before the cap
  std::vector<uint8_t> adjacency, used;
  int looks_run = 0;  // this frame's looks so far (Region::pass)
  detail::RegionIndex ap_index;
  std::vector<std::array<int, 3>> cycles;
  std::vector<detail::Candidate> candidates, choices;
  // the second and the faint look's
  struct Anchor {
    cv::Point2d centre;
    double radius;
    int rank;  // second look: 0 an AP and a FIP, 1 two FIPs; faint look: 0 (one square alone)
    int area;  // the larger square's (faint look: the AP's)
    double side = 0;  // faint look: the red square's longest axis
  };
  std::vector<Anchor> anchors, steep_anchors, steep_fip_anchors;
  std::vector<detail::Candidate> left_out;  // a round's landmarks left out as not their window's square's
  std::vector<std::pair<double, int>> veil_order;  // (paper beside, anchor): the veil round's order
  std::vector<Anchor> veil_anchors;
  std::vector<std::pair<cv::Rect, int64_t>> blobs;  // the first pass's larger regions: bbox, area
  detail::RegionIndex fip_index;
  std::vector<cv::Rect> looked;
  cv::Mat look_labels_buf;                 // look()'s labels are a window-sized view of it
  cv::Mat faint_src_buf, faint_img_buf;    // the faint look's white-balanced windows
  cv::Mat faint_rc_buf, faint_rc_img_buf;  // ... steep ones' colour from brightness
  std::vector<float> rc_scratch;
  std::vector<cv::Point3f> ink_scratch;  // joinPieces()'s pixels
  // sheet alignment (align_iterations): the sheet as green shows it, built
  // at the first alignment; the alignment's buffers
  detail::SheetModel align_model, align_model_near;
  detail::AlignScratch align_scratch;
  // Explaining the looks (detect() with an Explanation runs the detection
  // once more with `trace` set): the current look's labelling and square.
  Explanation* trace = nullptr;
  std::string trace_how;
  bool veil_measured = false;  // whether the last veil window measured a tint
  cv::Point2f trace_around;
  // A new round in the trace (nullptr when not tracing), and a reason its
  // squares were not looked around, `n` more times.
  Explanation::Round* traceRound(const LookRound& round, size_t anchors_n) {
    if (!trace) return nullptr;
    trace->rounds.push_back({round.name, static_cast<int>(anchors_n), 0, {}});
    return &trace->rounds.back();
  }
  // (a C string: nothing is made when not tracing)
  static void traceSkip(Explanation::Round* r, const char* reason, size_t n = 1) {
    if (!r || n == 0) return;
    for (auto& [why, count] : r->skipped)
      if (why == reason) {
        count += static_cast<int>(n);
        return;
      }
    r->skipped.emplace_back(reason, static_cast<int>(n));
  }
  size_t tracedLooks() const { return trace ? trace->looks.size() + static_cast<size_t>(trace->looks_more) : 0; }
  // The groups of three FIPs shaped as a landmark's (of `cycles` over `fips`
  // and `aps`, graph()'s) that make none, each with the check that refused
  // it (verification's on `img`) and its positions moved by `offset`; `found`
  // tells a square of a landmark found. Returns how many are shaped so.
  struct RefusedGroup {
    int check;      // its place in detail::Check
    double unlike;  // |log| of the triangle's size over a landmark's, in the squares' frame
    Explanation::Refused group;
  };
  int refusedGroups(const cv::Mat& img, const std::function<bool(const detail::Region&)>& found,
                    const cv::Point2f& offset, std::vector<RefusedGroup>& out);
  // The counts per check of `groups`, and the `keep` that came furthest.
  static void tally(std::vector<RefusedGroup>& groups, size_t keep,
                    std::vector<std::pair<std::string, int>>& refusals, std::vector<Explanation::Refused>& refused);
  int white_hist[766];                     // the faint look's histogram of b + g + r ...
  cv::Vec3i white_sums[766];               // ... and its pixels' channel sums per bin
  std::vector<detail::Region> all_fips, all_aps;
  std::vector<detail::Candidate> all_candidates;
  Detection det;

  explicit Impl(const DetectorParams& p) : params(p) {
    params.validate();
    paper = params.front_end == "paper";
    filter_settings = detail::FilterSettings::from(params);
    if (params.backend == "auto") force = autoForce();  // (read as the detector is made)
    if (params.backend != "cpu") {
      std::string why;
      // "auto" takes a GPU, not a software renderer emulating one on the CPU
      // (LD_GLES_AUTO_SOFTWARE: "auto" takes a software renderer too, and
      // times it against the CPU like a GPU; for tests)
      filters = detail::makeGlesFilters(why, true, params.backend == "auto" && !detail::envFlag("LD_GLES_AUTO_SOFTWARE"));
      if (!filters) {
        if (params.backend == "gles")
          throw BackendUnavailable("GLES backend unavailable: " + why + " (backend \"auto\" falls back to the CPU)");
        fallback_why = why;
        // (a GPU forced where auto found none was dropped without a word)
        warnBackend("GLES backend unavailable (" + why + "); running the CPU backend" +
                    (force && std::strcmp(force, "gles") == 0
                         ? "; LD_GLES_AUTO_FORCE=gles is ignored: auto has no GPU to keep"
                         : ""));
      } else if (params.backend == "auto") {
        rival = detail::makeCpuFilters();
      }
    }
    if (!filters) filters = detail::makeCpuFilters();
  }

  // Stages 1-3, with "auto"'s choice between the GPU and the CPU on the
  // first frames (once the GPU's own shader path is chosen).
  const cv::Mat* runFilters(const cv::Mat& img, StageTimer& timer) {
    if (rival && trial == kChoiceFrames) choose();
    if (!rival || !filters->settled(paper)) return runBackend(img, timer);
    const bool on_cpu = (trial / kChoiceBlock) % 2 == 1;
    const auto t0 = StageTimer::Clock::now();
    const cv::Mat* filtered = on_cpu ? filterOn(*rival, img, rival_labels, rival_edges, timer) : runBackend(img, timer);
    if (!rival) return filtered;  // the GPU failed: the CPU runs from now on
    if (on_cpu) labels = rival_labels, edges = rival_edges, ran = rival->name();
    const double ms = std::chrono::duration<double, std::milli>(StageTimer::Clock::now() - t0).count();
    if (trial % kChoiceBlock != 0 && !(last_large && !on_cpu)) (on_cpu ? cpu_ms : gpu_ms).push_back(ms);
    ++trial;
    return filtered;
  }

  // Keeps the GPU or the CPU for good, by their medians.
  void choose() {
    auto median = [](std::vector<double> v) {
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      return v[v.size() / 2];
    };
    const double gpu = median(gpu_ms), cpu = median(cpu_ms);
    const bool keep_cpu = force ? std::strcmp(force, "cpu") == 0 : cpu <= gpu;
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "the filters took %.3f ms on the GPU, transfers included, against %.3f ms on the CPU "
                  "(medians of %zu frames each)%s",
                  gpu, cpu, gpu_ms.size(), force && *force ? ", overridden by LD_GLES_AUTO_FORCE" : "");
    if (keep_cpu) {
      fallback_why = "auto chose the CPU: " + filters->info(paper) + ": " + buf;
      labels.release(), edges.release();  // (the last frame's may be views of the GPU's buffers)
      filters = std::move(rival);
    } else {
      choice = std::string("auto chose the GPU: ") + buf;
    }
    endChoice();
  }

  void endChoice() {
    rival.reset();
    rival_labels.release(), rival_edges.release();
    gpu_ms = {}, cpu_ms = {};
  }

  // Stages 1-3 on `f`'s filters into `l` (fast front end) or `e` (paper);
  // the image the labels were taken on.
  const cv::Mat* filterOn(detail::Filters& f, const cv::Mat& img, cv::Mat& l, cv::Mat& e, StageTimer& timer) {
    // Each frame leaves its thread free of the GPU's context, so that the
    // next may run in another (a Detector is used from one thread at a
    // time, not always the same one); 2-6 us a frame on Mesa.
    struct Release {
      detail::Filters& f;
      ~Release() { f.releaseThread(); }
    } release{f};
    const cv::Mat* filtered = &img;
    if (!paper) f.labelMap(img, filter_settings, l, filtered, timer);
    else f.edgeMap(img, filter_settings, e, timer);
    return filtered;
  }

  std::unique_ptr<detail::Filters> cpu_for_large;  // frames the GPU backend does not take
  bool large_said = false, last_large = false;  // (last_large: the last frame was one)
  // Stages 1-3 on the backend's filters; a GPU failing mid-run is dropped for
  // the CPU (auto's rival, where it has one), and the frame done again there.
  const cv::Mat* runBackend(const cv::Mat& img, StageTimer& timer) {
    ran = filters->name();
    last_large = false;
    try {
      return filterOn(*filters, img, labels, edges, timer);
    } catch (const detail::FrameTooLarge& e) {
      last_large = true;
      // (this frame alone on the CPU: a stray huge frame does not cost the GPU for good)
      if (!large_said) {
        std::cerr << program_invocation_short_name << ": warning: " << e.what()
                  << "; frames that large run on the CPU backend\n";
        large_said = true;
      }
      if (!cpu_for_large) cpu_for_large = detail::makeCpuFilters();
      labels.release();
      ran = cpu_for_large->name();
      return filterOn(*cpu_for_large, img, labels, edges, timer);
    } catch (const detail::BackendFailure& e) {
      fallback_why = e.what();
      warnBackend(std::string("GLES backend failed (") + e.what() + "); running the CPU backend from now on");
      filters = rival ? std::move(rival) : detail::makeCpuFilters();
      choice.clear();
      endChoice();
      ran = filters->name();
    }
    labels.release();  // may be a view of the GPU backend's buffer
    return filterOn(*filters, img, labels, edges, timer);
  }

  void run(const cv::Mat& input);
  void explain(Explanation& e);
  // The last run()'s colour image and filtered image (nullptr when it had
  // no colour image), for explain() to count the same frame's regions on.
  const cv::Mat* last_img = nullptr;
  const cv::Mat* last_src = nullptr;
  // The input as 8-bit BGR (`converted` when it had alpha); null when it is
  // not an image with colour.
  const cv::Mat* colourImage(const cv::Mat& input);
  int maxArea(const cv::Mat& img) const {
    return static_cast<int>(
        std::min<int64_t>(INT32_MAX, static_cast<int64_t>(img.total()) * params.max_area_frac_1000 / 1000));
  }
  void classify();
  int graph();
  void geometry(const cv::Mat& img, const cv::Mat& label_map);
  void complete(const cv::Mat& img, const cv::Mat& label_map);
  void secondLook(const cv::Mat& img, const cv::Mat& filtered, int max_area);
  void faintLook(const cv::Mat& img, const cv::Mat& filtered, int max_area);
  void faintWindow(const cv::Rect& win, const cv::Mat& img, const cv::Mat& filtered,
                   const detail::MaskThresholds& pale, int max_area, bool steep);
  int64_t veilWindow(const cv::Rect& win, const Anchor& a, const cv::Mat& img, const cv::Mat& filtered,
                     const detail::MaskThresholds& pale, int max_area, int64_t pixels_left);
  // `used`: the FIPs (then the APs, after fips.size()) some candidate takes.
  // The looks: the first pass's squares and landmarks go aside into all_*,
  // each look's join them there (look()), and endLooks() brings all back.
  void swapLooksLists() {
    std::swap(fips, all_fips);
    std::swap(aps, all_aps);
    std::swap(candidates, all_candidates);
  }
  void endLooks() {
    swapLooksLists();
    all_fips.clear();
    all_aps.clear();
    all_candidates.clear();
  }
  // An anchor's window (clipped to `frame`), unless its centre lies in a
  // window already looked at.
  bool freshWindow(const Anchor& a, const cv::Rect& frame, cv::Rect& win) const {
    const cv::Point centre(static_cast<int>(std::lround(a.centre.x)), static_cast<int>(std::lround(a.centre.y)));
    for (const auto& w : looked)
      if (w.contains(centre)) return false;
    win = anchorWindow(a, frame);
    return true;
  }
  // The window of anchor a: its radius around its centre, within the frame.
  static cv::Rect anchorWindow(const Anchor& a, const cv::Rect& frame) {
    const cv::Point centre(static_cast<int>(std::lround(a.centre.x)), static_cast<int>(std::lround(a.centre.y)));
    const int r = static_cast<int>(std::ceil(a.radius));
    return cv::Rect(centre.x - r, centre.y - r, 2 * r + 1, 2 * r + 1) & frame;
  }
  // The brightness of the paper one side from a red square (kVeilPaperPoints).
  static double veilPaper(const cv::Mat& img, const Anchor& a) {
    std::array<int, kVeilPaperPoints> v{};
    for (int d = 0; d < kVeilPaperPoints; ++d) {
      const double angle = 2 * CV_PI * d / kVeilPaperPoints;
      const long x = std::lround(a.centre.x + a.side * std::cos(angle));
      const long y = std::lround(a.centre.y + a.side * std::sin(angle));
      if (x < 0 || y < 0 || x >= img.cols || y >= img.rows) continue;  // (0 outside the frame)
      const uint8_t* q = img.ptr<uint8_t>(static_cast<int>(y)) + 3 * x;
      v[static_cast<size_t>(d)] = std::min({q[0], q[1], q[2]});
    }
    std::partial_sort(v.begin(), v.begin() + kVeilPaperKept, v.end(), std::greater<int>());
    double sum = 0;
    for (int i = 0; i < kVeilPaperKept; ++i) sum += v[static_cast<size_t>(i)];
    return sum / kVeilPaperKept;
  }
  void markUsed() {
    const size_t nf = fips.size();
    used.assign(nf + aps.size(), 0);
    for (const auto& c : candidates) used[c.tl] = used[c.tr] = used[c.bl] = used[nf + c.ap] = 1;
  }
  void look(const cv::Rect& win, const cv::Mat& src, const cv::Mat& img, const detail::MaskThresholds& t, int max_area,
            bool in_window);
  // The trace's record of the look whose squares and landmarks are in
  // fips, aps and candidates (in the window's coordinates when `in_window`);
  // nullptr beyond Explanation::kMaxLooks.
  Explanation::Look* traceLook(const cv::Rect& win, const cv::Mat& img, bool in_window);
};

// Landmarks with one square merged into a same-coloured background (the
// sheet's margin is a quarter of a square: at steep angles or with blur the
// mask joins them) or too faint for the mask: three squares found, the fourth
// measured where the layout puts it.
void Detector::Impl::complete(const cv::Mat& img, const cv::Mat& label_map) {
  const DetectorParams& p = params;
  const int n0 = static_cast<int>(fips.size());
  markUsed();
  auto labelAt = [&](const cv::Point2d& q) -> int {
    const int x = static_cast<int>(std::lround(q.x)), y = static_cast<int>(std::lround(q.y));
    return x >= 0 && y >= 0 && x < label_map.cols && y < label_map.rows ? label_map.at<uint8_t>(y, x) : -1;
  };
  auto mean = [](std::initializer_list<const detail::Region*> rs) {
    detail::Region m = **rs.begin();
    m.sxx = m.sxy = m.syy = 0;
    for (const auto* r : rs) {
      m.sxx += r->sxx / rs.size();
      m.sxy += r->sxy / rs.size();
      m.syy += r->syy / rs.size();
    }
    return m;
  };
  auto order = [&](detail::Candidate& c) {
    const cv::Point2d t(fips[c.tl].cx, fips[c.tl].cy), a(fips[c.tr].cx, fips[c.tr].cy),
        b(fips[c.bl].cx, fips[c.bl].cy);
    if ((a - t).cross(b - t) < 0) std::swap(c.tr, c.bl);
  };
  // The known squares are squares of the frame the centres make (verify
  // checks it again; here it saves measuring the missing one).
  auto squaresFit = [&](std::initializer_list<const detail::Region*> rs, cv::Point2d e1, cv::Point2d e2) {
    for (const auto* r : rs) {
      double scale, aniso;
      if (!detail::squareConsistency(*r, e1, e2, scale, aniso) ||
          aniso > detail::anisotropyLimit(p.max_anisotropy, r->area) || scale < p.square_scale_min ||
          scale > p.square_scale_max)
        return false;
    }
    return true;
  };
  auto tryCandidate = [&](detail::Candidate c) {
    c.completed = true;
    c.error = 1.0;  // ranks below complete landmarks
    order(c);
    if (!detail::verify(c, fips, aps, img, p, nullptr, glare_corrected)) return false;
    candidates.push_back(c);
    return true;
  };
  // A FIP missing: two FIPs joined by an edge, and an AP.
  int budget = kMaxCompletionTrials, evals = kMaxCompletionPairs;
  for (int i = 0; i < n0 && budget > 0 && evals > 0; ++i)
    for (int j = i + 1; j < n0; ++j) {
      if (!adjacency[static_cast<size_t>(i) * n0 + j] || used[i] || used[j]) continue;
      const detail::Region shape = mean({&fips[i], &fips[j]});
      const double side = shape.side();
      const double min_peak = 0.5 * std::min(detail::meanExcess(fips[i]), detail::meanExcess(fips[j]));
      const cv::Point2d pi(fips[i].cx, fips[i].cy), pj(fips[j].cx, fips[j].cy);
      const double dij = detail::normalisedDistance(fips[i], fips[j]);
      // The AP lies within about twice the pair's distance.
      ap_index.near(aps, pi.x, pi.y, 2.5 * cv::norm(pj - pi), [&](int k) {
        if (used[n0 + k] || budget <= 0 || --evals < 0) return;
        const double ratio = aps[k].side() / side;
        if (ratio < p.ap_size_min || ratio > p.ap_size_max) return;
        const cv::Point2d pa(aps[k].cx, aps[k].cy);
        // Distances in the frame of the squares' moments: neighbours 3 apart,
        // the diagonal 4.24 (only their ratios count: sizes are unreliable).
        const double dia = detail::normalisedDistance(fips[i], aps[k]);
        const double dja = detail::normalisedDistance(fips[j], aps[k]);
        if (!(dia >= p.d_min && dia <= p.d_max && dja >= p.d_min && dja <= p.d_max)) return;
        auto near = [](double ratio, double want) {
          return ratio > want / kTriangleTolerance && ratio < want * kTriangleTolerance;
        };
        // The missing one opposite the AP (it is TL: i, j diagonal, the AP next
        // to both), opposite j (i is TL: j next to i, the AP diagonal to i),
        // or opposite i (j is TL).
        const bool fits[3] = {near(dij / dia, std::sqrt(2.0)) && near(dia / dja, 1.0),
                              near(dia / dij, std::sqrt(2.0)) && near(dja / dij, 1.0),
                              near(dja / dij, std::sqrt(2.0)) && near(dia / dij, 1.0)};
        const cv::Point2d miss[3] = {pi + pj - pa, pi + pa - pj, pj + pa - pi};
        for (int conf = 0; conf < 3; ++conf) {
          if (!fits[conf] || labelAt(miss[conf]) == detail::kRed || labelAt(miss[conf]) < 0) continue;
          // The landmark's frame: TL to TR and TL to BL (their order does not matter here).
          const cv::Point2d tl = conf == 0 ? miss[0] : conf == 1 ? pi : pj;
          const cv::Point2d o1 = conf == 0 ? pi : miss[conf], o2 = conf == 0 ? pj : conf == 1 ? pj : pi;
          if (!squaresFit({&fips[i], &fips[j], &aps[k]}, o1 - tl, o2 - tl)) continue;
          detail::Region r;
          --budget;
          if (!detail::completeSquare(img, miss[conf], detail::kBlue, o1 - tl, o2 - tl, min_peak, r)) continue;
          r.pass = -1;  // measured on the image, whole: no pieces to join
          fips.push_back(r);
          const int m = static_cast<int>(fips.size()) - 1;
          detail::Candidate c;
          c.ap = k;
          if (conf == 0) c.tl = m, c.tr = i, c.bl = j;
          if (conf == 1) c.tl = i, c.tr = m, c.bl = j;
          if (conf == 2) c.tl = j, c.tr = m, c.bl = i;
          if (tryCandidate(c)) break;
          fips.pop_back();
        }
      });
    }
  // The AP missing: a 3-cycle of FIPs.
  for (const auto& cyc : cycles) {
    if (budget <= 0) break;
    if (used[cyc[0]] || used[cyc[1]] || used[cyc[2]]) continue;
    double min_peak = 1e9;
    for (int v : cyc) min_peak = std::min(min_peak, 0.5 * detail::meanExcess(fips[v]));
    int corner = 0;
    if (!detail::rightIsosceles(cyc, fips, kTriangleTolerance, &corner)) continue;
    {
      const auto& c0 = fips[cyc[corner]];
      const auto& a = fips[cyc[(corner + 1) % 3]];
      const auto& b = fips[cyc[(corner + 2) % 3]];
      const cv::Point2d pred(a.cx + b.cx - c0.cx, a.cy + b.cy - c0.cy);
      if (labelAt(pred) == detail::kBlue || labelAt(pred) < 0) continue;
      detail::Region r;
      const cv::Point2d tl(c0.cx, c0.cy);
      const cv::Point2d e1 = cv::Point2d(a.cx, a.cy) - tl, e2 = cv::Point2d(b.cx, b.cy) - tl;
      if (!squaresFit({&c0, &a, &b}, e1, e2)) continue;
      --budget;
      if (!detail::completeSquare(img, pred, detail::kRed, e1, e2, min_peak, r)) continue;
      // (2u)^2, u a sixth of TL to TR; only its part in the image (a look's
      // window, or the frame, may cut it), sampled at 8 x 8 points
      int in_image = 0;
      for (int k = 0; k < 64; ++k) {
        const cv::Point2d q = pred + (e1 * ((k % 8 + 0.5) / 4 - 1) + e2 * ((k / 8 + 0.5) / 4 - 1)) * (1.0 / 6);
        in_image += q.x >= -0.5 && q.y >= -0.5 && q.x < img.cols - 0.5 && q.y < img.rows - 0.5;
      }
      const double square_px = 4 * std::abs(e1.cross(e2)) / 36 * in_image / 64;
      if ((glare_corrected && r.area < kCompletedApMinFill * square_px) ||
          detail::meanChroma(r) < kCompletedApMinChroma)
        continue;
      r.pass = -1;
      aps.push_back(r);
      detail::Candidate c;
      c.tl = cyc[corner], c.tr = cyc[(corner + 1) % 3], c.bl = cyc[(corner + 2) % 3];
      c.ap = static_cast<int>(aps.size()) - 1;
      if (!tryCandidate(c)) aps.pop_back();
    }
  }
}

// 5. colour: FIP and AP candidates of `regions` by the colour ratios,
// largest first (the graph's 3-cycles come in index order: when a cluttered
// frame has more than max_cycles, those among the larger squares are kept).
void Detector::Impl::classify() {
  const DetectorParams& p = params;
  fips.clear();
  aps.clear();
  for (const auto& r : regions) {
    if (!paper && detail::fill(r) < p.min_fill) continue;
    if (r.colour == detail::kBlue && detail::isFip(r, p.color_ratio_a, p.color_ratio_b)) fips.push_back(r);
    else if (r.colour == detail::kRed && detail::isAp(r, p.color_ratio_a, p.color_ratio_b)) aps.push_back(r);
  }
  const auto larger = [](const detail::Region& a, const detail::Region& b) {
    return std::tie(b.area, a.cy, a.cx) < std::tie(a.area, b.cy, b.cx);
  };
  const auto cap = static_cast<size_t>(p.max_candidates);
  fips_found = static_cast<int>(fips.size());
  aps_found = static_cast<int>(aps.size());
  std::sort(aps.begin(), aps.end(), larger);
  if (aps.size() > cap) aps.resize(cap);
  if (fips.size() <= cap) {
    std::sort(fips.begin(), fips.end(), larger);
    return;
  }
  // Over the cap, the FIPs that could be a landmark's first: those with a
  // red square within reach (a FIP's centre is at most 4.25 of its sides
  // from its AP's, about 10 at the steepest view; 12 here) and of a size a
  // landmark's squares share, the likest their AP in size first, in steps
  // of 1.5 times (a landmark's squares are printed the same size); then the
  // rest; each the largest first. (Kept by size alone, hundreds of blue
  // things larger than a far landmark's squares pushed its squares out.)
  aps_by_x.clear();  // (the APs in x order: each FIP looks at those within its reach in x alone)
  for (size_t i = 0; i < aps.size(); ++i) aps_by_x.emplace_back(aps[i].cx, i);
  std::sort(aps_by_x.begin(), aps_by_x.end());
  near_score.resize(fips.size());  // (infinite: no AP within reach)
  for (size_t k = 0; k < fips.size(); ++k) {
    const detail::Region& f = fips[k];
    const double reach = 12 * std::sqrt(static_cast<double>(f.area));
    double best = std::numeric_limits<double>::infinity();  // |log| of the area ratio to the likest AP in reach
    for (auto it = std::lower_bound(aps_by_x.begin(), aps_by_x.end(), std::make_pair(f.cx - reach, size_t{0}));
         it != aps_by_x.end() && it->first <= f.cx + reach; ++it) {
      const detail::Region& ap = aps[it->second];
      const double dx = ap.cx - f.cx, dy = ap.cy - f.cy;
      if (dx * dx + dy * dy <= reach * reach && ap.area * 9 >= f.area && f.area * 9 >= ap.area)
        best = std::min(best, std::abs(std::log(static_cast<double>(f.area) / ap.area)));
    }
    near_score[k] = std::floor(best / std::log(1.5));
  }
  near_order.resize(fips.size());
  std::iota(near_order.begin(), near_order.end(), size_t{0});
  std::partial_sort(near_order.begin(), near_order.begin() + static_cast<std::ptrdiff_t>(cap), near_order.end(),
                    [&](size_t a, size_t b) {
                      if (near_score[a] != near_score[b]) return near_score[a] < near_score[b];
                      return larger(fips[a], fips[b]);
                    });
  kept_fips.clear();
  for (size_t i = 0; i < cap; ++i) kept_fips.push_back(fips[near_order[i]]);
  fips.swap(kept_fips);
}

// 6. the FIP graph of `fips` (`adjacency`: the distance and size-ratio
// constraints), its 3-cycles, and the index of `aps` for the AP choice.
int Detector::Impl::graph() {
  const DetectorParams& p = params;
  const int n = static_cast<int>(fips.size());
  int edges = 0;
  adjacency.assign(static_cast<size_t>(n) * n, 0);
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      if (detail::fipEdge(fips[i], fips[j], p)) {
        adjacency[static_cast<size_t>(i) * n + j] = adjacency[static_cast<size_t>(j) * n + i] = 1;
        ++edges;
      }
  detail::threeCycles(adjacency, n, cycles, static_cast<size_t>(p.max_cycles));
  ap_index.build(aps);
  return edges;
}

// 6-7. geometry: the FIP graph of `fips`, its 3-cycles, the AP among `aps`,
// verification, completion, overlaps: `candidates`.
void Detector::Impl::geometry(const cv::Mat& img, const cv::Mat& label_map) {
  const DetectorParams& p = params;
  const int n = static_cast<int>(fips.size());
  candidates.clear();
  // Three FIPs and an AP make a landmark; two FIPs and an AP, or three FIPs,
  // may be one whose fourth square the completion finds.
  const bool whole = n >= 3 && !aps.empty();
  const bool completion = !paper && p.complete_missing && (n >= 3 || (n >= 2 && !aps.empty()));
  if (!whole && !completion) return;
  graph();
  for (const auto& cyc : cycles) {
    if (!whole || !detail::rightIsosceles(cyc, fips, kTriangleTolerance)) continue;
    // Of the APs that fit, the one whose landmark verifies best.
    detail::Candidate c;
    if (detail::bestVerifiedChoice(cyc, fips, aps, img, p, choices, c, &ap_index, glare_corrected))
      candidates.push_back(c);
  }
  if (completion) complete(img, label_map);
  detail::resolveOverlaps(candidates, static_cast<int>(fips.size()), static_cast<int>(aps.size()), used);
}

// A second look around the squares no landmark took: a square whose
// neighbour merged with a background of its colour through the sheet's thin
// margin (behind a steeply seen or blurred landmark, JPEG's half-resolution
// colour tints the margin) comes apart under a stricter mask. Each look
// labels a window around a pair of such squares at saturation thresholds
// raised by second_look_raise and runs the same regions, colour, geometry
// and verification there; what it finds joins the first pass's landmarks
// unless one of them is already there.
void Detector::Impl::secondLook(const cv::Mat& img, const cv::Mat& filtered, int max_area) {
  const DetectorParams& p = params;
  const int nf = static_cast<int>(fips.size()), na = static_cast<int>(aps.size());
  markUsed();
  // Where a landmark may lie: an AP and a FIP, or two FIPs, that no
  // landmark took and that could be two squares of one (the graph's
  // distance and size constraints). Around the pair's midpoint, the other
  // squares lie within half its distance plus three sides (the squares'
  // longest axis is their side, foreshortened or not): the window adds five,
  // for squares the threshold made smaller than printed. Windows are at most
  // 0.6 of the frame's shorter side across (a larger landmark's margins are
  // too wide to merge through), AP pairs first, then the smaller windows
  // first; at most kMaxAnchors of them are kept (cluttered frames make
  // thousands of pairs).
  anchors.clear();
  fip_index.build(fips);
  const double max_radius = 0.3 * std::min(img.cols, img.rows);
  auto pairUp = [&](const detail::Region& a, const detail::Region& b, int rank) {
    const double side = std::max(detail::maxAxis(a), detail::maxAxis(b));
    if (side > kSecondLookMaxSide) return;
    const double radius = std::max(12.0, 0.5 * std::hypot(a.cx - b.cx, a.cy - b.cy) + 5 * side);
    if (radius <= max_radius) anchors.push_back({{(a.cx + b.cx) / 2, (a.cy + b.cy) / 2}, radius, rank, std::max(a.area, b.area)});
  };
  for (int k = 0; k < na; ++k) {
    if (used[nf + k]) continue;
    const detail::Region& ap = aps[k];
    const double side = ap.side();
    fip_index.near(fips, ap.cx, ap.cy, p.d_max * detail::maxAxis(ap) / p.ap_size_min, [&](int i) {
      if (used[i]) return;
      const double ratio = side / fips[i].side(), d = detail::normalisedDistance(fips[i], ap);
      if (ratio >= p.ap_size_min && ratio <= p.ap_size_max && d >= p.d_min && d <= p.d_max)
        pairUp(ap, fips[i], 0);
    });
  }
  for (int i = 0; i < nf; ++i) {
    if (used[i]) continue;
    fip_index.near(fips, fips[i].cx, fips[i].cy, p.d_max * detail::maxAxis(fips[i]) * p.w_max, [&](int j) {
      if (j > i && !used[j] && detail::fipEdge(fips[i], fips[j], p)) pairUp(fips[i], fips[j], 1);
    });
  }
  if (anchors.empty()) return;
  const auto first = [](const Anchor& a, const Anchor& b) {
    return std::tie(a.rank, a.radius, a.centre.x, a.centre.y) < std::tie(b.rank, b.radius, b.centre.x, b.centre.y);
  };
  const size_t pairs = anchors.size();  // (for the trace: before the cut)
  if (anchors.size() > kMaxAnchors) {
    std::nth_element(anchors.begin(), anchors.begin() + kMaxAnchors, anchors.end(), first);
    anchors.resize(kMaxAnchors);
  }
  std::sort(anchors.begin(), anchors.end(), first);
  // A merge leaves a region in the window larger than the pair's squares
  // (2.5 times the larger: the first pass's regions, kept or not, from the
  // labelling's accumulators); windows without one are not looked at.
  blobs.clear();
  for (const auto& r : runs.acc)
    if (r.n >= 12) blobs.push_back({cv::Rect(r.x0, r.y0, r.x1 - r.x0 + 1, r.y1 - r.y0 + 1), r.n});
  std::sort(blobs.begin(), blobs.end(), [](const auto& a, const auto& b) {
    return std::tie(b.second, a.first.y, a.first.x) < std::tie(a.second, b.first.y, b.first.x);
  });  // largest first

  const detail::MaskThresholds strict = raisedMask(filter_settings.mask, p.second_look_raise);
  // The first pass's lists stay aside; each look's squares and landmarks join them.
  swapLooksLists();
  const cv::Rect frame(0, 0, img.cols, img.rows);
  // Windows cover at most an eighth of the frame in all (cluttered frames have many unused squares).
  int64_t pixels_left = static_cast<int64_t>(img.total()) / 8;
  int looks = 0;
  looked.clear();
  Explanation::Round* traced = traceRound(kSecondLookRound, pairs);
  traceSkip(traced, "beyond the first kMaxAnchors (256), the AP pairs and the smaller windows first",
            pairs - anchors.size());
  if (trace) trace_how = "raised by second_look_raise";
  for (const auto& a : anchors) {
    if (looks >= p.second_looks || pixels_left < 25 * 25) {  // 25 x 25: the smallest window
      traceSkip(traced, looks >= p.second_looks ? kSecondLookRound.spent : "pixel budget spent (an eighth of the frame)",
                static_cast<size_t>(anchors.data() + anchors.size() - &a));
      break;
    }
    cv::Rect win;
    if (!freshWindow(a, frame, win)) {
      traceSkip(traced, "inside a window looked at");
      continue;
    }
    if (win.area() > pixels_left) {
      traceSkip(traced, "window larger than the pixel budget left");
      continue;
    }
    bool merged = false;
    for (const auto& b : blobs) {
      if (b.second < 2.5 * a.area) break;  // the rest are smaller
      if ((b.first & win).area() > 0) {
        merged = true;
        break;
      }
    }
    if (!merged) {
      traceSkip(traced, "no region there 2.5 times the pair's larger square (no merge)");
      continue;
    }
    pixels_left -= win.area();
    ++looks;
    looked.push_back(win);
    if (traced) ++traced->windows, trace_around = cv::Point2f(a.centre);
    look(win, filtered(win), img, strict, max_area, false);
  }
  endLooks();
}

// Whether paper lies beside a red square, as beside a landmark's AP (or a
// blue square, as beside a FIP): of the four points a little beyond its
// ends and sides (along its moments' axes), two or more bright (their
// largest channel `paper_over_ink` of the square's mean red, or blue, or
// more) and unsaturated (the smallest channel 0.65 of the largest or
// more). A steeply seen AP has the sheet's margins on its inner end and
// side (the paper between it and TR, and between it and BL); red things on
// coloured or dark surroundings, which took half the steep round's time on
// ld-bench's cluttered scenes, have not.
static bool paperBeside(const cv::Mat& img, const detail::Region& r, double paper_over_ink) {
  const double th = 0.5 * std::atan2(2 * r.sxy, r.sxx - r.syy);
  const cv::Point2d e(std::cos(th), std::sin(th)), n(-e.y, e.x);
  const double a = 0.5 * detail::maxAxis(r) + 2.5, b = 0.5 * detail::minAxis(r) + 2.5;
  // (the square's own ink's channel: red for an AP, blue for a FIP)
  const double ink = (r.colour == detail::kBlue ? r.sum_b : r.sum_r) / std::max(1.0, r.n_sum);
  const cv::Point2d c(r.cx, r.cy);
  int paper = 0;
  for (const cv::Point2d& q : {c + a * e, c - a * e, c + b * n, c - b * n}) {
    const int x = static_cast<int>(std::lround(q.x)), y = static_cast<int>(std::lround(q.y));
    if (x < 0 || y < 0 || x >= img.cols || y >= img.rows) continue;
    const cv::Vec3b v = img.at<cv::Vec3b>(y, x);
    const int mx = std::max({v[0], v[1], v[2]}), mn = std::min({v[0], v[1], v[2]});
    paper += mx >= paper_over_ink * ink && mn >= 0.65 * mx;
  }
  return paper >= 2;
}

// The faint look: around a red square that no landmark took, the window
// white-balanced by its own white (the mean of its brightest fifth: the
// sheet, or whatever white lies near), labelled with blue from
// faint_look_blue and run through the same regions, colour, geometry and
// verification. A steeply seen landmark's blue squares are a few pixels
// wide, their colour mixed with the paper's: under warm light the mix is
// violet or grey in the frame's colours, and blue again against the paper
// beside it; motion blur mixes a square's blue with the paper around it,
// paler than the first pass's threshold. Printed red
// stays red (it is bright), so the AP is where to look: from the larger
// red squares down (a nearer landmark's, whose window is the likelier to
// hold one whole), windows reaching 5 of the square's longest axes (the FIPs
// lie within 4.24 sides of the AP), at most faint_looks of them and an
// eighth of the frame in all. Then the steep round: around the red squares
// no landmark took yet that are shaped as a steeply seen AP (kSteepAxisRatio,
// kSteepMaxSide), windows reaching further, always white-balanced, their
// colour taken from their brightness, at most steep_looks of them and
// another eighth of the frame; then as many again around the blue squares
// shaped as a steeply seen FIP (kSteepFipAxisRatio, kSteepFipPaperOverInk).
void Detector::Impl::faintLook(const cv::Mat& img, const cv::Mat& filtered, int max_area) {
  const DetectorParams& p = params;
  const int nf = static_cast<int>(fips.size()), na = static_cast<int>(aps.size());
  markUsed();
  anchors.clear();
  steep_anchors.clear();
  steep_fip_anchors.clear();
  // (the faint look's anchors serve the veil round too, in frames it runs in)
  const int veil_looks = glare_corrected ? p.veil_looks : 0;
  const double max_radius = 0.3 * std::min(img.cols, img.rows);
  // The steep round's anchor at square r when it is shaped as a steeply
  // seen one: small, its axes `ratio`:1 or more, paper beside it.
  const auto steepAnchor = [&](const detail::Region& r, double ratio, double paper_over_ink, std::vector<Anchor>& to) {
    const double side = detail::maxAxis(r), radius = std::max(12.0, kSteepReach * side);
    if (side <= kSteepMaxSide && r.area >= kSteepMinArea && side >= ratio * detail::minAxis(r) &&
        radius <= max_radius && paperBeside(filtered, r, paper_over_ink))
      to.push_back({cv::Point2d(r.cx, r.cy), radius, 0, r.area});
  };
  for (int k = 0; k < na; ++k) {
    const double side = detail::maxAxis(aps[k]);
    if (used[nf + k] || side > kSecondLookMaxSide) continue;
    const double radius = std::max(12.0, kFaintLookReach * side);
    if ((p.faint_looks > 0 || veil_looks > 0) && radius <= max_radius && aps[k].area >= kFaintLookMinArea)
      anchors.push_back({cv::Point2d(aps[k].cx, aps[k].cy), radius, 0, aps[k].area, side});
    if (p.steep_looks > 0) steepAnchor(aps[k], kSteepAxisRatio, kSteepApPaperOverInk, steep_anchors);
  }
  if (p.steep_looks > 0)
    for (int k = 0; k < nf; ++k)
      if (!used[k]) steepAnchor(fips[k], kSteepFipAxisRatio, kSteepFipPaperOverInk, steep_fip_anchors);
  if (anchors.empty() && steep_anchors.empty() && steep_fip_anchors.empty()) return;
  const auto larger = [](const Anchor& a, const Anchor& b) {
    return std::tie(b.area, a.centre.x, a.centre.y) < std::tie(a.area, b.centre.x, b.centre.y);
  };
  std::sort(anchors.begin(), anchors.end(), larger);
  std::sort(steep_anchors.begin(), steep_anchors.end(), larger);
  std::sort(steep_fip_anchors.begin(), steep_fip_anchors.end(), larger);
  swapLooksLists();
  const cv::Rect frame(0, 0, img.cols, img.rows);
  const bool blurred = filtered.data != img.data;
  // Window-sized views of buffers as large as the largest window (no allocation per look).
  const int buf_side = 2 * static_cast<int>(std::ceil(max_radius)) + 1;
  faint_src_buf.create(buf_side, buf_side, CV_8UC3);
  if (blurred) faint_img_buf.create(buf_side, buf_side, CV_8UC3);
  if (!steep_anchors.empty() || !steep_fip_anchors.empty()) {
    faint_rc_buf.create(buf_side, buf_side, CV_8UC3);
    if (blurred) faint_rc_img_buf.create(buf_side, buf_side, CV_8UC3);
  }
  // Labelled with blue from faint_look_blue: a thin or blurred square's
  // blue mixed with the paper's is paler than the first pass's threshold.
  detail::MaskThresholds pale = filter_settings.mask;
  pale.blue = std::min(pale.blue, p.faint_look_blue);
  // Under a strong glare veil (setGlareCorrected) the stretch tints the
  // squares (a veil a few levels off in one channel, times about 4): blue at
  // any hue where it is the largest channel and above red.
  pale.wide_blue = glare_corrected;

  // Each round: up to `max_looks` windows, an eighth of the frame for them
  // (the steep round: at most kSteepMaxPixels) and as many pixels again for
  // measuring windows' white (a quarter of each window's pixels are sampled).
  // (kSteepFip: the steep round around blue squares, with a budget of its own)
  enum class Round { kFaint, kSteep, kSteepFip, kVeil };  // (kLookRounds' order, after the second look)
  const auto round = [&](const std::vector<Anchor>& from, int max_looks, Round kind) {
    const bool steep = kind == Round::kSteep || kind == Round::kSteepFip, veil = kind == Round::kVeil;
    const bool around_fip = kind == Round::kSteepFip;
    // Whether candidate c's AP (around_fip: one of its FIPs) is the anchor's square.
    const auto owns = [&](const detail::Candidate& c, const cv::Point2d& centre, double tol, double min_px) {
      if (!around_fip) return detail::nearCentre(all_aps[c.ap], centre, tol, min_px);
      return detail::nearCentre(all_fips[c.tl], centre, tol, min_px) ||
             detail::nearCentre(all_fips[c.tr], centre, tol, min_px) ||
             detail::nearCentre(all_fips[c.bl], centre, tol, min_px);
    };
    // (the veil round: a quarter of the frame, up to four looks a window)
    int64_t pixels_left = static_cast<int64_t>(img.total()) / (veil ? 4 : 8);
    // (the steep round's squares are small whatever the frame's size: its
    // windows, up to 131 px across, need no more room in a large frame than
    // in a 640x480 one)
    if (steep) pixels_left = std::min<int64_t>(pixels_left, kSteepMaxPixels);
    int64_t samples_left = pixels_left;
    int looks = 0;
    looked.clear();
    left_out.clear();
    const LookRound& named = kLookRounds[1 + static_cast<int>(kind)];  // (in Round's order, after the second look)
    Explanation::Round* traced = from.empty() || max_looks <= 0 ? nullptr : traceRound(named, from.size());
    for (const auto& a : from) {
      if (looks >= max_looks || pixels_left < 25 * 25) {
        traceSkip(traced, looks >= max_looks ? named.spent : "pixel budget spent",
                  static_cast<size_t>(from.data() + from.size() - &a));
        break;
      }
      // (a landmark found so far holds the anchor's square: nothing to look for)
      if (kind != Round::kFaint &&
          std::any_of(all_candidates.begin(), all_candidates.end(),
                      [&](const detail::Candidate& c) { return owns(c, a.centre, 0.5, 2.0); })) {
        traceSkip(traced, "a landmark found holds its square");
        continue;
      }
      cv::Rect win;
      if (veil) {
        // (the round takes only its own square's landmark from a window, so
        // a window looked at does not stand for the red squares in it. Two
        // anchors a fraction of a side apart, one square found twice, get a
        // window each: their sides differ, and so do the discs where the
        // QR's tint is measured; skipping the second lost 3 frames of 300
        // at glare 0.6, seeds 10-12)
        Anchor wide = a;
        wide.radius = std::min(max_radius, std::max(a.radius, kVeilReach * a.side));
        win = anchorWindow(wide, frame);
      } else if (!freshWindow(a, frame, win)) {
        // (unless a window looked at found a landmark around this square and
        // left it out as not its own square's: the square then gets a window
        // of its own, in which that landmark is its own; once. Two steeply
        // seen landmarks side by side: ld-synth scene -k 2 --size 0.15
        // --distance 2.5 --yaw 60:70 --roll -180:180 --x -0.12:0.12 --y
        // -0.1:0.1, 200 frames, seeds 3 / 4 / 5: 356 / 350 / 346 -> 360 /
        // 352 / 351 of 400)
        const auto mine = [&](const detail::Candidate& c) { return owns(c, a.centre, 1.0, 3.0); };
        const auto served = std::remove_if(left_out.begin(), left_out.end(), mine);
        if (served == left_out.end()) {
          traceSkip(traced, "inside a window looked at");
          continue;
        }
        left_out.erase(served, left_out.end());
        win = anchorWindow(a, frame);
      }
      if (win.area() > pixels_left || win.area() / 4 > samples_left) {
        traceSkip(traced, "window larger than the pixel budget left");
        continue;
      }
      samples_left -= win.area() / 4;
      // (a window measured, cast or not, stands for the red squares in it;
      // not in the veil round, above)
      if (!veil) looked.push_back(win);
      ++looks;
      const size_t before = all_candidates.size();
      const size_t looks_before = tracedLooks();
      if (trace) trace_around = cv::Point2f(a.centre);
      if (veil) {
        pixels_left -= veilWindow(win, a, img, filtered, pale, max_area, pixels_left);
      } else {
        pixels_left -= win.area();
        faintWindow(win, img, filtered, pale, max_area, steep);
      }
      if (kind != Round::kFaint) {
        // The steep and veil rounds look for the landmark of their own red
        // square (its AP within the square's longest axis of it; around a
        // blue square, one of its FIPs): others their recoloured window
        // shows are not taken (dark stripes on a warm wall beside an orange
        // bar, under adaptive white balance, made one).
        const auto other = [&](const detail::Candidate& c) { return !owns(c, a.centre, 1.0, 3.0); };
        if (trace) {  // (each look's landmarks were added in turn)
          size_t k = before;
          for (size_t i = looks_before; i < trace->looks.size(); ++i)
            for (int n = 0; n < trace->looks[i].landmarks && k < all_candidates.size(); ++n, ++k)
              trace->looks[i].dropped += other(all_candidates[k]);
        }
        // (the others aside into left_out, the own kept in order: one pass)
        size_t kept = before;
        for (size_t k = before; k < all_candidates.size(); ++k) {
          if (other(all_candidates[k])) left_out.push_back(all_candidates[k]);
          else all_candidates[kept++] = all_candidates[k];
        }
        all_candidates.erase(all_candidates.begin() + static_cast<std::ptrdiff_t>(kept), all_candidates.end());
      }
      if (traced) {
        if (tracedLooks() > looks_before) ++traced->windows;
        else if (!veil) traceSkip(traced, "no white in its window");
        else if (!veil_measured) traceSkip(traced, "no tint measured (the QR's discs off the frame or clipped)");
        else traceSkip(traced, "no tint to take out (under kVeilMinTint)");
      }
    }
  };
  round(anchors, p.faint_looks, Round::kFaint);
  round(steep_anchors, p.steep_looks, Round::kSteep);
  round(steep_fip_anchors, p.steep_looks, Round::kSteepFip);
  if (veil_looks > 0) {
    // The veil round's order: the brightest paper beside first (kVeilPaperPoints).
    veil_order.clear();
    for (size_t k = 0; k < anchors.size(); ++k)
      veil_order.emplace_back(-veilPaper(img, anchors[k]), static_cast<int>(k));
    std::sort(veil_order.begin(), veil_order.end());  // (ties: the faint look's order)
    veil_anchors.clear();
    for (const auto& o : veil_order) veil_anchors.push_back(anchors[static_cast<size_t>(o.second)]);
    round(veil_anchors, veil_looks, Round::kVeil);
  }
  endLooks();
}

// One window of the faint look's veil round (see DetectorParams::veil_looks):
// the tint a glare veil's subtraction left, measured on the QR where it
// would lie (kVeilQrReach of the red square's sides from it, in
// kVeilDirections directions; the two with the finest texture, the QR's
// modules), taken out of the window before labelling: one look per tint,
// and one more at raised thresholds where it adds no landmark. Returns the
// pixels looked at.
int64_t Detector::Impl::veilWindow(const cv::Rect& win, const Anchor& a, const cv::Mat& img, const cv::Mat& filtered,
                                   const detail::MaskThresholds& pale, int max_area, int64_t pixels_left) {
  std::array<double, kVeilDirections> texture;
  std::array<cv::Scalar, kVeilDirections> tint;
  for (int d = 0; d < kVeilDirections; ++d) {
    texture[d] = -1;
    const double angle = 2 * CV_PI * d / kVeilDirections;
    const cv::Point2d c = a.centre + kVeilQrReach * a.side * cv::Point2d(std::cos(angle), std::sin(angle));
    const double rt = kVeilTextureDisc * a.side, rc = kVeilTintDisc * a.side;
    const int x0 = std::max(0, static_cast<int>(std::floor(c.x - rt))), x1 = std::min(img.cols - 2, static_cast<int>(std::ceil(c.x + rt)));
    const int y0 = std::max(0, static_cast<int>(std::floor(c.y - rt))), y1 = std::min(img.rows - 2, static_cast<int>(std::ceil(c.y + rt)));
    int64_t fine = 0;
    int n = 0, m = 0;
    cv::Vec3d sum(0, 0, 0);
    for (int y = y0; y <= y1; ++y) {
      const uint8_t* row = img.ptr<uint8_t>(y);
      const uint8_t* below = img.ptr<uint8_t>(y + 1);
      for (int x = x0; x <= x1; ++x) {
        const double r2 = (x - c.x) * (x - c.x) + (y - c.y) * (y - c.y);
        if (r2 > rt * rt) continue;
        const uint8_t* q = row + 3 * x;
        const int v = q[0] + q[1] + q[2];
        fine += std::abs(v - (q[3] + q[4] + q[5])) + std::abs(v - (below[3 * x] + below[3 * x + 1] + below[3 * x + 2]));
        ++n;
        // (clipped pixels, the white modules at the hot spot, carry no tint)
        if (r2 <= rc * rc && std::max({q[0], q[1], q[2]}) < kVeilClipped) sum += cv::Vec3d(q[0], q[1], q[2]), ++m;
      }
    }
    if (n == 0 || m < kVeilMinTintPixels) continue;
    const cv::Vec3d mean = sum / m;
    const double grey = (mean[0] + mean[1] + mean[2]) / 3;
    tint[d] = cv::Scalar(mean[0] - grey, mean[1] - grey, mean[2] - grey);
    texture[d] = static_cast<double>(fine) / n;
  }
  // The two most textured directions, most first.
  int first = -1, second = -1;
  for (int d = 0; d < kVeilDirections; ++d) {
    if (texture[d] < 0) continue;
    if (first < 0 || texture[d] > texture[first]) second = first, first = d;
    else if (second < 0 || texture[d] > texture[second]) second = d;
  }
  veil_measured = first >= 0;
  int64_t pixels = 0;
  for (const int pick : {first, second}) {
    if (pick < 0 || pixels + win.area() > pixels_left) break;
    const cv::Scalar& t = tint[pick];
    // A tint too slight to have hidden the squares' blue needs no look, nor
    // one the first look took out already.
    if (cv::norm(t, cv::NORM_INF) < kVeilMinTint) continue;
    if (pick == second && first >= 0 && cv::norm(t - tint[first], cv::NORM_INF) < kVeilMinTint) continue;
    // (pixels clipped in some channel, the sheet's white at the hot spot,
    // carry no tint, as where it was measured, and keep their colour:
    // taken out of them, a tint of B -83 G +18 R +65 turned the clipped
    // sheet pale blue, and the window around a landmark's AP showed 1 FIP
    // and no AP, 14 FIPs and 4 APs now; in another the sheet broke into
    // 276 blue specks. On the lighting sweep's glare point at 0.75, seeds
    // 1-6: 574 -> 581 of 600 found; seeds 7-15: 858 -> 872 of 900; at 0.9,
    // seeds 1-3: 133 -> 150 of 300. With a blurring front end the labelled
    // image keeps its own clipped pixels, the verified one the frame's)
    cv::Mat src = faint_src_buf(cv::Rect(0, 0, win.width, win.height));
    detail::subtractChannels(filtered(win), t, src, kVeilClipped);
    cv::Mat balanced = src;
    if (filtered.data != img.data) {  // blurred: the looks label the filtered image, verify on the frame
      balanced = faint_img_buf(cv::Rect(0, 0, win.width, win.height));
      detail::subtractChannels(img(win), t, balanced, kVeilClipped);
    }
    const size_t before = all_candidates.size();
    if (trace) trace_how = cv::format("tint B %+.0f G %+.0f R %+.0f taken out", t[0], t[1], t[2]);
    look(win, src, balanced, pale, max_area, true);
    pixels += win.area();
    // No landmark added (none at all: the round keeps only the anchor's
    // afterwards): the window again at thresholds raised by
    // second_look_raise, as the second look raises the first pass's (from
    // the pale ones here: blue back to 0.25, red 0.55 by default), the
    // squares without the pale pixels around them, which had made other
    // squares in the sheet, or run into its margin. On the lighting sweep's
    // glare point at 0.75, seeds 1-9: 857 -> 862 of 900 found; seeds 10-15,
    // not looked at while choosing: 562 -> 570 of 600.
    if (all_candidates.size() == before && pixels + win.area() <= pixels_left) {
      if (trace) trace_how += ", raised by second_look_raise";
      look(win, src, balanced, raisedMask(pale, params.second_look_raise), max_area, true);
      pixels += win.area();
    }
  }
  return pixels;
}

// One window of the faint look (see faintLook()): its white measured, the
// window white-balanced by it (steep: always; else only where it has a
// cast), steep windows' colour taken from their brightness, then look().
void Detector::Impl::faintWindow(const cv::Rect& win, const cv::Mat& img, const cv::Mat& filtered,
                                 const detail::MaskThresholds& pale, int max_area, bool steep) {
  // The white: the mean colour of the brightest fifth (by the sum of the
  // channels) of every other pixel of every other row, from one pass that
  // counts and sums the pixels per sum of channels.
  const cv::Mat f = filtered(win);
  std::fill(std::begin(white_hist), std::end(white_hist), 0);
  std::fill(std::begin(white_sums), std::end(white_sums), cv::Vec3i(0, 0, 0));
  int samples = 0;
  for (int y = 0; y < f.rows; y += 2) {
    const uint8_t* q = f.ptr<uint8_t>(y);
    for (int x = 0; x < f.cols; x += 2, q += 6, ++samples) {
      const int v = q[0] + q[1] + q[2];
      ++white_hist[v];
      white_sums[v] += cv::Vec3i(q[0], q[1], q[2]);
    }
  }
  cv::Vec3d white(0, 0, 0);
  int n_white = 0;
  for (int v = 765; v >= 0 && n_white < std::max(1, samples / 5); --v) {
    n_white += white_hist[v];
    white += cv::Vec3d(white_sums[v]);
  }
  const double top = std::max({white[0], white[1], white[2]}), low = std::min({white[0], white[1], white[2]});
  if (!(low > 0) || (!steep && top < kFaintLookMinCast * low)) {
    // A white already white (or none): the window as it is.
    if (trace) trace_how = "as it is (no cast)";
    if (!steep) look(win, f, img(win), pale, max_area, true);
    return;
  }
  const cv::Vec3d gain(top / white[0], top / white[1], top / white[2]);
  cv::Mat src = faint_src_buf(cv::Rect(0, 0, win.width, win.height));
  detail::scaleChannels(f, gain, src);
  cv::Mat balanced = src;
  if (filtered.data != img.data) {  // blurred: the looks label the filtered image, verify on the frame
    balanced = faint_img_buf(cv::Rect(0, 0, win.width, win.height));
    detail::scaleChannels(img(win), gain, balanced);
  }
  if (trace) trace_how = steep ? "white-balanced, colour from brightness" : "white-balanced";
  if (steep) {
    // The balanced white's level: the mean of its brightest channel.
    const double level = top / n_white;
    cv::Mat recoloured = faint_rc_buf(cv::Rect(0, 0, win.width, win.height));
    detail::colourFromBrightness(src, level, recoloured, rc_scratch);
    if (balanced.data != src.data) {
      cv::Mat rc_img = faint_rc_img_buf(cv::Rect(0, 0, win.width, win.height));
      detail::colourFromBrightness(balanced, level, rc_img, rc_scratch);
      balanced = rc_img;
    } else {
      balanced = recoloured;
    }
    src = recoloured;
  }
  look(win, src, balanced, pale, max_area, true);
}

// One look of the second or the faint look: `src` (the window `win` of the
// filtered frame, or its white-balanced copy) labelled at thresholds `t`,
// its regions through colour, geometry and verification on `img`: the whole
// frame (`in_window` false), or the window's own image (true: geometry
// works in the window's coordinates, then its squares move to the frame's).
// Its squares and landmarks join all_fips, all_aps and all_candidates unless
// a landmark of them is there already.
void Detector::Impl::look(const cv::Rect& win, const cv::Mat& src, const cv::Mat& img, const detail::MaskThresholds& t,
                          int max_area, bool in_window) {
  const DetectorParams& p = params;
  look_labels_buf.create(std::max(look_labels_buf.rows, src.rows), std::max(look_labels_buf.cols, src.cols), CV_8UC1);
  cv::Mat look_labels = look_labels_buf(cv::Rect(0, 0, src.cols, src.rows));
  detail::saturationMask(src, t, look_labels);
  detail::extractRegions(look_labels, src, t, p.min_area_px, max_area, p.min_fill, runs, regions);
  auto toFrame = [&win](std::vector<detail::Region>& v) {
    for (auto& q : v) {
      q.x0 += win.x, q.x1 += win.x, q.cx += win.x;
      q.y0 += win.y, q.y1 += win.y, q.cy += win.y;
    }
  };
  if (!in_window) toFrame(regions);
  ++looks_run;
  for (auto& q : regions) q.pass = looks_run;
  classify();
  geometry(img, in_window ? look_labels : labels);
  Explanation::Look* traced = trace ? traceLook(win, img, in_window) : nullptr;
  if (in_window) {
    toFrame(fips);
    toFrame(aps);
  }
  const int of = static_cast<int>(all_fips.size()), oa = static_cast<int>(all_aps.size());
  for (auto c : candidates) {
    // The same landmark again (found by the first pass or an earlier
    // look): a square of it where a square of one already is. The first
    // finding stays.
    const detail::Region* mine[4] = {&fips[c.tl], &fips[c.tr], &fips[c.bl], &aps[c.ap]};
    bool again = false;
    for (const auto& k : all_candidates) {
      const detail::Region* theirs[4] = {&all_fips[k.tl], &all_fips[k.tr], &all_fips[k.bl], &all_aps[k.ap]};
      for (const auto* m : mine)
        for (const auto* q : theirs)
          again |= detail::nearCentre(*m, {q->cx, q->cy});
    }
    if (again) continue;
    c.tl += of, c.tr += of, c.bl += of, c.ap += oa;
    all_candidates.push_back(c);
    if (traced) ++traced->landmarks;
  }
  all_fips.insert(all_fips.end(), fips.begin(), fips.end());
  all_aps.insert(all_aps.end(), aps.begin(), aps.end());
}

Explanation::Look* Detector::Impl::traceLook(const cv::Rect& win, const cv::Mat& img, bool in_window) {
  if (trace->looks.size() >= Explanation::kMaxLooks) {
    ++trace->looks_more;
    return nullptr;
  }
  Explanation::Look l;
  l.round = trace->rounds.empty() ? std::string() : trace->rounds.back().round;
  l.how = trace_how;
  l.window = win;
  l.around = trace_around;
  l.fips = static_cast<int>(fips.size());
  l.aps = static_cast<int>(aps.size());
  const cv::Point2f offset = in_window ? cv::Point2f(static_cast<float>(win.x), static_cast<float>(win.y)) : cv::Point2f();
  // A square of a landmark this look found, or of one found before it.
  auto found = [&](const detail::Region& r) {
    for (const auto& c : candidates)
      for (const detail::Region* q : {&fips[c.tl], &fips[c.tr], &fips[c.bl], &aps[c.ap]})
        if (detail::nearCentre(r, {q->cx, q->cy})) return true;
    for (const auto& c : all_candidates)
      for (const detail::Region* q : {&all_fips[c.tl], &all_fips[c.tr], &all_fips[c.bl], &all_aps[c.ap]})
        if (detail::nearCentre(r, {q->cx - offset.x, q->cy - offset.y})) return true;
    return false;
  };
  graph();  // (geometry() builds it only where three FIPs and an AP, or a completion, could make a landmark)
  std::vector<RefusedGroup> groups;
  l.right_isosceles = refusedGroups(img, found, offset, groups);
  tally(groups, Explanation::kMaxLookRefused, l.refusals, l.refused);
  trace->looks.push_back(std::move(l));
  return &trace->looks.back();
}

const cv::Mat* Detector::Impl::colourImage(const cv::Mat& input) {
  // Gray images have no colour: no landmarks. Other types are not images we know.
  if (input.empty() || input.depth() != CV_8U || input.cols < 3 || input.rows < 3) return nullptr;
  if (input.channels() == 3) return &input;
  if (input.channels() != 4) return nullptr;
  cv::cvtColor(input, converted, cv::COLOR_BGRA2BGR);
  return &converted;
}

// The first pass again after run(), each stage counted, and the check that
// refused each right-isosceles triangle of FIPs that is not part of a found
// landmark (with the AP it was tried with: the nearest of its choices), into
// `e` as detect() started it (empty but for the looks' trace).
void Detector::Impl::explain(Explanation& e) {
  const auto t0 = std::chrono::steady_clock::now();
  if (const cv::Mat* img = last_img) {
    const DetectorParams& p = params;
    const cv::Mat* src = last_src;
    // (every region, sparse ones included, to count them: classify() drops them as detection does)
    if (!paper) detail::extractRegions(labels, *src, filter_settings.mask, p.min_area_px, maxArea(*img), 0.0, runs, regions);
    else detail::contourRegions(edges, *img, p.min_area_px, maxArea(*img), contours, regions);
    for (const auto& r : regions) {
      const bool blue = r.colour == detail::kBlue;
      if (!blue && r.colour != detail::kRed) continue;
      (blue ? e.blue_regions : e.red_regions)++;
      if (!paper && detail::fill(r) < p.min_fill) (blue ? e.blue_sparse : e.red_sparse)++;
      else if (blue ? !detail::isFip(r, p.color_ratio_a, p.color_ratio_b) : !detail::isAp(r, p.color_ratio_a, p.color_ratio_b))
        (blue ? e.blue_off_colour : e.red_off_colour)++;
    }
    classify();
    e.fips = static_cast<int>(fips.size());
    e.aps = static_cast<int>(aps.size());
    e.fips_over_cap = fips_found - e.fips;
    e.aps_over_cap = aps_found - e.aps;
    e.fip_pairs = graph();
    e.triangles = static_cast<int>(cycles.size());
    // A square of a found landmark: within half its side of one of its centres.
    auto found = [&](const detail::Region& r) {
      for (const auto& lm : det.landmarks)
        for (const cv::Point2f& q : {lm.fip_tl, lm.fip_tr, lm.fip_bl, lm.ap})
          if (detail::nearCentre(r, q)) return true;
      return false;
    };
    std::vector<RefusedGroup> refused;
    e.right_isosceles = refusedGroups(*img, found, {0, 0}, refused);
    tally(refused, Explanation::kMaxRefused, e.refusals, e.refused);
  }
  e.ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

int Detector::Impl::refusedGroups(const cv::Mat& img, const std::function<bool(const detail::Region&)>& found,
                                  const cv::Point2f& offset, std::vector<RefusedGroup>& out) {
  const DetectorParams& p = params;
  auto at = [&offset](const detail::Region& r) {
    return cv::Point2f(static_cast<float>(r.cx), static_cast<float>(r.cy)) + offset;
  };
  int right_isosceles = 0;
  for (const auto& cyc : cycles) {
    int corner = 0;
    if (!detail::rightIsosceles(cyc, fips, kTriangleTolerance, &corner)) continue;
    ++right_isosceles;
    if (found(fips[cyc[0]]) || found(fips[cyc[1]]) || found(fips[cyc[2]])) continue;
    detail::apChoices(cyc, fips, aps, p, choices, &ap_index);
    Explanation::Refused r;
    detail::Check check = detail::Check::kNoAp;
    if (choices.empty()) {
      // As TL, TR, BL would be: the corner, then clockwise in the image.
      const cv::Point2f tl = at(fips[cyc[corner]]), a = at(fips[cyc[(corner + 1) % 3]]),
                        b = at(fips[cyc[(corner + 2) % 3]]);
      const bool clockwise = (a - tl).cross(b - tl) > 0;
      r.fips = {tl, clockwise ? a : b, clockwise ? b : a};
      r.check = detail::checkName(check);
    } else {
      bool verified = false;
      detail::Check first = detail::Check::kNoAp;
      for (size_t k = 0; k < choices.size() && !verified; ++k) {
        detail::Candidate c = choices[k];
        detail::Check why = detail::Check::kNoAp;
        verified = detail::verify(c, fips, aps, img, p, &why, glare_corrected);
        if (k == 0) first = why;
      }
      if (verified) continue;  // a landmark that lost to an overlapping one
      const detail::Candidate& c = choices[0];
      r.fips = {at(fips[c.tl]), at(fips[c.tr]), at(fips[c.bl])};
      r.ap = at(aps[c.ap]);
      check = first;
      r.check = detail::checkName(check);
    }
    // How like a landmark's the triangle is: neighbours 3 apart in the
    // frame of the squares' moments (far-apart large things make triangles too).
    double d = 0;
    for (int k = 0; k < 3; ++k) d += detail::normalisedDistance(fips[cyc[k]], fips[cyc[(k + 1) % 3]]);
    const double unlike = std::abs(std::log(d / (3 * (2 + std::sqrt(2.0)))));
    out.push_back({static_cast<int>(check), unlike, std::move(r)});
  }
  return right_isosceles;
}

void Detector::Impl::tally(std::vector<RefusedGroup>& groups, size_t keep,
                           std::vector<std::pair<std::string, int>>& refusals,
                           std::vector<Explanation::Refused>& refused) {
  // Counts per check; the groups that came furthest first, then the most landmark-like.
  for (int i = 0; i < detail::kNumChecks; ++i) {
    int n = 0;
    for (const auto& r : groups) n += r.check == i;
    if (n > 0) refusals.emplace_back(detail::checkName(static_cast<detail::Check>(i)), n);
  }
  std::stable_sort(groups.begin(), groups.end(), [](const RefusedGroup& a, const RefusedGroup& b) {
    return std::tie(b.check, a.unlike) < std::tie(a.check, b.unlike);
  });
  for (size_t k = 0; k < groups.size() && k < keep; ++k) refused.push_back(std::move(groups[k].group));
}

void Detector::Impl::run(const cv::Mat& input) {
  det.landmarks.clear();
  det.stages.clear();
  det.total_ms = 0;
  det.pose_error.clear();
  looks_run = 0;
  StageTimer timer(det.stages);
  last_img = last_src = nullptr;
  const cv::Mat* img = colourImage(input);
  if (!img) return;
  const DetectorParams& p = params;
  const int max_area = maxArea(*img);

  // 1-3. BLUR, SATURATION, (EDGES): the backend's filters
  const cv::Mat* src = runFilters(*img, timer);
  last_img = img;
  last_src = src;

  // 4. CONTOURS: candidate regions
  if (!paper) detail::extractRegions(labels, *src, filter_settings.mask, p.min_area_px, max_area, p.min_fill, runs, regions);
  else detail::contourRegions(edges, *img, p.min_area_px, max_area, contours, regions);
  timer.stamp("contours");

  // 5. COLOUR: FIP and AP candidates by the colour ratios
  classify();
  timer.stamp("colour");

  // 6-7. GEOMETRY: FIP graph, its 3-cycles, the AP, verification, overlaps
  geometry(*img, labels);
  timer.stamp("geometry");

  // 7c. SECOND LOOK around the squares no landmark took
  if (!paper && p.second_looks > 0) {
    secondLook(*img, *src, max_area);
    timer.stamp("second look");
  }
  // 7d. FAINT LOOK around the red squares no landmark took
  if (!paper && (p.faint_looks > 0 || p.steep_looks > 0 || (glare_corrected && p.veil_looks > 0))) {
    faintLook(*img, *src, max_area);
    timer.stamp("faint look");
  }

  // 8. CORNERS (through the undistorted image when the camera distorts: the
  // sheet maps to it by a homography)
  const bool pose = camera && side_m > 0 && camera->fits(img->size());
  if (camera && !pose) {
    if (misfit_size != img->size()) misfit = camera->misfit(img->size()), misfit_size = img->size();
    det.pose_error = misfit;  // (into the detection's own buffer: no allocation a frame)
  }
  if (pose && scaled.size != img->size()) scaled = camera->scaledTo(img->size());
  const bool distorted = pose && scaled.hasDistortion();
  const int align = p.align_iterations >= 0 ? p.align_iterations : pose ? DetectorParams::kAutoAlignIterations : 0;
  markUsed();
  for (const auto& c : candidates) {
    std::array<cv::Point2d, 4> centres;
    const std::array<const detail::Region*, 4> squares{&fips[c.tl], &fips[c.tr], &fips[c.bl], &aps[c.ap]};
    if (paper)  // (the paper's bounding rectangles are not pieces)
      for (int i = 0; i < 4; ++i) centres[i] = {squares[i]->cx, squares[i]->cy};
    else
      detail::joinPieces(*img, squares, fips, aps, used, glare_corrected, ink_scratch, centres);
    std::array<cv::Point2d, 4> corrected, corners;
    if (distorted) detail::undistortPixels(scaled, centres);
    if (!detail::fitCorners(centres, p.centre_iterations, corrected, corners)) continue;
    if (align > 0) {
      if (align_model.per_unit == 0) {
        detail::sheetModel(kAlignPerUnit, align_model);
        detail::sheetModel(kAlignNearPerUnit, align_model_near);
      }
      detail::alignSheet(*img, distorted ? &scaled : nullptr, align_model, align, corrected, corners,
                         align_scratch, &align_model_near);
    }
    if (distorted) {
      detail::distortPixels(scaled, corrected);
      detail::distortPixels(scaled, corners);
    }
    Landmark lm;
    lm.fip_tl = corrected[0];
    lm.fip_tr = corrected[1];
    lm.fip_bl = corrected[2];
    lm.ap = corrected[3];
    for (int i = 0; i < 4; ++i) lm.corners[i] = corners[i];
    lm.score = c.score;
    // a distortion model that does not invert there (found by
    // tests/fuzz/fuzz_camera) gives no landmark rather than NaN positions
    if (!finiteLandmark(lm)) continue;
    det.landmarks.push_back(lm);
  }
  timer.stamp("corners");

  // 9. POSE
  if (pose) {
    for (auto& lm : det.landmarks) {
      Pose pose;
      if (detail::estimatePose(lm.corners, scaled, side_m, pose)) lm.pose = pose;
    }
    timer.stamp("pose");
  }
  det.total_ms = timer.totalMs();
}

Detector::Detector(const DetectorParams& params) : impl_(std::make_unique<Impl>(params)) {}
Detector::~Detector() = default;
Detector::Detector(Detector&&) noexcept = default;
Detector& Detector::operator=(Detector&&) noexcept = default;

void Detector::setCamera(const CameraModel& camera, double side_m) {
  // (an infinite side, or a focal length of 0, NaN or below, gave landmarks
  // no pose and no pose_error saying why)
  if (!(side_m > 0) || !std::isfinite(side_m))
    throw std::invalid_argument("Detector::setCamera: side_m must be a finite length > 0");
  for (int i = 0; i < 9; ++i)
    if (!std::isfinite(camera.K.val[i]))
      throw std::invalid_argument("Detector::setCamera: the camera matrix has a value that is not finite");
  if (!(camera.K(0, 0) > 0) || !(camera.K(1, 1) > 0))
    throw std::invalid_argument("Detector::setCamera: the camera matrix's fx and fy must be > 0");
  impl_->camera = camera;
  impl_->scaled = camera;
  impl_->side_m = side_m;
  impl_->misfit_size = {};
}

const Detection& Detector::detect(const cv::Mat& bgr) {
  requireReadableImage(bgr, "Detector::detect");
  impl_->run(bgr);
  return impl_->det;
}

void Detector::addStageBefore(const char* name, double ms) {
  impl_->det.stages.insert(impl_->det.stages.begin(), StageTime{name, ms});  // (its capacity kept: no allocation once warm)
  impl_->det.total_ms += ms;
}

const Detection& Detector::detect(const cv::Mat& bgr, Explanation& why) {
  // The detection, untraced (its times are its own); then again as a run
  // that records the looks (the same landmarks), its times put back to the
  // untraced run's; then the first pass explained.
  requireReadableImage(bgr, "Detector::detect");
  impl_->run(bgr);
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<StageTime> stages = impl_->det.stages;
  const double total_ms = impl_->det.total_ms;
  const char* ran = impl_->ran;  // (backend "auto" still choosing may run the traced one on the other)
  why = Explanation();
  struct Untrace {
    Impl& impl;
    ~Untrace() { impl.trace = nullptr; }
  };
  {
    Untrace untrace{*impl_};
    impl_->trace = &why;
    impl_->run(bgr);
  }
  impl_->det.stages = stages;
  impl_->det.total_ms = total_ms;
  impl_->ran = ran;
  why.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  impl_->explain(why);
  return impl_->det;
}

const DetectorParams& Detector::params() const { return impl_->params; }

const char* Detector::backend() const { return impl_->ran ? impl_->ran : impl_->filters->name(); }

bool Detector::choosingBackend() const { return impl_->rival != nullptr; }

void Detector::setGlareCorrected(bool corrected) { impl_->glare_corrected = corrected; }

std::string Detector::backendInfo() const {
  std::string s = impl_->filters->info(impl_->paper);
  if (impl_->rival) s += "; auto: timing it against the CPU on the first frames";
  if (!impl_->choice.empty()) s += "; " + impl_->choice;
  if (!impl_->fallback_why.empty()) s += " (GLES not used: " + impl_->fallback_why + ")";
  return s;
}

}  // namespace ld
