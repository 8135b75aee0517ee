// Reads the QR code of a detected landmark: the homography from the
// landmark's corners to the sheet (docs/landmark.md), an upright view of the
// QR square only, at a resolution chosen from its projected size, then zbar
// (QR only), retried with a few variations before giving up.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace ld {

struct QrReaderParams {
  /// Side of the upright QR view in pixels is about this many times the QR
  /// square's projected side, clamped to [min_side_px, max_side_px]: more
  /// resolution for zbar than the camera gave, without the cost of huge views.
  double upsample = 2.0;
  int min_side_px = 160;
  int max_side_px = 480;
  /// Margin around the QR square in the view, in units u of the sheet: room
  /// for corner error without reaching the coloured squares.
  double margin_u = 0.2;
  /// Try sharpening, Otsu and adaptive binarization and other scales when the
  /// plain view does not decode.
  bool retry_variations = true;
  /// Last, fit the code to the pixels (qr_pixel_model.hpp) where a module is
  /// under 2 px and the QR square at most 72 px: the farthest reads, at 7-13
  /// ms a try for a 37-module code. ld-qr-reader's
  /// stacks of frames decode without it (their averaged view is upsampled
  /// twice, and the fit there read 2 stacks in 26 at 1.05 m for 17 ms more).
  bool fit_pixels = true;
};

/// What one decode attempt found.
struct QrResult {
  std::string payload;
  /// Which variation decoded it: 0 the plain view; 1 Otsu, 2 sharpened, 3
  /// adaptive threshold, 4 and 5 other scales of the view; 6 the modules read
  /// one by one and equalised against the blur, 7 the same thresholded as
  /// read or after a fixed sharpening, 8 the modules fitted to the pixels
  /// through a model of the camera's blur (QrReaderParams::fit_pixels), 9
  /// modules given (decodeModules: QrStack's vote over frames' fits).
  int attempt = 0;
};

class QrReader {
 public:
  /// Throws std::invalid_argument naming a parameter out of its range
  /// (upsample 0.25-16, min_side_px and max_side_px 16-4096, min_side_px not
  /// over max_side_px,
  /// margin_u 0-1).
  explicit QrReader(const QrReaderParams& params = {});
  ~QrReader();
  QrReader(QrReader&&) noexcept;
  QrReader& operator=(QrReader&&) noexcept;

  /// Decodes the QR of the landmark whose pattern corners (TL, TR, BR, BL,
  /// LANDMARK.md's `corners`) are given, in an 8-bit BGR, BGRA or gray
  /// image. nullopt when no variation decodes (too small, blurred, damaged,
  /// missing) or there is nothing to read (an empty image, corners not
  /// finite). Throws std::invalid_argument, naming the type, for an image
  /// of another type (16-bit, float).
  std::optional<QrResult> decode(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners);

  /// The upright gray view of the last decode() call (for debugging, ld-view);
  /// empty when that call made none (nothing to read).
  const cv::Mat& lastView() const;

  /// The modules the pixel model (QrReaderParams::fit_pixels) fitted in the
  /// last decode() call, n x n row-major, 1 dark, with `n` the modules
  /// across; nullptr where it did not run (a nearer code, one read another
  /// way first) or fitted none. Valid until the next call.
  const std::vector<uint8_t>* lastFittedModules(int& n) const;

  /// Decodes an n-module code given module by module (n x n row-major, 1
  /// dark; the function patterns drawn as every code has them): attempt 9.
  std::optional<QrResult> decodeModules(int n, const std::vector<uint8_t>& modules);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A read code as one sharp frame showed it, module by module: whether the
/// landmark under a track still shows that code in a later frame, for the
/// cost of sampling its modules (tens of microseconds), not a decode. The
/// tracker can give a read track's id to another landmark within its gate
/// (a scene cut, a landmark half the image wide leaving as its neighbour
/// comes in), and the payload read under the id went with it until the next
/// re-read. Codes of payloads that differ in one character still differ in
/// 8-29 % of their modules (the error correction's codewords and the mask
/// change), so sharp frames tell them apart; a blurred or washed-out frame
/// says nothing. Each module's shade is taken against the darkest and the
/// lightest modules within two of it (smoothed over two more), so a hot spot
/// or a shadow over part of the code turns few of its modules, and stops a
/// look only where it clips the code to white.
class QrLook {
 public:
  enum class Verdict {
    Unsure,  ///< no look, or the frame does not show the modules sharply
    Same,    ///< the modules it shows are the look's
    Other,   ///< another code: many modules the other way, dark to light and light to dark alike
  };
  /// From a frame whose code was just read at `corners` (TL, TR, BR, BL of
  /// the pattern square) in an 8-bit gray, BGR or BGRA image: the code's
  /// size (the one of 21, 25, ... modules whose function patterns the frame
  /// shows best) and each other module's shade. False, and the look left
  /// empty, where the frame does not show them sharply: under
  /// kMinPxPerModule pixels a module, function patterns or timing rows not
  /// clear, or corners not finite.
  bool capture(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners);
  /// The landmark at `corners` in another frame, against the look.
  Verdict compare(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners);
  bool empty() const { return n_ == 0; }
  int modules() const { return n_; }  ///< across; 0 when empty
  void clear() { n_ = 0; }

  static constexpr double kMinPxPerModule = 1.5;
  /// Other takes at least this many modules, and this share of those both
  /// frames show clearly, turned each way (noise and blur turn few, and
  /// mostly isolated modules one way; a hot spot turns them one way), each
  /// among at least kMinAround neighbours of the other shade in the frame
  /// (under a finger or its shadow the modules turn together)...
  static constexpr int kMinTurned = 6;
  static constexpr double kMinTurnedShare = 0.02;
  static constexpr int kMinAround = 2;
  /// ... and strewn: their scatter at least this many modules (standard
  /// deviation) across its narrower axis, where a pen's lie along a line.
  static constexpr double kMinSpread = 2.0;

 private:
  int n_ = 0;
  std::vector<int8_t> ref_;  // n x n: 1 dark, 0 light, -1 unclear or a function module
};

/// Several frames of one landmark's QR averaged in the sheet's frame, for
/// codes no single frame resolves: each frame is warped to the same upright
/// view (the QR square and half a unit around it, at twice the camera's
/// resolution), and the running mean of the views is decoded as an image of
/// its own. Averaging lowers noise and JPEG blocks by the square root of
/// the frames, and frames seen at different sub-pixel positions fill in
/// detail one frame's pixels miss. ld-qr-reader keeps one per undecoded track.
class QrStack {
 public:
  /// The first `max_frames` frames weigh the same; each later one weighs
  /// 1 / max_frames (an exponential mean: older frames fade out).
  /// Throws std::invalid_argument for max_frames under 1 (0 and -3 were taken).
  explicit QrStack(int max_frames = 8);
  /// Movable, not copyable: its buffers (cv::Mat) would be shared by a copy,
  /// the frames added to one changing the other's mean (an API audit).
  QrStack(const QrStack&) = delete;
  QrStack& operator=(const QrStack&) = delete;
  QrStack(QrStack&&) = default;
  QrStack& operator=(QrStack&&) = default;

  /// Adds one frame (8-bit BGR, BGRA or gray; another type throws
  /// std::invalid_argument, as QrReader::decode) with the landmark's pattern
  /// corners (TL, TR, BR, BL). False, and nothing added, when the QR is too
  /// small to read or a corner is not finite. A QR whose projected size differs from
  /// the stack's by more than a quarter (the robot came closer), or whose
  /// pattern jumped by more than its side since the last frame seen (another
  /// landmark: a tracker that swapped two tracks' ids), restarts it.
  bool add(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners);

  /// The track's landmark in a frame that is not added (not tried): only
  /// where it is, so that a jump is told from a landmark moving across the
  /// image between tries. Call it for every frame of the track. True when
  /// the landmark jumped and the stack's frames were dropped.
  bool follow(const std::array<cv::Point2f, 4>& corners);

  /// Frames in the mean (at most max_frames: older ones have faded).
  int frames() const { return std::min(n_, std::max(1, max_frames_)); }

  /// Adds the modules the pixel model fitted on a frame of this landmark
  /// (QrReader::lastFittedModules, right after the frame's own decode, and
  /// with the frame add()ed) to the stack's vote: the last max_frames fits
  /// (frames without one push none out). Each frame's pixels see the
  /// modules at other sub-pixel positions and with their own noise, so a
  /// module one frame's fit gets wrong most others get right. A restart of
  /// the stack drops them too. With max_frames under kMinVotes there is no
  /// vote.
  void addModules(int n, const std::vector<uint8_t>& modules);
  /// addModules() of `reader`'s last fit, where its last decode() made one.
  void addFit(const QrReader& reader) {
    int n = 0;
    if (const auto* modules = reader.lastFittedModules(n)) addModules(n, *modules);
  }

  /// Decodes the mean view with `reader` (every variation of QrReader::decode
  /// that its parameters allow), else, once kMinVotes or more frames' fits
  /// of one code size are in the vote, each module as most of them read
  /// it (QrReader::decodeModules; a tie goes to the latest frame's).
  std::optional<QrResult> decode(QrReader& reader);
  static constexpr int kMinVotes = 3;

  /// The parameters of the reader ld-qr-reader decodes its stacks with: no
  /// pixel model (QrReaderParams::fit_pixels) on the mean, a view upsampled
  /// twice.
  static QrReaderParams readerParams() {
    QrReaderParams p;
    p.fit_pixels = false;
    return p;
  }

  /// The mean view (8-bit gray), empty before the first frame. Valid until
  /// the next call. Once warmed up, adding and decoding do not allocate for
  /// a QR of the same size.
  const cv::Mat& meanView();

  void clear() { restart(); }

 private:
  std::optional<QrResult> decodeMean(QrReader& reader);
  void restart() {
    n_ = 0;
    votes_ = next_fit_ = 0;
  }
  int max_frames_;
  int n_ = 0;
  // The vote: the last max_frames fits (a ring), each with its code size.
  std::vector<std::vector<uint8_t>> fits_;
  std::vector<int> fit_n_;
  int votes_ = 0, next_fit_ = 0;
  std::vector<uint8_t> voted_;
  std::vector<int> dark_;
  // Restarts the stack when the pattern (centre, QR side) jumped by more
  // than kMaxJump pattern sides since the last frame seen (true then, with
  // frames in the stack); remembers it.
  bool checkJump(const std::array<cv::Point2f, 4>& corners, double qr_px);
  static constexpr double kMaxJump = 1.0;  // in pattern sides, between frames seen
  double qr_px_ = 0;  // the projected QR side of the stack's first frame
  cv::Point2f centre_;  // the pattern's centre in the last frame seen
  cv::Mat mean_, gray_, view_, view_f_, mean8_;
};

}  // namespace ld
