// Conversions between ld::image_t messages and cv::Mat.
//
// Every decode checks that the message is self-consistent (sizes, strides,
// pixel format) before touching its bytes, and throws ImageFormatError with
// a one-line reason otherwise: a bad message never reads past its buffer.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

#include "ld/image_t.hpp"

namespace ld {

/// Thrown when an image_t cannot be decoded; what() names the problem.
class ImageFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The FourCC code of four characters, as V4L2 and bot_core.image_t use it.
constexpr int32_t fourcc(char a, char b, char c, char d) {
  return static_cast<int32_t>(static_cast<uint32_t>(static_cast<uint8_t>(a)) |
                              (static_cast<uint32_t>(static_cast<uint8_t>(b)) << 8) |
                              (static_cast<uint32_t>(static_cast<uint8_t>(c)) << 16) |
                              (static_cast<uint32_t>(static_cast<uint8_t>(d)) << 24));
}

/// "GRAY", "RGB", "BGR", "RGBA", "BGRA", "YUYV", "UYVY", "MJPEG", or the
/// FourCC text ("0x…" when it is not printable) for anything else.
std::string pixelFormatName(int32_t pixelformat);

/// Inverse of pixelFormatName for the supported formats (case-insensitive;
/// "GREY" and "MJPG" are accepted too). Throws ImageFormatError when unknown.
int32_t pixelFormatFromName(const std::string& name);

/// True for the formats imageToBgr can decode.
bool isSupportedPixelFormat(int32_t pixelformat);

/// Whether `pixelformat` holds the colour of two pixels together (YUYV,
/// UYVY): its frames have an even width.
inline bool pixelsInPairs(int32_t pixelformat) {
  return pixelformat == image_t::PIXEL_FORMAT_YUYV || pixelformat == image_t::PIXEL_FORMAT_UYVY;
}

/// The most pixels of an MJPEG image_t (8K UHD fits): a JPEG decoder
/// allocates the whole image before it finds its data missing, so a few
/// hundred bytes claiming 30000x30000 would otherwise cost gigabytes.
constexpr int64_t kMaxMjpegPixels = int64_t{1} << 25;

/// Checks, without decoding the pixels, what imageToBgr checks first: a
/// supported format, sizes and strides that fit the data, and for MJPEG a
/// JPEG frame header within the size limit that agrees with width and height
/// (the compressed data itself is only checked by decoding it). Throws
/// ImageFormatError naming the problem.
void checkImage(const image_t& msg);
/// checkImage's reason as text, "" when the message is good: for a process's
/// line on a frame it drops, and ld-run's count of them.
std::string imageProblem(const image_t& msg);

/// Decodes JPEG bytes with libjpeg into 8-bit BGR (or GRAY), `out` reused
/// when it has the size already. Empty when the image was whole; otherwise
/// why: "is damaged (libjpeg: Corrupt JPEG data: premature end of data
/// segment)" (libjpeg fills what it cannot read with grey and goes on, and
/// printed that line on stderr itself, uncounted; warnings that say nothing
/// of the pixels, and padding before the end marker, are no damage), "could
/// not be decoded (libjpeg: Not a JPEG file: ...)", "could not be decoded
/// (libjpeg: its frame 65500x65500 is larger than 1073741824 pixels)"
/// (`out` empty then). libjpeg prints nothing.
std::string decodeJpeg(const uint8_t* data, size_t size, cv::Mat& out, bool gray = false,
                       int64_t max_pixels = int64_t{1} << 30);

/// Whether JPEG bytes hold a whole image: an end-of-image marker after the
/// first scan's header. libjpeg decodes a stream cut short into grey rows
/// (with a warning of its own that names nothing), and OpenCV takes that as
/// the image. Bytes after the marker (a camera's padding) are allowed.
bool jpegComplete(const uint8_t* data, size_t size);

/// Whether OpenCV's cv::imdecode (IMREAD_COLOR) gives exactly decodeJpeg's
/// BGR image for these JPEG bytes: both decode with libjpeg's defaults, but
/// OpenCV turns an image as its Exif orientation says (it takes the first
/// APP1 block for Exif, whatever its name) and converts CMYK its own way.
/// So: grey or three-component colour, with no APP1 block before the scan.
bool jpegReadsAsDecoded(const uint8_t* data, size_t size);

/// Decodes any supported format into 8-bit BGR. `out` is reused when it
/// already has the right size and type, so a warmed-up caller does not
/// allocate (MJPEG decoding allocates inside libjpeg regardless).
void imageToBgr(const image_t& msg, cv::Mat& out);
cv::Mat imageToBgr(const image_t& msg);

/// Decodes to GRAY (CV_8UC1) for GRAY messages and BGR (CV_8UC3) otherwise.
void imageToMat(const image_t& msg, cv::Mat& out);

/// Encodes an 8-bit image (1, 3 or 4 channels; 3 and 4 are taken as BGR and
/// BGRA) into `pixelformat`. Compressed formats use `jpeg_quality`.
/// Throws ImageFormatError when the conversion is not possible (YUYV/UYVY need an
/// even width) or would give a message its readers refuse (a side over
/// 32768 px; an MJPEG image over 2^25 pixels) or none at all (a raw image
/// of more than 2^31 - 1 bytes, which image_t's int32 size cannot say).
image_t matToImage(const cv::Mat& image, int32_t pixelformat, int64_t utime,
                   int64_t seq = -1, int jpeg_quality = 90);

/// The frame's sequence number from the "seq" metadata, if present and a
/// whole number 0 or more.
std::optional<int64_t> imageSeq(const image_t& msg);

/// Sets (or replaces) the "seq" metadata; an existing entry is rewritten in
/// place (no allocation once the message has one: a camera's or a player's
/// message kept from frame to frame).
void setImageSeq(image_t& msg, int64_t seq);

}  // namespace ld
