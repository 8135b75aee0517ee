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

#include "ld/artwork.hpp"
#include "ld/camera.hpp"

namespace ld::synth {

/// One landmark in the scene. The pose is the sheet's object frame (origin at
/// the sheet centre, x right, y down on the sheet) in the camera frame (x
/// right, y down, z forward), as LANDMARK.md's `pose`.
struct LandmarkPlacement {
  int id = 0;                 // ground-truth identity, carried to the truth
  std::string payload = "ld"; // QR text
  artwork::QrEcc ecc = artwork::QrEcc::Auto;  // its error correction (as ld-generate's --ecc)
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
///
/// "Faces the camera" means the sheet's normal points back along that ray
/// with the sheet's x axis kept horizontal (in the camera's x-z plane), so on
/// the optical axis yaw = pitch = roll = 0 is rvec = 0 exactly. The turns are
/// composed as R = R_face * R_y(yaw) * R_x(pitch) * R_z(roll) (roll first, in
/// the sheet plane), with these signs:
///  - positive yaw turns the sheet's right edge (+x) towards the camera: its
///    right side looks taller, the camera sees it from the sheet's right;
///  - positive pitch turns the top edge towards the camera (top looks wider);
///  - positive roll turns the sheet clockwise as seen in the image.
/// nx = +-1 and ny = +-1 are the image borders (pixel 0 and width-1 / height-1);
/// with a distorted camera the ray is that of the distorted pixel.
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

/// A textured rectangle in the scene (a wall, a floor: what a sequence moves
/// past), drawn over the background before distractors, cards and landmarks.
/// Frame and pose as a landmark's: origin at the rectangle's centre, x right,
/// y down, the texture covering [-w/2, w/2] x [-h/2, h/2].
struct Surface {
  cv::Mat texture;               // 8-bit BGR
  std::vector<cv::Mat> mipmaps;  // optional: texture, pyrDown(texture), ... (makeMipmaps)
  cv::Size2d size_m{1.0, 1.0};   // width (along x) and height (along y), metres
  cv::Vec3d rvec{0, 0, 0};
  cv::Vec3d tvec{0, 0, 1};
};

/// Fills s.mipmaps from s.texture, so that rendering a distant or oblique
/// surface neither aliases nor rebuilds the pyramid every frame.
void makeMipmaps(Surface& s);

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
  /// Textured planes drawn over the background (sequences use them for walls
  /// and floor, so the world stays put while the camera moves).
  std::vector<Surface> surfaces;
  /// Seed of the sensor noise alone; 0: derived from `seed`. Sequences keep
  /// `seed` (the world) fixed and change this per frame.
  uint64_t noise_seed = 0;
};

/// The printed-ink appearance of the landmark's colours (BGR) that render()
/// uses when printed_ink is set: dark purplish blue, orange-ish red, slightly
/// grey paper, not quite black toner.
artwork::Colours printedInk();

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

/// LANDMARK.md's JSON for one frame's ground truth, one line (no newline):
/// {"image", "width", "height", ["seq", "utime",] "landmarks": [{"id", "payload",
/// "fip_tl", "fip_tr", "fip_bl", "ap", "corners", "pose": {"t", "rvec",
/// "distance"}, "in_view"}]}. seq and utime are written when >= 0.
std::string truthJsonLine(const std::string& image, cv::Size size,
                          const std::vector<LandmarkTruth>& truth, int64_t seq = -1,
                          int64_t utime = -1);

// ---------------------------------------------------------------------------
// Sequences: a camera moving through a small world.

/// A robot driving past a wall (with a gentle approach and a turn of its
/// heading, from looking ahead to looking back) and a floor; landmarks with
/// distinct payloads hang on the wall at about camera height, so they enter
/// the view on one side and leave it on the other. The path runs from 1.3 m
/// before the first landmark to 1.3 m past the last, at the speed that fits
/// the sequence's duration ((frames - 1) / fps) but at most 0.8 m/s: a
/// shorter sequence drives the middle part of the path. Motion blur follows
/// from the speed (1/125 s exposure).
struct SequenceOptions {
  std::string out_dir;              // PNG frames and truth.jsonl; empty: none
  bool write_png = true;            // false: truth.jsonl only (still in out_dir)
  std::string log_path;             // LCM log of image_t; empty: none
  std::string channel = "IMAGE";
  std::string pixel_format = "bgr"; // gray, rgb, bgr, yuyv, uyvy, mjpeg (image_convert names)
  int jpeg_quality = 90;            // for mjpeg
  int frames = 120;
  double fps = 30.0;
  int64_t start_utime = 1700000000000000;  // utime of frame 0 (fixed: deterministic logs)
  int landmarks = 3;                // on the wall, ids 0..K-1
  double side_m = 0.15;
  std::vector<std::string> payloads;  // per landmark; default "room-101", "room-102", ...
  artwork::QrEcc ecc = artwork::QrEcc::Auto;  // the codes' error correction (as ld-generate's --ecc)
  CameraModel camera = CameraModel::defaultVga();
  uint64_t seed = 1;
};

/// The world and the camera path of a sequence; frames rendered on demand.
class Sequence {
 public:
  explicit Sequence(const SequenceOptions& options);  // throws std::invalid_argument on bad options
  int frames() const { return options_.frames; }
  int64_t utime(int i) const;
  /// Frame i's scene: camera-frame poses of the landmarks (stable ids) and the surfaces.
  SceneSpec scene(int i) const;
  /// The camera's pose in the world (world: x along the wall, y down, z towards it).
  void cameraPose(int i, cv::Matx33d& R_world_camera, cv::Vec3d& position) const;

 private:
  SequenceOptions options_;
  std::vector<Surface> world_surfaces_;  // poses in the world frame
  std::vector<LandmarkPlacement> world_landmarks_;
  Lighting lighting_;
  Degradation degradation_;
  double wall_z_ = 2.0, camera_height_ = 0.5, x_start_ = -1, x_end_ = 1;
  double s0_ = 0, s1_ = 1;  // the part of the path driven (speed limit)
};

struct SequenceStats {
  int frames = 0;
  int frames_with_landmark_in_view = 0;
};

/// Renders a sequence: out_dir/000000.png ... (unless !write_png),
/// out_dir/truth.jsonl (with seq and utime) and, with log_path, an LCM log of
/// image_t on `channel` with utime = start_utime + i * 1e6 / fps (also the
/// event timestamp) and "seq" metadata i. Throws std::runtime_error with a
/// one-line reason (unwritable folder or log, bad options).
SequenceStats writeSequence(const SequenceOptions& options);

}  // namespace ld::synth
