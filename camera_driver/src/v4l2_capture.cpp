#include "ld/v4l2_capture.hpp"

#include "ld/image_convert.hpp"

#include <fcntl.h>
#include <sys/mman.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

namespace ld {
namespace {

// ---------------------------------------------------------------------------
// Small helpers

// ioctl, retried while a signal interrupts it (as libv4l's xioctl does).
int xioctl(V4l2Io& io, int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = io.ioctl(fd, request, arg);
  } while (r < 0 && errno == EINTR);
  return r;
}

std::string fixedText(const uint8_t* text, size_t max) {
  const char* p = reinterpret_cast<const char*>(text);
  return std::string(p, strnlen(p, max));
}

bool deviceGone(int err) { return err == ENODEV || err == EIO || err == ENXIO; }

CaptureError::Kind kindOf(int err) {
  if (deviceGone(err)) return CaptureError::Kind::DeviceLost;
  if (err == EACCES || err == EPERM || err == EBUSY) return CaptureError::Kind::Unavailable;
  return CaptureError::Kind::Io;
}

// The one-line reason an open() failed, as ld-camera prints it.
CaptureError openError(const std::string& path, int err) {
  using K = CaptureError::Kind;
  switch (err) {
    case ENOENT:
    case ENODEV:
    case ENXIO: return CaptureError(K::NoDevice, path + ": no such device");
    case EACCES:
    case EPERM:
      return CaptureError(K::Unavailable,
                          path + ": permission denied (is the user in the 'video' group?)");
    case EBUSY: return CaptureError(K::Unavailable, path + ": busy (in use by another process)");
    default: return CaptureError(K::Io, path + ": cannot open: " + std::strerror(err));
  }
}

// Bytes per pixel of the raw formats ld-camera knows; 0 for compressed or unknown.
uint32_t bytesPerPixel(uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV:
    case V4L2_PIX_FMT_UYVY: return 2;
    case V4L2_PIX_FMT_GREY: return 1;
    case V4L2_PIX_FMT_RGB24:
    case V4L2_PIX_FMT_BGR24: return 3;
    default: return 0;
  }
}

bool isCompressed(uint32_t fourcc) {
  return fourcc == V4L2_PIX_FMT_MJPEG || fourcc == V4L2_PIX_FMT_JPEG;
}

std::string fpsNumber(double fps) {
  char buf[32];
  if (std::fabs(fps - std::round(fps)) < 1e-3) std::snprintf(buf, sizeof buf, "%.0f", fps);
  else std::snprintf(buf, sizeof buf, "%.2f", fps);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  return s;
}

double fractionFps(const v4l2_fract& interval) {
  if (interval.numerator == 0 || interval.denominator == 0) return 0;
  return static_cast<double>(interval.denominator) / interval.numerator;
}

std::string sizeText(uint32_t w, uint32_t h) { return std::to_string(w) + "x" + std::to_string(h); }

const V4l2FormatDesc* findFormat(const std::vector<V4l2FormatDesc>& formats, uint32_t fourcc) {
  for (const auto& f : formats)
    if (f.fourcc == fourcc) return &f;
  return nullptr;
}

// Rates of one frame size (VIDIOC_ENUM_FRAMEINTERVALS).
void enumerateIntervals(V4l2Io& io, int fd, uint32_t fourcc, V4l2FrameSize& size,
                        const std::string& device) {
  for (uint32_t i = 0; i < 256; ++i) {
    v4l2_frmivalenum iv{};
    iv.index = i;
    iv.pixel_format = fourcc;
    iv.width = size.width;
    iv.height = size.height;
    if (xioctl(io, fd, VIDIOC_ENUM_FRAMEINTERVALS, &iv) < 0) {
      const int err = errno;
      if (err == EINVAL || err == ENOTTY) return;  // end of the list, or not supported
      throw CaptureError(kindOf(err), device + ": VIDIOC_ENUM_FRAMEINTERVALS failed: " +
                                          std::strerror(err));
    }
    if (iv.type == V4L2_FRMIVAL_TYPE_DISCRETE) {
      if (const double fps = fractionFps(iv.discrete); fps > 0) size.fps.push_back(fps);
    } else {
      size.max_fps = fractionFps(iv.stepwise.min);
      size.min_fps = fractionFps(iv.stepwise.max);
      return;
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------
// Names

std::string fourccText(uint32_t fourcc) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    if (!std::isprint(static_cast<unsigned char>(c))) {
      char hex[16];
      std::snprintf(hex, sizeof hex, "0x%08x", fourcc);
      return hex;
    }
    s += c;
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

std::string captureFormatName(uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV: return "YUYV";
    case V4L2_PIX_FMT_MJPEG: return "MJPEG";
    case V4L2_PIX_FMT_GREY: return "GREY";
    default: return fourccText(fourcc);
  }
}

uint32_t captureFormatFromName(const std::string& name) {
  std::string up = name;
  std::transform(up.begin(), up.end(), up.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  if (up == "YUYV") return V4L2_PIX_FMT_YUYV;
  if (up == "MJPEG" || up == "MJPG") return V4L2_PIX_FMT_MJPEG;
  if (up == "GREY" || up == "GRAY") return V4L2_PIX_FMT_GREY;
  throw std::invalid_argument("unknown capture format '" + name +
                              "' (expected yuyv, mjpeg or grey)");
}

// ---------------------------------------------------------------------------
// Enumeration

bool V4l2FrameSize::contains(uint32_t w, uint32_t h) const {
  if (!isRange()) return w == width && h == height;
  if (w < min_width || w > width || h < min_height || h > height) return false;
  return (w - min_width) % step_width == 0 && (h - min_height) % std::max(1u, step_height) == 0;
}

std::string V4l2FrameSize::sizeText() const {
  if (!isRange()) return ld::sizeText(width, height);
  std::string s = ld::sizeText(min_width, min_height) + "-" + ld::sizeText(width, height);
  if (step_width > 1 || step_height > 1) s += " step " + ld::sizeText(step_width, step_height);
  return s;
}

std::string V4l2FrameSize::fpsText() const {
  if (!fps.empty()) {
    std::string s;
    for (double f : fps) s += fpsNumber(f) + " ";
    return s + "fps";
  }
  if (max_fps > 0) return fpsNumber(min_fps) + "-" + fpsNumber(max_fps) + " fps";
  return "";
}

bool V4l2FormatDesc::offers(uint32_t w, uint32_t h) const {
  return std::any_of(sizes.begin(), sizes.end(),
                     [&](const V4l2FrameSize& s) { return s.contains(w, h); });
}

std::vector<V4l2FormatDesc> enumerateFormats(V4l2Io& io, int fd, const std::string& device) {
  std::vector<V4l2FormatDesc> formats;
  for (uint32_t i = 0; i < 256; ++i) {
    v4l2_fmtdesc d{};
    d.index = i;
    d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(io, fd, VIDIOC_ENUM_FMT, &d) < 0) {
      const int err = errno;
      if (err == EINVAL) break;
      throw CaptureError(kindOf(err),
                         device + ": VIDIOC_ENUM_FMT failed: " + std::strerror(err));
    }
    V4l2FormatDesc f;
    f.fourcc = d.pixelformat;
    f.description = fixedText(d.description, sizeof d.description);
    f.compressed = (d.flags & V4L2_FMT_FLAG_COMPRESSED) != 0;
    for (uint32_t k = 0; k < 1024; ++k) {
      v4l2_frmsizeenum s{};
      s.index = k;
      s.pixel_format = f.fourcc;
      if (xioctl(io, fd, VIDIOC_ENUM_FRAMESIZES, &s) < 0) {
        const int err = errno;
        if (err == EINVAL || err == ENOTTY) break;
        throw CaptureError(kindOf(err),
                           device + ": VIDIOC_ENUM_FRAMESIZES failed: " + std::strerror(err));
      }
      V4l2FrameSize size;
      if (s.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
        size.width = s.discrete.width;
        size.height = s.discrete.height;
      } else {
        size.width = s.stepwise.max_width;
        size.height = s.stepwise.max_height;
        size.min_width = s.stepwise.min_width;
        size.min_height = s.stepwise.min_height;
        size.step_width = std::max(1u, s.stepwise.step_width);
        size.step_height = std::max(1u, s.stepwise.step_height);
      }
      enumerateIntervals(io, fd, f.fourcc, size, device);
      f.sizes.push_back(std::move(size));
      if (s.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;  // a range is the only entry
    }
    formats.push_back(std::move(f));
  }
  return formats;
}

V4l2DeviceInfo queryDevice(V4l2Io& io, const std::string& path) {
  V4l2DeviceInfo info;
  info.path = path;
  const int fd = io.open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const std::string what = openError(path, errno).what();
    info.error = what.substr(path.size() + 2);
    return info;
  }
  v4l2_capability cap{};
  if (xioctl(io, fd, VIDIOC_QUERYCAP, &cap) < 0) {
    info.error = std::string("not a V4L2 device (VIDIOC_QUERYCAP: ") + std::strerror(errno) + ")";
  } else {
    info.card = fixedText(cap.card, sizeof cap.card);
    info.driver = fixedText(cap.driver, sizeof cap.driver);
    info.bus_info = fixedText(cap.bus_info, sizeof cap.bus_info);
    const uint32_t caps =
        (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
      info.error = "not a video capture device";
      if (caps & V4L2_CAP_META_CAPTURE) info.error += " (metadata node)";
      else if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) info.error += " (multi-planar only)";
    } else if (!(caps & V4L2_CAP_STREAMING)) {
      info.error = "no streaming I/O";
    } else {
      try {
        info.formats = enumerateFormats(io, fd, path);
        info.capture = true;
      } catch (const CaptureError& e) {
        info.error = e.what();
      }
    }
  }
  io.close(fd);
  return info;
}

std::vector<V4l2DeviceInfo> listDevices(V4l2Io& io) {
  std::vector<V4l2DeviceInfo> out;
  for (const auto& path : io.deviceNodes()) out.push_back(queryDevice(io, path));
  return out;
}

std::string formatDeviceList(const std::vector<V4l2DeviceInfo>& devices) {
  if (devices.empty()) return "no V4L2 devices (no /dev/video* nodes)\n";
  std::ostringstream os;
  for (const auto& d : devices) {
    os << d.path << ":";
    if (!d.card.empty()) os << " " << d.card << " (" << d.driver << ", " << d.bus_info << ")";
    if (!d.capture) {
      os << (d.card.empty() ? " " : ": ") << d.error << "\n";
      continue;
    }
    os << "\n";
    if (d.formats.empty()) os << "  (no formats enumerated)\n";
    for (const auto& f : d.formats) {
      std::string name = captureFormatName(f.fourcc);
      name.resize(std::max<size_t>(name.size(), 6), ' ');
      os << "  " << name << " " << f.description << (f.compressed ? ", compressed" : "") << "\n";
      for (const auto& s : f.sizes) {
        std::string size = s.sizeText();
        const std::string fps = s.fpsText();
        if (!fps.empty()) size.resize(std::max<size_t>(size.size(), 11), ' ');
        os << "    " << size << (fps.empty() ? "" : " " + fps) << "\n";
      }
    }
  }
  return os.str();
}

std::string offeredFormatsText(const std::vector<V4l2FormatDesc>& formats) {
  if (formats.empty()) return "no formats";
  std::string s;
  for (const auto& f : formats) {
    if (!s.empty()) s += "; ";
    s += captureFormatName(f.fourcc);
    std::string sizes;
    for (const auto& z : f.sizes) sizes += (sizes.empty() ? " " : ", ") + z.sizeText();
    s += sizes;
  }
  return s;
}

std::string CaptureFormat::describe() const {
  std::string s = captureFormatName(fourcc) + " " + sizeText(width, height);
  if (fps > 0) s += " @ " + fpsNumber(fps) + " fps";
  if (exposure_ms > 0) s += ", exposure " + fpsNumber(exposure_ms) + " ms";
  return s + ", " + std::to_string(buffers) + " buffers";
}

// ---------------------------------------------------------------------------
// V4l2Capture

V4l2Capture::V4l2Capture(V4l2Io& io, Clock& clock) : io_(io), clock_(clock) {}

V4l2Capture::~V4l2Capture() { close(); }

void V4l2Capture::fail(const std::string& what, int err) const {
  const CaptureError::Kind kind = kindOf(err);
  if (kind == CaptureError::Kind::DeviceLost)
    throw CaptureError(kind, device_ + ": device lost (" + what + ": " + std::strerror(err) + ")");
  throw CaptureError(kind, device_ + ": " + what + " failed: " + std::strerror(err));
}

const CaptureFormat& V4l2Capture::open(const std::string& device, const CaptureRequest& request) {
  using K = CaptureError::Kind;
  close();
  device_ = device;
  format_ = {};
  offered_.clear();
  stats_ = {};
  have_sequence_ = false;

  // 1. Open, and check it is a capture device with streaming I/O.
  const int fd = io_.open(device.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw openError(device, errno);
  fd_ = fd;
  try {
    v4l2_capability cap{};
    if (xioctl(io_, fd_, VIDIOC_QUERYCAP, &cap) < 0) {
      const int err = errno;
      if (err == ENOTTY || err == EINVAL)
        throw CaptureError(K::NotCapture, device + " is not a V4L2 device");
      fail("VIDIOC_QUERYCAP", err);
    }
    format_.card = fixedText(cap.card, sizeof cap.card);
    format_.driver = fixedText(cap.driver, sizeof cap.driver);
    const uint32_t caps =
        (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    const std::string named = device + " (" + format_.card + ")";
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE)) {
      if (caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE)
        throw CaptureError(K::NotCapture,
                           named + " offers only multi-planar capture, which is not supported");
      throw CaptureError(K::NotCapture, named + " is not a video capture device" +
                                            ((caps & V4L2_CAP_META_CAPTURE)
                                                 ? std::string(" (it is a metadata node)")
                                                 : std::string()));
    }
    if (!(caps & V4L2_CAP_STREAMING))
      throw CaptureError(K::NotCapture, named + " does not support streaming I/O");
    // (a media-controller camera, as the Raspberry Pi's unicam: its pipeline
    // is set up by libcamera, and streaming alone fails with "Broken pipe")
    if (caps & V4L2_CAP_IO_MC)
      throw CaptureError(K::NotCapture, named + " is a media-controller camera (" + format_.driver +
                                            "): its pipeline needs libcamera (libcamerify ld-camera ...) or the "
                                            "legacy camera driver");

    // 2.-3. Formats, sizes, rates; set the format and the rate.
    offered_ = enumerateFormats(io_, fd_, device);
    negotiate(request);
    setFrameRate(request.fps);
    // (refused or not here, at open; set again in start(): some cameras reset it at STREAMON)
    exposure_ms_ = request.exposure_ms;
    if (exposure_ms_ > 0) setExposure(exposure_ms_);

    // 4. Buffers.
    allocateBuffers(std::max(4u, request.buffers));
  } catch (...) {
    close();
    throw;
  }
  return format_;
}

void V4l2Capture::negotiate(const CaptureRequest& request) {
  using K = CaptureError::Kind;
  v4l2_format cur{};
  cur.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(io_, fd_, VIDIOC_G_FMT, &cur) < 0) fail("VIDIOC_G_FMT", errno);

  const uint32_t fourcc = request.fourcc ? request.fourcc : cur.fmt.pix.pixelformat;
  const V4l2FormatDesc* desc = findFormat(offered_, fourcc);
  uint32_t w = request.width, h = request.height;
  if (w == 0 || h == 0) {
    w = cur.fmt.pix.width;
    h = cur.fmt.pix.height;
    if (fourcc != cur.fmt.pix.pixelformat && desc && !desc->sizes.empty() &&
        !desc->offers(w, h)) {
      w = desc->sizes.front().width;
      h = desc->sizes.front().height;
    }
  }
  const std::string refused = device_ + " does not offer " + captureFormatName(fourcc) + " " +
                              sizeText(w, h) + "; it offers: " + offeredFormatsText(offered_);
  // A driver that enumerates nothing (or no sizes of the format) is trusted
  // to say what it took in S_FMT.
  if (!offered_.empty() && (!desc || (!desc->sizes.empty() && !desc->offers(w, h))))
    throw CaptureError(K::FormatRefused, refused);

  v4l2_format f{};
  f.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  f.fmt.pix.width = w;
  f.fmt.pix.height = h;
  f.fmt.pix.pixelformat = fourcc;
  f.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(io_, fd_, VIDIOC_S_FMT, &f) < 0) {
    const int err = errno;
    if (err == EBUSY)
      throw CaptureError(K::Unavailable,
                         device_ + ": busy (another process is streaming from it)");
    if (err == EINVAL) throw CaptureError(K::FormatRefused, refused);
    fail("VIDIOC_S_FMT", err);
  }
  // Drivers do not fail S_FMT for a format they lack: they substitute one.
  if (f.fmt.pix.pixelformat != fourcc || f.fmt.pix.width != w || f.fmt.pix.height != h)
    throw CaptureError(K::FormatRefused,
                       refused + " (the driver substituted " +
                           captureFormatName(f.fmt.pix.pixelformat) + " " +
                           sizeText(f.fmt.pix.width, f.fmt.pix.height) + ")");

  format_.fourcc = fourcc;
  format_.width = w;
  format_.height = h;
  bytes_per_pixel_ = bytesPerPixel(fourcc);
  compressed_ = isCompressed(fourcc) || (desc && desc->compressed);
  if (compressed_) bytes_per_pixel_ = 0;
  format_.bytesperline = f.fmt.pix.bytesperline;
  format_.sizeimage = f.fmt.pix.sizeimage;
  if (bytes_per_pixel_ > 0) {
    format_.bytesperline = std::max(format_.bytesperline, w * bytes_per_pixel_);
    format_.sizeimage = std::max(format_.sizeimage, format_.bytesperline * h);
  } else if (compressed_) {
    format_.bytesperline = 0;
  }
}

void V4l2Capture::setFrameRate(double fps) {
  v4l2_streamparm p{};
  p.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(io_, fd_, VIDIOC_G_PARM, &p) < 0) {
    const int err = errno;
    if (deviceGone(err)) fail("VIDIOC_G_PARM", err);
    format_.fps = 0;  // the driver has no frame-rate control
    return;
  }
  if (fps > 0 && (p.parm.capture.capability & V4L2_CAP_TIMEPERFRAME)) {
    // The nearest enumerated rate of this size, when the driver lists them.
    double chosen = fps;
    if (const V4l2FormatDesc* desc = findFormat(offered_, format_.fourcc)) {
      for (const auto& s : desc->sizes) {
        if (!s.contains(format_.width, format_.height)) continue;
        if (!s.fps.empty())
          chosen = *std::min_element(s.fps.begin(), s.fps.end(), [&](double a, double b) {
            return std::fabs(a - fps) < std::fabs(b - fps);
          });
        else if (s.max_fps > 0)
          chosen = std::clamp(fps, s.min_fps, s.max_fps);
        break;
      }
    }
    v4l2_streamparm set{};
    set.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    set.parm.capture.timeperframe.numerator = 1000;
    set.parm.capture.timeperframe.denominator = static_cast<uint32_t>(std::lround(chosen * 1000));
    if (xioctl(io_, fd_, VIDIOC_S_PARM, &set) < 0) {
      const int err = errno;
      if (deviceGone(err)) fail("VIDIOC_S_PARM", err);
    } else {
      p = set;  // the driver writes back the rate it took
    }
  }
  format_.fps = fractionFps(p.parm.capture.timeperframe);
}

void V4l2Capture::setExposure(double ms) {
  using K = CaptureError::Kind;
  exposure_busy_ = false;
  const std::string named = deviceAndCard();
  v4l2_queryctrl q{};
  q.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  const int rc = xioctl(io_, fd_, VIDIOC_QUERYCTRL, &q);
  const int err = rc < 0 ? errno : 0;
  if (deviceGone(err)) fail("VIDIOC_QUERYCTRL", err);
  if (rc < 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED))
    throw CaptureError(K::ControlRefused, named + " has no manual exposure control (V4L2_CID_EXPOSURE_ABSOLUTE; "
                                                  "v4l2-ctl -d " + device_ + " -l lists its controls): run without the exposure");
  // What close() puts back: the camera is left as it was found.
  v4l2_control mode{}, time{};
  mode.id = V4L2_CID_EXPOSURE_AUTO;
  time.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  // (once per open: a start() after a stop() finds the values set before)
  if (saved_exposure_mode_ < 0 && saved_exposure_time_ < 0) {
    saved_exposure_mode_ = xioctl(io_, fd_, VIDIOC_G_CTRL, &mode) == 0 ? mode.value : -1;
    saved_exposure_time_ = xioctl(io_, fd_, VIDIOC_G_CTRL, &time) == 0 ? time.value : -1;
  }
  // Automatic exposure off first: while it is on, drivers may refuse the time
  // (EACCES, as the fake does) or overwrite it. A device without the switch
  // (EINVAL) has only the manual time.
  mode.value = V4L2_EXPOSURE_MANUAL;
  if (xioctl(io_, fd_, VIDIOC_S_CTRL, &mode) < 0 && errno != EINVAL) {
    const int e = errno;
    // (the firmware refused it, or the driver while streaming; the device is there)
    exposure_busy_ = e == EBUSY;
    if (e == EIO || e == EILSEQ || e == EBUSY)
      throw CaptureError(K::ControlRefused, named + " refused to turn its automatic exposure off (" +
                                                std::strerror(e) + "): run without the exposure");
    fail("VIDIOC_S_CTRL (automatic exposure off)", e);
  }
  // In the control's unit (100 us), within its range (clamped as a double:
  // any finite time the command line takes), on its steps.
  const int64_t step = std::max(1, q.step);
  const double want = std::clamp(ms * 10, static_cast<double>(q.minimum), static_cast<double>(q.maximum));
  int64_t units = q.minimum + (std::llround(want) - q.minimum + step / 2) / step * step;
  if (units > q.maximum) units -= step;
  time.value = static_cast<int32_t>(units);
  if (xioctl(io_, fd_, VIDIOC_S_CTRL, &time) < 0) {
    const int e = errno;
    // (EIO: uvcvideo's answer for a control the firmware lacks; EILSEQ:
    // older kernels' for a time refused while auto exposure stays on)
    if (e == EBUSY) {  // (a control the driver takes only while not streaming)
      exposure_busy_ = true;
      throw CaptureError(K::ControlRefused, named + " refused the exposure time" +
                                                (streaming_ ? " while streaming" : "") + " (" + std::strerror(e) + ")");
    }
    if (e == EACCES || e == EPERM || e == EIO || e == EILSEQ)
      throw CaptureError(K::ControlRefused, named + " refused the exposure time (" + std::strerror(e) +
                                                "): its automatic exposure could not be turned off");
    fail("VIDIOC_S_CTRL (exposure time)", e);
  }
  if (xioctl(io_, fd_, VIDIOC_G_CTRL, &time) < 0) fail("VIDIOC_G_CTRL (exposure time)", errno);
  format_.exposure_ms = time.value / 10.0;
}

void V4l2Capture::restoreExposure() noexcept {
  if (saved_exposure_mode_ < 0 && saved_exposure_time_ < 0) return;
  v4l2_control c{};
  if (saved_exposure_time_ >= 0) {
    c.id = V4L2_CID_EXPOSURE_ABSOLUTE;
    c.value = saved_exposure_time_;
    xioctl(io_, fd_, VIDIOC_S_CTRL, &c);
  }
  if (saved_exposure_mode_ >= 0) {
    c.id = V4L2_CID_EXPOSURE_AUTO;
    c.value = saved_exposure_mode_;
    xioctl(io_, fd_, VIDIOC_S_CTRL, &c);
  }
  saved_exposure_mode_ = saved_exposure_time_ = -1;
}

void V4l2Capture::allocateBuffers(unsigned count) {
  using K = CaptureError::Kind;
  v4l2_requestbuffers rb{};
  rb.count = count;
  rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  rb.memory = V4L2_MEMORY_MMAP;
  if (xioctl(io_, fd_, VIDIOC_REQBUFS, &rb) < 0) {
    const int err = errno;
    if (err == EINVAL)
      throw CaptureError(K::NotCapture,
                         device_ + " does not support memory-mapped streaming");
    if (err == EBUSY)
      throw CaptureError(K::Unavailable,
                         device_ + ": busy (another process is streaming from it)");
    fail("VIDIOC_REQBUFS", err);
  }
  if (rb.count < 2)
    throw CaptureError(K::Io, device_ + ": the driver granted " + std::to_string(rb.count) +
                                  " buffer(s); capture needs at least 2");
  buffers_.resize(rb.count);
  for (uint32_t i = 0; i < rb.count; ++i) {
    v4l2_buffer b{};
    b.index = i;
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (xioctl(io_, fd_, VIDIOC_QUERYBUF, &b) < 0) fail("VIDIOC_QUERYBUF", errno);
    void* p = io_.mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                       static_cast<off_t>(b.m.offset));
    if (p == MAP_FAILED) fail("mmap of buffer " + std::to_string(i), errno);
    buffers_[i].start = p;
    buffers_[i].length = b.length;
    buffers_[i].state = BufferState::Dequeued;
  }
  format_.buffers = rb.count;
}

void V4l2Capture::queue(uint32_t index) {
  v4l2_buffer b{};
  b.index = index;
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  if (xioctl(io_, fd_, VIDIOC_QBUF, &b) < 0) fail("VIDIOC_QBUF", errno);
  buffers_[index].state = BufferState::Queued;
}

void V4l2Capture::start() {
  if (!isOpen()) throw std::logic_error("V4l2Capture::start: not open");
  if (streaming_) return;
  // 5. Queue every buffer the caller does not hold, then stream.
  for (uint32_t i = 0; i < buffers_.size(); ++i)
    if (buffers_[i].state == BufferState::Dequeued) queue(i);
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(io_, fd_, VIDIOC_STREAMON, &type) < 0) {
    const int err = errno;
    // (uvcvideo's answer when the USB bus has not the bandwidth the format needs)
    if (err == ENOSPC)
      throw CaptureError(CaptureError::Kind::Io,
                         device_ + ": not enough USB bandwidth for " + format_.describe() +
                             " (VIDIOC_STREAMON: No space left on device): use MJPEG, a smaller size or rate, or "
                             "another USB port or controller");
    fail("VIDIOC_STREAMON", err);
  }
  streaming_ = true;
  have_sequence_ = false;
  raw_bytesused_set_ = false;
  // The manual exposure again once streaming: cameras such as the Logitech
  // C920 set their exposure time again at STREAMON, auto exposure off or not.
  if (exposure_ms_ > 0) {
    const double set_at_open = format_.exposure_ms;
    try {
      setExposure(exposure_ms_);
    } catch (const CaptureError& e) {
      // A camera that takes no control while streaming (EBUSY, and that
      // alone) keeps the exposure set before STREAMON: manual, at that time,
      // unless STREAMON changed either.
      if (e.kind() != CaptureError::Kind::ControlRefused || !exposure_busy_) throw;
      const std::optional<std::string> changed = exposureChangedAtStreamon(set_at_open);
      if (!changed) throw;
      if (!changed->empty())
        throw CaptureError(CaptureError::Kind::ControlRefused,
                           deviceAndCard() + " takes no exposure control while streaming, and STREAMON " + *changed +
                               ": run without the exposure");
      format_.exposure_ms = set_at_open;
    }
  }
}

std::optional<std::string> V4l2Capture::exposureChangedAtStreamon(double set_at_open) {
  v4l2_control time{}, mode{};
  time.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  mode.id = V4L2_CID_EXPOSURE_AUTO;
  if (xioctl(io_, fd_, VIDIOC_G_CTRL, &time) < 0) {
    const int err = errno;
    if (deviceGone(err)) fail("VIDIOC_G_CTRL (exposure time)", err);
    return std::nullopt;
  }
  std::string changed;
  if (xioctl(io_, fd_, VIDIOC_G_CTRL, &mode) < 0) {
    const int err = errno;
    if (deviceGone(err)) fail("VIDIOC_G_CTRL (automatic exposure)", err);
    if (err != EINVAL) return std::nullopt;  // (EINVAL: no such switch, the time alone)
  } else if (mode.value != V4L2_EXPOSURE_MANUAL) {
    changed = "turned its automatic exposure on again";
  }
  if (time.value / 10.0 != set_at_open)
    changed += (changed.empty() ? "" : " and ") + std::string("changed its exposure time from ") +
               fpsNumber(set_at_open) + " to " + fpsNumber(time.value / 10.0) + " ms";
  return changed;
}

size_t V4l2Capture::usedBytes(const v4l2_buffer& b) {
  const Buffer& buf = buffers_[b.index];
  if (b.flags & V4L2_BUF_FLAG_ERROR) {  // e.g. lost USB packets: data unreliable
    ++stats_.errored;
    return 0;
  }
  size_t used = b.bytesused;
  if (compressed_) {
    // (uvcvideo checks the size of raw frames alone: a JPEG cut short comes
    // without the error flag)
    if (used == 0 || used > buf.length ||
        (format_.fourcc == V4L2_PIX_FMT_MJPEG && !jpegComplete(static_cast<const uint8_t*>(buf.start), used))) {
      ++stats_.truncated;
      return 0;
    }
    return used;
  }
  // (0: a driver that never sets bytesused for raw frames, which has its
  // frames whole; once it has set it, an empty buffer is no frame)
  if (used == 0 && raw_bytesused_set_) {
    ++stats_.truncated;
    return 0;
  }
  if (used == 0) used = std::min<size_t>(buf.length, format_.sizeimage);
  else raw_bytesused_set_ = true;
  const size_t need = bytes_per_pixel_ > 0
                          ? static_cast<size_t>(format_.bytesperline) * (format_.height - 1) +
                                static_cast<size_t>(format_.width) * bytes_per_pixel_
                          : static_cast<size_t>(format_.bytesperline) * format_.height;
  used = std::min(used, buf.length);
  if (used < need) {
    ++stats_.truncated;
    return 0;
  }
  return used;
}

bool V4l2Capture::grab(Frame& frame, int timeout_ms) {
  using K = CaptureError::Kind;
  if (!streaming_) throw std::logic_error("V4l2Capture::grab: not streaming");
  if (std::none_of(buffers_.begin(), buffers_.end(),
                   [](const Buffer& b) { return b.state == BufferState::Queued; }))
    throw std::logic_error("V4l2Capture::grab: every buffer is held; requeue() frames first");

  // 6. Wait for a filled buffer, dequeue it.
  pollfd p{fd_, POLLIN, 0};
  const int r = io_.poll(&p, 1, timeout_ms);
  if (r < 0) {
    if (errno == EINTR) return false;
    fail("poll", errno);
  }
  if (r == 0) return false;
  if (p.revents & POLLNVAL) throw CaptureError(K::Io, device_ + ": poll: invalid descriptor");

  // Then every other filled buffer, without waiting: the newest good frame
  // is handed out and the older ones go back to the driver, counted as
  // stale (a consumer slower than the camera gets the present, not frames
  // up to its buffers old, and the camera drops the oldest, not the newest).
  v4l2_buffer b{};  // the frame kept
  size_t used = 0;
  bool got = false;
  // (bounded: a driver that filled buffers as fast as they are given back
  // would keep this loop going)
  for (size_t n = 0; n < 2 * buffers_.size(); ++n) {
    const bool first = n == 0;
    v4l2_buffer d{};
    d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    d.memory = V4L2_MEMORY_MMAP;
    if (xioctl(io_, fd_, VIDIOC_DQBUF, &d) < 0) {
      const int err = errno;
      // (drained; or an error with a frame in hand: that frame is handed
      // out, and the next grab meets the error again)
      if (got) break;
      if (err == EAGAIN && !first) break;  // (only bad frames were waiting)
      if (err == EAGAIN) {
        // A wakeup with nothing to dequeue. With POLLERR that would repeat at
        // once forever: the device is in an error state.
        if (p.revents & POLLERR)
          throw CaptureError(K::Io, device_ + ": the device reports an error (POLLERR)");
        ++stats_.spurious;
        return false;
      }
      fail("VIDIOC_DQBUF", err);
    }
    if (d.index >= buffers_.size())
      throw CaptureError(K::Io, device_ + ": VIDIOC_DQBUF returned buffer " +
                                    std::to_string(d.index) + " of " +
                                    std::to_string(buffers_.size()));
    buffers_[d.index].state = BufferState::Held;
    // (every frame dequeued, good or not, counts for the driver's gaps: a
    // frame cut short is no frame the driver dropped)
    if (have_sequence_ && d.sequence > last_sequence_ + 1)
      stats_.sequence_gaps += d.sequence - last_sequence_ - 1;
    have_sequence_ = true;
    last_sequence_ = d.sequence;
    const size_t good = usedBytes(d);
    if (good == 0) {  // (flagged or cut short: counted, and given back)
      queue(d.index);
      continue;
    }
    if (got) {
      queue(b.index);
      ++stats_.stale;
    }
    b = d;
    used = good;
    got = true;
  }
  if (!got) return false;
  Buffer& buf = buffers_[b.index];

  // The driver's timestamp is CLOCK_MONOTONIC; utime is wall-clock time.
  const int64_t now_mono = clock_.monotonicUs();
  const int64_t now_real = clock_.realtimeUs();
  const int64_t ts = static_cast<int64_t>(b.timestamp.tv_sec) * 1000000 + b.timestamp.tv_usec;
  const bool monotonic =
      (b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC && ts > 0;
  frame.data = static_cast<const uint8_t*>(buf.start);
  frame.bytesused = used;
  frame.fourcc = format_.fourcc;
  frame.width = format_.width;
  frame.height = format_.height;
  frame.bytesperline = format_.bytesperline;
  frame.driver_timestamp = monotonic;
  frame.monotonic_us = monotonic ? ts : now_mono;
  frame.utime = frame.monotonic_us + (now_real - now_mono);
  frame.sequence = b.sequence;
  frame.seq = b.sequence;
  frame.index = static_cast<int>(b.index);
  ++stats_.frames;
  return true;
}

void V4l2Capture::requeue(const Frame& frame) {
  if (frame.index < 0 || static_cast<size_t>(frame.index) >= buffers_.size() ||
      buffers_[frame.index].state != BufferState::Held)
    throw std::logic_error("V4l2Capture::requeue: the frame's buffer is not held");
  queue(static_cast<uint32_t>(frame.index));
}

void V4l2Capture::stop() {
  if (!streaming_) return;
  streaming_ = false;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  // STREAMOFF takes back every queued buffer; held ones stay with the caller.
  for (auto& b : buffers_)
    if (b.state == BufferState::Queued) b.state = BufferState::Dequeued;
  if (xioctl(io_, fd_, VIDIOC_STREAMOFF, &type) < 0 && !deviceGone(errno))
    fail("VIDIOC_STREAMOFF", errno);
}

void V4l2Capture::close() noexcept {
  if (fd_ < 0) return;
  // 7. Stop, unmap, free, close. Errors are ignored: the device may be gone.
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(io_, fd_, VIDIOC_STREAMOFF, &type);
    streaming_ = false;
  }
  bool mapped = false;
  for (auto& b : buffers_) {
    if (b.start) {
      io_.munmap(b.start, b.length);
      mapped = true;
    }
  }
  buffers_.clear();
  if (mapped) {
    v4l2_requestbuffers rb{};
    rb.count = 0;
    rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    rb.memory = V4L2_MEMORY_MMAP;
    xioctl(io_, fd_, VIDIOC_REQBUFS, &rb);
  }
  restoreExposure();
  io_.close(fd_);
  fd_ = -1;
}

// ---------------------------------------------------------------------------
// Reconnecting

int64_t Backoff::nextDelayUs() {
  double d = policy_.initial_s;
  for (int i = 0; i < attempts_ && d < policy_.max_s; ++i) d *= policy_.factor;
  ++attempts_;
  return std::llround(std::min(d, policy_.max_s) * 1e6);
}

ReconnectingCapture::ReconnectingCapture(V4l2Io& io, Clock& clock, std::string device,
                                         CaptureRequest request, BackoffPolicy policy, Log log)
    : capture_(io, clock),
      clock_(clock),
      device_(std::move(device)),
      request_(request),
      backoff_(policy),
      policy_(policy),
      log_(std::move(log)) {}

const CaptureFormat& ReconnectingCapture::start() {
  capture_.open(device_, request_);
  capture_.start();
  down_ = false;
  rebase_ = next_seq_ > 0;  // started again after stop(): the numbering goes on
  last_frame_us_ = clock_.monotonicUs();
  return capture_.format();
}

CaptureStats ReconnectingCapture::totals() const {
  CaptureStats t = closed_;
  if (capture_.isOpen()) t += capture_.stats();  // (a closed capture's counts are in closed_)
  return t;
}

int64_t ReconnectingCapture::stallLimitUs() const {
  const double fps = capture_.format().fps > 0 ? capture_.format().fps : 30.0;
  // (a long manual exposure lowers the rate the camera keeps)
  return std::max<int64_t>({2000000, std::llround(10e6 / fps), std::llround(3e3 * capture_.format().exposure_ms)});
}

void ReconnectingCapture::lost(const std::string& why) {
  closed_ = totals();
  capture_.close();
  down_ = true;
  // Lost again before a good frame came since the last reopening (a camera
  // whose firmware stays stalled, or sends bad frames alone): the backoff
  // goes on growing and nothing more is logged until a good frame comes.
  const bool again = reopened_ && !good_since_open_;
  lost_at_us_ = clock_.monotonicUs();
  if (!again) {
    backoff_.reset();
    attempts_ = 0;
    last_error_.clear();
  }
  quiet_ = again;
  next_attempt_us_ = lost_at_us_ + backoff_.nextDelayUs();
  if (log_ && !again)
    log_(why + "; reopening every " + fpsNumber(policy_.initial_s) + "-" +
         fpsNumber(policy_.max_s) + " s until it is back");
}

bool ReconnectingCapture::tryReopen(int timeout_ms) {
  int64_t now = clock_.monotonicUs();
  if (now < next_attempt_us_) {
    clock_.sleepUs(std::min<int64_t>(next_attempt_us_ - now, int64_t{timeout_ms} * 1000));
    now = clock_.monotonicUs();
    if (now < next_attempt_us_) return false;
  }
  ++attempts_;
  try {
    capture_.open(device_, request_);
    capture_.start();
  } catch (const CaptureError& e) {
    capture_.close();
    // A missing device is what reopening expects; anything else is logged
    // when it changes, not at every attempt.
    if (e.kind() != CaptureError::Kind::NoDevice && last_error_ != e.what()) {
      last_error_ = e.what();
      if (log_) log_("still reopening: " + last_error_);
    }
    next_attempt_us_ = clock_.monotonicUs() + backoff_.nextDelayUs();
    return false;
  }
  down_ = false;
  rebase_ = true;
  ++reconnects_;
  last_frame_us_ = clock_.monotonicUs();
  reopened_ = true;
  good_since_open_ = false;
  if (log_ && !quiet_) {
    char secs[32];
    std::snprintf(secs, sizeof secs, "%.1f", (clock_.monotonicUs() - lost_at_us_) / 1e6);
    log_(device_ + ": reopened after " + std::to_string(attempts_) + " attempt" +
         (attempts_ == 1 ? "" : "s") + " (" + secs + " s): " + capture_.format().describe());
  }
  return true;
}

bool ReconnectingCapture::grab(Frame& frame, int timeout_ms) {
  if (down_ && !tryReopen(timeout_ms)) return false;
  try {
    if (!capture_.grab(frame, timeout_ms)) {
      const int64_t quiet = clock_.monotonicUs() - last_frame_us_;
      if (quiet > stallLimitUs()) {
        char secs[32];
        std::snprintf(secs, sizeof secs, "%.1f", quiet / 1e6);
        const CaptureStats now = totals();
        const int64_t bad = now.errored + now.truncated - bad_at_good_;
        lost(device_ + ": no good frame for " + secs + " s while streaming (" +
             (bad > 0 ? std::to_string(bad) + " flagged bad or cut short" : std::string("the camera stalled")) +
             ")");
      }
      return false;
    }
  } catch (const CaptureError& e) {
    if (e.kind() != CaptureError::Kind::DeviceLost && e.kind() != CaptureError::Kind::Io) throw;
    lost(e.what());
    return false;
  }
  last_frame_us_ = clock_.monotonicUs();
  good_since_open_ = true;
  quiet_ = false;
  {
    const CaptureStats now = totals();
    bad_at_good_ = now.errored + now.truncated;
  }
  if (rebase_) {
    seq_base_ = next_seq_ - frame.sequence;
    rebase_ = false;
  }
  frame.seq = seq_base_ + frame.sequence;
  next_seq_ = frame.seq + 1;
  return true;
}

void ReconnectingCapture::requeue(const Frame& frame) {
  if (down_) return;  // the buffers went with the device
  try {
    capture_.requeue(frame);
  } catch (const CaptureError& e) {
    if (e.kind() != CaptureError::Kind::DeviceLost && e.kind() != CaptureError::Kind::Io) throw;
    lost(e.what());
  }
}

void ReconnectingCapture::stop() noexcept {
  closed_ = totals();
  capture_.close();
  down_ = false;
}

}  // namespace ld
