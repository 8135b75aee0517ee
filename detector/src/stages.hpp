// The detector's stages as free functions, so tests can drive each one alone.
// Not a public interface: the names follow the paper's Fig. 2 and
// include/ld/detector.hpp's stage list.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/detector.hpp"

namespace ld::detail {

/// Label values of the colour mask.
enum Colour : uint8_t { kNone = 0, kBlue = 1, kRed = 2 };

/// One candidate square: a connected region of one colour (fast front end)
/// or a contour's bounding rectangle (paper front end).
struct Region {
  uint8_t colour = kNone;            ///< kBlue or kRed: the dominant hue of the mask
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  ///< bounding box, inclusive
  int area = 0;                      ///< pixels
  double cx = 0, cy = 0;             ///< centre: saturation-weighted centroid (or bbox centre)
  double sxx = 0, sxy = 0, syy = 0;  ///< second central moments of the area (px^2)
  double sum_b = 0, sum_g = 0, sum_r = 0;  ///< channel sums the colour ratio is taken on
  double n_sum = 0;                  ///< pixels those sums are over
  int pass = 0;                      ///< the labelling it came from: 0 the first pass, then each look's
  int width() const { return x1 - x0 + 1; }
  int height() const { return y1 - y0 + 1; }
  /// Side of the square this region would be (from the moments: sqrt(12) *
  /// det^(1/4)), pixels.
  double side() const;
};

// ---------------------------------------------------------------- front ends

/// Thresholds of the fast front end's per-pixel rule.
struct MaskThresholds {
  double blue = 0.25;  ///< saturation a blue pixel exceeds
  double red = 0.45;   ///< saturation a red pixel exceeds
  int value_min = 40; ///< darker pixels are never saturated
  /// Blue at any hue where blue is the largest channel and above red
  /// (180..300 degrees, 300 left out), not only 210..270. CPU only: the
  /// GLES label shader has the narrow window; only the faint look (on the
  /// CPU) sets it, under a strong glare veil (Detector::setGlareCorrected).
  bool wide_blue = false;
};

/// 2. saturation (fast front end): one pass over an 8-bit BGR image writing a
/// CV_8U label image: kBlue where blue is the pixel's largest channel and it
/// is saturated ((max - min) > threshold * max, max >= value_min), kRed where
/// red is and its hue is below 30 degrees (r - g > g - b: red and
/// red-orange, not yellow), kNone elsewhere. Blue must lie within 210..270
/// degrees (not cyan or violet; with t.wide_blue, anywhere blue is largest
/// and above red).
void saturationMask(const cv::Mat& bgr, const MaskThresholds& t, cv::Mat& labels);

/// `out` = `bgr` with channel c times gain[c], rounded and saturated to 8
/// bits: cv::multiply(bgr, gain, out) value for value, without the block
/// buffer cv::multiply allocates at each call. `out` must have bgr's size
/// and type already (a view of a buffer kept between frames).
void scaleChannels(const cv::Mat& bgr, const cv::Vec3d& gain, cv::Mat& out);

/// `out` = `bgr` less `tint` per channel, saturated to 8 bits: cv::subtract(
/// bgr, tint, out) value for value (which rounds the tint to integers first),
/// without its allocation; but pixels whose largest channel is `keep_from`
/// or more (256: none) as they are in `bgr`. `out` as for scaleChannels,
/// and not `bgr` itself when keep_from is 255 or less.
void subtractChannels(const cv::Mat& bgr, const cv::Scalar& tint, cv::Mat& out, int keep_from = 256);

/// Colour from brightness: `bgr` (8-bit, white-balanced so that its white
/// of level `white` is grey) with each pixel's colour taken again from the
/// sharp brightness. Cameras and JPEG carry colour at half resolution or
/// less, so a square two or three pixels wide (a steeply seen landmark's)
/// keeps its darkness but spreads its colour over the paper beside it, to
/// grey. Over each 3 x 3 neighbourhood the colour difference from grey
/// (b - y, r - y) per unit of darkness (white - y) is one ink's, and each
/// pixel gets its own darkness times it: the neighbourhood's colour moves
/// onto its dark pixels and off the paper. Uniform areas keep their colour
/// (pale ones, under a twentieth of white's darkness, lose some); a neutral
/// ink (toner) stays neutral. `out` gets bgr's size and type; `scratch`
/// keeps the sums between calls (no allocation once large enough).
void colourFromBrightness(const cv::Mat& bgr, double white, cv::Mat& out, std::vector<float>& scratch);

/// Scratch memory of the run-based labelling, kept between frames.
struct RunScratch {
  struct Run {
    int y, x0, x1;
    uint8_t colour;
    int parent;
  };
  struct Acc {  // area moments of a region
    int64_t n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    uint8_t colour = 0;
  };
  struct Sums {  // pixel sums of a kept region
    int64_t w = 0, wx = 0, wy = 0, b = 0, g = 0, r = 0;
  };
  std::vector<Run> runs;
  std::vector<int> region_of;  // run -> region
  std::vector<Acc> acc;        // per region
  std::vector<int> keep;       // region -> index in the output, or -1
  std::vector<Sums> sums;      // per output region
};

/// 4. contours (fast front end): 4-connected regions of each colour of the
/// label image (run-based union-find). Regions outside [min_area, max_area]
/// or filling less than min_fill of their moments' square are dropped; the
/// rest get bbox, area moments, a centroid weighted by saturation above the
/// threshold (sub-pixel, smooth at the edges) and the channel sums of their
/// pixels.
void extractRegions(const cv::Mat& labels, const cv::Mat& bgr, const MaskThresholds& t, int min_area,
                    int max_area, double min_fill, RunScratch& scratch, std::vector<Region>& out);

/// HSV saturation of an 8-bit BGR image (0..255), as the paper's front end uses.
void saturationImage(const cv::Mat& bgr, cv::Mat& sat);

/// 4. contours (paper front end): the bounding rectangles of the contours of
/// an edge image, with bbox centres, moments of the rectangle, and channel
/// sums over the rectangle in `bgr` (the paper's rule). The colour field is
/// the largest of the sums.
void contourRegions(const cv::Mat& edges, const cv::Mat& bgr, int min_area, int max_area,
                    std::vector<std::vector<cv::Point>>& contours, std::vector<Region>& out);

// ---------------------------------------------------------------- colour

/// 5. colour: FIP when sum blue > a * sum red and sum blue > b * sum green, AP
/// when the same holds for red.
bool isFip(const Region& r, double a, double b);
/// Area over the area of the square the moments describe (side()^2).
double fill(const Region& r);
bool isAp(const Region& r, double a, double b);

// ---------------------------------------------------------------- geometry

/// The distance of two regions' centres in units of their mean square side,
/// measured in the frame their mean moments define (affine invariant: 3 for
/// two FIPs of one landmark side by side, 4.24 across the diagonal, whatever
/// the view), or a negative value when the moments are degenerate.
double normalisedDistance(const Region& a, const Region& b);

/// 6. graph: the paper's constraints (1) and (2): normalised centre distance
/// in [d_min, d_max], width and height ratios (from the moments' per-axis
/// spread) in [w_min, w_max] and [h_min, h_max].
bool fipEdge(const Region& a, const Region& b, const DetectorParams& p);

/// The 3-cycles of a graph given by its adjacency matrix (n x n, row major,
/// nonzero = edge), as index triples i < j < k in lexicographic order; at
/// most max_out of them (the first).
void threeCycles(const std::vector<uint8_t>& adjacency, int n, std::vector<std::array<int, 3>>& out,
                 size_t max_out = SIZE_MAX);

/// Regions sorted by x, for the squares near a point.
struct RegionIndex {
  std::vector<int> order;
  std::vector<double> xs;
  void build(const std::vector<Region>& regions);
  /// f(k) for every region k whose centre lies within r of (x, y) in x and in y.
  template <typename F>
  void near(const std::vector<Region>& regions, double x, double y, double r, F&& f) const {
    auto it = std::lower_bound(xs.begin(), xs.end(), x - r);
    for (; it != xs.end() && *it <= x + r; ++it) {
      const int k = order[static_cast<size_t>(it - xs.begin())];
      if (std::abs(regions[k].cy - y) <= r) f(k);
    }
  }
};

/// The longest axis of a region's moments as a square's side: sqrt(12
/// lambda_max), pixels.
double maxAxis(const Region& r);
/// The shortest axis the same way: sqrt(12 lambda_min).
double minAxis(const Region& r);
/// Whether `p` lies within `axes` of the region's longest axis (and
/// `min_px` at least) of its centre: the defaults, within half its side,
/// say a point is at the square (a landmark's centre there, the same
/// square found again).
inline bool nearCentre(const Region& r, const cv::Point2d& p, double axes = 0.5, double min_px = 2.0) {
  return std::hypot(r.cx - p.x, r.cy - p.y) < std::max(min_px, axes * maxAxis(r));
}

/// Whether three FIPs make a right isosceles triangle in the frame of their
/// moments (two sides alike, the third sqrt(2) longer, within `tol` as a
/// ratio), and which of them is the corner (opposite the longest side).
bool rightIsosceles(const std::array<int, 3>& cycle, const std::vector<Region>& fips, double tol,
                    int* corner = nullptr);

/// A landmark candidate: indices into the FIP and AP lists.
struct Candidate {
  int tl = -1, tr = -1, bl = -1, ap = -1;
  double error = 0;  ///< combined geometric error (lower is better)
  float score = 0;
  bool completed = false;  ///< one square found by completeSquare
};

/// 7. AP choice and ordering for a 3-cycle: for each choice of corner FIP the
/// AP is predicted at TR + BL - TL, and where the perspective that the three
/// squares' sizes show puts it (a homography's denominator w is affine on
/// the sheet; a square's side goes as w^(-3/2)); every AP candidate within
/// ap_max_offset FIP sides of either prediction, of a compatible size, is a
/// choice, nearest first, at most max_out. TR and BL are ordered so TL, TR,
/// AP, BL run clockwise in the image. Where red things lie near the
/// landmark's AP the nearest need not be the AP: verification decides
/// between the choices.
void apChoices(const std::array<int, 3>& cycle, const std::vector<Region>& fips, const std::vector<Region>& aps,
               const DetectorParams& p, std::vector<Candidate>& out, const RegionIndex* ap_index = nullptr,
               size_t max_out = 4);
/// The nearest of apChoices; false when no AP fits.
bool chooseAp(const std::array<int, 3>& cycle, const std::vector<Region>& fips,
              const std::vector<Region>& aps, const DetectorParams& p, Candidate& out,
              const RegionIndex* ap_index = nullptr);

/// The checks a group of three FIPs meets, in the order it meets them (a
/// group refused by a later one came further): an AP where the layout puts
/// one (apChoices), then verify's.
enum class Check : uint8_t {
  kNoAp,
  kNotConvex,
  kDegenerateMoments,
  kSideLength,
  kSideRatio,
  kAngle,
  kDegenerateSquare,
  kSquareAnisotropic,
  kSquareScale,
  kSquareSize,
  kOutsideImage,
  kSheetSaturated,
  kSheetDark,
  kSheetUneven,
  kNoQr,
  kCentreSaturated,
  kCentreColoured,
  kCover,
  kSquareAtCentre,
  kOtherSquares,
  kCount  ///< not a check: how many there are
};
constexpr int kNumChecks = static_cast<int>(Check::kCount);
/// The check's name as explanations give it ("no AP", "cover", ...).
const char* checkName(Check check);

/// Verification against look-alikes: convex quadrilateral, consistent sizes,
/// a square layout in the frame of the squares' moments, white unsaturated
/// sheet between the squares and at the centre, no coloured region at the
/// centre. Sets the candidate's score. `why`, when given, names the failed check.
/// `glare_corrected`: the frame had a strong glare veil subtracted
/// (Detector::setGlareCorrected), where a QR washed out to the sheet's
/// brightness may count by its texture (DetectorParams::qr_washed_dip).
bool verify(Candidate& c, const std::vector<Region>& fips, const std::vector<Region>& aps,
            const cv::Mat& bgr, const DetectorParams& p, Check* why = nullptr, bool glare_corrected = false);

/// 7 and verification for one 3-cycle: of its AP choices (apChoices, into
/// `choices`), the one whose landmark verifies with the least error, in
/// `out`. False when none verifies.
bool bestVerifiedChoice(const std::array<int, 3>& cycle, const std::vector<Region>& fips,
                        const std::vector<Region>& aps, const cv::Mat& bgr, const DetectorParams& p,
                        std::vector<Candidate>& choices, Candidate& out, const RegionIndex* ap_index = nullptr,
                        bool glare_corrected = false);

/// The fraction of the segment between two square centres a and b that the
/// two squares cover, from the colour-excess profile along it (each end's
/// hue: blue b - max(g, r), red r - max(g, b)) cut at half way between each
/// end's peak and the white gap between them. 1/3 between any two squares of
/// a landmark (a square's half extent along any line through its centre over
/// the distance of two centres), whatever the view, blur or threshold; 2/3
/// between a corner square and one in the middle of a card. Negative when
/// the profile shows no gap. With CoverProfile::kAbsorbed the profile is
/// the light each end's ink absorbs instead (blue: -max(g, r), red:
/// -max(g, b)): the brightness's edges, sharp where the camera smeared the
/// colour.
enum class CoverProfile { kExcess, kAbsorbed };
/// Verification holds the absorbed light's cover of every side within
/// these (within cover_min and cover_max too): a third within about a
/// quarter of itself (0.27 to 0.42 on landmarks whose colour's profile
/// failed, in the yaw and 2000 K sweeps).
constexpr double kAbsorbedCoverMin = 0.25, kAbsorbedCoverMax = 0.42;
double coverFraction(const cv::Mat& bgr, cv::Point2d a, uint8_t colour_a, cv::Point2d b, uint8_t colour_b,
                     CoverProfile profile = CoverProfile::kExcess);

/// A square of `colour` around `guess` where the layout predicts one but the
/// mask has no region of its own for it (it merged with a same-coloured
/// background through the sheet's thin margin, or it is too faint): the centroid and moments of
/// the colour excess above half its peak within 1.5 half-sides of the guess
/// in the layout's frame (e1 = TR - TL, e2 = BL - TL). False when the peak
/// excess is below `min_peak` (no such square there).
bool completeSquare(const cv::Mat& bgr, cv::Point2d guess, uint8_t colour, cv::Point2d e1, cv::Point2d e2,
                    double min_peak, Region& out);

/// Colour excess of a region's own colour, per pixel: its mean colour's
/// (blue: b - max(g, r), red: r - max(g, b)).
double meanExcess(const Region& r);
/// ... over its mean colour's brightness (the colour's strength whatever the
/// light's level).
double meanChroma(const Region& r);

/// How a square's measured moments compare with those the layout predicts
/// from the centres (the affine frame of TL, TR, BL: a square of side 2u has
/// the moments (e1 e1' + e2 e2') / 108 for e1 = TR - TL, e2 = BL - TL):
/// `scale` the side ratio measured / predicted, `anisotropy` the ratio of
/// the axes of the measured moments in the predicted square's frame (1 for
/// a square; large for a stripe or a bar). False when degenerate.
bool squareConsistency(const Region& r, cv::Point2d e1, cv::Point2d e2, double& scale, double& anisotropy);

/// The largest anisotropy `squareConsistency` may report for a region of
/// `area` pixels: max_anisotropy, loosened for tiny regions whose moments
/// are only roughly a square's (by 8 / area).
inline double anisotropyLimit(double max_anisotropy, int area) {
  return max_anisotropy + 8.0 / std::max(1, area);
}

/// Candidates sharing a region: the best score wins, greedily.
void resolveOverlaps(std::vector<Candidate>& candidates, int n_fips, int n_aps,
                     std::vector<uint8_t>& used_scratch);

// ---------------------------------------------------------------- corners, pose

/// 3x3 homography mapping src[i] to dst[i] (4 points, exact). False when degenerate.
bool homography4(const std::array<cv::Point2d, 4>& src, const std::array<cv::Point2d, 4>& dst,
                 cv::Matx33d& H);
cv::Point2d applyH(const cv::Matx33d& H, const cv::Point2d& p);

/// 8. corners: the homography from the sheet (units u) to the image fitted to
/// the four measured square centres (TL, TR, BL, AP), each corrected for the
/// perspective shift of a projected square's centroid (`iterations` times),
/// then the pattern corners TL, TR, BR, BL. Returns false when degenerate.
bool fitCorners(const std::array<cv::Point2d, 4>& centres, int iterations,
                std::array<cv::Point2d, 4>& corrected_centres, std::array<cv::Point2d, 4>& corners,
                cv::Matx33d* H_out = nullptr);

/// 8. corners, sheet alignment (DetectorParams::align_iterations): the
/// sheet as the image's green channel shows it, `per_unit` px per unit u:
/// white paper (255) and the four squares (0; both inks absorb green),
/// smoothed a little (a 3x3 Gaussian, as the view is), its gradients, and
/// what counts (all but the QR square, whose modules are unknown).
struct SheetModel {
  int per_unit = 0;
  cv::Mat value, dx, dy;  ///< CV_32F
  cv::Mat valid;          ///< CV_8U, 255 where the sheet is known
};
void sheetModel(int per_unit, SheetModel& model);

/// Buffers of alignSheet() kept between calls.
struct AlignScratch {
  cv::Mat green, view, undistorted;
  std::vector<cv::Point3f> rays;
  std::vector<cv::Point2f> at;
};

/// Aligns the sheet `far_model` to the green channel of `bgr` around the
/// landmark whose centres (TL, TR, BL, AP) and corners (TL, TR, BR, BL) are
/// given: Gauss-Newton over a homography and the light's gain and offset,
/// from the corners' homography, up to `iterations` steps. Sheets over
/// kAlignMaxSide px (120) take `near_model` instead (a finer one, on 60-120
/// of their pixels each way), up to kAlignNearMaxSide px (480). With a
/// `distorting` camera the centres and corners are in its undistorted
/// image's pixels, and the crop is taken through its distortion (pixels it
/// takes out of the frame are left out of the fit). Replaces the centres
/// and corners with the alignment's and returns true, unless the sheet is
/// over kAlignMaxSide px without a near model or over kAlignNearMaxSide px,
/// the fit is degenerate, or it moves a centre by more than a quarter of
/// its square's smaller projected side (then they stay as they are: false).
bool alignSheet(const cv::Mat& bgr, const CameraModel* distorting, const SheetModel& far_model, int iterations,
                std::array<cv::Point2d, 4>& centres, std::array<cv::Point2d, 4>& corners, AlignScratch& scratch,
                const SheetModel* near_model = nullptr);

/// 8. corners: the centres of a landmark's squares (TL, TR, BL, AP: the
/// regions `squares`, FIPs of `fips` and the AP of `aps`) with the pieces
/// of a square the mask split (a lamp's hot spot or JPEG's colour across
/// it: a row of pixels under the threshold) joined to it: regions of its
/// colour from the same labelling that no landmark takes (`used`: the
/// FIPs', then the APs' after fips.size()), touching the square's box, of a tenth of the printed
/// square or more, whose centres lie within 0.75 of its side of its centre
/// (in the frame of the four centres) and which together with it, by their
/// moments, are no larger than the printed square and a pixel's blur; each
/// centre the joined pieces' area-weighted centroid. In a frame whose
/// squares a glare veil's stretch tinted (`tinted`), a square (joined, or
/// the completion's) still covering under kPieceWhole of the printed one is
/// measured on `bgr` instead: where a square of the printed size is
/// darkest in its pixels' weakest channel against a ring of the margin's
/// paper around it, within 0.3 units of the piece (`scratch`: its pixels,
/// kept between calls).
void joinPieces(const cv::Mat& bgr, const std::array<const Region*, 4>& squares, const std::vector<Region>& fips,
                const std::vector<Region>& aps, const std::vector<uint8_t>& used, bool tinted,
                std::vector<cv::Point3f>& scratch, std::array<cv::Point2d, 4>& centres);

/// Pixel positions of a distorting camera to those of its ideal pinhole
/// (same K), and back.
void undistortPixels(const CameraModel& camera, std::array<cv::Point2d, 4>& pts);
void distortPixels(const CameraModel& camera, std::array<cv::Point2d, 4>& pts);

/// 9. pose: cv::solvePnP (IPPE square) on the pattern corners; the result is
/// in the sheet's object frame of LANDMARK.md (x right, y down on the sheet,
/// origin at its centre).
bool estimatePose(const std::array<cv::Point2f, 4>& corners, const CameraModel& camera,
                  double side_m, Pose& out);

}  // namespace ld::detail
