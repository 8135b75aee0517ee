#include "ld/image_convert.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <csetjmp>
#include <cstdio>
#include <limits>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <jpeglib.h>
#include <jerror.h>

namespace ld {
namespace {

constexpr int kMaxSide = 1 << 15;

struct FormatInfo {
  int32_t code;
  const char* name;
  int bytes_per_pixel;  // 0: compressed
};

const FormatInfo kFormats[] = {
    {image_t::PIXEL_FORMAT_GRAY, "GRAY", 1},  {image_t::PIXEL_FORMAT_RGB, "RGB", 3},
    {image_t::PIXEL_FORMAT_BGR, "BGR", 3},    {image_t::PIXEL_FORMAT_RGBA, "RGBA", 4},
    {image_t::PIXEL_FORMAT_BGRA, "BGRA", 4},  {image_t::PIXEL_FORMAT_YUYV, "YUYV", 2},
    {image_t::PIXEL_FORMAT_UYVY, "UYVY", 2},  {image_t::PIXEL_FORMAT_MJPEG, "MJPEG", 0},
};

const FormatInfo* findFormat(int32_t code) {
  for (const auto& f : kFormats)
    if (f.code == code) return &f;
  return nullptr;
}

[[noreturn]] void fail(const std::string& what) { throw ImageFormatError("image_t: " + what); }

// Checks the header of a raw (uncompressed) message and returns a Mat view of
// its pixels with `channels` channels of bytes per pixel.
cv::Mat rawView(const image_t& msg, const FormatInfo& f) {
  const std::string fmt = f.name;
  if (msg.width <= 0 || msg.height <= 0 || msg.width > kMaxSide || msg.height > kMaxSide)
    fail(fmt + " image has invalid size " + std::to_string(msg.width) + "x" +
         std::to_string(msg.height));
  if (static_cast<size_t>(msg.size) != msg.data.size() || msg.size < 0)
    fail(fmt + " size field " + std::to_string(msg.size) + " does not match " +
         std::to_string(msg.data.size()) + " data bytes");
  if (pixelsInPairs(f.code) && msg.width % 2 != 0)
    fail(fmt + " image needs an even width, got " + std::to_string(msg.width));
  const int64_t row_bytes = static_cast<int64_t>(msg.width) * f.bytes_per_pixel;
  const int64_t stride = msg.row_stride == 0 ? row_bytes : msg.row_stride;
  if (stride < row_bytes)
    fail(fmt + " row_stride " + std::to_string(msg.row_stride) + " is less than width*" +
         std::to_string(f.bytes_per_pixel) + " = " + std::to_string(row_bytes));
  const int64_t needed = stride * (msg.height - 1) + row_bytes;
  if (msg.size < needed)
    fail(fmt + " " + std::to_string(msg.width) + "x" + std::to_string(msg.height) +
         " with row_stride " + std::to_string(stride) + " needs " + std::to_string(needed) +
         " bytes, message has " + std::to_string(msg.size));
  // (more than whole rows hold: a width or height that is not the data's,
  // which would draw part of the frame as a smaller one)
  if (msg.size > stride * msg.height)
    fail(fmt + " " + std::to_string(msg.width) + "x" + std::to_string(msg.height) +
         " with row_stride " + std::to_string(stride) + " holds at most " + std::to_string(stride * msg.height) +
         " bytes, message has " + std::to_string(msg.size) + " (a wrong width or height?)");
  const int type = CV_8UC(f.bytes_per_pixel);
  return cv::Mat(msg.height, msg.width, type, const_cast<uint8_t*>(msg.data.data()),
                 static_cast<size_t>(stride));
}

// What a JPEG stream's headers say, read without decoding: the frame size
// of its SOFn header (empty when it has none before its scan data), its
// colour components, whether an APP1 block comes before its scan (OpenCV
// reads the first as Exif, whatever its name), and where its first scan
// (SOS) starts (0 when it has none before its end).
struct JpegHeaders {
  cv::Size frame;
  int components = 0;
  bool exif = false;
  size_t scan = 0;
};
JpegHeaders jpegHeaders(const uint8_t* p, size_t n) {
  JpegHeaders h;
  if (n < 4 || p[0] != 0xFF || p[1] != 0xD8) return h;  // SOI
  size_t i = 2;
  bool sof = false;  // (the first frame header counts)
  while (i + 4 <= n) {
    if (p[i] != 0xFF) return h;
    const uint8_t m = p[i + 1];
    if (m == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (m == 0x01 || (m >= 0xD0 && m <= 0xD8)) {  // markers without a length
      i += 2;
      continue;
    }
    if (m == 0xD9) return h;  // EOI before any scan
    if (m == 0xDA) {
      h.scan = i;
      return h;
    }
    const size_t len = (static_cast<size_t>(p[i + 2]) << 8) | p[i + 3];
    if (len < 2) return h;
    if (!sof && m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC) {  // SOF0..SOF15
      if (len < 7 || i + 9 > n) return h;
      h.frame = {(p[i + 7] << 8) | p[i + 8], (p[i + 5] << 8) | p[i + 6]};
      if (i + 10 <= n) h.components = p[i + 9];
      sof = true;
    }
    if (m == 0xE1) h.exif = true;
    i += 2 + len;
  }
  return h;
}

// Whether the stream has an end-of-image marker after its scan's header:
// in the entropy-coded data a 0xFF byte is followed by 0x00 or a restart
// marker (D0-D7), so FF D9 there is the end of the image.
bool endsAfterScan(const uint8_t* p, size_t n, size_t scan) {
  if (scan == 0) return false;
  for (size_t i = n; i-- > scan + 1;)
    if (p[i] == 0xD9 && p[i - 1] == 0xFF) return true;
  return false;
}

// The checks of an MJPEG message that need no decoding.
void checkMjpeg(const image_t& msg) {
  if (msg.size == 0 && msg.data.empty()) fail("MJPEG message has no data");
  if (static_cast<size_t>(msg.size) != msg.data.size() || msg.size <= 0)
    fail("MJPEG size field " + std::to_string(msg.size) + " does not match " +
         std::to_string(msg.data.size()) + " data bytes");
  const JpegHeaders headers = jpegHeaders(msg.data.data(), msg.data.size());
  const cv::Size frame = headers.frame;
  if (frame.width <= 0 || frame.height <= 0)
    fail("MJPEG data is not a JPEG stream with a frame size");
  // 0x0: a sender that does not know the size (the JPEG's own is taken);
  // any other size must be the JPEG's
  if ((msg.width != 0 || msg.height != 0) && (frame.width != msg.width || frame.height != msg.height))
    fail("MJPEG data is " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
         " but the message says " + std::to_string(msg.width) + "x" +
         std::to_string(msg.height));
  if (static_cast<int64_t>(frame.width) * frame.height > kMaxMjpegPixels)
    fail("MJPEG frame " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
         " is larger than " + std::to_string(kMaxMjpegPixels) + " pixels");
  if (!endsAfterScan(msg.data.data(), msg.data.size(), headers.scan))
    fail("MJPEG data ends before its image does (no end-of-image marker: a frame cut short)");
}

// libjpeg's errors: a fatal one jumps back to the decode; a warning that the
// data is damaged (libjpeg fills what it cannot read with grey and goes on)
// is kept. Nothing is printed on stderr.
struct JpegErrors {
  jpeg_error_mgr mgr;
  std::jmp_buf fatal;
  int damage;
  char first[JMSG_LENGTH_MAX];
};

void onJpegFatal(j_common_ptr c) {
  auto* e = reinterpret_cast<JpegErrors*>(c->err);
  (*c->err->format_message)(c, e->first);  // (the error that ended it, over a warning before)
  std::longjmp(e->fatal, 1);
}

// The warnings that say pixels were lost. Others say nothing of the picture:
// "Invalid SOS parameters for sequential JPEG" (zeros some cameras write),
// an unknown JFIF revision or Adobe transform; and bytes before the end
// marker are the padding many UVC cameras put there (before a restart
// marker, they are data that belongs to no block: damage).
bool isDamage(const jpeg_error_mgr& err) {
  switch (err.msg_code) {
    case JWRN_HIT_MARKER:
    case JWRN_HUFF_BAD_CODE:
    case JWRN_ARITH_BAD_CODE:
    case JWRN_MUST_RESYNC:
    case JWRN_JPEG_EOF:
    case JWRN_BOGUS_PROGRESSION: return true;
    case JWRN_EXTRANEOUS_DATA: return err.msg_parm.i[1] != JPEG_EOI;
    default: return false;
  }
}

void onJpegMessage(j_common_ptr c, int level) {
  auto* e = reinterpret_cast<JpegErrors*>(c->err);
  if (level >= 0 || !isDamage(*c->err)) return;  // (level >= 0: a trace)
  if (e->damage++ == 0) (*c->err->format_message)(c, e->first);
}

// The decode itself, without C++ objects alive across its setjmp. `out` is
// sized by `size` (width, height, channels) once the header is read; it
// returns false when it could not be (no memory). Returns 0 when whole, 1
// when damaged, 2 when not decoded; `why` holds the reason.
int decodeJpegRaw(const uint8_t* data, size_t n, bool gray, int64_t max_pixels, cv::Mat* out, char* why,
                  bool (*size)(cv::Mat*, int, int, int) noexcept) {
  jpeg_decompress_struct cinfo;
  JpegErrors errors;
  cinfo.err = jpeg_std_error(&errors.mgr);
  errors.mgr.error_exit = onJpegFatal;
  errors.mgr.emit_message = onJpegMessage;
  errors.damage = 0;
  errors.first[0] = '\0';
  if (setjmp(errors.fatal)) {
    jpeg_destroy_decompress(&cinfo);
    std::snprintf(why, JMSG_LENGTH_MAX, "%s", errors.first);
    return 2;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(n));
  (void)jpeg_read_header(&cinfo, TRUE);
  // (CMYK, as Photoshop writes it, comes out as CMYK: converted after)
  const bool cmyk = cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK;
#ifdef JCS_EXTENSIONS  // libjpeg-turbo's BGR output; IJG's libjpeg: RGB, swapped after
  const J_COLOR_SPACE colour = JCS_EXT_BGR;
#else
  const J_COLOR_SPACE colour = JCS_RGB;
#endif
  cinfo.out_color_space = cmyk ? JCS_CMYK : gray ? JCS_GRAYSCALE : colour;
  // (before libjpeg allocates a thing for the image: a header may say anything)
  if (static_cast<int64_t>(cinfo.image_width) * cinfo.image_height > max_pixels) {
    std::snprintf(why, JMSG_LENGTH_MAX, "its frame %ux%u is larger than %lld pixels", cinfo.image_width,
                  cinfo.image_height, static_cast<long long>(max_pixels));
    jpeg_destroy_decompress(&cinfo);
    return 2;
  }
  jpeg_start_decompress(&cinfo);
  if (!size(out, static_cast<int>(cinfo.output_width), static_cast<int>(cinfo.output_height),
            cmyk ? 4 : gray ? 1 : 3)) {
    std::snprintf(why, JMSG_LENGTH_MAX, "no memory for its %ux%u pixels", cinfo.output_width, cinfo.output_height);
    jpeg_destroy_decompress(&cinfo);
    return 2;
  }
  while (cinfo.output_scanline < cinfo.output_height) {
    JSAMPROW row = out->ptr<uint8_t>(static_cast<int>(cinfo.output_scanline));
    jpeg_read_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_decompress(&cinfo);
  jpeg_destroy_decompress(&cinfo);
  std::snprintf(why, JMSG_LENGTH_MAX, "%s", errors.first);
  return errors.damage > 0 ? 1 : 0;
}

void decodeMjpeg(const image_t& msg, cv::Mat& out) {
  checkMjpeg(msg);
  const std::string problem = decodeJpeg(msg.data.data(), msg.data.size(), out, false, kMaxMjpegPixels);
  if (!problem.empty()) fail("MJPEG data " + problem);
  if ((msg.width != 0 || msg.height != 0) && (out.cols != msg.width || out.rows != msg.height))
    fail("MJPEG data is " + std::to_string(out.cols) + "x" + std::to_string(out.rows) +
         " but the message says " + std::to_string(msg.width) + "x" +
         std::to_string(msg.height));
}

// BGR to packed 4:2:2 (BT.601, video range, as V4L2 cameras send it and as
// cvtColor's YUV422 decoders expect); `yuyv` selects Y0 U Y1 V, else U Y0 V Y1.
void encodePacked422(const cv::Mat& bgr, bool yuyv, std::vector<uint8_t>& dst) {
  dst.resize(static_cast<size_t>(bgr.cols) * bgr.rows * 2);
  uint8_t* o = dst.data();
  auto clamp8 = [](double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); };
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; x += 2) {
      double luma[2], u = 0, v = 0;
      for (int k = 0; k < 2; ++k) {
        const double b = p[x + k][0], g = p[x + k][1], r = p[x + k][2];
        luma[k] = 16 + 0.2568 * r + 0.5041 * g + 0.0979 * b;
        u += 0.5 * (128 - 0.1482 * r - 0.2910 * g + 0.4392 * b);
        v += 0.5 * (128 + 0.4392 * r - 0.3678 * g - 0.0714 * b);
      }
      const uint8_t y0 = clamp8(luma[0]), y1 = clamp8(luma[1]), cu = clamp8(u), cv = clamp8(v);
      if (yuyv) {
        o[0] = y0; o[1] = cu; o[2] = y1; o[3] = cv;
      } else {
        o[0] = cu; o[1] = y0; o[2] = cv; o[3] = y1;
      }
      o += 4;
    }
  }
}

}  // namespace

std::string pixelFormatName(int32_t pixelformat) {
  if (const FormatInfo* f = findFormat(pixelformat)) return f->name;
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((static_cast<uint32_t>(pixelformat) >> (8 * i)) & 0xff);
    if (!std::isprint(static_cast<unsigned char>(c))) {
      char hex[16];
      std::snprintf(hex, sizeof hex, "0x%08x", static_cast<uint32_t>(pixelformat));
      return hex;
    }
    s += c;
  }
  return "'" + s + "'";
}

int32_t pixelFormatFromName(const std::string& name) {
  std::string up = name;
  std::transform(up.begin(), up.end(), up.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  if (up == "GREY") up = "GRAY";
  if (up == "MJPG" || up == "JPEG") up = "MJPEG";
  for (const auto& f : kFormats)
    if (up == f.name) return f.code;
  throw ImageFormatError("unknown pixel format '" + name +
                         "' (expected GRAY, RGB, BGR, RGBA, BGRA, YUYV, UYVY or MJPEG)");
}

bool isSupportedPixelFormat(int32_t pixelformat) { return findFormat(pixelformat) != nullptr; }

std::string decodeJpeg(const uint8_t* data, size_t size, cv::Mat& out, bool gray, int64_t max_pixels) {
  char why[JMSG_LENGTH_MAX] = "";
  // (sized in place: a warmed-up caller's buffer is reused)
  // (an exception may not cross libjpeg's frames: said as a failure)
  const auto sizeOut = [](cv::Mat* m, int w, int h, int channels) noexcept {
    try {
      m->create(h, w, CV_8UC(channels));
      return true;
    } catch (...) {
      return false;
    }
  };
  const int result = decodeJpegRaw(data, size, gray, max_pixels, &out, why, sizeOut);
  if (result == 2) {
    out.release();
    return std::string("could not be decoded (libjpeg: ") + why + ")";
  }
#ifndef JCS_EXTENSIONS
  if (out.channels() == 3) cv::cvtColor(out, out, cv::COLOR_RGB2BGR);
#endif
  if (out.channels() == 4) {  // CMYK as Adobe stores it (inverted): each colour times K
    cv::Mat bgr(out.rows, out.cols, CV_8UC3);
    for (int y = 0; y < out.rows; ++y) {
      const uint8_t* s = out.ptr<uint8_t>(y);
      uint8_t* d = bgr.ptr<uint8_t>(y);
      for (int x = 0; x < out.cols; ++x, s += 4, d += 3) {
        d[0] = static_cast<uint8_t>(s[2] * s[3] / 255);
        d[1] = static_cast<uint8_t>(s[1] * s[3] / 255);
        d[2] = static_cast<uint8_t>(s[0] * s[3] / 255);
      }
    }
    if (gray) cv::cvtColor(bgr, out, cv::COLOR_BGR2GRAY);
    else out = bgr;
  }
  return result == 1 ? std::string("is damaged (libjpeg: ") + why + ")" : "";
}

bool jpegComplete(const uint8_t* data, size_t size) {
  return endsAfterScan(data, size, jpegHeaders(data, size).scan);
}

bool jpegReadsAsDecoded(const uint8_t* data, size_t size) {
  const JpegHeaders h = jpegHeaders(data, size);
  return h.scan != 0 && !h.exif && (h.components == 1 || h.components == 3);
}

void checkImage(const image_t& msg) {
  const FormatInfo* f = findFormat(msg.pixelformat);
  if (!f) fail("unsupported pixel format " + pixelFormatName(msg.pixelformat));
  if (f->bytes_per_pixel == 0) checkMjpeg(msg);
  else (void)rawView(msg, *f);
}

std::string imageProblem(const image_t& msg) {
  try {
    checkImage(msg);
  } catch (const ImageFormatError& e) {
    return e.what();
  }
  return "";
}

void imageToBgr(const image_t& msg, cv::Mat& out) {
  const FormatInfo* f = findFormat(msg.pixelformat);
  if (!f) fail("unsupported pixel format " + pixelFormatName(msg.pixelformat));
  if (f->bytes_per_pixel == 0) {
    decodeMjpeg(msg, out);
    return;
  }
  const cv::Mat src = rawView(msg, *f);
  switch (f->code) {
    case image_t::PIXEL_FORMAT_GRAY: cv::cvtColor(src, out, cv::COLOR_GRAY2BGR); break;
    case image_t::PIXEL_FORMAT_RGB: cv::cvtColor(src, out, cv::COLOR_RGB2BGR); break;
    case image_t::PIXEL_FORMAT_BGR: src.copyTo(out); break;
    case image_t::PIXEL_FORMAT_RGBA: cv::cvtColor(src, out, cv::COLOR_RGBA2BGR); break;
    case image_t::PIXEL_FORMAT_BGRA: cv::cvtColor(src, out, cv::COLOR_BGRA2BGR); break;
    case image_t::PIXEL_FORMAT_YUYV: cv::cvtColor(src, out, cv::COLOR_YUV2BGR_YUYV); break;
    case image_t::PIXEL_FORMAT_UYVY: cv::cvtColor(src, out, cv::COLOR_YUV2BGR_UYVY); break;
    default: fail("unsupported pixel format " + pixelFormatName(msg.pixelformat));
  }
}

cv::Mat imageToBgr(const image_t& msg) {
  cv::Mat out;
  imageToBgr(msg, out);
  return out;
}

void imageToMat(const image_t& msg, cv::Mat& out) {
  if (msg.pixelformat == image_t::PIXEL_FORMAT_GRAY) {
    rawView(msg, *findFormat(msg.pixelformat)).copyTo(out);
    return;
  }
  imageToBgr(msg, out);
}

image_t matToImage(const cv::Mat& image, int32_t pixelformat, int64_t utime, int64_t seq,
                   int jpeg_quality) {
  if (image.empty()) throw ImageFormatError("matToImage: empty image");
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3 &&
                                 image.channels() != 4))
    throw ImageFormatError("matToImage: need an 8-bit image with 1, 3 or 4 channels");
  const FormatInfo* f = findFormat(pixelformat);
  if (!f) throw ImageFormatError("matToImage: unsupported pixel format " +
                                 pixelFormatName(pixelformat));
  // (nothing its readers refuse: checkImage's limits)
  if (image.cols > kMaxSide || image.rows > kMaxSide)
    throw ImageFormatError("matToImage: a " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                           " image is more than the " + std::to_string(kMaxSide) + " px a side that image_t takes");
  if (f->bytes_per_pixel == 0 && int64_t{image.cols} * image.rows > kMaxMjpegPixels)
    throw ImageFormatError("matToImage: a " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                           " image is more than the " + std::to_string(kMaxMjpegPixels) +
                           " pixels an MJPEG image_t takes");
  // (image_t's size is an int32: a raw image of more bytes has none)
  if (const int64_t bytes = int64_t{image.cols} * image.rows * f->bytes_per_pixel;
      bytes > std::numeric_limits<int32_t>::max())
    throw ImageFormatError("matToImage: a " + std::to_string(image.cols) + "x" + std::to_string(image.rows) + " " +
                           f->name + " image is " + std::to_string(bytes) + " bytes, more than the " +
                           std::to_string(std::numeric_limits<int32_t>::max()) + " an image_t holds");

  cv::Mat bgr;
  if (image.channels() == 1) cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  else if (image.channels() == 4) cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  else bgr = image;

  image_t msg;
  msg.utime = utime;
  msg.width = image.cols;
  msg.height = image.rows;
  msg.pixelformat = pixelformat;
  msg.nmetadata = 0;

  cv::Mat packed;
  switch (pixelformat) {
    case image_t::PIXEL_FORMAT_GRAY:
      if (image.channels() == 1) packed = image;
      else cv::cvtColor(bgr, packed, cv::COLOR_BGR2GRAY);
      break;
    case image_t::PIXEL_FORMAT_RGB: cv::cvtColor(bgr, packed, cv::COLOR_BGR2RGB); break;
    case image_t::PIXEL_FORMAT_BGR: packed = bgr; break;
    case image_t::PIXEL_FORMAT_RGBA: cv::cvtColor(bgr, packed, cv::COLOR_BGR2RGBA); break;
    case image_t::PIXEL_FORMAT_BGRA: cv::cvtColor(bgr, packed, cv::COLOR_BGR2BGRA); break;
    case image_t::PIXEL_FORMAT_YUYV:
    case image_t::PIXEL_FORMAT_UYVY:
      if (image.cols % 2 != 0)
        throw ImageFormatError("matToImage: " + std::string(f->name) +
                               " needs an even width, got " + std::to_string(image.cols));
      encodePacked422(bgr, pixelformat == image_t::PIXEL_FORMAT_YUYV, msg.data);
      msg.row_stride = image.cols * 2;
      break;
    case image_t::PIXEL_FORMAT_MJPEG: {
      const std::vector<int> params{cv::IMWRITE_JPEG_QUALITY, jpeg_quality};
      if (!cv::imencode(".jpg", image.channels() == 1 ? image : bgr, msg.data, params))
        throw ImageFormatError("matToImage: JPEG encoding failed");
      msg.row_stride = 0;
      break;
    }
    default: break;
  }
  if (!packed.empty()) {
    const size_t row = static_cast<size_t>(packed.cols) * packed.elemSize();
    msg.row_stride = static_cast<int32_t>(row);
    msg.data.resize(row * static_cast<size_t>(packed.rows));
    for (int y = 0; y < packed.rows; ++y)
      std::copy_n(packed.ptr<uint8_t>(y), row, msg.data.data() + row * static_cast<size_t>(y));
  }
  msg.size = static_cast<int32_t>(msg.data.size());
  if (seq >= 0) setImageSeq(msg, seq);
  return msg;
}

std::optional<int64_t> imageSeq(const image_t& msg) {
  for (const auto& m : msg.metadata) {
    if (m.key != "seq") continue;
    if (m.n <= 0 || static_cast<size_t>(m.n) != m.value.size() || m.n > 20) return std::nullopt;
    const char* b = reinterpret_cast<const char*>(m.value.data());
    int64_t v = 0;
    const auto r = std::from_chars(b, b + m.n, v);
    // (a negative one is no frame number: ld-run's ranges read "frames -5-29")
    if (r.ec != std::errc() || r.ptr != b + m.n || v < 0) return std::nullopt;
    return v;
  }
  return std::nullopt;
}

void setImageSeq(image_t& msg, int64_t seq) {
  char text[24];
  const auto end = std::to_chars(text, text + sizeof text, seq).ptr;
  const auto n = static_cast<int32_t>(end - text);
  auto entry = std::find_if(msg.metadata.begin(), msg.metadata.end(), [](const auto& m) { return m.key == "seq"; });
  if (entry == msg.metadata.end()) {
    entry = msg.metadata.emplace(entry);
    entry->key = "seq";
    msg.nmetadata = static_cast<int32_t>(msg.metadata.size());
  }
  entry->value.reserve(20);  // (once: any later number fits, rewritten in place)
  entry->value.assign(text, end);
  entry->n = n;
}

}  // namespace ld
