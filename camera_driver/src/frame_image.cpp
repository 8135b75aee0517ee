#include "ld/frame_image.hpp"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/image_convert.hpp"

namespace ld {
namespace {

struct RawFormat {
  uint32_t fourcc;
  int32_t pixelformat;
  int bytes_per_pixel;
};

const RawFormat kRaw[] = {
    {V4L2_PIX_FMT_YUYV, image_t::PIXEL_FORMAT_YUYV, 2},
    {V4L2_PIX_FMT_UYVY, image_t::PIXEL_FORMAT_UYVY, 2},
    {V4L2_PIX_FMT_GREY, image_t::PIXEL_FORMAT_GRAY, 1},
    {V4L2_PIX_FMT_RGB24, image_t::PIXEL_FORMAT_RGB, 3},
    {V4L2_PIX_FMT_BGR24, image_t::PIXEL_FORMAT_BGR, 3},
};

const RawFormat* rawFormat(uint32_t fourcc) {
  for (const auto& r : kRaw)
    if (r.fourcc == fourcc) return &r;
  return nullptr;
}

bool isJpeg(uint32_t fourcc) { return fourcc == V4L2_PIX_FMT_MJPEG || fourcc == V4L2_PIX_FMT_JPEG; }

[[noreturn]] void fail(const Frame& f, const std::string& what) {
  throw ImageFormatError("frame " + std::to_string(f.seq) + " (" + captureFormatName(f.fourcc) +
                         " " + std::to_string(f.width) + "x" + std::to_string(f.height) +
                         "): " + what);
}

// A view of a raw frame's pixels, checked against bytesused.
cv::Mat rawView(const Frame& f, const RawFormat& r) {
  const size_t row = static_cast<size_t>(f.width) * r.bytes_per_pixel;
  const size_t stride = f.bytesperline ? f.bytesperline : row;
  if (f.width == 0 || f.height == 0 || stride < row) fail(f, "inconsistent size or stride");
  const size_t need = stride * (f.height - 1) + row;
  if (f.bytesused < need)
    fail(f, "truncated: " + std::to_string(f.bytesused) + " bytes, need " + std::to_string(need));
  return cv::Mat(static_cast<int>(f.height), static_cast<int>(f.width), CV_8UC(r.bytes_per_pixel),
                 const_cast<uint8_t*>(f.data), stride);
}

void setHeader(const Frame& f, int32_t pixelformat, int32_t row_stride, image_t& msg) {
  msg.utime = f.utime;
  msg.width = static_cast<int32_t>(f.width);
  msg.height = static_cast<int32_t>(f.height);
  msg.pixelformat = pixelformat;
  msg.row_stride = row_stride;
  msg.size = static_cast<int32_t>(msg.data.size());
}

}  // namespace

ImageConversion imageConversionFromName(const std::string& name) {
  std::string s = name;
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (s == "none" || s == "captured") return ImageConversion::AsCaptured;
  if (s == "bgr") return ImageConversion::Bgr;
  if (s == "rgb") return ImageConversion::Rgb;
  if (s == "gray" || s == "grey") return ImageConversion::Gray;
  throw std::invalid_argument("unknown conversion '" + name + "' (expected bgr, rgb or gray)");
}

std::string imageConversionName(ImageConversion conversion) {
  switch (conversion) {
    case ImageConversion::Bgr: return "bgr";
    case ImageConversion::Rgb: return "rgb";
    case ImageConversion::Gray: return "gray";
    default: return "none";
  }
}

void FrameToImage::convert(const Frame& frame, image_t& msg) {
  if (!frame.data) fail(frame, "no data");
  if (conversion_ == ImageConversion::AsCaptured) copyAsCaptured(frame, msg);
  else decodeAndConvert(frame, msg);
  setImageSeq(msg, frame.seq);
}

void FrameToImage::copyAsCaptured(const Frame& f, image_t& msg) {
  if (isJpeg(f.fourcc)) {
    if (f.bytesused == 0) fail(f, "empty JPEG frame");
    msg.data.resize(f.bytesused);
    std::memcpy(msg.data.data(), f.data, f.bytesused);
    setHeader(f, image_t::PIXEL_FORMAT_MJPEG, 0, msg);
    return;
  }
  const RawFormat* r = rawFormat(f.fourcc);
  if (!r) fail(f, "pixel format " + fourccText(f.fourcc) + " cannot be published");
  const cv::Mat view = rawView(f, *r);
  // Whole rows with the driver's padding: one copy, stride kept.
  const size_t stride = view.step[0];
  const size_t n = stride * (f.height - 1) + static_cast<size_t>(f.width) * r->bytes_per_pixel;
  msg.data.resize(n);
  std::memcpy(msg.data.data(), f.data, n);
  setHeader(f, r->pixelformat, static_cast<int32_t>(stride), msg);
}

void FrameToImage::decodeAndConvert(const Frame& f, image_t& msg) {
  // 1. The frame as a BGR or GRAY (or YUV/RGB view) image.
  cv::Mat src;
  int code = -1;  // cvtColor code from src to the requested output; -1: copy
  const ImageConversion out = conversion_;
  if (isJpeg(f.fourcc)) {
    if (f.bytesused == 0) fail(f, "empty JPEG frame");
    // (libjpeg's damage said, not filled with grey and published as good)
    const std::string problem = decodeJpeg(f.data, f.bytesused, decoded_, out == ImageConversion::Gray);
    if (!problem.empty()) fail(f, "the JPEG data " + problem);
    if (decoded_.cols != static_cast<int>(f.width) || decoded_.rows != static_cast<int>(f.height))
      fail(f, "the JPEG is " + std::to_string(decoded_.cols) + "x" +
                  std::to_string(decoded_.rows));
    src = decoded_;
    if (out == ImageConversion::Rgb) code = cv::COLOR_BGR2RGB;
  } else {
    const RawFormat* r = rawFormat(f.fourcc);
    if (!r) fail(f, "pixel format " + fourccText(f.fourcc) + " cannot be converted");
    src = rawView(f, *r);
    const bool bgr = out == ImageConversion::Bgr, rgb = out == ImageConversion::Rgb;
    switch (f.fourcc) {
      case V4L2_PIX_FMT_YUYV:
        code = bgr ? cv::COLOR_YUV2BGR_YUYV : rgb ? cv::COLOR_YUV2RGB_YUYV : cv::COLOR_YUV2GRAY_YUYV;
        break;
      case V4L2_PIX_FMT_UYVY:
        code = bgr ? cv::COLOR_YUV2BGR_UYVY : rgb ? cv::COLOR_YUV2RGB_UYVY : cv::COLOR_YUV2GRAY_UYVY;
        break;
      case V4L2_PIX_FMT_GREY: code = bgr ? cv::COLOR_GRAY2BGR : rgb ? cv::COLOR_GRAY2RGB : -1; break;
      case V4L2_PIX_FMT_RGB24: code = bgr ? cv::COLOR_RGB2BGR : rgb ? -1 : cv::COLOR_RGB2GRAY; break;
      case V4L2_PIX_FMT_BGR24: code = bgr ? -1 : rgb ? cv::COLOR_BGR2RGB : cv::COLOR_BGR2GRAY; break;
      default: break;
    }
  }

  // 2. Converted straight into the message's (reused) storage.
  const int channels = out == ImageConversion::Gray ? 1 : 3;
  const size_t row = static_cast<size_t>(f.width) * channels;
  msg.data.resize(row * f.height);
  cv::Mat dst(static_cast<int>(f.height), static_cast<int>(f.width), CV_8UC(channels),
              msg.data.data(), row);
  if (code < 0) src.copyTo(dst);
  else cv::cvtColor(src, dst, code);
  if (code == cv::COLOR_YUV2GRAY_YUYV || code == cv::COLOR_YUV2GRAY_UYVY) {
    // Y is video range (16-235), as the BGR decoders assume: stretch it so
    // that GRAY matches BGR-then-gray.
    if (y_to_gray_.empty()) {
      y_to_gray_.create(1, 256, CV_8U);
      for (int i = 0; i < 256; ++i)
        y_to_gray_.at<uint8_t>(i) = cv::saturate_cast<uint8_t>((i - 16) * 255.0 / 219.0);
    }
    cv::LUT(dst, y_to_gray_, dst);
  }
  if (dst.data != msg.data.data()) fail(f, "conversion produced an unexpected layout");
  int32_t pf = image_t::PIXEL_FORMAT_BGR;
  if (out == ImageConversion::Gray) pf = image_t::PIXEL_FORMAT_GRAY;
  if (out == ImageConversion::Rgb) pf = image_t::PIXEL_FORMAT_RGB;
  setHeader(f, pf, static_cast<int32_t>(row), msg);
}

}  // namespace ld
