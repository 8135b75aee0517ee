// Fuzz target: the detector on arbitrary images (ld/detector.hpp).
//
// Bytes 0-4 are a header: flags (bits 0-1: channels - 1, bit 2: the paper's
// front end, bit 3: no completion of missing squares, bit 4: sizes times 8,
// bit 5: 16-bit pixels, bit 6: a frame the adaptive detector took a strong
// glare veil out of, Detector::setGlareCorrected: the faint look's veil
// round, its wide blue and the washed-QR rule run), width and height
// (little-endian, 0..640, or up to 5120 on a side and 16 Mpixel with bit 4). The rest, repeated, fills the
// pixels row by row, so a seed holding a whole frame is that frame. Every
// size from 0x0 up, any channel count: detect() must return (no landmarks
// for what it cannot read) or, for an image type it does not take (16-bit,
// two channels), throw std::invalid_argument and only then; whatever it
// reports must be finite.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <stdexcept>

#include "ld/detector.hpp"

namespace {

bool finite(const cv::Point2f& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// One detector per parameter variant, kept between inputs as the process
// keeps its own between frames (buffers reused across frame sizes).
ld::Detector& detectorFor(int variant) {
  static std::array<ld::Detector, 4> detectors = [] {
    ld::DetectorParams fast, paper = ld::DetectorParams::paper();
    ld::DetectorParams fast_whole = fast, paper_whole = paper;
    fast_whole.complete_missing = false;
    paper_whole.complete_missing = false;
    return std::array<ld::Detector, 4>{ld::Detector(fast), ld::Detector(paper),
                                       ld::Detector(fast_whole), ld::Detector(paper_whole)};
  }();
  return detectors[static_cast<size_t>(variant)];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 5) return 0;
  const int flags = data[0];
  const int channels = (flags & 3) + 1;
  const int variant = ((flags >> 2) & 1) | (((flags >> 3) & 1) << 1);
  const bool large = flags & 16;
  const int depth = flags & 32 ? CV_16U : CV_8U;
  const bool glare_corrected = flags & 64;
  int width = (data[1] | (data[2] << 8)) % 641;
  int height = (data[3] | (data[4] << 8)) % 641;
  if (large) {
    width *= 8;
    height *= 8;
    while (static_cast<int64_t>(width) * height > (16 << 20)) height /= 2;
  }
  const uint8_t* pattern = data + 5;
  const size_t n = size - 5;

  cv::Mat image(height, width, CV_MAKETYPE(depth, channels));
  if (!image.empty()) {
    if (n == 0) {
      image.setTo(cv::Scalar::all(0));
    } else {
      size_t k = 0;
      for (int y = 0; y < image.rows; ++y) {
        uint8_t* row = image.ptr<uint8_t>(y);
        const size_t row_bytes = static_cast<size_t>(image.cols) * image.elemSize();
        for (size_t x = 0; x < row_bytes; ++x) {
          row[x] = pattern[k];
          if (++k == n) k = 0;
        }
      }
    }
  }

  ld::Detector& detector = detectorFor(variant);
  detector.setGlareCorrected(glare_corrected);  // (per frame, as ld::AdaptiveDetector sets it)
  const bool readable = image.empty() || (depth == CV_8U && channels != 2);
  const ld::Detection* found = nullptr;
  try {
    found = &detector.detect(image);
  } catch (const std::invalid_argument&) {
    if (readable) std::abort();
    return 0;
  }
  if (!readable) std::abort();  // (taken without a word: it finds nothing)
  const ld::Detection& det = *found;
  if (det.landmarks.size() > 10000) std::abort();
  for (const ld::Landmark& lm : det.landmarks) {
    if (!finite(lm.fip_tl) || !finite(lm.fip_tr) || !finite(lm.fip_bl) || !finite(lm.ap))
      std::abort();
    for (const auto& c : lm.corners)
      if (!finite(c)) std::abort();
    if (!(lm.score >= 0 && lm.score <= 1)) std::abort();
  }
  return 0;
}
