// The landmark tracker: section IV of the paper, made robust for a moving
// robot. Stable ids for the detections of a video stream.
//
//   1. expire     drop pool landmarks unseen for max_lifetime_s (frame
//                 timestamps, not frame counts: independent of the frame rate)
//   2. predict    move each pool landmark to the new frame's time with its
//                 constant velocity (position and size); a landmark that was
//                 not detected in the previous frame may also be matched
//                 where it was last seen (the robot stopped or turned back:
//                 a landmark that left the image comes back where it left);
//                 one predicted past a side of the image it was last seen
//                 near comes back through that side (given the image size),
//                 also, last seen within a size of that side, where it left
//                 moved along that side as its motion went
//   3. assign     the paper's three cases: empty pool (all new), no detections
//                 (all age), both non-empty: optimal assignment (Hungarian)
//                 on the distance between the predicted pool landmark and the
//                 new one: pairs beyond the maximum distance or the size ratio
//                 are never made; a pair within gains its margin (the gate's
//                 radius less the distance, in landmark sizes) and the assignment of the largest
//                 total gain wins, so two poor pairs never displace a good one
//                 and a landmark that leaves as another comes leaves its id
//                 behind; a detection two pool landmarks could both be goes to
//                 the one seen more recently (the margin is divided by 1 + the
//                 seconds unseen); in a frame whose other landmarks are where
//                 their predictions put them, a pair far off a well-predicted
//                 landmark's prediction is refused
//   4. update     matched tracks take the detection (corners, pose; the track's
//                 payload is kept when the detection has none) and refresh
//                 their velocity; unmatched tracks coast; unmatched detections
//                 become new tracks with new ids (an id is never reused),
//                 starting with the image motion common to the other tracks
//   5. report     visible and coasting tracks, in creation order
//
// A Tracker keeps its buffers between frames: once warmed up (pool and
// detection counts seen before), update() does not allocate, except to copy a
// payload longer than the string's small buffer.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/detector.hpp"
#include "ld/hungarian.hpp"

namespace ld {

/// The tracker's parameters: the paper's three (lifetime, distance, size
/// ratio) and the prediction that lets ids survive fast robot motion.
struct TrackerParams {
  /// Paper 1: a landmark stays in the pool while it was seen less than this
  /// long ago (seconds, from the frames' utime). Longer keeps ids through
  /// longer occlusions but lets a vanished landmark's id be taken by another
  /// that appears near its predicted position.
  double max_lifetime_s = 1.0;
  /// Paper 2: largest distance between a pool landmark (predicted) and a new
  /// one that may be the same landmark, in landmark sizes (mean side of the
  /// pattern square, averaged over the pair), so it holds near and far.
  /// Larger tolerates faster unpredicted motion; smaller separates close
  /// landmarks. Two landmarks' centres are at least about 1.1 sizes apart.
  /// A landmark seen once (no velocity yet) that missed frames may be twice
  /// as far. A landmark detected in the frame before, whose motion is
  /// measured, in a frame whose other landmarks are where their predictions
  /// put them, may be no further than a size from its prediction, unless its
  /// detections have been further from theirs (README, "The tracker").
  double max_distance = 2.0;
  /// Extra distance allowed per second a landmark has been unseen (landmark
  /// sizes per second): the prediction of a coasting landmark gets less
  /// certain with time. 0 keeps the gate fixed.
  double coast_distance_growth = 1.0;
  /// Paper 3: largest ratio between the larger and the smaller size of a pair
  /// (predicted pool landmark, new landmark). Smaller rejects matches with a
  /// near and a far landmark; larger tolerates fast approach.
  double max_size_ratio = 1.5;
  /// Constant-velocity prediction of position and size (beyond the paper).
  /// A new track starts with the image motion common to the tracks already
  /// followed (on a robot, mostly its own motion). Off: a pool landmark is
  /// compared where it was last seen.
  bool predict = true;
  /// Weight of the newest measured velocity (0..1] against the previous
  /// estimate: 1 follows the motion at once, smaller smooths detector noise.
  double velocity_smoothing = 0.5;
  /// A track is reported once it has been detected this many times: 1 reports
  /// every detection, 2 or 3 hide one-frame false positives.
  int min_hits = 1;
  /// Report coasting tracks (not detected in this frame, within lifetime) at
  /// their predicted position with visible = false.
  bool report_coasting = true;

  /// Reads a YAML/XML file (cv::FileStorage) whose keys are the field names
  /// above; absent keys keep their defaults. Throws std::runtime_error naming
  /// the file and the unknown or malformed key, and validates the result.
  static TrackerParams load(const std::string& path);
  /// Writes every field (a file load() reads back).
  void save(const std::string& path) const;
  /// The same as YAML text.
  std::string toYaml() const;
  /// Throws std::invalid_argument naming the first inconsistent field.
  void validate() const;
};

/// One track as reported for a frame.
struct Track {
  int64_t id = -1;                 ///< stable id, from 1, never reused
  int32_t age = 0;                 ///< frames since the track was created (0: new)
  int32_t hits = 0;                ///< frames in which it was detected
  int32_t frames_since_seen = 0;   ///< 0 when detected in this frame
  int64_t time_since_seen_us = 0;  ///< utime of this frame - utime of the last detection
  bool visible = false;            ///< detected in this frame (false: coasting)
  int detection_index = -1;        ///< index in update()'s detections; -1 when coasting
  /// Visible: the detection (with the track's payload when it has none).
  /// Coasting: the last detection moved to its predicted position and size;
  /// pose, payload and score are the last detection's.
  Landmark landmark;
  cv::Point2f velocity;            ///< image velocity of the centre, px/s
};

struct TrackerStats {
  int64_t frames = 0;               ///< update() calls
  int64_t tracks_created = 0;
  int64_t tracks_dropped = 0;       ///< expired after max_lifetime_s, or the longest unseen beyond kMaxPool
  int64_t matches = 0;              ///< detections assigned to an existing track
  int64_t rejected_detections = 0;  ///< non-finite or degenerate detections, ignored
  int64_t resets = 0;               ///< pool cleared because time went backwards
  int64_t late_frames = 0;          ///< frames a little older than the previous one, not tracked
};

/// Centre of a landmark: the mean of its four square centres.
cv::Point2f landmarkCentre(const Landmark& lm);
/// Size of a landmark in pixels: the mean side of its corners quadrilateral.
double landmarkSize(const Landmark& lm);

class Tracker {
 public:
  /// Throws std::invalid_argument when params do not validate.
  explicit Tracker(const TrackerParams& params = {});

  /// Tracks the detections of one frame captured at `utime` (microseconds).
  /// Frames must come in time order. A frame older than the previous one by
  /// up to kLateFrameUs is a message that came late (reordered on the way):
  /// it is not tracked, the pool is left as it was, and the result is empty
  /// (stats().late_frames counts it; ld-tracker publishes nothing for it). A
  /// frame older by more (a log replayed from its start, a clock stepped
  /// back), or the kStepBackFrames-th frame in a row from behind, each newer
  /// than the one before, clears the pool first, ids still never reused. Detections with
  /// non-finite coordinates or a size under one pixel are ignored. The
  /// returned reference stays valid until the next call.
  ///
  /// `image`, the frame's size when known: a pool landmark last seen in one
  /// half of the image and predicted past that half's side (a corner of its
  /// pattern square beyond it) is only paired with a detection in that half:
  /// it comes back through the side it left by (large landmarks: as one left
  /// through one side, the next came in through the other within its gate
  /// and took its id).
  const std::vector<Track>& update(const std::vector<Landmark>& detections, int64_t utime,
                                   cv::Size image = {});
  /// How much older than the previous frame a frame may be and still be a
  /// late message rather than time starting again: a second, the default
  /// lifetime (a message held up 4 frames on a busy network cleared the
  /// pool when this was 0.1 s, and the tracks rebuilt from that old frame
  /// moved every id along a row of landmarks panning past). A log replayed
  /// again goes back by its length.
  static constexpr int64_t kLateFrameUs = 1'000'000;
  /// A run of this many frames from behind, each newer than the one before,
  /// is time stepped back (a clock set back, a short log replayed again),
  /// not messages held up: the pool is cleared at the last of them, which is
  /// tracked (a clock set back 0.5 s gave half a second of nothing).
  static constexpr int kStepBackFrames = 3;
  /// The most landmarks the pool holds: beyond them the longest unseen go
  /// (counted in tracks_dropped). Lifetimes count the frames' utime, so a
  /// publisher whose utime stands still expires nothing (ld-tracker says
  /// so), and with --max-lifetime of days neither does one that stamps its
  /// frames: each landmark that came and went stayed, and the assignment
  /// over thousands took seconds a frame.
  static constexpr size_t kMaxPool = 2000;

  /// The tracks reported by the last update().
  const std::vector<Track>& tracks() const { return out_; }
  /// Empties the pool (ids continue from where they were).
  void reset();
  /// Landmarks in the pool, reported or not (min_hits).
  size_t poolSize() const { return pool_.size(); }
  const TrackerParams& params() const { return params_; }
  const TrackerStats& stats() const { return stats_; }

 private:
  enum class Motion : uint8_t {
    None,      // no velocity: predicted where last seen
    Borrowed,  // the common image motion, until the track's own is measured
    Measured,  // from the track's own detections
  };
  struct PoolEntry {
    int64_t id = 0;
    Landmark lm;                     // last detection
    cv::Point2d centre;              // of the last detection
    double size = 0;                 //   "
    cv::Point2d velocity;            // px/s
    double size_rate = 0;            // px/s
    Motion motion = Motion::None;
    bool restart_motion = false;     // this frame: velocity from the common motion
    int64_t last_seen_utime = 0;
    int32_t age = 0, hits = 0, frames_since_seen = 0;
    cv::Point2d pred_centre;         // at the current frame's utime
    double pred_size = 0;
    int detection = -1;              // matched detection this frame
    // How far its detections have been from where its motion put them
    // (landmark sizes, a running mean over frames followed without a gap,
    // its motion measured): 1, unknown, until then.
    double miss_distance = 1.0;
    int64_t seen_gap_us = 0;         // between its last two detections
  };

  void predict(int64_t utime);
  void assign(int64_t utime, cv::Size image);
  // The sides of the image a pool landmark is predicted to have left by (a
  // corner of its pattern square past them) and was last seen near (in that
  // side's half); none when `image` is empty.
  struct Sides {
    bool left = false, right = false, top = false, bottom = false;
    bool any() const { return left || right || top || bottom; }
    // Whether a point is in the half of the image towards one of them.
    bool towards(const cv::Point2d& p, cv::Size image) const;
  };
  Sides sidesLeftBy(const PoolEntry& e, cv::Size image) const;
  // A matched pair whose detection is much further from the landmark's
  // prediction than its detections have been, and than the frame's other
  // landmarks are from theirs, is no pair (refused: true).
  bool refuseSurprises(int64_t utime);
  // How far inside its gate valid detection j is from a pool landmark at
  // (centre, size), in landmark sizes: the gate's radius (max_dist sizes, the pair's
  // mean size) less their distance, and the same inside the plain gate
  // (max_distance sizes); negative outside them, -1 for both when the pair
  // fails the size ratio.
  std::pair<double, double> gateMargins(const cv::Point2d& centre, double size, size_t j, double max_dist) const;
  void updateMatched(PoolEntry& e, const Landmark& det, int d, int64_t utime);
  void report(int64_t utime);

  TrackerParams params_;
  TrackerStats stats_;
  int64_t next_id_ = 1;
  bool has_time_ = false;
  int64_t last_utime_ = 0;
  int behind_ = 0;             // frames from behind in a row, each newer than the one before
  int64_t behind_utime_ = 0;   // the last of them
  std::vector<PoolEntry> pool_;
  std::vector<Track> out_;
  // per-frame scratch, kept between frames
  std::vector<cv::Point2d> det_centre_;
  std::vector<double> det_size_;
  std::vector<int> det_index_;      // valid detections' indices into the input
  std::vector<char> det_matched_;
  std::vector<double> common_vx_, common_vy_;
  std::vector<double> gain_, cost_;
  std::vector<size_t> judged_;          // refuseSurprises: the pool entries judged,
  std::vector<cv::Point2d> shift_;      //   their detections' shift from their predictions,
  std::vector<double> others_x_, others_y_;  // the others' shifts, each way
  std::vector<int> row_to_col_;
  Hungarian hungarian_;
};

}  // namespace ld
