// V4L2 memory-mapped streaming capture.
//
// V4l2Capture does one device's capture the way the V4L2 spec describes it:
//   1. open the node non-blocking, VIDIOC_QUERYCAP: a video capture device
//      with streaming I/O;
//   2. enumerate formats, frame sizes and frame intervals; refuse a format or
//      size the device does not offer with an error listing what it offers;
//   3. VIDIOC_S_FMT (checking what the driver substituted), VIDIOC_S_PARM
//      (the nearest offered frame rate); with a manual exposure asked for,
//      VIDIOC_S_CTRL: V4L2_CID_EXPOSURE_AUTO to manual, then
//      V4L2_CID_EXPOSURE_ABSOLUTE (read back with VIDIOC_G_CTRL);
//   4. VIDIOC_REQBUFS (at least 4 mmap buffers), VIDIOC_QUERYBUF + mmap each;
//   5. VIDIOC_QBUF all, VIDIOC_STREAMON;
//   6. per frame: poll, VIDIOC_DQBUF, hand out a view of the mmap buffer with
//      the driver's timestamp (CLOCK_MONOTONIC, converted to wall-clock
//      microseconds), then VIDIOC_QBUF it back (requeue);
//   7. VIDIOC_STREAMOFF, munmap, VIDIOC_REQBUFS(0), close.
// ReconnectingCapture adds the process policy: a device that disappears while
// streaming is reopened with exponential backoff, forever, logging once per
// series of attempts. listDevices() is `ld-camera --list`.
//
// Every system call goes through V4l2Io and every clock read through Clock
// (ld/v4l2_device.hpp), so all of this runs against FakeV4l2Device in tests.
// Not thread-safe: one thread drives a capture.
#pragma once

#include <linux/videodev2.h>

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "ld/v4l2_device.hpp"

namespace ld {

// ---------------------------------------------------------------------------
// Pixel format names

/// The four characters of a FourCC ("YUYV", "MJPG"), or "0x…" when not printable.
std::string fourccText(uint32_t fourcc);

/// The name ld-camera uses: "YUYV", "MJPEG", "GREY", else fourccText().
std::string captureFormatName(uint32_t fourcc);

/// Inverse of captureFormatName for the formats ld-camera captures:
/// "yuyv", "mjpeg" (or "mjpg"), "grey" (or "gray"), case-insensitive.
/// Throws std::invalid_argument otherwise.
uint32_t captureFormatFromName(const std::string& name);

// ---------------------------------------------------------------------------
// Errors

/// A capture failure; what() is one line naming the device and the problem.
class CaptureError : public std::runtime_error {
 public:
  enum class Kind {
    NoDevice,       ///< the node does not exist ("/dev/video0: no such device")
    Unavailable,    ///< exists but cannot be used now: permission denied, busy
    NotCapture,     ///< not a V4L2 video capture device with streaming I/O
    FormatRefused,  ///< the device does not offer the requested format or size
    ControlRefused, ///< the device has no control the request needs (manual exposure)
    DeviceLost,     ///< the device went away (unplugged) while in use
    Io,             ///< any other failing call
  };
  CaptureError(Kind kind, const std::string& what) : std::runtime_error(what), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

// ---------------------------------------------------------------------------
// What a device offers (VIDIOC_ENUM_FMT / ENUM_FRAMESIZES / ENUM_FRAMEINTERVALS)

struct V4l2FrameSize {
  uint32_t width = 0, height = 0;  ///< the size; for a range, its maximum
  /// Non-zero for a stepwise or continuous range of sizes (rare on webcams).
  uint32_t min_width = 0, min_height = 0, step_width = 0, step_height = 0;
  std::vector<double> fps;        ///< discrete frame rates, as enumerated
  double min_fps = 0, max_fps = 0;  ///< a stepwise/continuous range of rates, else 0

  bool isRange() const { return step_width != 0; }
  bool contains(uint32_t w, uint32_t h) const;
  /// "640x480" or "160x120-1920x1080 step 8x8".
  std::string sizeText() const;
  /// "30 15 fps", "1-30 fps", or "" when the driver enumerates no intervals.
  std::string fpsText() const;
};

struct V4l2FormatDesc {
  uint32_t fourcc = 0;
  std::string description;  ///< the driver's text ("YUYV 4:2:2", "Motion-JPEG")
  bool compressed = false;
  std::vector<V4l2FrameSize> sizes;

  bool offers(uint32_t w, uint32_t h) const;
};

struct V4l2DeviceInfo {
  std::string path, card, driver, bus_info;
  bool capture = false;  ///< a video capture device with streaming I/O
  std::string error;     ///< why it cannot be used (empty when capture)
  std::vector<V4l2FormatDesc> formats;
};

/// Enumerates the formats (with sizes and rates) of an open capture fd.
/// Throws CaptureError (naming `device`) when an enumeration call fails
/// other than by reaching the end of the list.
std::vector<V4l2FormatDesc> enumerateFormats(V4l2Io& io, int fd,
                                             const std::string& device = "device");

/// Opens `path` briefly and describes it; failures land in `error`.
V4l2DeviceInfo queryDevice(V4l2Io& io, const std::string& path);

/// Every node of io.deviceNodes(), described.
std::vector<V4l2DeviceInfo> listDevices(V4l2Io& io);

/// The text of `ld-camera --list`:
///   /dev/video0: HD Webcam (uvcvideo, usb-0000:00:14.0-1)
///     YUYV   YUYV 4:2:2
///       640x480     30 15 fps
///     MJPEG  Motion-JPEG, compressed
///       1280x720    30 fps
///   /dev/video1: HD Webcam (uvcvideo, usb-0000:00:14.0-1): not a video capture device
std::string formatDeviceList(const std::vector<V4l2DeviceInfo>& devices);

/// "YUYV 640x480, 320x240; MJPEG 1280x720, 640x480": what a refused-format
/// error lists as offered.
std::string offeredFormatsText(const std::vector<V4l2FormatDesc>& formats);

// ---------------------------------------------------------------------------
// Capture

/// What to ask the device for.
struct CaptureRequest {
  /// V4L2_PIX_FMT_YUYV, _MJPEG or _GREY (any the device offers works);
  /// 0 keeps the device's current format.
  uint32_t fourcc = V4L2_PIX_FMT_YUYV;
  /// 0x0 keeps the device's current size (with the current format) or takes
  /// the first offered size (with another format).
  uint32_t width = 640, height = 480;
  /// Frames per second; the nearest rate the device offers is set (the
  /// negotiated rate is reported, not an error). 0 keeps the device's rate.
  double fps = 30;
  /// mmap buffers to request; fewer than 4 is raised to 4 (one being filled,
  /// one being read, the rest absorb jitter). The driver may grant more.
  unsigned buffers = 4;
  /// Manual exposure time in milliseconds (automatic exposure off); 0 leaves
  /// the device's exposure as it is. Short exposures keep a moving robot's
  /// frames sharp (the image moves less during one) and darker. Set in the
  /// control's unit (V4L2_CID_EXPOSURE_ABSOLUTE: 100 microseconds), clamped
  /// to its range; the time set is reported. A device without the control
  /// is refused (CaptureError::Kind::ControlRefused). close() puts the
  /// device's exposure back as open() found it.
  double exposure_ms = 0;
};

/// What the device agreed to.
struct CaptureFormat {
  uint32_t fourcc = 0, width = 0, height = 0;
  uint32_t bytesperline = 0;  ///< row stride of raw formats (>= width * bytes per pixel)
  uint32_t sizeimage = 0;     ///< buffer bytes the driver needs per frame
  double fps = 0;             ///< 0 when the device does not report a rate
  double exposure_ms = 0;     ///< the manual exposure set; 0: the device's own (not asked for)
  unsigned buffers = 0;       ///< mmap buffers granted
  std::string card, driver;

  /// "YUYV 640x480 @ 30 fps, 4 buffers" (", exposure 5 ms" after the rate when set).
  std::string describe() const;
};

/// One captured frame: a view of an mmap buffer, valid until requeue().
struct Frame {
  const uint8_t* data = nullptr;
  size_t bytesused = 0;  ///< bytes of the frame in `data` (a JPEG's length for MJPEG)
  uint32_t fourcc = 0, width = 0, height = 0, bytesperline = 0;
  int64_t utime = 0;         ///< capture time, wall-clock (CLOCK_REALTIME) microseconds
  int64_t monotonic_us = 0;  ///< the same instant on CLOCK_MONOTONIC
  bool driver_timestamp = false;  ///< false: the driver gave none; dequeue time used
  uint32_t sequence = 0;  ///< the driver's frame counter (restarts on STREAMON)
  int64_t seq = 0;  ///< sequence number for messages (continues across reconnects)
  int index = -1;   ///< the buffer; requeue() gives it back to the driver
};

/// Counters of a capture since open().
struct CaptureStats {
  int64_t frames = 0;          ///< frames handed out by grab()
  int64_t spurious = 0;        ///< wakeups with nothing to dequeue (EAGAIN)
  int64_t errored = 0;         ///< buffers the driver flagged V4L2_BUF_FLAG_ERROR (skipped)
  int64_t truncated = 0;       ///< raw frames shorter than a full image (skipped)
  int64_t sequence_gaps = 0;   ///< frames the driver dropped (jumps in `sequence`)
  int64_t stale = 0;           ///< good frames given back unseen: a newer one was waiting

  CaptureStats& operator+=(const CaptureStats& o) {
    frames += o.frames;
    spurious += o.spurious;
    errored += o.errored;
    truncated += o.truncated;
    sequence_gaps += o.sequence_gaps;
    stale += o.stale;
    return *this;
  }
};

class V4l2Capture {
 public:
  explicit V4l2Capture(V4l2Io& io, Clock& clock = systemClock());
  ~V4l2Capture();
  V4l2Capture(const V4l2Capture&) = delete;
  V4l2Capture& operator=(const V4l2Capture&) = delete;

  /// Steps 1-4. Throws CaptureError; on error nothing stays open or mapped.
  const CaptureFormat& open(const std::string& device, const CaptureRequest& request);
  /// Step 5.
  void start();
  /// Waits up to `timeout_ms` for a frame: the newest good one filled (older
  /// ones waiting are given back at once, counted as stats().stale). False
  /// on timeout, on a spurious wakeup, on EINTR and when every buffer
  /// dequeued was flagged bad or cut short (requeued at once). Throws
  /// CaptureError (DeviceLost when the device went away).
  /// Each frame must be requeued before all buffers are held.
  bool grab(Frame& frame, int timeout_ms);
  /// Gives the frame's buffer back to the driver; `frame` is invalid after.
  void requeue(const Frame& frame);
  /// VIDIOC_STREAMOFF; buffers stay mapped, start() streams again.
  void stop();
  /// Stops, unmaps every buffer, frees them, puts back an exposure open()
  /// changed, and closes. Never throws.
  void close() noexcept;

  bool isOpen() const { return fd_ >= 0; }
  bool isStreaming() const { return streaming_; }
  const std::string& device() const { return device_; }
  const CaptureFormat& format() const { return format_; }
  /// What the device offers (enumerated by open()).
  const std::vector<V4l2FormatDesc>& offered() const { return offered_; }
  const CaptureStats& stats() const { return stats_; }

 private:
  enum class BufferState { Dequeued, Queued, Held };  // Held: handed out by grab()
  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
    BufferState state = BufferState::Dequeued;
  };
  [[noreturn]] void fail(const std::string& what, int err) const;
  void negotiate(const CaptureRequest& request);
  void setFrameRate(double fps);
  // The bytes of a dequeued buffer's frame, or 0 when it is flagged bad or
  // cut short (counted in stats_).
  size_t usedBytes(const v4l2_buffer& b);
  void setExposure(double ms);
  // After the exposure was refused with EBUSY while streaming: what
  // STREAMON changed of the exposure set before it ("" for nothing), or
  // nullopt when that cannot be read (throws when the device went).
  std::optional<std::string> exposureChangedAtStreamon(double set_at_open);
  void restoreExposure() noexcept;
  // The device and its card's name, as errors name it.
  std::string deviceAndCard() const { return device_ + " (" + format_.card + ")"; }
  void allocateBuffers(unsigned count);
  void queue(uint32_t index);

  V4l2Io& io_;
  Clock& clock_;
  int fd_ = -1;
  bool streaming_ = false;
  bool compressed_ = false;
  double exposure_ms_ = 0;  // the manual exposure asked for, set at each start()
  bool raw_bytesused_set_ = false;  // the driver set bytesused of a raw frame since STREAMON
  uint32_t bytes_per_pixel_ = 0;  // 0: compressed or unknown
  std::string device_;
  CaptureFormat format_;
  std::vector<V4l2FormatDesc> offered_;
  std::vector<Buffer> buffers_;
  CaptureStats stats_;
  bool have_sequence_ = false;
  uint32_t last_sequence_ = 0;
  int32_t saved_exposure_mode_ = -1, saved_exposure_time_ = -1;  // put back by close(); -1: nothing
  bool exposure_busy_ = false;  // setExposure()'s refusal was EBUSY (a control taken only while not streaming)
};

// ---------------------------------------------------------------------------
// Reconnecting after the device goes away

/// Reopen delays: initial_s, doubling (factor) up to max_s.
struct BackoffPolicy {
  double initial_s = 0.1;
  double max_s = 2.0;
  double factor = 2.0;
};

class Backoff {
 public:
  explicit Backoff(BackoffPolicy policy = {}) : policy_(policy) {}
  /// The delay before the next attempt: initial, initial*factor, ... max.
  int64_t nextDelayUs();
  void reset() { attempts_ = 0; }
  int attempts() const { return attempts_; }

 private:
  BackoffPolicy policy_;
  int attempts_ = 0;
};

/// V4l2Capture plus ld-camera's policy: errors opening the device at start()
/// are fatal (thrown); losing it later is not: grab() reports it once
/// through `log`, closes, and reopens with backoff until the device is back,
/// then logs once more. A stream that stops delivering good frames while
/// the device stays (a UVC camera's firmware or USB stalls, or every frame
/// flagged bad) is lost too: no good frame for max(2 s, 10 frame intervals,
/// 3 exposures) closes and reopens it; lost so again before a good frame
/// came, the backoff grows on and nothing more is logged. grab()
/// never blocks longer than its timeout, so the caller can check for a stop
/// request between calls. A frame's data lies in the device's mapped
/// buffers: a frame still held when a grab() or requeue() loses the stream
/// (the device gone, or a stall closed) is gone with them, its data no
/// longer to be read; requeue() of it does nothing. ld-camera holds one
/// frame at a time, publishing it before the next grab().
class ReconnectingCapture {
 public:
  using Log = std::function<void(const std::string&)>;

  ReconnectingCapture(V4l2Io& io, Clock& clock, std::string device, CaptureRequest request,
                      BackoffPolicy policy = {}, Log log = {});

  /// Opens and starts streaming. Throws CaptureError.
  const CaptureFormat& start();
  /// A frame (true), or false on timeout / while reconnecting. Frame::seq
  /// continues across reconnects, and across stop() and start() again.
  /// Throws only for errors that are not about
  /// the device going away.
  bool grab(Frame& frame, int timeout_ms);
  /// Gives the frame back; a device lost here is handled like in grab().
  void requeue(const Frame& frame);
  /// Stops and closes.
  void stop() noexcept;

  bool connected() const { return capture_.isStreaming(); }
  int reconnects() const { return reconnects_; }
  const CaptureFormat& format() const { return capture_.format(); }
  const V4l2Capture& capture() const { return capture_; }
  /// The capture's counts summed over every reopening (V4l2Capture's start
  /// again at each open).
  CaptureStats totals() const;
  /// No good frame for this long while streaming: the stream is lost.
  int64_t stallLimitUs() const;

 private:
  void lost(const std::string& why);
  bool tryReopen(int timeout_ms);

  V4l2Capture capture_;
  Clock& clock_;
  std::string device_;
  CaptureRequest request_;
  Backoff backoff_;
  BackoffPolicy policy_;
  Log log_;
  bool down_ = false;
  int64_t lost_at_us_ = 0, next_attempt_us_ = 0;
  std::string last_error_;
  int reconnects_ = 0, attempts_ = 0;
  bool rebase_ = false;
  int64_t seq_base_ = 0, next_seq_ = 0;
  int64_t last_frame_us_ = 0;  // the last good frame (or the stream's start)
  CaptureStats closed_;        // the counts of the captures closed so far
  bool reopened_ = false;        // reopened at least once
  bool good_since_open_ = false; // a good frame since the last (re)open
  bool quiet_ = false;           // lost again without a good frame: not logged
  int64_t bad_at_good_ = 0;      // flagged + cut short at the last good frame
};

}  // namespace ld
