// Pinhole camera intrinsics in OpenCV's calibration file format
// (cv::FileStorage YAML/XML with camera_matrix, distortion_coefficients,
// image_width, image_height), as OpenCV's calibration sample writes them.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace ld {

struct CameraModel {
  /// The largest image side a calibration file may give (as the frames').
  static constexpr int kMaxImageSide = 16384;

  cv::Matx33d K = cv::Matx33d::eye();  // camera matrix
  cv::Mat dist;                        // distortion coefficients (empty: none)
  cv::Size size;                       // image size the calibration is for

  /// 640x480, f = 600 px, principal point at the image centre, no distortion:
  /// the project's default camera.
  static CameraModel defaultVga();
  /// A distortion-free camera of the given size and focal length in pixels.
  static CameraModel pinhole(cv::Size size, double focal_px);

  /// Reads a calibration file; throws std::runtime_error naming the file and
  /// the missing or malformed field.
  static CameraModel load(const std::string& path);
  void save(const std::string& path) const;

  /// The same camera for another image size (scales K; distortion is kept).
  CameraModel scaledTo(cv::Size new_size) const;
  /// Whether frames of `frame` size can use this calibration scaled
  /// (scaledTo): the calibration's size is unknown (0x0), or the two have
  /// the same aspect ratio within 1 %. Another aspect ratio is another crop
  /// of the sensor (a 16:9 mode of a 4:3 sensor): its K does not scale.
  bool fits(cv::Size frame) const;
  /// Why frames of `frame` size cannot use it, for people ("" when fits()).
  std::string misfit(cv::Size frame) const;

  /// The same camera for its images turned: mirrored left to right first
  /// where `mirrored` (u' = width - 1 - u), then turned `quarter_turns_cw`
  /// quarter turns clockwise, as a JPEG's Exif orientation turns a photo
  /// upright (a phone's portrait photo is stored as the sensor took it,
  /// landscape, and turned for people: ld-detect reads it turned, as OpenCV
  /// does). K, the distortion's tangential and thin-prism terms and the size
  /// turn with the image. Sets `out` and returns "", or why it cannot
  /// (a tilted-sensor model, or skew under a quarter turn).
  std::string turned(int quarter_turns_cw, bool mirrored, CameraModel& out) const;

  bool hasDistortion() const;
  /// Why the distortion coefficients cannot be this camera's: a point of the
  /// image taken back to ideal coordinates and distorted again does not come
  /// back to where it was (by a twentieth of the image's diagonal, far beyond
  /// a real lens model's shortfall). "" when they can, or there are none.
  std::string distortionProblem() const;
};

}  // namespace ld
