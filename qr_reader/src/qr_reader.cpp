#include "ld/qr_reader.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>
#include <zbar.h>

#include "ld/landmark_layout.hpp"

namespace ld {
namespace {

// Homography from the upright view (side px, QR square plus margin) to the image.
cv::Matx33d viewToImage(const std::array<cv::Point2f, 4>& corners, int side, double margin_u) {
  std::vector<cv::Point2f> sheet, img(corners.begin(), corners.end());
  for (const auto& c : layout::kCornersU)
    sheet.emplace_back(static_cast<float>(c[0]), static_cast<float>(c[1]));
  const cv::Matx33d sheet_to_image(cv::getPerspectiveTransform(sheet, img));
  // view pixel (x, y) -> sheet u: u = q0 + (x + 0.5) * span / side
  const double q0 = layout::kQrMin - margin_u;
  const double span = (layout::kQrMax - layout::kQrMin) + 2 * margin_u;
  const double s = span / side;
  const cv::Matx33d view_to_sheet(s, 0, q0 + 0.5 * s, 0, s, q0 + 0.5 * s, 0, 0, 1);
  return sheet_to_image * view_to_sheet;
}

double projectedQrSide(const std::array<cv::Point2f, 4>& c) {
  double pattern = 0;
  for (size_t i = 0; i < 4; ++i) pattern += cv::norm(c[i] - c[(i + 1) % 4]);
  pattern /= 4;
  return pattern * (layout::kQrMax - layout::kQrMin) / (layout::kPatternMax - layout::kPatternMin);
}

}  // namespace

struct QrReader::Impl {
  QrReaderParams params;
  zbar::ImageScanner scanner;
  cv::Mat gray, view, work, blurred;

  std::optional<std::string> scan(const cv::Mat& img) {
    cv::Mat cont = img.isContinuous() ? img : img.clone();
    zbar::Image z(static_cast<unsigned>(cont.cols), static_cast<unsigned>(cont.rows), "Y800",
                  cont.data, static_cast<unsigned long>(cont.total()));
    std::optional<std::string> found;
    if (scanner.scan(z) > 0) {
      for (auto s = z.symbol_begin(); s != z.symbol_end(); ++s)
        if (s->get_type() == zbar::ZBAR_QRCODE) {
          found = s->get_data();
          break;
        }
    }
    z.set_data(nullptr, 0);
    return found;
  }
};

QrReader::QrReader(const QrReaderParams& params) : impl_(std::make_unique<Impl>()) {
  impl_->params = params;
  impl_->scanner.set_config(zbar::ZBAR_NONE, zbar::ZBAR_CFG_ENABLE, 0);
  impl_->scanner.set_config(zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_ENABLE, 1);
  // The payload's bytes as encoded: zbar's text conversion guesses a charset
  // and turns short UTF-8 strings into Shift-JIS mojibake.
  impl_->scanner.set_config(zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_BINARY, 1);
}
QrReader::~QrReader() = default;
QrReader::QrReader(QrReader&&) noexcept = default;
QrReader& QrReader::operator=(QrReader&&) noexcept = default;

const cv::Mat& QrReader::lastView() const { return impl_->view; }

std::optional<QrResult> QrReader::decode(const cv::Mat& image,
                                         const std::array<cv::Point2f, 4>& corners) {
  Impl& m = *impl_;
  const QrReaderParams& p = m.params;
  if (image.empty() || image.depth() != CV_8U) return std::nullopt;
  for (const auto& c : corners)
    if (!std::isfinite(c.x) || !std::isfinite(c.y)) return std::nullopt;
  const double qr_px = projectedQrSide(corners);
  if (!(qr_px >= 8.0)) return std::nullopt;  // nothing to read

  if (image.channels() == 3) cv::cvtColor(image, m.gray, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4) cv::cvtColor(image, m.gray, cv::COLOR_BGRA2GRAY);
  else m.gray = image;

  const int side = std::clamp(static_cast<int>(std::lround(p.upsample * qr_px)), p.min_side_px,
                              p.max_side_px);
  const cv::Matx33d H = viewToImage(corners, side, p.margin_u);
  cv::warpPerspective(m.gray, m.view, H, {side, side}, cv::INTER_CUBIC | cv::WARP_INVERSE_MAP,
                      cv::BORDER_REPLICATE);

  int attempt = 0;
  if (auto s = m.scan(m.view)) return QrResult{*s, attempt};
  if (!p.retry_variations) return std::nullopt;

  // 1: Otsu binarization of the view.
  ++attempt;
  cv::threshold(m.view, m.work, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  // 2: unsharp mask against blur.
  ++attempt;
  cv::GaussianBlur(m.view, m.blurred, {0, 0}, std::max(1.0, side / 120.0));
  cv::addWeighted(m.view, 2.0, m.blurred, -1.0, 0, m.work);
  if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  // 3: adaptive threshold against uneven light (glare, gradient).
  ++attempt;
  const int block = (side / 8) | 1;
  cv::adaptiveThreshold(m.view, m.work, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY,
                        std::max(3, block), 5);
  if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  // 4, 5: other scales of the view.
  for (double scale : {0.6, 1.6}) {
    ++attempt;
    cv::resize(m.view, m.work, {}, scale, scale, scale < 1 ? cv::INTER_AREA : cv::INTER_CUBIC);
    if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  }
  return std::nullopt;
}

}  // namespace ld
