// Fuzz target: image_t messages decoded into images (ld/image_convert.hpp).
//
// Byte 0 says how the rest is read:
//  - even: an encoded image_t exactly as it comes off the bus;
//  - odd: a header (format, width, height, row_stride, size skew: 8 bytes)
//    and then the pixel bytes, so that every pixel format gets messages that
//    are consistent, nearly consistent (truncated, short strides, odd widths,
//    negative sizes) and, for MJPEG, any bytes as the JPEG stream.
// Decoding may only succeed with an image of the size the message says (an
// MJPEG message of 0x0: the JPEG's own), or
// throw ld::ImageFormatError; anything else (another exception, a crash, a
// sanitizer report, gigabytes allocated) is a finding.
#include <cstdint>
#include <cstdlib>

#include "ld/image_convert.hpp"
#include "ld/message_decode.hpp"

namespace {

int16_t s16(const uint8_t* p) { return static_cast<int16_t>(p[0] | (p[1] << 8)); }

bool fromHeader(const uint8_t* data, size_t size, ld::image_t& msg) {
  if (size < 9) return false;
  static const int32_t kFormats[] = {
      ld::image_t::PIXEL_FORMAT_GRAY, ld::image_t::PIXEL_FORMAT_RGB,
      ld::image_t::PIXEL_FORMAT_BGR,  ld::image_t::PIXEL_FORMAT_RGBA,
      ld::image_t::PIXEL_FORMAT_BGRA, ld::image_t::PIXEL_FORMAT_YUYV,
      ld::image_t::PIXEL_FORMAT_UYVY, ld::image_t::PIXEL_FORMAT_MJPEG,
      ld::fourcc('H', '2', '6', '4'), ld::image_t::PIXEL_FORMAT_INVALID};
  msg.utime = 1;
  msg.pixelformat = kFormats[data[0] % (sizeof kFormats / sizeof kFormats[0])];
  msg.width = s16(data + 1);
  msg.height = s16(data + 3);
  msg.row_stride = s16(data + 5);
  const int skew = static_cast<int8_t>(data[7]);  // the size field against the bytes present
  msg.data.assign(data + 8, data + size);
  msg.size = static_cast<int32_t>(msg.data.size()) + (skew == 0 || skew > 4 ? 0 : skew - 2);
  msg.nmetadata = 0;
  msg.metadata.clear();
  if (data[7] & 0x80) ld::setImageSeq(msg, data[8]);
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  ld::image_t msg;
  const bool ok = data[0] % 2 == 0 ? ld::decodeMessage(data + 1, size - 1, msg)
                                   : fromHeader(data + 1, size - 1, msg);
  if (!ok) return 0;
  (void)ld::imageSeq(msg);
  (void)ld::pixelFormatName(msg.pixelformat);

  cv::Mat bgr, mat;
  try {
    ld::imageToBgr(msg, bgr);
    if (bgr.type() != CV_8UC3 || bgr.empty()) std::abort();
    // only an MJPEG message may leave its size out (0x0)
    if ((msg.width != 0 || msg.height != 0) && (bgr.cols != msg.width || bgr.rows != msg.height))
      std::abort();
  } catch (const ld::ImageFormatError&) {
  }
  try {
    ld::imageToMat(msg, mat);
    if (mat.empty() || (mat.type() != CV_8UC1 && mat.type() != CV_8UC3)) std::abort();
  } catch (const ld::ImageFormatError&) {
  }
  return 0;
}
