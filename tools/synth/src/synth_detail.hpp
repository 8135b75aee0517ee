// Internals of ld_synth shared by its sources (not a public header).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/synth.hpp"

namespace ld::synth::detail {

/// splitmix64 of a and b: independent seeds from one.
uint64_t mix(uint64_t a, uint64_t b);

/// Deterministic random numbers (std::mt19937_64, with our own conversions so
/// the numbers do not depend on the standard library's distributions).
class Rand {
 public:
  explicit Rand(uint64_t seed) : eng_(seed) {}
  uint64_t next() { return eng_(); }
  double uni() { return static_cast<double>(eng_() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uni(double a, double b) { return a + (b - a) * uni(); }
  /// Uniform integer in [a, b].
  int integer(int a, int b) {
    return a + static_cast<int>(std::min<double>(b - a, std::floor(uni() * (b - a + 1))));
  }
  size_t index(size_t n) { return static_cast<size_t>(integer(0, static_cast<int>(n) - 1)); }
  bool chance(double p) { return uni() < p; }
  double normal();

 private:
  std::mt19937_64 eng_;
};

/// The ideal pinhole image things are drawn into.
struct Canvas {
  cv::Mat img;                 // 8-bit BGR
  cv::Matx33d K;               // its intrinsics
  cv::Point2d offset{0, 0};    // canvas pixel = camera's ideal pixel + offset
};

cv::Matx33d rotX(double deg);
cv::Matx33d rotY(double deg);
cv::Matx33d rotZ(double deg);
cv::Matx33d fromRvec(const cv::Vec3d& r);
cv::Vec3d toRvec(const cv::Matx33d& R);

/// Linear-light multipliers (BGR) for a black body of `kelvin` (its CIE 1931
/// Planckian-locus colour) on a camera balanced for 6500 K whose auto white
/// balance leaves 70 % of the cast (in log terms), luminance kept.
cv::Vec3d whiteBalance(double kelvin);

/// A wall: paint colour, slow unevenness, fine grain. `ppm`: pixels per metre.
void paintWall(cv::Mat& img, double ppm, Rand& r);
/// A procedural background; with_floor: an Office/Clutter scene may show a
/// floor (else furniture stands on the bottom edge); paint_wall false: only
/// the things on the wall (the wall of a sequence is painted in pieces).
void paintBackground(cv::Mat& img, Background kind, double ppm, bool with_floor, Rand& r,
                     bool paint_wall = true);
/// A floor texture seen from above: carpet, wooden planks along x, or tiles.
void paintFloor(cv::Mat& img, double ppm, Rand& r);
/// `count` colourful distractors (some blue/red squares of `fip_px` sizes),
/// none overlapping `avoid`.
void paintDistractors(cv::Mat& img, int count, const std::vector<double>& fip_px,
                      const std::vector<cv::Rect>& avoid, double ppm, Rand& r);
/// A landmark-like card: variant 0 red square in the middle, 1 red square
/// next to TL (with a QR-like block), 2 colours swapped. `side` pixels.
cv::Mat cardTexture(int variant, int side, const artwork::Colours& ink, Rand& r);

}  // namespace ld::synth::detail
