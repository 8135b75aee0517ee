// Evaluation on ld-synth scenes: how often the detector finds a landmark and
// the QR reader reads its payload, swept over viewing angle and distance.
// Shared by the accuracy tests and ld-eval, so that what the tests assert and
// what the report prints are the same measurement.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "ld/artwork.hpp"
#include "ld/camera.hpp"
#include "ld/detector.hpp"
#include "ld/synth.hpp"

namespace ld::eval {

/// A distinct test payload for index i: ASCII, UTF-8 (accents, Greek, CJK)
/// and long ones, up to 100 bytes, cycling through those kinds.
std::string payloadFor(int i);

/// Conditions of one sweep. Every trial renders one landmark at the swept
/// distance and yaw, with random roll (any, when any_roll), pitch within
/// +-max_pitch_deg, position in the image's middle half (moved to the centre
/// when it would leave the view) and random lighting and degradation
/// (ld::synth::randomConditions), all drawn from `seed`.
struct SweepOptions {
  CameraModel camera = CameraModel::defaultVga();
  double side_m = 0.15;
  int trials = 20;  ///< per sweep point
  uint64_t seed = 1;
  bool any_roll = true;
  double max_pitch_deg = 10.0;
  bool decode = false;  ///< also read the QR (from the detected corners)
  /// The payload printed on trial k's landmark (k drawn at random in [0, 1000)).
  std::function<std::string(int)> payload = payloadFor;
  artwork::QrEcc ecc = artwork::QrEcc::Auto;  ///< its QR's error correction (ld-generate --ecc)
  DetectorParams params;
  /// Detect through ld::AdaptiveDetector (lighting adaptation) instead of the
  /// fixed defaults. Each trial is a fresh frame: the adapter has only the
  /// frame itself to go by, no landmarks seen before.
  bool adaptive = false;
  /// What is printed and detected: "landmark" (ours), or "apriltag" /
  /// "aruco": that marker at the same printed size and the same poses,
  /// found by its own detector (ld/markers.hpp). Markers have no payload.
  std::string target = "landmark";
  /// Overrides of the random lighting (negative: keep randomConditions').
  double colour_temp_k = -1;  ///< 2700 tungsten .. 6500 daylight
  double gain = -1;           ///< 1 = well lit office
  double glare = -1;          ///< peak of a specular spot near the landmark
  /// Motion blur of this length (pixels; a camera turning or driving during
  /// the exposure), along a direction drawn per trial; negative: keep
  /// randomConditions' mild degradation.
  double motion_px = -1;
  /// With decode: also read each trial's QR over this many frames as
  /// ld-qr-reader reads an undecoded track: the same scene again with its
  /// own sensor noise, the landmark moved by up to a third of a pixel each
  /// time (a moving camera), found by the detector in each; read when any
  /// frame alone or their mean (ld::QrStack) reads. 0: single frames only.
  int stack_frames = 0;
  /// Also the pose of each found landmark or marker, from its four corners
  /// (ld::poseFromCorners: IPPE_SQUARE with `camera` and `side_m`), against
  /// the truth: Point::pose_errors.
  bool pose = false;
  /// A folder to write each frame our detector went wrong on into (empty:
  /// none): a landmark it missed; with `decode`, one it found and did not
  /// read (named with "_unread"); a distractor frame where it found
  /// landmarks (named "distractors..."). The frame as rendered (PNG, named by
  /// the side, the sweep point, the seed, the trial, `misses_tag` and the
  /// detector: fixed or adaptive), with a line appended to misses.jsonl
  /// there (startMisses() empties it) giving its kind, the trial's pose,
  /// light and the truth's centres (a false landmark's: the landmarks
  /// found; one not read: the payload and what the frame read): what
  /// `ld-detect --explain` (with `--adaptive` for the adaptive detector's)
  /// can be run on to see why. A frame or line that cannot be written:
  /// MissesError.
  std::string misses_dir;
  /// Tells apart the missed frames of sweeps over the same points (the QR
  /// sweep's short and long payloads, say): in their names and lines.
  std::string misses_tag;
};

/// What writing a missed frame or its line failed on (a full disk).
struct MissesError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Empties the misses.jsonl of `dir` (an earlier run's), a folder that
/// exists (ld::prepareOutputFolder). Throws std::runtime_error naming what
/// failed.
void startMisses(const std::string& dir);

/// How far found landmarks' (or markers') corners and poses lie from the
/// truth, one entry per add(): the corners' mean distance from the truth's
/// (px), and with a pose the angle between its rotation and the truth's
/// (degrees) and its distance's relative error (|d - true d| / true d).
struct PoseErrors {
  std::vector<double> corner_px, rotation_deg, distance_frac;
  void add(const std::array<cv::Point2f, 4>& corners, const std::optional<Pose>& pose,
           const synth::LandmarkTruth& truth);
};

/// One sweep point: the swept value and what happened in its trials.
struct Point {
  double distance_m = 0, yaw_deg = 0;
  double motion_px = -1;  ///< the blur of the point's frames (SweepOptions::motion_px)
  int trials = 0;
  int detected = 0;       ///< the landmark was found (centres match the truth)
  int decoded = 0;        ///< ... and its QR read to exactly its payload
  int wrong_payload = 0;  ///< a payload other than the printed one (must stay 0)
  int decoded_stacked = 0;  ///< read over stack_frames frames, alone or stacked (stack_frames > 0)
  int decoded_stack = 0;    ///< ... of which the stack (ld::QrStack: the frames' mean, or their fits' vote) read it
  /// With SweepOptions::pose, one entry per found landmark or marker, its
  /// pose from its corners (a pose that did not solve adds a corner error
  /// only).
  PoseErrors pose_errors;
  double detectRate() const { return trials ? static_cast<double>(detected) / trials : 0; }
  double decodeRate() const { return trials ? static_cast<double>(decoded) / trials : 0; }
  double stackedDecodeRate() const { return trials ? static_cast<double>(decoded_stacked) / trials : 0; }
};

/// The trials at one (distance, yaw), yaw drawn uniformly from
/// [yaw_deg - yaw_jitter_deg, yaw_deg + yaw_jitter_deg].
Point measure(const SweepOptions& options, double distance_m, double yaw_deg,
              double yaw_jitter_deg = 0.0);

/// Sweeps: one Point per value. `progress`, when set, is called after each point.
std::vector<Point> overYaw(const SweepOptions& options, double distance_m,
                           const std::vector<double>& yaws_deg,
                           const std::function<void(const Point&)>& progress = {});
std::vector<Point> overDistance(const SweepOptions& options, const std::vector<double>& distances_m,
                                double max_abs_yaw_deg,
                                const std::function<void(const Point&)>& progress = {});
/// Over motion blur lengths (pixels) at one distance, yaw within +-max_abs_yaw_deg.
std::vector<Point> overMotion(const SweepOptions& options, double distance_m, const std::vector<double>& blurs_px,
                              double max_abs_yaw_deg, const std::function<void(const Point&)>& progress = {});

/// False landmarks per frame on `frames` scenes with colourful distractors,
/// landmark-like cards and no landmark, under the options' lighting.
double falsePositivesPerFrame(const SweepOptions& options, int frames);

/// measure() and falsePositivesPerFrame() for the fixed defaults ([0]) and
/// the adaptive detector ([1]) on the same rendered frames (options.adaptive
/// is not looked at): what `ld-eval lighting` compares. Landmarks only:
/// throws std::invalid_argument for a marker target.
std::array<Point, 2> measureFixedAndAdaptive(const SweepOptions& options, double distance_m, double yaw_deg,
                                             double yaw_jitter_deg = 0.0);
std::array<double, 2> falsePositivesFixedAndAdaptive(const SweepOptions& options, int frames);

/// Totals over a sweep's points.
Point total(const std::vector<Point>& points);

/// The q-quantile (0..1) of `values` (the element at q * n of them sorted);
/// 0 when there are none.
double quantile(std::vector<double> values, double q);

}  // namespace ld::eval
