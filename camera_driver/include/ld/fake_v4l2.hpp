// A fake V4L2 webcam (and a fake clock) for tests and `ld-camera --fake`.
//
// FakeV4l2Device implements V4l2Io the way a UVC webcam and the kernel's
// videobuf2 behave, for one or more device nodes:
//   VIDIOC_QUERYCAP, ENUM_FMT, ENUM_FRAMESIZES, ENUM_FRAMEINTERVALS (discrete),
//   G_FMT / S_FMT / TRY_FMT (an unknown format or size is substituted, not
//   refused, as real drivers do; EBUSY while buffers exist), G_PARM / S_PARM
//   (nearest offered rate), REQBUFS (MMAP only; count clamped; 0 frees, EBUSY
//   while mapped or streaming), QUERYBUF, mmap/munmap of its own buffers,
//   QBUF / DQBUF (EAGAIN when non-blocking and nothing is ready), STREAMON /
//   STREAMOFF, and poll (POLLIN when a buffer is done, POLLERR when not
//   streaming or nothing is queued).
// While streaming it "captures" a frame every 1/fps of its Clock: the oldest
// queued buffer gets a moving test pattern (pattern()), the frame's sequence
// number, and the frame time as a CLOCK_MONOTONIC timestamp with
// V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC; with nothing queued the frame is dropped
// (a gap in the sequence). poll() sleeps on the Clock until the next frame,
// so with SystemClock it runs at the camera's rate and with FakeClock a test
// runs instantly.
//
// Fault injection: a node can be missing (open fails ENOENT), unplugged while
// in use (its ioctls fail ENODEV, poll gives POLLERR, mappings stay valid
// until munmap, as in the kernel) and plugged back; any ioctl can be made to
// fail with a chosen errno; opening can fail (EACCES, EBUSY). Counters say
// what was opened, mapped and unmapped, so tests catch leaks.
// Single-threaded, like the capture that uses it.
#pragma once

#include <linux/videodev2.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "ld/v4l2_device.hpp"

namespace ld {

/// Time that moves only when slept on (or advanced): tests do not wait.
class FakeClock final : public Clock {
 public:
  /// Starts at monotonic `start_us`; realtime is monotonic + `offset_us`.
  explicit FakeClock(int64_t start_us = 1000000000, int64_t offset_us = 1700000000000000 - 1000000000)
      : now_us_(start_us), offset_us_(offset_us) {}
  int64_t monotonicUs() override { return now_us_; }
  int64_t realtimeUs() override { return now_us_ + offset_us_; }
  void sleepUs(int64_t us) override {
    if (us > 0) {
      now_us_ += us;
      slept_us_ += us;
    }
  }
  void advanceUs(int64_t us) { now_us_ += us; }
  int64_t offsetUs() const { return offset_us_; }
  int64_t sleptUs() const { return slept_us_; }

 private:
  int64_t now_us_, offset_us_;
  int64_t slept_us_ = 0;
};

struct FakeFrameSize {
  uint32_t width = 0, height = 0;
  std::vector<uint32_t> fps;  ///< discrete rates, highest first
};

struct FakeFormat {
  uint32_t fourcc = 0;  ///< V4L2_PIX_FMT_YUYV, _MJPEG or _GREY
  std::string description;
  std::vector<FakeFrameSize> sizes;
};

/// One emulated device node.
struct FakeCameraSpec {
  std::string path = "/dev/video0";
  std::string card = "Fake UVC Camera";
  std::string driver = "uvcvideo";
  std::string bus_info = "usb-0000:00:14.0-1";
  uint32_t device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING | V4L2_CAP_EXT_PIX_FORMAT;
  std::vector<FakeFormat> formats;
  /// Extra bytes at the end of each row of raw formats (bytesperline >
  /// width * bytes per pixel); the padding is filled with 0xEE.
  uint32_t row_padding = 0;
  uint32_t max_buffers = 32;
  bool timeperframe = true;  ///< supports S_PARM
  /// Has the exposure controls of a UVC webcam: V4L2_CID_EXPOSURE_AUTO (a
  /// menu: manual or aperture priority, the default) and
  /// V4L2_CID_EXPOSURE_ABSOLUTE (3-2047 in 100 us, default 156), which
  /// refuses to be set (EACCES) while automatic exposure is on; both reset
  /// at power-on. VIDIOC_QUERYCTRL, G_CTRL and S_CTRL (values clamped).
  bool exposure_control = true;
  bool exposure_auto_control = true;  ///< has V4L2_CID_EXPOSURE_AUTO (without it the time is always settable)
  bool exposure_manual_mode = true;   ///< its menu has manual (without it: EINVAL, and the time stays refused)
  int32_t exposure_step = 1;          ///< the time's step, in 100 us
  uint32_t timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
  /// Sets its exposure time back to the default at STREAMON, automatic
  /// exposure off or not, as the Logitech C920 does.
  bool resets_exposure_at_streamon = false;
  /// Refuses its controls (S_CTRL: EBUSY) while streaming.
  bool controls_busy_while_streaming = false;
  /// Every n-th MJPEG frame comes cut to half its bytes, without the error
  /// flag (uvcvideo checks the size of raw frames alone); 0: never.
  int mjpeg_cut_every = 0;
  /// Leaves bytesused 0 on raw frames, as some capture cards' drivers do.
  bool raw_bytesused_zero = false;

  /// A webcam offering YUYV 640x480 (30, 15 fps), 320x240 (30, 15 fps),
  /// 1280x720 (10 fps); MJPEG 1280x720, 640x480, 320x240 (30, 15 fps);
  /// GREY 640x480 (30 fps). Starts in YUYV 640x480 at 30 fps.
  static FakeCameraSpec webcam(const std::string& path = "/dev/video0");
  /// The second node UVC creates for each camera: metadata capture only.
  static FakeCameraSpec metadataNode(const std::string& path = "/dev/video1");
};

class FakeV4l2Device final : public V4l2Io {
 public:
  explicit FakeV4l2Device(Clock& clock,
                          std::vector<FakeCameraSpec> nodes = {FakeCameraSpec::webcam()});
  ~FakeV4l2Device() override;

  // V4l2Io
  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;
  void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override;
  int munmap(void* addr, size_t length) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  std::vector<std::string> deviceNodes() override;

  // Fault injection
  /// The node disappears: open fails ENOENT, descriptors already open fail
  /// with ENODEV (poll: POLLERR); mappings stay valid until munmap.
  void unplug(const std::string& path = "/dev/video0");
  /// The node is back, in its power-on state; old descriptors stay dead.
  void replug(const std::string& path = "/dev/video0");
  /// Unplugs the node when the frame after its `after_frames`-th captured
  /// one (from now) is due, so that those `after_frames` are delivered, and
  /// plugs it back `replug_after_us` later (never when negative).
  void scheduleUnplug(const std::string& path, int64_t after_frames, int64_t replug_after_us);
  /// The node stops delivering frames while it stays streaming (a UVC
  /// camera's firmware or USB stalls), until its next STREAMON, or for good
  /// when `wedged` (until replugged).
  void stall(const std::string& path = "/dev/video0", bool wedged = false);
  /// The next `times` calls of `request` (on any node) fail with `err`.
  void failIoctl(unsigned long request, int err, int times = 1);
  /// open() of `path` fails with `err` (EACCES, EBUSY...) until set to 0.
  void failOpen(const std::string& path, int err);

  // What happened
  struct Stats {
    int opens = 0;          ///< successful opens
    int open_fds = 0;       ///< descriptors open now
    int mmaps = 0, munmaps = 0;
    int live_mappings = 0;  ///< mmaps not yet unmapped
    uint32_t requested_buffers = 0;  ///< count asked for by the last REQBUFS
    uint32_t allocated_buffers = 0;  ///< buffers that exist now
    int streamons = 0, streamoffs = 0;
    int64_t frames = 0;   ///< frames written into buffers
    int64_t dropped = 0;  ///< frames due while nothing was queued
  };
  Stats stats(const std::string& path = "/dev/video0") const;
  /// Every open() attempt: the node, the Clock's monotonic time, and 0 or the errno.
  struct OpenAttempt {
    std::string path;
    int64_t time_us;
    int error;
  };
  const std::vector<OpenAttempt>& openAttempts() const { return open_attempts_; }
  /// The node's current format (as G_FMT reports it).
  v4l2_pix_format currentFormat(const std::string& path = "/dev/video0") const;
  /// The node's exposure controls now: V4L2_CID_EXPOSURE_AUTO's value and
  /// V4L2_CID_EXPOSURE_ABSOLUTE's (100 us).
  struct Exposure {
    int32_t mode = 0, time = 0;
  };
  Exposure exposure(const std::string& path = "/dev/video0") const;

  /// The BGR test pattern of frame `sequence`: colour gradients, a white
  /// square moving 8 px per frame, and the sequence number written on it.
  static cv::Mat pattern(uint32_t width, uint32_t height, uint32_t sequence);

 private:
  struct Node;
  struct Handle;
  Node* nodeOf(int fd, int* err);
  Node* findNode(const std::string& path);
  const Node* findNode(const std::string& path) const;
  void pump(Node& node);
  void capture(Node& node, uint32_t index, int64_t time_us);
  int64_t nextDueUs(const Node& node) const;
  void checkReplug();
  int doIoctl(Node& node, int fd, unsigned long request, void* arg);

  Clock& clock_;
  std::vector<std::unique_ptr<Node>> nodes_;
  std::map<int, Handle> fds_;
  int next_fd_ = 100;
  struct Mapping {
    std::shared_ptr<std::vector<uint8_t>> memory;
    size_t length;
    Node* node;
  };
  std::map<void*, Mapping> mappings_;
  struct IoctlFault {
    unsigned long request;
    int err;
    int times;
  };
  std::vector<IoctlFault> faults_;
  std::vector<OpenAttempt> open_attempts_;
};

}  // namespace ld
