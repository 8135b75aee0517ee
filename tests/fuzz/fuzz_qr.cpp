// Fuzz target: the QR reader on arbitrary images and corners
// (ld/qr_reader.hpp), and its pixel model on its own on any grid
// (qr_pixel_model.hpp).
//
// Bytes 0-18 are a header: byte 0 the version the pixel model is given (1-15),
// bytes 1 and 2 the image's width and height (8-135 px, small: the pixel
// model runs where a module is under 2 px), bytes 3-18 the four corners (TL,
// TR, BR, BL) as little-endian int16 in eighths of a pixel (on the image,
// far off it, crossed, degenerate). The rest, repeated, fills the gray
// pixels row by row. Nothing may crash; an estimate must be n x n modules
// of 0 and 1.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/landmark_layout.hpp"
#include "ld/qr_reader.hpp"
#include "../../qr_reader/src/qr_pixel_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  constexpr size_t kHeader = 19;
  if (size <= kHeader) return 0;
  const int version = 1 + data[0] % 15, n = 17 + 4 * version;
  const int w = 8 + data[1] % 128, h = 8 + data[2] % 128;
  std::array<cv::Point2f, 4> corners;
  for (size_t k = 0; k < 4; ++k) {
    const auto x = static_cast<int16_t>(data[3 + 4 * k] | data[4 + 4 * k] << 8);
    const auto y = static_cast<int16_t>(data[5 + 4 * k] | data[6 + 4 * k] << 8);
    corners[k] = {x / 8.0f, y / 8.0f};
  }
  const uint8_t* rest = data + kHeader;
  const size_t rest_size = size - kHeader;
  cv::Mat gray(h, w, CV_8UC1);
  for (int i = 0; i < w * h; ++i) gray.data[i] = rest[static_cast<size_t>(i) % rest_size];

  // kept between inputs, as the process keeps its reader between frames
  static ld::QrReader reader;
  if (const auto r = reader.decode(gray, corners))
    if (r->attempt < 0 || r->attempt > 8) std::abort();

  static ld::detail::QrPixelModel model;
  std::vector<uint8_t> modules;
  if (model.estimate(gray, ld::layout::sheetToImage(corners) * ld::detail::moduleToSheet(n), n, modules)) {
    if (modules.size() != static_cast<size_t>(n) * n) std::abort();
    for (uint8_t m : modules)
      if (m > 1) std::abort();
  }
  return 0;
}
