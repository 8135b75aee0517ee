// ld-synth: synthetic scenes, the project's own source of test data.
//
// Landmarks at full 3D poses seen by a pinhole camera (with the camera's
// distortion when it has one), over procedural backgrounds with colourful
// blue and red distractors, lit and degraded like a cheap webcam: printed-ink
// colours, gain, colour temperature, gradient, glare, defocus and motion
// blur, sensor noise and JPEG. Ground truth is exact, from the pose.
// Everything is deterministic for a given seed.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/camera.hpp"

namespace ld::synth {

/// One landmark in the scene. The pose is the sheet's object frame (origin at
/// the sheet centre, x right, y down on the sheet) in the camera frame (x
/// right, y down, z forward), as LANDMARK.md's `pose`.
struct LandmarkPlacement {
  int id = 0;                 // ground-truth identity, carried to the truth
  std::string payload = "ld"; // QR text
  double side_m = 0.15;       // printed sheet side S
  cv::Vec3d rvec{0, 0, 0};
  cv::Vec3d tvec{0, 0, 1};
  /// When set: this square 8-bit BGR image is printed on the sheet instead of
  /// the landmark artwork (benchmarks put AprilTag and ArUco markers at the
  /// same poses this way). It covers the whole sheet of side side_m.
  cv::Mat texture;
};

/// A pose that faces the camera at `distance` metres along the ray through
/// normalised image position (nx, ny) in [-1, 1] (0, 0 = optical axis), then
/// turned by yaw (about the sheet's vertical axis: the paper's horizontal
/// viewing angle), pitch (about its horizontal axis) and roll (in its plane).
/// Angles in degrees. yaw = pitch = roll = 0 gives a frontal, upright sheet.
LandmarkPlacement placeLandmark(const CameraModel& camera, double distance, double yaw_deg,
                                double pitch_deg, double roll_deg, double nx = 0, double ny = 0,
                                double side_m = 0.15, const std::string& payload = "ld",
                                int id = 0);

struct Lighting {
  double gain = 1.0;              // overall brightness (1 = well lit office)
  double colour_temp_k = 6500.0;  // 2700 = tungsten (yellow), 6500 = daylight
  double gradient = 0.0;          // 0..1: brightness falls by this much across the frame
  double gradient_angle_deg = 0.0;
  double glare = 0.0;             // 0..1: peak of a specular spot added to the frame
  cv::Point2d glare_centre{0.5, 0.5};  // normalised image position of the spot
  double glare_radius = 0.15;          // fraction of the image width
};

struct Degradation {
  double defocus_sigma_px = 0.0;  // Gaussian defocus
  double motion_px = 0.0;         // motion blur length
  double motion_angle_deg = 0.0;
  double noise_sigma = 0.0;       // sensor noise, 8-bit units at mid grey
  int jpeg_quality = 0;           // 0: no JPEG round trip
};

enum class Background {
  Plain,    // an evenly lit wall
  Office,   // walls, furniture-like blocks, posters, textures
  Clutter,  // dense colourful clutter
};

struct SceneSpec {
  CameraModel camera = CameraModel::defaultVga();
  std::vector<LandmarkPlacement> landmarks;
  Background background = Background::Office;
  int distractors = 6;              // colourful blue and red objects
  int landmark_like_cards = 0;      // cards with a red square in the middle or next to TL
  bool printed_ink = true;          // printed, not nominal, colours
  Lighting lighting;
  Degradation degradation;
  uint64_t seed = 1;                // background, distractors and noise
};

/// Ground truth of one landmark, exact from the pose (LANDMARK.md fields).
struct LandmarkTruth {
  int id = 0;
  std::string payload;
  cv::Point2d fip_tl, fip_tr, fip_bl, ap;
  std::array<cv::Point2d, 4> corners;  // TL, TR, BR, BL
  cv::Vec3d t, rvec;
  double distance = 0;
  bool in_view = false;  // all four corners inside the image and in front of the camera
};

struct Frame {
  cv::Mat bgr;                        // CV_8UC3, camera.size
  std::vector<LandmarkTruth> truth;   // one per landmark of the spec, in order
};

/// Renders one frame.
Frame render(const SceneSpec& spec);

/// Ground truth alone (no rendering).
LandmarkTruth truthFor(const CameraModel& camera, const LandmarkPlacement& lm);

/// A random scene of the kind used by tests and benchmarks: the given
/// landmarks over a random background, with random but realistic lighting
/// and degradation drawn from `seed` (mild ranges; exact ranges documented
/// in the implementation).
SceneSpec randomConditions(const CameraModel& camera, std::vector<LandmarkPlacement> landmarks,
                           uint64_t seed);

}  // namespace ld::synth
