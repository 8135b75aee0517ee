// Captured frames to ld::image_t messages.
//
// As captured (the default), a frame goes on the bus compact and untouched:
//   YUYV  -> PIXEL_FORMAT_YUYV, row_stride = the driver's bytesperline
//   GREY  -> PIXEL_FORMAT_GRAY, row_stride = bytesperline
//   MJPEG -> PIXEL_FORMAT_MJPEG, the frame's bytesused bytes, row_stride 0
// (UYVY, RGB24 and BGR24 captures map to their image_t formats the same way.)
// On request (ld-camera --convert) the frame is decoded and converted to
// packed BGR, RGB or GRAY first. The message's storage is reused: once warm,
// converting a frame allocates nothing (MJPEG decoding aside: libjpeg
// allocates inside OpenCV).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "ld/image_t.hpp"
#include "ld/v4l2_capture.hpp"

namespace ld {

enum class ImageConversion { AsCaptured, Bgr, Rgb, Gray };

/// "none" (or "captured"), "bgr", "rgb", "gray" (or "grey"); case-insensitive.
/// Throws std::invalid_argument otherwise.
ImageConversion imageConversionFromName(const std::string& name);
std::string imageConversionName(ImageConversion conversion);

class FrameToImage {
 public:
  explicit FrameToImage(ImageConversion conversion = ImageConversion::AsCaptured)
      : conversion_(conversion) {}

  /// Fills `msg` from `frame`: utime, size, pixel format, data and the "seq"
  /// metadata (frame.seq), reusing msg's storage. Throws ImageFormatError
  /// (from ld/image_convert.hpp) when the frame cannot be converted: a
  /// truncated raw frame, a JPEG that does not decode, a format it does not know.
  void convert(const Frame& frame, image_t& msg);

  ImageConversion conversion() const { return conversion_; }

 private:
  void copyAsCaptured(const Frame& frame, image_t& msg);
  void decodeAndConvert(const Frame& frame, image_t& msg);

  ImageConversion conversion_;
  cv::Mat decoded_;
  cv::Mat y_to_gray_;  // video-range Y to full-range gray
};

}  // namespace ld
