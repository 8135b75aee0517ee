// The one definition of the printed landmark (docs/landmark.md, LANDMARK.md).
//
// A square white sheet of side S; u = S / 9. Sheet frame: x right, y down,
// origin at the sheet's top-left corner. Three blue finder patterns (FIPs)
// and one red alignment pattern (AP), each a 2u square; a QR code in the
// middle 4u square.
#pragma once

#include <array>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace ld::layout {

constexpr double kUnits = 9.0;        // sheet side in units u
constexpr double kSquareSide = 2.0;   // coloured square side in u
constexpr double kPatternMin = 0.5;   // pattern square [0.5u, 8.5u]^2
constexpr double kPatternMax = 8.5;
constexpr double kQrMin = 2.5;        // QR square [2.5u, 6.5u]^2
constexpr double kQrMax = 6.5;

/// Index of each coloured square in the arrays below.
enum Square { kFipTl = 0, kFipTr = 1, kFipBl = 2, kAp = 3 };

/// Centres of TL, TR, BL, AP in units u.
constexpr std::array<std::array<double, 2>, 4> kCentresU{{{1.5, 1.5}, {7.5, 1.5}, {1.5, 7.5}, {7.5, 7.5}}};

/// Outer corners of the pattern square in units u: TL, TR, BR, BL.
constexpr std::array<std::array<double, 2>, 4> kCornersU{
    {{kPatternMin, kPatternMin}, {kPatternMax, kPatternMin}, {kPatternMax, kPatternMax}, {kPatternMin, kPatternMax}}};

/// The homography from the sheet frame (units u) to the image, given the
/// image positions of the pattern square's corners (TL, TR, BR, BL).
inline cv::Matx33d sheetToImage(const std::array<cv::Point2f, 4>& corners) {
  cv::Point2f sheet[4], img[4];
  for (int i = 0; i < 4; ++i) {
    sheet[i] = {static_cast<float>(kCornersU[i][0]), static_cast<float>(kCornersU[i][1])};
    img[i] = corners[i];
  }
  return cv::Matx33d(cv::getPerspectiveTransform(sheet, img));
}

/// The side of the QR square in the image, in pixels, from the pattern
/// square's corners (TL, TR, BR, BL): their mean side, scaled.
inline double projectedQrSide(const std::array<cv::Point2f, 4>& corners) {
  double pattern = 0;
  for (size_t i = 0; i < 4; ++i) pattern += cv::norm(corners[i] - corners[(i + 1) % 4]);
  return pattern / 4 * (kQrMax - kQrMin) / (kPatternMax - kPatternMin);
}

/// A point given in units u, in the sheet frame scaled to a sheet of `side`
/// (any length unit, or pixels).
inline cv::Point2d sheetPoint(const std::array<double, 2>& u, double side) {
  return {u[0] * side / kUnits, u[1] * side / kUnits};
}

/// 3D point of the object frame used for pose: the sheet frame moved to the
/// sheet's centre (z = 0 on the sheet, z = x cross y points into the wall).
inline cv::Point3d objectPoint(const std::array<double, 2>& u, double side) {
  return {(u[0] - kUnits / 2) * side / kUnits, (u[1] - kUnits / 2) * side / kUnits, 0.0};
}

/// The four pattern corners (TL, TR, BR, BL) in the object frame.
inline std::array<cv::Point3d, 4> objectCorners(double side) {
  return {objectPoint(kCornersU[0], side), objectPoint(kCornersU[1], side),
          objectPoint(kCornersU[2], side), objectPoint(kCornersU[3], side)};
}

/// The four square centres (TL, TR, BL, AP) in the object frame.
inline std::array<cv::Point3d, 4> objectCentres(double side) {
  return {objectPoint(kCentresU[0], side), objectPoint(kCentresU[1], side),
          objectPoint(kCentresU[2], side), objectPoint(kCentresU[3], side)};
}

}  // namespace ld::layout
