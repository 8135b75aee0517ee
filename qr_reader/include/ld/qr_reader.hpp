// Reads the QR code of a detected landmark: the homography from the
// landmark's corners to the sheet (docs/landmark.md), an upright view of the
// QR square only, at a resolution chosen from its projected size, then zbar
// (QR only), retried with a few variations before giving up.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>

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
};

/// What one decode attempt found.
struct QrResult {
  std::string payload;
  /// Which variation decoded it: 0 the plain view; 1 Otsu, 2 sharpened, 3
  /// adaptive threshold, 4 and 5 other scales of the view; 6 the modules read
  /// one by one and equalised against the blur, 7 the same thresholded as
  /// read or after a fixed sharpening.
  int attempt = 0;
};

class QrReader {
 public:
  explicit QrReader(const QrReaderParams& params = {});
  ~QrReader();
  QrReader(QrReader&&) noexcept;
  QrReader& operator=(QrReader&&) noexcept;

  /// Decodes the QR of the landmark whose pattern corners (TL, TR, BR, BL,
  /// LANDMARK.md's `corners`) are given, in an 8-bit BGR or gray image.
  /// nullopt when no variation decodes (too small, blurred, damaged, missing).
  std::optional<QrResult> decode(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners);

  /// The upright gray view of the last decode() call (for debugging, ld-view).
  const cv::Mat& lastView() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ld
