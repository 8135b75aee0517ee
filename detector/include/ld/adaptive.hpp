// Adaptive lighting (the paper's first item of future work): the detector's
// colour ratios, saturation thresholds and value floor assume a roughly
// neutral, well exposed image. Warm tungsten light turns the white sheet
// orange and dims the blue squares; dim light pushes printed blue under the
// value floor. Rather than retuning those thresholds by hand, the adapter
// estimates the light's colour and level and corrects the frame (one gain per
// channel) before detection, which moves every colour threshold with the
// light at once:
//  - from the white sheet of landmarks confirmed in recent frames (the one
//    surface whose true colour is known), when there are any;
//  - otherwise from the frame itself: the mean of its brightest unclipped
//    pixels (walls, paper and ceilings are the usual near-white surfaces).
// Estimates are smoothed over frames; gains are bounded so that noise in the
// dark is not amplified without limit, and a strongly corrected frame is
// smoothed a little against the amplified noise. Before the gains, a glare
// veil (a hot spot lifting every channel of part of the frame) is estimated
// from the local black level and subtracted where it covers dark and white
// together.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "ld/detector.hpp"

namespace ld {

struct AdaptiveParams {
  /// The corrected white's brightest channel (0..255).
  double target_white = 200.0;
  /// Per-channel gains are clamped to [1 / max_gain, max_gain].
  double max_gain = 8.0;
  /// Frame estimate: the whitest this fraction of pixels (not clipped).
  double bright_fraction = 0.05;
  /// Weight of a new estimate against the running one (1: no smoothing).
  double smoothing = 0.5;
  /// A landmark-sheet estimate stays preferred for this many frames.
  int landmark_memory_frames = 30;
  /// No correction while the estimated white is within this relative
  /// deviation from the target on every channel (saves the pass in good light).
  double deadband = 0.08;
  /// Gaussian smoothing (sigma, px) of the corrected frame when a channel's
  /// gain exceeds denoise_above_gain: strong gains turn the weak channel's
  /// noise and JPEG blocks into speckle that breaks the squares up.
  double denoise_sigma = 1.2;
  double denoise_above_gain = 1.3;
  /// Glare: light reflected off the sheet (a lamp's hot spot, a window)
  /// adds the same amount to every channel, which desaturates the squares
  /// below the colour thresholds. Where the local black level (the darkest
  /// pixels within glare_window px) has risen more than glare_min_lift above
  /// the frame's own black level, while the same window still holds pixels
  /// glare_min_contrast brighter than that (dark ink and white paper under
  /// one veil, not a plain pale wall; near the clip, most of the range left),
  /// the veil is subtracted and the range stretched back to white. Its
  /// colour is measured on the veiled blocks (the light's), its level taken
  /// up the hot spot's slope. glare_min_lift 0 turns it off.
  double glare_min_lift = 60.0;
  double glare_min_contrast = 60.0;
  int glare_window = 40;
  /// Where the glare pass stretched a channel back by this factor or more
  /// ((255 - black) / (255 - veil): 4 under a veil of about 190), a veil a
  /// few levels off in one channel tints the blue squares towards cyan or
  /// violet; AdaptiveDetector then has the detector's faint look take blue
  /// at any hue where blue is the largest channel
  /// (Detector::setGlareCorrected). A huge value turns that off.
  double wide_hue_min_stretch = 3.0;
};

class LightingAdapter {
 public:
  /// Throws std::invalid_argument naming a parameter out of its range
  /// (target_white 1-255, max_gain 1-64, bright_fraction and smoothing up
  /// to 1, glare_window 1-4096 px, ...; NaN nowhere).
  explicit LightingAdapter(const AdaptiveParams& params = {});
  /// Movable, not copyable: its buffers (cv::Mat) would be shared by a copy,
  /// each one's corrections written into the other's frames (an API audit).
  LightingAdapter(const LightingAdapter&) = delete;
  LightingAdapter& operator=(const LightingAdapter&) = delete;
  LightingAdapter(LightingAdapter&&) = default;
  LightingAdapter& operator=(LightingAdapter&&) = default;

  /// The frame to detect on: `bgr` corrected for the current estimate (or
  /// `bgr` itself when no correction is needed, and for a frame that is not
  /// BGR: gray, empty). Updates the estimate from the frame first when no
  /// landmark was confirmed recently. The returned reference is to the
  /// adapter's own buffer, valid until the next call while the adapter
  /// lives, or to `bgr` itself, valid while `bgr` is: a temporary given
  /// (`correct(cv::imread(...))`) dangles at the end of the statement.
  const cv::Mat& correct(const cv::Mat& bgr);

  /// Feeds back the detections made on the corrected frame of the last
  /// correct() call with the original frame: the sheet between the squares
  /// of each landmark is a white reference.
  void observe(const cv::Mat& original_bgr, const Detection& detection);

  /// Per-channel gains (B, G, R) applied by the last correct().
  cv::Vec3d gains() const { return gains_; }
  /// Whether the last correct() subtracted a glare veil somewhere.
  bool glareCorrected() const { return glare_corrected_; }
  /// The largest factor by which the last correct()'s glare pass stretched
  /// a channel back to the full range, (255 - black) / (255 - veil) over
  /// the veiled blocks; 1 where it subtracted no veil.
  double veilStretch() const { return veil_stretch_; }
  /// Whether that stretch reached wide_hue_min_stretch: what
  /// Detector::setGlareCorrected is to be told for the corrected frame.
  bool strongVeil() const { return glare_corrected_ && veil_stretch_ >= params_.wide_hue_min_stretch; }
  /// The colour (B, G, R over the strongest) of the veil the last correct()
  /// looked for: measured on the veiled blocks when there were enough of
  /// them, else the running white estimate's, else neutral (also when the
  /// glare pass is off or the frame was not corrected).
  const cv::Vec3d& veilColour() const { return veil_colour_; }
  /// Whether the last estimate came from a landmark's sheet.
  bool fromLandmarks() const { return frames_since_landmark_ < params_.landmark_memory_frames; }

  void reset();

 private:
  void update(const cv::Vec3d& white);
  const cv::Mat& deglare(const cv::Mat& bgr);

  AdaptiveParams params_;
  cv::Vec3d white_{0, 0, 0};  // running estimate of white (BGR); 0: none yet
  cv::Vec3d gains_{1, 1, 1};
  int frames_since_landmark_ = 1 << 20;
  cv::Mat corrected_;
  std::vector<int> hist_;
  std::vector<cv::Vec3d> level_sums_;  // the frame estimate's channel sums per weakest-channel level
  bool glare_corrected_ = false;
  double veil_stretch_ = 1.0;
  cv::Mat deglared_, row_min_, block_min_, block_white_, local_black_, local_open_, local_white_, veil_coarse_,
      veiled_;
  cv::Mat window_kernel_, spread_kernel_;  // the glare pass's morphology
  std::vector<double> veil_ratios_[2];     // veiled blocks' blue and red lifts over green's
  cv::Vec3d veil_colour_{1, 1, 1};
  cv::Mat veil_full_;  // the block veil interpolated to every pixel
};

/// A Detector with a LightingAdapter in front: detect() corrects the frame,
/// detects, and feeds the confirmed landmarks back. With the adapter turned
/// off (`--adaptive` not given), frames go to the detector as they are.
/// It takes what Detector takes: BGR, BGRA (corrected as BGR) or gray (no
/// landmarks).
class AdaptiveDetector {
 public:
  explicit AdaptiveDetector(const DetectorParams& params = {}, const AdaptiveParams& adaptive = {});
  /// `detector` as it is (camera, backend), the adapter in front when `enabled`.
  AdaptiveDetector(Detector detector, bool enabled, const AdaptiveParams& adaptive = {});
  const Detection& detect(const cv::Mat& bgr);
  /// detect() with Detector's explanation of the corrected frame.
  const Detection& detect(const cv::Mat& bgr, Explanation& why);
  Detector& detector() { return detector_; }
  LightingAdapter& adapter() { return adapter_; }
  bool enabled() const { return enabled_; }

 private:
  // The frame corrected, and the detector told whether the correction
  // stretched a veil away by wide_hue_min_stretch or more.
  const cv::Mat& correct(const cv::Mat& bgr);
  // A BGRA frame as BGR (in bgr_, kept between frames); others as they are.
  const cv::Mat& asBgr(const cv::Mat& image);
  // detect(), with the explanation where `why` is given.
  const Detection& detectWith(const cv::Mat& image, Explanation* why);
  cv::Mat bgr_;
  Detector detector_;
  LightingAdapter adapter_;
  bool enabled_ = true;
};

}  // namespace ld
