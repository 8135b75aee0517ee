#include "ld/fake_v4l2.hpp"

#include <fcntl.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <deque>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "ld/image_convert.hpp"

namespace ld {
namespace {

constexpr uint32_t kPage = 4096;
// A UVC webcam's exposure time control, in 100 us: its range and power-on value.
constexpr int32_t kExposureMin = 3, kExposureMax = 2047, kExposureDefault = 156;

bool hasExposureControl(const FakeCameraSpec& spec, uint32_t id) {
  if (!spec.exposure_control) return false;
  return id == V4L2_CID_EXPOSURE_ABSOLUTE || (id == V4L2_CID_EXPOSURE_AUTO && spec.exposure_auto_control);
}

template <size_t N>
void copyText(uint8_t (&dst)[N], const std::string& src) {
  std::memset(dst, 0, N);
  std::memcpy(dst, src.data(), std::min(N - 1, src.size()));
}

uint32_t rawBytesPerPixel(uint32_t fourcc) {
  switch (fourcc) {
    case V4L2_PIX_FMT_YUYV: return 2;
    case V4L2_PIX_FMT_GREY: return 1;
    default: return 0;
  }
}

int fail(int err) {
  errno = err;
  return -1;
}

}  // namespace

// ---------------------------------------------------------------------------
// Specs

FakeCameraSpec FakeCameraSpec::webcam(const std::string& path) {
  FakeCameraSpec s;
  s.path = path;
  s.formats = {
      {V4L2_PIX_FMT_YUYV, "YUYV 4:2:2", {{640, 480, {30, 15}}, {320, 240, {30, 15}}, {1280, 720, {10}}}},
      {V4L2_PIX_FMT_MJPEG, "Motion-JPEG", {{1280, 720, {30, 15}}, {640, 480, {30, 15}}, {320, 240, {30, 15}}}},
      {V4L2_PIX_FMT_GREY, "8-bit Greyscale", {{640, 480, {30}}}},
  };
  return s;
}

FakeCameraSpec FakeCameraSpec::metadataNode(const std::string& path) {
  FakeCameraSpec s;
  s.path = path;
  s.device_caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
  s.formats = {};
  return s;
}

// ---------------------------------------------------------------------------
// State

struct FakeV4l2Device::Node {
  FakeCameraSpec spec;
  bool present = true;
  int generation = 0;
  int open_error = 0;

  v4l2_pix_format fmt{};
  uint32_t fps = 30;
  int owner_fd = -1;
  int32_t exposure_mode = V4L2_EXPOSURE_APERTURE_PRIORITY, exposure_time = kExposureDefault;

  enum class State { Dequeued, Queued, Done };
  struct Buf {
    std::shared_ptr<std::vector<uint8_t>> memory;
    uint32_t length = 0, offset = 0;
    State state = State::Dequeued;
    bool mapped = false;
    uint32_t bytesused = 0, sequence = 0, flags = 0;
    timeval timestamp{};
  };
  std::vector<Buf> bufs;
  std::deque<uint32_t> queued, done;
  bool streaming = false;
  int64_t stream_start_us = 0;
  int64_t frames_due = 0;  // frame slots elapsed since STREAMON
  uint32_t sequence = 0;

  int64_t unplug_after_frames = -1, replug_after_us = -1, replug_at_us = -1;
  bool stalled = false, wedged = false;  // (wedged: stalled through STREAMON too)
  Stats stats;

  bool captures() const { return (spec.device_caps & V4L2_CAP_VIDEO_CAPTURE) != 0; }
  int64_t intervalUs() const { return 1000000 / std::max(1u, fps); }

  const FakeFormat* findFormat(uint32_t fourcc) const {
    for (const auto& f : spec.formats)
      if (f.fourcc == fourcc) return &f;
    return nullptr;
  }

  // What S_FMT / TRY_FMT make of a request: a format and size the device
  // has, the nearest to what was asked.
  v4l2_pix_format adjust(const v4l2_pix_format& want) const {
    const FakeFormat* f = findFormat(want.pixelformat);
    if (!f) f = &spec.formats.front();
    // (a format that lists no sizes, as some capture cards': any size taken)
    const FakeFrameSize any{std::max(16u, want.width), std::max(16u, want.height), {}};
    const FakeFrameSize* best = f->sizes.empty() ? &any : &f->sizes.front();
    int64_t best_d = std::numeric_limits<int64_t>::max();
    for (const auto& s : f->sizes) {
      const int64_t d = std::abs(int64_t{s.width} * s.height - int64_t{want.width} * want.height) +
                        std::abs(int64_t{s.width} - want.width);
      if (d < best_d) {
        best_d = d;
        best = &s;
      }
    }
    v4l2_pix_format p{};
    p.width = best->width;
    p.height = best->height;
    p.pixelformat = f->fourcc;
    p.field = V4L2_FIELD_NONE;
    p.colorspace = V4L2_COLORSPACE_SRGB;
    const uint32_t bpp = rawBytesPerPixel(f->fourcc);
    if (bpp) {
      p.bytesperline = p.width * bpp + spec.row_padding;
      p.sizeimage = p.bytesperline * p.height;
    } else {
      p.bytesperline = 0;
      p.sizeimage = p.width * p.height * 2;  // what UVC reports as the largest frame
    }
    return p;
  }

  const FakeFrameSize* currentSize() const {
    const FakeFormat* f = findFormat(fmt.pixelformat);
    if (!f) return nullptr;
    for (const auto& s : f->sizes)
      if (s.width == fmt.width && s.height == fmt.height) return &s;
    return nullptr;
  }

  uint32_t nearestFps(uint32_t want) const {
    const FakeFrameSize* s = currentSize();
    if (!s || s->fps.empty()) return 30;
    return *std::min_element(s->fps.begin(), s->fps.end(), [&](uint32_t a, uint32_t b) {
      return std::abs(int64_t{a} - want) < std::abs(int64_t{b} - want);
    });
  }

  void powerOn() {
    stalled = wedged = false;
    fmt = {};
    fps = 30;
    exposure_mode = V4L2_EXPOSURE_APERTURE_PRIORITY;
    exposure_time = kExposureDefault;
    if (captures() && !spec.formats.empty()) {
      v4l2_pix_format want{};
      want.pixelformat = spec.formats.front().fourcc;
      const auto& sizes = spec.formats.front().sizes;  // (a format may list none)
      want.width = sizes.empty() ? 640 : sizes.front().width;
      want.height = sizes.empty() ? 480 : sizes.front().height;
      fmt = adjust(want);
      fps = nearestFps(fps);
    }
  }

  void dropQueue() {
    streaming = false;
    queued.clear();
    done.clear();
    for (auto& b : bufs) b.state = State::Dequeued;
  }
};

struct FakeV4l2Device::Handle {
  Node* node;
  int generation;
  bool nonblock;
};

FakeV4l2Device::FakeV4l2Device(Clock& clock, std::vector<FakeCameraSpec> nodes) : clock_(clock) {
  for (auto& spec : nodes) {
    auto n = std::make_unique<Node>();
    n->spec = std::move(spec);
    n->powerOn();
    nodes_.push_back(std::move(n));
  }
}

FakeV4l2Device::~FakeV4l2Device() = default;

FakeV4l2Device::Node* FakeV4l2Device::findNode(const std::string& path) {
  for (auto& n : nodes_)
    if (n->spec.path == path) return n.get();
  return nullptr;
}

const FakeV4l2Device::Node* FakeV4l2Device::findNode(const std::string& path) const {
  for (const auto& n : nodes_)
    if (n->spec.path == path) return n.get();
  return nullptr;
}

FakeV4l2Device::Node* FakeV4l2Device::nodeOf(int fd, int* err) {
  const auto it = fds_.find(fd);
  if (it == fds_.end()) {
    *err = EBADF;
    return nullptr;
  }
  Node* n = it->second.node;
  if (!n->present || it->second.generation != n->generation) {
    *err = ENODEV;
    return nullptr;
  }
  return n;
}

void FakeV4l2Device::checkReplug() {
  const int64_t now = clock_.monotonicUs();
  for (auto& n : nodes_)
    if (!n->present && n->replug_at_us >= 0 && now >= n->replug_at_us) replug(n->spec.path);
}

// ---------------------------------------------------------------------------
// Fault injection

void FakeV4l2Device::unplug(const std::string& path) {
  Node* n = findNode(path);
  if (!n || !n->present) return;
  n->present = false;
  ++n->generation;  // descriptors opened before this are dead for good
  n->dropQueue();
  n->bufs.clear();  // mapped memory lives on in mappings_ until munmap
  n->owner_fd = -1;
  n->unplug_after_frames = -1;
  n->replug_at_us = n->replug_after_us >= 0 ? clock_.monotonicUs() + n->replug_after_us : -1;
}

void FakeV4l2Device::replug(const std::string& path) {
  Node* n = findNode(path);
  if (!n || n->present) return;
  n->present = true;
  n->replug_at_us = -1;
  n->powerOn();
}

void FakeV4l2Device::scheduleUnplug(const std::string& path, int64_t after_frames,
                                    int64_t replug_after_us) {
  if (Node* n = findNode(path)) {
    n->unplug_after_frames = n->stats.frames + after_frames;
    n->replug_after_us = replug_after_us;
  }
}

void FakeV4l2Device::stall(const std::string& path, bool wedged) {
  if (Node* n = findNode(path)) {
    n->stalled = true;
    n->wedged = wedged;
  }
}

void FakeV4l2Device::failIoctl(unsigned long request, int err, int times) {
  faults_.push_back({request, err, times});
}

void FakeV4l2Device::failOpen(const std::string& path, int err) {
  if (Node* n = findNode(path)) n->open_error = err;
}

FakeV4l2Device::Stats FakeV4l2Device::stats(const std::string& path) const {
  const Node* n = findNode(path);
  if (!n) return {};
  Stats s = n->stats;
  s.open_fds = static_cast<int>(std::count_if(
      fds_.begin(), fds_.end(), [&](const auto& kv) { return kv.second.node == n; }));
  s.live_mappings = static_cast<int>(std::count_if(
      mappings_.begin(), mappings_.end(), [&](const auto& kv) { return kv.second.node == n; }));
  s.allocated_buffers = static_cast<uint32_t>(n->bufs.size());
  return s;
}

v4l2_pix_format FakeV4l2Device::currentFormat(const std::string& path) const {
  const Node* n = findNode(path);
  return n ? n->fmt : v4l2_pix_format{};
}

FakeV4l2Device::Exposure FakeV4l2Device::exposure(const std::string& path) const {
  const Node* n = findNode(path);
  return n ? Exposure{n->exposure_mode, n->exposure_time} : Exposure{};
}

// ---------------------------------------------------------------------------
// Frames

cv::Mat FakeV4l2Device::pattern(uint32_t width, uint32_t height, uint32_t sequence) {
  const int w = static_cast<int>(width), h = static_cast<int>(height);
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y) {
    auto* p = img.ptr<cv::Vec3b>(y);
    for (int x = 0; x < w; ++x)
      p[x] = cv::Vec3b(static_cast<uint8_t>(255 * x / std::max(1, w - 1)),
                       static_cast<uint8_t>(255 * y / std::max(1, h - 1)), 96);
  }
  const int side = std::max(8, h / 4);
  const int x0 = static_cast<int>((int64_t{sequence} * 8) % std::max(1, w - side));
  const int y0 = (h - side) / 2;
  cv::rectangle(img, cv::Rect(x0, y0, side, side), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(img, std::to_string(sequence), cv::Point(x0 + side / 10, y0 + side * 6 / 10),
              cv::FONT_HERSHEY_SIMPLEX, side / 80.0, cv::Scalar(0, 0, 0),
              std::max(1, side / 40));
  return img;
}

int64_t FakeV4l2Device::nextDueUs(const Node& node) const {
  return node.stream_start_us + (node.frames_due + 1) * node.intervalUs();
}

void FakeV4l2Device::capture(Node& node, uint32_t index, int64_t time_us) {
  Node::Buf& b = node.bufs[index];
  uint8_t* dst = b.memory->data();
  const v4l2_pix_format& f = node.fmt;
  const cv::Mat img = pattern(f.width, f.height, node.sequence);
  b.flags = node.spec.timestamp_flags;
  if (f.pixelformat == V4L2_PIX_FMT_MJPEG) {
    const image_t m = matToImage(img, image_t::PIXEL_FORMAT_MJPEG, 0, -1, 85);
    if (m.data.size() > b.length) {
      b.flags |= V4L2_BUF_FLAG_ERROR;
      b.bytesused = b.length;
    } else {
      std::memcpy(dst, m.data.data(), m.data.size());
      std::memset(dst + m.data.size(), 0xEE, b.length - m.data.size());
      b.bytesused = static_cast<uint32_t>(m.data.size());
      const int cut = node.spec.mjpeg_cut_every;
      if (cut > 0 && (node.stats.frames + 1) % cut == 0) b.bytesused /= 2;  // (no error flag)
    }
  } else {
    const bool yuyv = f.pixelformat == V4L2_PIX_FMT_YUYV;
    const image_t m =
        matToImage(img, yuyv ? int32_t{image_t::PIXEL_FORMAT_YUYV} : int32_t{image_t::PIXEL_FORMAT_GRAY}, 0);
    const size_t row = static_cast<size_t>(f.width) * (yuyv ? 2 : 1);
    std::memset(dst, 0xEE, b.length);
    for (uint32_t y = 0; y < f.height; ++y)
      std::memcpy(dst + static_cast<size_t>(y) * f.bytesperline, m.data.data() + y * row, row);
    b.bytesused = node.spec.raw_bytesused_zero ? 0 : f.sizeimage;
  }
  b.sequence = node.sequence++;
  b.timestamp.tv_sec = static_cast<time_t>(time_us / 1000000);
  b.timestamp.tv_usec = static_cast<suseconds_t>(time_us % 1000000);
  b.state = Node::State::Done;
  node.done.push_back(index);
  ++node.stats.frames;
}

// Produces every frame that is due by now.
void FakeV4l2Device::pump(Node& node) {
  if (!node.present || !node.streaming || node.stalled) return;
  const int64_t now = clock_.monotonicUs();
  const int64_t interval = node.intervalUs();
  // After a long stall (a process stopped in a debugger) skip to the present.
  const int64_t behind = (now - nextDueUs(node)) / interval;
  if (behind > 64) {
    node.frames_due += behind;
    node.sequence += static_cast<uint32_t>(behind);
    node.stats.dropped += behind;
  }
  while (node.present && node.streaming && nextDueUs(node) <= now) {
    // (unplugged when the frame after the last asked for is due: the last
    // one is delivered; unplugged as it was captured, it was lost with its
    // buffer, and `--fake-unplug-after N` published N - 1 frames)
    if (node.unplug_after_frames >= 0 && node.stats.frames >= node.unplug_after_frames) {
      unplug(node.spec.path);
      break;
    }
    const int64_t t = nextDueUs(node);
    ++node.frames_due;
    if (node.queued.empty()) {
      ++node.sequence;
      ++node.stats.dropped;
      continue;
    }
    const uint32_t index = node.queued.front();
    node.queued.pop_front();
    capture(node, index, t);
  }
}

// ---------------------------------------------------------------------------
// V4l2Io

int FakeV4l2Device::open(const char* path, int flags) {
  checkReplug();
  Node* n = findNode(path);
  int err = 0;
  if (!n || !n->present) err = ENOENT;
  else if (n->open_error) err = n->open_error;
  open_attempts_.push_back({path, clock_.monotonicUs(), err});
  if (err) return fail(err);
  const int fd = next_fd_++;
  fds_[fd] = Handle{n, n->generation, (flags & O_NONBLOCK) != 0};
  ++n->stats.opens;
  return fd;
}

int FakeV4l2Device::close(int fd) {
  const auto it = fds_.find(fd);
  if (it == fds_.end()) return fail(EBADF);
  Node* n = it->second.node;
  if (it->second.generation == n->generation && n->owner_fd == fd) {
    // Closing the owner stops streaming and frees the buffers (mapped memory
    // stays valid until munmap, as in the kernel).
    if (n->streaming) ++n->stats.streamoffs;
    n->dropQueue();
    n->bufs.clear();
    n->owner_fd = -1;
  }
  fds_.erase(it);
  return 0;
}

int FakeV4l2Device::ioctl(int fd, unsigned long request, void* arg) {
  checkReplug();
  int err = 0;
  Node* n = nodeOf(fd, &err);
  if (!n) return fail(err);
  for (auto it = faults_.begin(); it != faults_.end(); ++it) {
    if (it->request != request) continue;
    const int e = it->err;
    if (--it->times <= 0) faults_.erase(it);
    return fail(e);
  }
  return doIoctl(*n, fd, request, arg);
}

int FakeV4l2Device::doIoctl(Node& n, int fd, unsigned long request, void* arg) {
  const bool nonblock = fds_.at(fd).nonblock;
  const bool capture_type_ok = n.captures();
  auto busy = [&] { return n.owner_fd >= 0 && n.owner_fd != fd; };

  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* c = static_cast<v4l2_capability*>(arg);
      *c = {};
      copyText(c->driver, n.spec.driver);
      copyText(c->card, n.spec.card);
      copyText(c->bus_info, n.spec.bus_info);
      c->version = (6u << 16) | (1u << 8);
      c->device_caps = n.spec.device_caps;
      c->capabilities = n.spec.device_caps | V4L2_CAP_DEVICE_CAPS;
      return 0;
    }
    case VIDIOC_ENUM_FMT: {
      auto* d = static_cast<v4l2_fmtdesc*>(arg);
      if (!capture_type_ok || d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE ||
          d->index >= n.spec.formats.size())
        return fail(EINVAL);
      const FakeFormat& f = n.spec.formats[d->index];
      const uint32_t index = d->index, type = d->type;
      *d = {};
      d->index = index;
      d->type = type;
      d->pixelformat = f.fourcc;
      d->flags = f.fourcc == V4L2_PIX_FMT_MJPEG ? V4L2_FMT_FLAG_COMPRESSED : 0;
      copyText(d->description, f.description);
      return 0;
    }
    case VIDIOC_ENUM_FRAMESIZES: {
      auto* s = static_cast<v4l2_frmsizeenum*>(arg);
      const FakeFormat* f = capture_type_ok ? n.findFormat(s->pixel_format) : nullptr;
      if (!f || s->index >= f->sizes.size()) return fail(EINVAL);
      s->type = V4L2_FRMSIZE_TYPE_DISCRETE;
      s->discrete.width = f->sizes[s->index].width;
      s->discrete.height = f->sizes[s->index].height;
      return 0;
    }
    case VIDIOC_ENUM_FRAMEINTERVALS: {
      auto* iv = static_cast<v4l2_frmivalenum*>(arg);
      const FakeFormat* f = capture_type_ok ? n.findFormat(iv->pixel_format) : nullptr;
      if (!f) return fail(EINVAL);
      for (const auto& s : f->sizes) {
        if (s.width != iv->width || s.height != iv->height) continue;
        if (iv->index >= s.fps.size()) return fail(EINVAL);
        iv->type = V4L2_FRMIVAL_TYPE_DISCRETE;
        iv->discrete.numerator = 1;
        iv->discrete.denominator = s.fps[iv->index];
        return 0;
      }
      return fail(EINVAL);
    }
    case VIDIOC_G_FMT: {
      auto* f = static_cast<v4l2_format*>(arg);
      if (!capture_type_ok || f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      f->fmt.pix = n.fmt;
      return 0;
    }
    case VIDIOC_TRY_FMT:
    case VIDIOC_S_FMT: {
      auto* f = static_cast<v4l2_format*>(arg);
      if (!capture_type_ok || f->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      const v4l2_pix_format adjusted = n.adjust(f->fmt.pix);
      if (request == VIDIOC_S_FMT) {
        if (busy() || !n.bufs.empty() || n.streaming) return fail(EBUSY);
        n.fmt = adjusted;
        n.fps = n.nearestFps(n.fps);
      }
      f->fmt.pix = adjusted;
      return 0;
    }
    case VIDIOC_QUERYCTRL: {
      auto* q = static_cast<v4l2_queryctrl*>(arg);
      const uint32_t id = q->id;
      if (!hasExposureControl(n.spec, id)) return fail(EINVAL);
      *q = {};
      q->id = id;
      if (id == V4L2_CID_EXPOSURE_AUTO) {
        q->type = V4L2_CTRL_TYPE_MENU;
        copyText(q->name, "Auto Exposure");
        q->minimum = V4L2_EXPOSURE_AUTO, q->maximum = V4L2_EXPOSURE_APERTURE_PRIORITY, q->step = 1;
        q->default_value = V4L2_EXPOSURE_APERTURE_PRIORITY;
      } else {
        q->type = V4L2_CTRL_TYPE_INTEGER;
        copyText(q->name, "Exposure Time, Absolute");
        q->minimum = kExposureMin, q->maximum = kExposureMax, q->step = n.spec.exposure_step;
        q->default_value = kExposureDefault;
        if (n.exposure_mode != V4L2_EXPOSURE_MANUAL) q->flags = V4L2_CTRL_FLAG_INACTIVE;
      }
      return 0;
    }
    case VIDIOC_G_CTRL:
    case VIDIOC_S_CTRL: {
      auto* c = static_cast<v4l2_control*>(arg);
      if (!hasExposureControl(n.spec, c->id)) return fail(EINVAL);
      int32_t& v = c->id == V4L2_CID_EXPOSURE_AUTO ? n.exposure_mode : n.exposure_time;
      if (request == VIDIOC_G_CTRL) {
        c->value = v;
        return 0;
      }
      if (n.spec.controls_busy_while_streaming && n.streaming) return fail(EBUSY);
      if (c->id == V4L2_CID_EXPOSURE_AUTO) {
        // a UVC webcam's menu: manual and aperture priority only
        const bool manual_ok = c->value == V4L2_EXPOSURE_MANUAL && n.spec.exposure_manual_mode;
        if (!manual_ok && c->value != V4L2_EXPOSURE_APERTURE_PRIORITY) return fail(EINVAL);
      } else {
        if (n.spec.exposure_auto_control && n.exposure_mode != V4L2_EXPOSURE_MANUAL) return fail(EACCES);
        const int32_t step = std::max(1, n.spec.exposure_step);
        c->value = kExposureMin + (std::clamp(c->value, kExposureMin, kExposureMax) - kExposureMin) / step * step;
      }
      v = c->value;
      return 0;
    }
    case VIDIOC_G_PARM:
    case VIDIOC_S_PARM: {
      auto* p = static_cast<v4l2_streamparm*>(arg);
      if (!capture_type_ok || p->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_PARM) {
        if (!n.spec.timeperframe) return fail(ENOTTY);
        if (busy() || n.streaming) return fail(EBUSY);
        const v4l2_fract t = p->parm.capture.timeperframe;
        const uint32_t want =
            t.numerator ? static_cast<uint32_t>((t.denominator + t.numerator / 2) / t.numerator)
                        : n.fps;
        n.fps = n.nearestFps(want);
      }
      p->parm.capture = {};
      if (n.spec.timeperframe) {
        p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
        p->parm.capture.timeperframe = {1, n.fps};
      }
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* rb = static_cast<v4l2_requestbuffers*>(arg);
      if (!capture_type_ok || rb->type != V4L2_BUF_TYPE_VIDEO_CAPTURE ||
          rb->memory != V4L2_MEMORY_MMAP)
        return fail(EINVAL);
      if (busy() || n.streaming) return fail(EBUSY);
      if (std::any_of(n.bufs.begin(), n.bufs.end(), [](const Node::Buf& b) { return b.mapped; }))
        return fail(EBUSY);
      n.stats.requested_buffers = rb->count;
      n.dropQueue();
      n.bufs.clear();
      if (rb->count == 0) {
        n.owner_fd = -1;
        return 0;
      }
      const uint32_t count = std::max(1u, std::min(rb->count, n.spec.max_buffers));
      const uint32_t length = (n.fmt.sizeimage + kPage - 1) / kPage * kPage;
      n.bufs.resize(count);
      for (uint32_t i = 0; i < count; ++i) {
        n.bufs[i].memory = std::make_shared<std::vector<uint8_t>>(length, 0);
        n.bufs[i].length = length;
        n.bufs[i].offset = i * length;
      }
      rb->count = count;
      n.owner_fd = fd;
      return 0;
    }
    case VIDIOC_QUERYBUF:
    case VIDIOC_QBUF:
    case VIDIOC_DQBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (!capture_type_ok || b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE ||
          b->memory != V4L2_MEMORY_MMAP)
        return fail(EINVAL);
      if (request != VIDIOC_QUERYBUF && busy()) return fail(EBUSY);
      uint32_t index = b->index;
      if (request == VIDIOC_QBUF) {
        if (index >= n.bufs.size() || n.bufs[index].state != Node::State::Dequeued)
          return fail(EINVAL);
        n.bufs[index].state = Node::State::Queued;
        n.queued.push_back(index);
        pump(n);
        return 0;
      }
      if (request == VIDIOC_DQBUF) {
        if (!n.streaming) return fail(EINVAL);
        pump(n);
        while (n.done.empty()) {
          if (nonblock) return fail(EAGAIN);
          if (n.queued.empty()) return fail(EINVAL);  // would block forever
          clock_.sleepUs(nextDueUs(n) - clock_.monotonicUs());
          pump(n);
          if (!n.present) return fail(ENODEV);
        }
        index = n.done.front();
        n.done.pop_front();
        n.bufs[index].state = Node::State::Dequeued;
      }
      if (index >= n.bufs.size()) return fail(EINVAL);
      const Node::Buf& buf = n.bufs[index];
      const uint32_t type = b->type, memory = b->memory;
      *b = {};
      b->index = index;
      b->type = type;
      b->memory = memory;
      b->length = buf.length;
      b->m.offset = buf.offset;
      b->field = V4L2_FIELD_NONE;
      b->bytesused = buf.bytesused;
      b->sequence = buf.sequence;
      b->timestamp = buf.timestamp;
      b->flags = buf.flags | (buf.mapped ? V4L2_BUF_FLAG_MAPPED : 0) |
                 (buf.state == Node::State::Queued ? V4L2_BUF_FLAG_QUEUED : 0) |
                 (buf.state == Node::State::Done ? V4L2_BUF_FLAG_DONE : 0);
      if (request == VIDIOC_QUERYBUF) b->flags &= ~V4L2_BUF_FLAG_ERROR;
      return 0;
    }
    case VIDIOC_STREAMON:
    case VIDIOC_STREAMOFF: {
      const int type = *static_cast<int*>(arg);
      if (!capture_type_ok || type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (busy()) return fail(EBUSY);
      if (request == VIDIOC_STREAMOFF) {
        if (n.streaming) ++n.stats.streamoffs;
        n.dropQueue();
        return 0;
      }
      if (n.bufs.empty()) return fail(EINVAL);
      if (n.streaming) return 0;
      n.streaming = true;
      n.stalled = n.wedged;
      if (n.spec.resets_exposure_at_streamon) n.exposure_time = kExposureDefault;
      n.stream_start_us = clock_.monotonicUs();
      n.frames_due = 0;
      n.sequence = 0;
      ++n.stats.streamons;
      return 0;
    }
    default: return fail(ENOTTY);
  }
}

void* FakeV4l2Device::mmap(void*, size_t length, int prot, int flags, int fd, off_t offset) {
  checkReplug();
  int err = 0;
  Node* n = nodeOf(fd, &err);
  if (!n) {
    errno = err;
    return MAP_FAILED;
  }
  if (!(flags & MAP_SHARED) || !(prot & PROT_READ) || n->owner_fd != fd) {
    errno = EINVAL;
    return MAP_FAILED;
  }
  for (auto& b : n->bufs) {
    if (static_cast<off_t>(b.offset) != offset) continue;
    if (length == 0 || length > b.length || b.mapped) break;
    b.mapped = true;
    void* p = b.memory->data();
    mappings_[p] = Mapping{b.memory, length, n};
    ++n->stats.mmaps;
    return p;
  }
  errno = EINVAL;
  return MAP_FAILED;
}

int FakeV4l2Device::munmap(void* addr, size_t length) {
  const auto it = mappings_.find(addr);
  if (it == mappings_.end() || it->second.length != length) return fail(EINVAL);
  Node* n = it->second.node;
  for (auto& b : n->bufs)
    if (b.memory == it->second.memory) b.mapped = false;
  ++n->stats.munmaps;
  mappings_.erase(it);
  return 0;
}

int FakeV4l2Device::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  const int64_t never = std::numeric_limits<int64_t>::max();
  const int64_t start = clock_.monotonicUs();
  const int64_t deadline = timeout_ms < 0 ? never : start + int64_t{timeout_ms} * 1000;
  for (;;) {
    checkReplug();
    int ready = 0;
    int64_t wake = never;
    for (nfds_t i = 0; i < nfds; ++i) {
      pollfd& p = fds[i];
      p.revents = 0;
      const auto it = fds_.find(p.fd);
      if (it == fds_.end()) {
        p.revents = POLLNVAL;
      } else {
        Node* n = it->second.node;
        pump(*n);
        if (!n->present || it->second.generation != n->generation) p.revents = POLLERR;
        else if (!n->streaming || n->owner_fd != p.fd) p.revents = POLLERR;
        else if (!n->done.empty()) p.revents = static_cast<short>(p.events & (POLLIN | POLLRDNORM));
        else if (n->queued.empty()) p.revents = POLLERR;
        else if (!n->stalled) wake = std::min(wake, nextDueUs(*n));  // (stalled: nothing until the deadline)
      }
      if (p.revents) ++ready;
    }
    const int64_t now = clock_.monotonicUs();
    if (ready > 0 || now >= deadline) return ready;
    const int64_t until = std::min(wake, deadline);
    if (until == never) return 0;  // nothing will ever be ready: do not hang
    clock_.sleepUs(std::max<int64_t>(1, until - now));
  }
}

std::vector<std::string> FakeV4l2Device::deviceNodes() {
  checkReplug();
  std::vector<std::string> out;
  for (const auto& n : nodes_)
    if (n->present) out.push_back(n->spec.path);
  std::sort(out.begin(), out.end(), [](const std::string& a, const std::string& b) {
    return a.size() != b.size() ? a.size() < b.size() : a < b;
  });
  return out;
}

}  // namespace ld
