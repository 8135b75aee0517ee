// AprilTag 3 and ArUco markers printed like our landmark (same sheet, same
// printed size) and their detectors, for comparisons in ld-bench and ld-eval.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace ld::markers {

enum class Kind {
  AprilTag,  ///< AprilTag 3, tag36h11 (Debian's libapriltag), one thread, default decimation
  Aruco,     ///< OpenCV's ArUco, DICT_4X4_50, default parameters
};

/// "AprilTag 3" or "ArUco"; parse("apriltag" | "aruco") throws std::invalid_argument otherwise.
std::string name(Kind kind);
Kind parse(const std::string& s);

/// A square white sheet texture (8-bit BGR, side_px) with marker `id`
/// (its black border included) filling the pattern square [0.5u, 8.5u] of
/// the 9u sheet, where our landmark's pattern is: the same printed size.
cv::Mat sheetTexture(Kind kind, int id, int side_px);

using Quad = std::array<cv::Point2f, 4>;

struct Found {
  int id;
  Quad corners;  ///< the marker's outer corners (black border), image pixels (OpenCV's convention: a pixel's centre at the integer)
};

/// A detector for one kind; keeps its state between frames.
class Detector {
 public:
  explicit Detector(Kind kind);
  ~Detector();
  Detector(Detector&&) noexcept;
  Detector& operator=(Detector&&) noexcept;
  /// Markers in an 8-bit gray image.
  std::vector<Found> detect(const cv::Mat& gray);
  Kind kind() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Whether a marker quad is the one whose true outer corners (TL, TR, BR,
/// BL of the pattern square) are `truth`: centres within max(3 px, 10 % of a side).
bool matches(const Quad& quad, const std::array<cv::Point2d, 4>& truth);

}  // namespace ld::markers
