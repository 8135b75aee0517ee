// The landmark detector: section III of the paper (Fig. 2), on the landmark of
// docs/landmark.md, with what the paper lacked (small squares, any roll,
// several landmarks, look-alike rejection, sub-pixel corners, pose).
//
//   1. blur        optional (none in the fast front end; the paper's 9x9)
//   2. saturation  fast: one vectorised pass labelling each pixel blue, red or
//                  neither (HSV saturation over a per-colour threshold, a
//                  value floor, a hue window); paper: the HSV saturation image
//   3. edges       paper front end only: Canny on the saturation image
//   4. contours    fast: 4-connected regions of each colour (run-based
//                  union-find), with area moments, a saturation-weighted
//                  sub-pixel centroid and channel sums; paper: contours'
//                  bounding rectangles
//   5. colour      the paper's colour ratios (sum blue > a * sum red and
//                  sum blue > b * sum green; the same for red) into FIP and AP
//                  candidates
//   6-7. geometry  the FIP graph (distance (1) and size-ratio (2) constraints,
//                  measured in the frame of the squares' second moments so
//                  that they hold at any roll and foreshortening), its
//                  3-cycles, the AP where TR + BL - TL predicts it, or
//                  where the perspective the squares' sizes show puts it
//                  (which fixes TL at any roll), TL, TR, AP, BL clockwise; then
//                  verification against look-alikes (squares of the frame the
//                  centres make, a third of each side covered by squares, an
//                  even white sheet between them, a QR darker than the sheet
//                  in the middle, no coloured square there); landmarks whose
//                  fourth square merged into a same-coloured background
//                  completed from the other three; overlaps resolved by score
//   7c. second look (fast front end) windows around pairs of squares no
//                  landmark took, where a larger region lies, labelled again
//                  at raised saturation thresholds and put through 4-7
//   7d. faint look (fast front end) windows around red squares no landmark
//                  took, white-balanced by their own white, labelled again
//                  and put through 4-7; then windows around those shaped as
//                  a steeply seen AP, and around blue squares shaped as a
//                  steeply seen FIP, their colour taken again from the
//                  sharp brightness (the steep round); under a strong glare
//                  veil, windows with the tint the QR shows taken out (the
//                  veil round)
//   8. corners     the homography from the four square centres (a square
//                  the mask split into pieces measured as the pieces
//                  together; under a strong glare veil, one still in pieces
//                  where its ink is), each corrected for the perspective shift of a
//                  projected square's centroid, gives the pattern's outer
//                  corners (through the undistorted image when the camera
//                  distorts)
//   9. pose        cv::solvePnP (IPPE square) when intrinsics and side are set
//
// Each stage is stamped by name into Detection::stages: "blur", "saturation",
// "edges", "contours", "colour", "geometry", "second look", "faint look",
// "corners", "pose" (those that ran).
//
// Backends (DetectorParams::backend): stages 1-3, the per-pixel filters, run
// on the CPU or on the GPU through OpenGL ES shaders on a headless EGL
// context ("gles"); stages 4-9 are the same code for both. The GLES backend
// uploads each frame as a texture through a pixel buffer ("upload"), runs
// the fast front end's labelling (fragment shader), or the paper front
// end's blur, saturation, Sobel, non-maximum suppression and double
// threshold (OpenGL ES 3.1 compute shaders or 3.0 fragment shaders, the
// faster of the two as measured on the first frames), and reads back one
// byte per pixel ("readback": the label image, or the edge candidates whose
// hysteresis then runs on the CPU: "hysteresis"). The shaders do the CPU's
// integer arithmetic (OpenCV's fixed-point blur included): both backends
// give the same label images, edge maps and landmarks. Each GPU stage ends
// in glFinish, so stage times are the GPU's. A GLES Detector holds its own
// EGL context; use it from one thread at a time (not always the same one:
// each frame leaves the context current on no thread).
//
// A Detector keeps its buffers between frames: once warmed up, detect() with
// the default fast front end does not allocate for frames of the same size.
// What does: the pose (cv::solvePnP) and the sheet alignment before it
// (align_iterations), the paper front end (OpenCV's Canny and contours, a
// few hundred small buffers a frame), and AdaptiveDetector's correction
// (OpenCV's filter objects, about 50); README, "Allocation per frame".
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/camera.hpp"

namespace ld {

/// Every parameter of the pipeline, with the default that works across the
/// project's synthetic scenes (one set for all of them: no per-scene tuning).
struct DetectorParams {
  /// Front end. "fast" (default): one pass computing a saturation mask whose
  /// connected regions are the candidate squares; keeps 3-8 px squares whole.
  /// "paper": the paper's blur -> saturation -> Canny -> contours.
  std::string front_end = "fast";

  /// Where the per-pixel filters run. "cpu" (default); "gles": OpenGL ES
  /// shaders on a headless EGL context, a software renderer (Mesa's
  /// llvmpipe) included (the Detector's constructor throws
  /// std::runtime_error when none can be made); "auto": where an EGL
  /// context on a GPU can be made, the GPU and the CPU in turn on the first
  /// frames (after the GPU's own choice of shader path), in blocks of 4
  /// frames, 3 blocks each, each timed with its transfers after a warm-up
  /// frame, then for good the one with the smaller median (the landmarks
  /// are the same either way); else
  /// (no EGL, or only a software renderer, which is slower than the CPU
  /// backend) the CPU with one warning on stderr per process. A GPU that
  /// fails later, mid-run, is dropped for the CPU with one warning,
  /// whichever was asked for. The environment variable LD_EGL_FORCE_FAIL=1
  /// makes every EGL context fail (fallback tests),
  /// LD_EGL_PLATFORM=device|surfaceless|gbm restricts the EGL platform
  /// tried; LD_GLES_COMPUTE=0 or 1 keeps the paper front end off or on
  /// compute shaders instead of measuring which is faster;
  /// LD_GLES_AUTO_SOFTWARE=1 lets "auto" time a software renderer too, and
  /// LD_GLES_AUTO_FORCE=gles or cpu makes it keep that one whatever it
  /// measured (tests).
  std::string backend = "cpu";

  // 1. blur
  /// Gaussian kernel (odd, 1 to 31; 0 = no blur; -1 = the front end's own:
  /// none for "fast", the paper's 9 for "paper"). Blur costs time and erases
  /// small squares.
  int blur_kernel = -1;
  /// Gaussian sigma (0: from the kernel, or the paper's 3 with -1 under the
  /// paper front end). With -1 under "fast" (no blur) a sigma is refused.
  double blur_sigma = 0.0;

  // 2. saturation
  /// HSV saturation (0..1) the AP's (red) pixels exceed, and every pixel in
  /// the paper front end. Lower finds fainter, smaller and more distant
  /// squares, and more background; warm light makes white paper orange
  /// (S ~ 0.25 at 4000 K), which this must stay above.
  double saturation_threshold = 0.45;
  /// The same for the FIPs' (blue) pixels in the fast front end: printed blue
  /// is dark and only moderately saturated, while no usual light makes white
  /// paper blue, so blue can go lower and keep small FIPs whole.
  double saturation_threshold_blue = 0.25;
  /// Darker pixels (max channel, 0..255) are never saturated: in the dark,
  /// sensor noise alone makes saturated speckles by the thousand.
  int value_min = 40;

  // 3. edges (paper front end)
  double canny_low = 50.0;   ///< Canny hysteresis thresholds on the saturation image
  double canny_high = 150.0;

  // 4. contours
  int min_area_px = 3;           ///< smaller regions are noise
  int max_area_frac_1000 = 100;  ///< larger than this per-mille of the frame: not a square

  // 5. colour ratios (paper: a, b in [1.2, 1.6]). The fast front end takes
  // the sums over a region's own pixels, the paper front end over its
  // bounding rectangle. Higher rejects more faint or greyish regions.
  double color_ratio_a = 1.1;  ///< FIP: sum blue > a * sum red;  AP: sum red > a * sum blue
  double color_ratio_b = 1.1;  ///< FIP: sum blue > b * sum green; AP: sum red > b * sum green
  /// A candidate square must fill at least this fraction of the square its
  /// moments describe (1 for a solid square or parallelogram; rings, strokes,
  /// scattered noise fill less). Fast front end only.
  double min_fill = 0.5;

  // 6. FIP graph: distance (1), as centre distance in units of the pair's mean
  // square side, measured in the frame of the pair's second moments (so it
  // holds under any roll and foreshortening: 3 for neighbours, 4.24 across
  // the diagonal), and the size ratio (2) per image axis.
  double d_min = 1.6;  ///< Paper D_min
  double d_max = 11.0;  ///< Paper D_max (thresholded small squares come out much smaller than printed)
  double w_min = 0.33;  ///< Paper W_min: width ratio of two FIPs
  double w_max = 3.0;  ///< Paper W_max
  double h_min = 0.33;  ///< Paper H_min: height ratio
  double h_max = 3.0;  ///< Paper H_max

  // 7. AP gates: the AP lies where TR + BL - TL predicts.
  double ap_max_offset = 0.8;  ///< distance to the predicted position, in FIP sides
  double ap_size_min = 0.4;    ///< AP side / mean FIP side
  double ap_size_max = 2.5;

  // 7b. verification against look-alikes
  /// Allowed deviation of the layout from a square with right angles, in the
  /// frame of the squares' moments: the ratio of its longest to its shortest
  /// side may reach 1 + this, the cosine of its angle this (its sides must
  /// also lie in [d_min, d_max]). Lower rejects more look-alikes and more
  /// steep, blurred views.
  double shape_tolerance = 0.5;
  /// Each square against the one the centres predict (the frame of TL, TR,
  /// BL): its moments' axes in that frame may differ by this ratio at most
  /// (stripes and bars differ more)...
  double max_anisotropy = 2.2;
  /// ... and its side over the predicted side must lie in this range
  /// (thresholded faint squares come out small).
  double square_scale_min = 0.25;
  double square_scale_max = 1.6;
  /// The sheet between the squares and at the centre must be less saturated
  /// than this (0..1), but for one spot between the squares in a hue no ink
  /// or look-alike shows (40-180 degrees, yellow to cyan: a sticker) ...
  double sheet_max_saturation = 0.45;
  /// ... and at least this bright relative to the FIPs' brightest channel
  /// (printed blue is dark: about half the paper's brightness) ...
  double sheet_min_value = 1.0;
  /// ... and even: its darkest sample at least this fraction of its brightest.
  double sheet_uniformity = 0.6;
  /// The QR square's mean brightness over the sheet's: at most this. The
  /// black modules (grey when too small to resolve) tell a landmark from
  /// squares of other things that happen to lie like one.
  double qr_max_brightness = 0.85;
  /// ... or, on a sheet at the sensor's white clip (its samples' mean of the
  /// channels 235 or more), at least qr_dark_samples of the 25 points
  /// sampled over its middle grey (no more saturated than the sheet may be) and darker than
  /// qr_dark_sample times the sheet's brightness: a QR washed out by glare,
  /// whose white modules clip with the sheet, still shows its dark ones (a
  /// blank centre shows none, coloured squares are not grey).
  /// qr_dark_samples = 26: the mean alone.
  int qr_dark_samples = 4;
  double qr_dark_sample = 0.8;
  /// ... or, on a clipped sheet, the mean of the grey ones of those 25
  /// points (22 of them grey at least: no coloured thing's) at most this
  /// times the sheet's brightness. A clipped sheet is brighter than it
  /// reads: under glare 0.6 a QR whose modules are a pixel each reads
  /// 0.88-0.92 of a sheet read at 250-254, with no point dark enough for
  /// qr_dark_sample. At qr_max_brightness or below: no such rule.
  double qr_clipped_max_brightness = 0.93;
  /// ... or, in frames with a strong glare veil taken out
  /// (Detector::setGlareCorrected, as ld::AdaptiveDetector sets per frame) and on a
  /// sheet clipped all round (every one of its 12 samples 235 or more), at
  /// least 3 of those 25 points this many levels (0..255) or more under the
  /// brightest of them, 22 of them grey at least. Where a hot spot's peak
  /// lies on the QR it lifts the QR past the sheet's brightness, and what is
  /// left of its dark modules is points a few levels under its white ones;
  /// a blank middle at the clip is flat, as is a uniform grey. (Not in other
  /// frames: a bright wall clipped in two channels has as much noise in the
  /// third.) Under glare 0.75 the adaptive detector finds 90-92 of 100
  /// frames of the lighting sweep's point, against 72-73 without. 0: no
  /// such rule.
  double qr_washed_dip = 6;
  /// Along each side of the quadrilateral (TL-TR, TR-AP, AP-BL, BL-TL) the
  /// two squares cover 1/3 of the distance between their centres, in any
  /// view; the colour profile's cover must lie in [cover_min, cover_max].
  /// This is what tells a landmark from cards and objects whose squares are
  /// spaced otherwise, whatever the threshold made of the squares' sizes.
  double cover_min = 0.18;
  double cover_max = 0.5;
  /// Fast front end: also accept a landmark whose fourth square has no
  /// region of its own (merged with a same-coloured background through the
  /// sheet's thin margin, as at steep angles, or too faint for the mask) when
  /// its colour is there where the other three put it; it must pass the same
  /// verification, and ranks below landmarks found whole.
  bool complete_missing = true;
  /// Fast front end, the second look: windows per frame (0: none) around
  /// pairs of squares (up to 16 px) that no landmark took, where the first
  /// pass left a larger region, labelled again with both saturation
  /// thresholds raised by second_look_raise. A square joined to a
  /// same-coloured object behind the sheet through its thin margin (steep
  /// views, blur, JPEG's half-resolution colour) comes apart there. Found
  /// landmarks pass the same verification; the windows cover at most an
  /// eighth of the frame. More windows find more such landmarks in cluttered
  /// frames and cost more time (stage "second look").
  int second_looks = 8;
  double second_look_raise = 0.1;  ///< higher parts more merges and loses fainter squares (the veil round's windows too)
  /// Fast front end, the faint look: windows per frame (0: none) around red
  /// squares (up to 16 px long, of 6 pixels or more) that no landmark took, larger
  /// squares first, each white-balanced by its own white (the mean of its
  /// brightest fifth; a white with no colour cast is left as it is) and
  /// labelled again, blue from faint_look_blue. A steeply seen landmark's
  /// blue squares, a few pixels wide and mixed with the paper's colour, are
  /// violet or grey under warm light and blue again against the paper beside
  /// them; motion blur spreads a square's blue over the paper and pales it;
  /// printed red stays red. Found landmarks pass the same verification; the
  /// windows cover at most an eighth of the frame (stage "faint look").
  int faint_looks = 16;
  /// The faint look's blue saturation threshold (the first pass's,
  /// saturation_threshold_blue, where that is lower). Lower finds paler
  /// (more blurred, thinner) squares near a red one and more bluish
  /// background there.
  double faint_look_blue = 0.15;
  /// The faint look's steep round: windows per frame (0: none), after the
  /// faint look's own, around red squares (of 4 pixels or more, up to 10 px
  /// long) whose axes differ by 1.3:1 or more as thresholded (a steeply seen
  /// AP, printed 3:1 at 70 degrees, comes out rounded by the camera's or
  /// JPEG's half-resolution colour), with bright unsaturated paper
  /// beside them on two of four sides, as a steeply seen AP is, that no
  /// landmark took, reaching 6.5 of their longest axes, white-balanced, and
  /// with their colour taken
  /// again from the sharp brightness before labelling (at 60-70 degrees of
  /// yaw a 9 cm landmark's blue squares are 2-3 px wide; the half-resolution
  /// colour of cameras and JPEG spreads their blue over the paper beside
  /// them, to grey): over each 3 x 3 neighbourhood the colour per unit of
  /// darkness below the white is one ink's, and each pixel gets its own
  /// darkness times it. Only landmarks whose AP is the window's red square
  /// are taken. Another eighth of the frame at most, and no more than a
  /// 640x480 frame's eighth (the squares it looks around are small). Then
  /// as many windows again, with a budget of their own, around blue squares
  /// no landmark took shaped as a steeply seen FIP (axes 1.6:1 or more,
  /// paper beside them 1.1 times their blue or brighter), for landmarks
  /// whose AP joined a red or brown background: only landmarks with a FIP
  /// at the window's blue square are taken. In either round, where a
  /// window leaves out a landmark as not its square's and that landmark's
  /// square is one the round has yet to look around, that square gets a
  /// window of its own even inside the first (two steep landmarks side by
  /// side), budgets allowing.
  int steep_looks = 16;
  /// The faint look's veil round: windows per frame (0: none), only in
  /// frames that had a strong glare veil subtracted (setGlareCorrected),
  /// around the red squares no landmark took (as the faint look's), with
  /// the tint the veil's subtraction left taken out. A veil a few levels off
  /// in one channel, stretched back 4 times, tints the blue squares violet,
  /// cyan or brown; the QR beside them is printed black on white and tinted
  /// alike, so its colour is that tint: in the two directions from the red
  /// square where the QR would lie that have the finest texture (its
  /// modules), the mean colour of the unclipped pixels less its grey is
  /// subtracted from the window before labelling. Only landmarks whose AP
  /// is the window's red square are taken, so each red square gets its own
  /// window (one inside another's window is still looked around), those
  /// with the brightest paper beside them first (a sheet the hot spot
  /// clipped reads near white once the veil is out). A window whose look
  /// adds no landmark is looked at again at thresholds raised by
  /// second_look_raise. A quarter of the frame at most.
  int veil_looks = 8;
  /// FIP and AP candidates kept (largest first; over the cap, the FIPs with
  /// a red square of a like size within reach first), and 3-cycles of the
  /// FIP graph examined (those among the largest squares first): what bounds
  /// the time of frames cluttered with hundreds of small blue and red things.
  int max_candidates = 400;
  int max_cycles = 10000;

  // 8. corners
  /// Perspective correction of the square centres before the corners are
  /// extrapolated (iterations; 0 = take the centroids as the centres).
  int centre_iterations = 2;
  /// Sheet alignment for pose: after the centres, the whole sheet (its four
  /// squares and its white paper; the QR, unknown, left out) is fitted to
  /// the image's green channel (Gauss-Newton over a homography and the
  /// light's gain and offset) for up to this many steps, and the centres
  /// and corners are taken from it: it uses every edge of the sheet at once
  /// where the centres use each square's own pixels. On ld-synth's scenes
  /// at 2.5 m (15 cm, yaw within +-40 degrees) the corners' median error
  /// goes from 0.21 to 0.065 px and the pose's rotation error (90th
  /// percentile) from 29 to 1.0 degrees (README, "Sheet alignment for
  /// pose"); at 0.5 m the rotation's from 1.3 to 0.3 degrees. Costs about
  /// 0.3 ms per landmark of up to 120 px, more on larger ones (fitted to a
  /// finer model). Left out for sheets whose longest side is over 480 px,
  /// and not taken where it would move a centre by more than a quarter of
  /// its square's smaller side. With a distorting camera (setCamera) the
  /// crop is taken through the distortion. -1 (default): kAutoAlignIterations
  /// steps when the detector computes a pose (setCamera, with a calibration
  /// that fits the frame), none otherwise, so that detection alone keeps its
  /// speed and every pose gets the sharper corners; 0: never (paper() sets
  /// it; a parameters file with `front_end: paper` keeps the default); N
  /// (1-100): N steps, with or without a pose, for every landmark of up to
  /// 480 px. Worse than the centroids on clean but defocused frames (README,
  /// "Sheet alignment for pose").
  int align_iterations = -1;
  static constexpr int kAutoAlignIterations = 10;

  /// The paper's own settings: "paper" front end with its 9x9 blur.
  static DetectorParams paper();

  /// Reads a YAML/XML file (cv::FileStorage) whose keys are the field names
  /// above; absent keys keep their defaults. Throws std::runtime_error naming
  /// the file and the bad key.
  static DetectorParams load(const std::string& path);
  void save(const std::string& path) const;
  /// Throws std::invalid_argument naming the first inconsistent field.
  void validate() const;
};

/// The sheet's object frame (origin at the sheet's centre, x right, y down on
/// the sheet, z into the wall) in the camera frame (x right, y down, z
/// forward): a frontal, upright sheet has rvec = 0.
struct Pose {
  cv::Vec3d t;     ///< sheet centre in the camera frame, metres
  cv::Vec3d rvec;  ///< Rodrigues vector of the sheet frame
  double distance = 0;  ///< |t|
};

/// One detection, in LANDMARK.md's terms.
struct Landmark {
  cv::Point2f fip_tl, fip_tr, fip_bl, ap;
  std::array<cv::Point2f, 4> corners;  ///< TL, TR, BR, BL outer corners of the pattern
  float score = 0;                     ///< 0..1, higher fits the layout better
  std::optional<Pose> pose;
  std::optional<std::string> payload;  ///< filled by the QR reader, not the detector
};

/// Whether every position of a landmark is a finite number.
inline bool finiteLandmark(const Landmark& lm) {
  const auto finite = [](const cv::Point2f& p) { return std::isfinite(p.x) && std::isfinite(p.y); };
  if (!finite(lm.fip_tl) || !finite(lm.fip_tr) || !finite(lm.fip_bl) || !finite(lm.ap)) return false;
  for (const auto& c : lm.corners)
    if (!finite(c)) return false;
  return true;
}

struct StageTime {
  const char* name;
  double ms;
};

struct Detection {
  std::vector<Landmark> landmarks;
  std::vector<StageTime> stages;  ///< in pipeline order
  double total_ms = 0;
  /// Why the landmarks carry no pose although a camera is set (its
  /// calibration does not fit the frame: CameraModel::misfit); "" otherwise.
  std::string pose_error;
  double stageMs(const std::string& name) const;  ///< 0 when the stage did not run
};

/// Why a frame gave the landmarks it gave: what the first pass kept at each
/// stage and, for each group of squares shaped as a landmark's that gave
/// none, the check that refused it (Detector::detect with an Explanation;
/// `ld-detect --explain`); then each look after it (the second look, the
/// faint look, the steep and veil rounds): the windows it looked at, what
/// each found and refused, and the squares it did not look around, and why.
/// The first pass's counts are its own: the completion of a missing square
/// and the looks add squares of their own.
struct Explanation {
  int blue_regions = 0, red_regions = 0;        ///< labelled regions within min_area_px and max_area_frac_1000
  int blue_sparse = 0, red_sparse = 0;          ///< of them, filling less than min_fill
  int blue_off_colour = 0, red_off_colour = 0;  ///< of the rest, failing the colour ratios a and b
  int fips = 0, aps = 0;                        ///< FIP and AP candidates
  int fips_over_cap = 0, aps_over_cap = 0;      ///< candidates beyond max_candidates, left out
  int fip_pairs = 0;                            ///< FIP graph edges (distance and size-ratio constraints)
  int triangles = 0;                            ///< the graph's 3-cycles
  int right_isosceles = 0;                      ///< of them, shaped as a landmark's three FIPs
  /// Three FIPs shaped as a landmark's that made none (not part of a found
  /// landmark), the AP tried with them, and the check that refused them.
  struct Refused {
    std::array<cv::Point2f, 3> fips;  ///< TL, TR, BL (with no AP: the right angle's, then clockwise)
    std::optional<cv::Point2f> ap;    ///< empty: no red square where the AP belongs
    std::string check;                ///< "no AP", or the name of verification's check
  };
  /// Those that came furthest through verification (its later checks
  /// first), at most kMaxRefused.
  std::vector<Refused> refused;
  static constexpr size_t kMaxRefused = 10;
  std::vector<std::pair<std::string, int>> refusals;  ///< how many groups each check refused, in check order

  /// One look after the first pass: a window labelled again (at raised
  /// thresholds, white-balanced, or with a glare veil's tint taken out) and
  /// run through colour, geometry and verification.
  struct Look {
    std::string round;        ///< "second look", "faint look", "steep round", "steep round (around blue squares)" or "veil round"
    std::string how;          ///< how the window was labelled: "raised by second_look_raise", "as it is (no cast)",
                              ///< "white-balanced", "white-balanced, colour from brightness", "tint B -3 G +5 R -2
                              ///< taken out" (and ", raised by second_look_raise" after it)
    cv::Rect window;          ///< in the frame
    cv::Point2f around;       ///< the square it looked around (the second look: the pair's midpoint)
    int fips = 0, aps = 0;    ///< FIP and AP candidates in the window
    int right_isosceles = 0;  ///< groups of three FIPs shaped as a landmark's
    int landmarks = 0;        ///< landmarks it found that were not found before it
    int dropped = 0;          ///< of them, not the round's own square's (the steep and veil rounds keep only that one)
    std::vector<std::pair<std::string, int>> refusals;  ///< as the first pass's, for this window
    std::vector<Refused> refused;  ///< those that came furthest, at most kMaxLookRefused
  };
  /// A round of looks: the squares (the second look: pairs of squares) it
  /// could look around, the windows it looked at, and why the others were
  /// not looked at, with how many.
  struct Round {
    std::string round;
    int anchors = 0, windows = 0;
    std::vector<std::pair<std::string, int>> skipped;
  };
  std::vector<Round> rounds;  ///< in the order they ran
  std::vector<Look> looks;    ///< in the order run, at most kMaxLooks
  int looks_more = 0;         ///< looks run beyond kMaxLooks
  static constexpr size_t kMaxLooks = 48, kMaxLookRefused = 3;
  double ms = 0;  ///< what explaining took, the looks' own run included (not counted in the detection's times)
};

/// An explanation as lines for people (no trailing newline), each count and
/// check with the parameters that decide it, each line after `indent`.
std::string describe(const Explanation& explanation, const DetectorParams& params, const std::string& indent = "");

/// Thrown by the Detector when backend "gles" is asked for and no GPU context
/// can be made (no EGL display, a driver not up yet): the environment, not
/// the parameters ("auto" falls back to the CPU instead).
struct BackendUnavailable : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class Detector {
 public:
  /// Throws std::invalid_argument on bad parameters, std::runtime_error
  /// when backend "gles" was asked for and no EGL context can be made.
  explicit Detector(const DetectorParams& params = {});
  ~Detector();
  /// Movable, not copyable; a detector moved from may only be assigned to
  /// or destroyed (its state went with the move).
  Detector(Detector&&) noexcept;
  Detector& operator=(Detector&&) noexcept;

  /// Whether the frames given from now on had a strong glare veil
  /// subtracted (ld::AdaptiveDetector says so per frame: where its glare
  /// pass stretched a channel back by AdaptiveParams::wide_hue_min_stretch
  /// or more). The stretch multiplies what is left, 4 times under a veil of
  /// about 190, so a veil a few levels off in one channel tints the blue
  /// squares towards cyan or violet: the faint look then takes blue at any
  /// hue where blue is the largest channel and above red, not only 210-270
  /// degrees; the veil round looks (veil_looks); and verification counts a
  /// QR the hot spot washed out past the sheet by its modules' dips
  /// (qr_washed_dip). Default false.
  void setGlareCorrected(bool corrected);

  /// Enables pose: intrinsics of the camera and the printed sheet side S in
  /// metres. Frames of another size than the calibration use the scaled
  /// camera when they have its aspect ratio (CameraModel::fits); frames of
  /// another aspect ratio get no pose, and Detection::pose_error says why.
  void setCamera(const CameraModel& camera, double side_m);

  /// Detects landmarks in an 8-bit BGR or BGRA (or gray: no landmarks)
  /// image; an empty one has none. Throws std::invalid_argument, naming the
  /// type, for any other (16-bit, float, two channels, 3 or more
  /// dimensions). The returned reference is to the detector's own result:
  /// valid until the next detect() on this detector, and while the detector
  /// lives (`const auto& lms = ld::Detector().detect(img).landmarks;`
  /// dangles; two results kept at once need a copy: `ld::Detection d =
  /// det.detect(img);`).
  const Detection& detect(const cv::Mat& bgr);
  /// detect(), then the first pass again, counted and with each refused
  /// group's check, into `why`, and the looks as a run of their own records
  /// them (the detection runs twice: with backend "auto" still choosing,
  /// both count as its trials): slower, for finding out why a landmark is
  /// missed, not for the hot path. The detection's times are the untraced
  /// run's.
  const Detection& detect(const cv::Mat& bgr, Explanation& why);
  /// Adds a stage that ran before detect() on the same frame (the adaptive
  /// lighting's correction) to the last detection's times, first in their
  /// order and in total_ms.
  void addStageBefore(const char* name, double ms);

  const DetectorParams& params() const;

  /// The backend whose filters ran the last frame: "cpu" or "gles" (with
  /// "auto", both in turn on the first frames, then what it chose;
  /// "cpu" after a GPU failure; a frame without colour runs no filters and
  /// leaves it as it was).
  const char* backend() const;
  /// True while backend "auto" is still timing the GPU against the CPU (its
  /// first frames, about 24 after the GPU's own shader-path choice):
  /// backend() may change until then, and not after.
  bool choosingBackend() const;
  /// One line on it: the GPU, its driver and EGL platform; for the CPU after
  /// a fallback, why the GPU is not used.
  std::string backendInfo() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Evaluation helper (tests, benchmarks, report tools): whether a detection
/// is the landmark whose true square centres are `truth` (TL, TR, BL, AP):
/// each of its four centres within max(min_tol_px, tol_frac * FIP side) of
/// the truth, the FIP side taken as |TR - TL| / 3. Wrongly ordered
/// detections do not match.
bool matchesTruth(const Landmark& detection, const std::array<cv::Point2d, 4>& truth,
                  double min_tol_px = 2.0, double tol_frac = 0.3);

/// The pose of a printed square of side `side_m` (the pattern square's
/// outer corners, TL, TR, BR, BL, as Landmark::corners, ArUco and AprilTag
/// give theirs) seen by `camera`: what Detector computes for its landmarks
/// (cv::solvePnP, SOLVEPNP_IPPE_SQUARE), for corners found otherwise (a
/// marker's, in an evaluation). Empty when it does not solve.
std::optional<Pose> poseFromCorners(const std::array<cv::Point2f, 4>& corners, const CameraModel& camera,
                                    double side_m);

}  // namespace ld
