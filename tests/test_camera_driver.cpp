// The V4L2 capture against a fake webcam: capability checks, format
// negotiation, buffers (no leaks), the capture loop with driver timestamps and
// sequence numbers, EAGAIN/EINTR, unplugging and reopening with backoff, a
// missing device, --list, and frames to image_t. A fake clock makes backoff
// and frame timing instant. A real /dev/video* is tried when there is one.
// Last, ld-camera itself runs on its --fake webcam, writing an LCM log file.
#include <gtest/gtest.h>

#include <tuple>

#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/fake_v4l2.hpp"
#include "ld/frame_image.hpp"
#include "ld/image_convert.hpp"
#include "ld/v4l2_capture.hpp"

namespace {

using ld::CaptureError;
using Kind = ld::CaptureError::Kind;

constexpr int64_t kFrameUs = 1000000 / 30;  // the fake's frame interval at 30 fps

// Runs `f`, expects a CaptureError of `kind`, returns its message.
template <typename F>
std::string captureError(F&& f, Kind kind) {
  try {
    f();
  } catch (const CaptureError& e) {
    EXPECT_EQ(static_cast<int>(e.kind()), static_cast<int>(kind)) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no CaptureError";
  return "";
}

ld::CaptureRequest request(uint32_t fourcc, uint32_t w, uint32_t h, double fps = 30) {
  ld::CaptureRequest r;
  r.fourcc = fourcc;
  r.width = w;
  r.height = h;
  r.fps = fps;
  return r;
}

// Opens /dev/video0 at YUYV 640x480 with a manual exposure of 5 ms.
void openWithExposure(ld::V4l2Capture& cap) {
  auto r = request(V4L2_PIX_FMT_YUYV, 640, 480);
  r.exposure_ms = 5;
  cap.open("/dev/video0", r);
}

void expectNoLeaks(const ld::FakeV4l2Device& dev, const std::string& path = "/dev/video0") {
  const auto s = dev.stats(path);
  EXPECT_EQ(s.open_fds, 0);
  EXPECT_EQ(s.live_mappings, 0);
  EXPECT_EQ(s.mmaps, s.munmaps);
  EXPECT_EQ(s.allocated_buffers, 0u);
}

double meanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  const cv::Scalar m = cv::mean(d);
  return (m[0] + m[1] + m[2]) / a.channels();
}

struct Fixture : ::testing::Test {
  ld::FakeClock clock;
  ld::FakeV4l2Device dev{clock, {ld::FakeCameraSpec::webcam(), ld::FakeCameraSpec::metadataNode()}};
};

// ---------------------------------------------------------------------------
// Capabilities and formats

using Capabilities = Fixture;

TEST_F(Capabilities, MetadataNodeIsNotACaptureDevice) {
  ld::V4l2Capture cap(dev, clock);
  const std::string msg = captureError([&] { cap.open("/dev/video1", {}); }, Kind::NotCapture);
  EXPECT_EQ(msg, "/dev/video1 (Fake UVC Camera) is not a video capture device (it is a metadata node)");
  EXPECT_FALSE(cap.isOpen());
  expectNoLeaks(dev, "/dev/video1");
}

TEST(CapabilitiesNoStreaming, ReadOnlyDeviceIsRefused) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", {}); }, Kind::NotCapture),
            "/dev/video0 (Fake UVC Camera) does not support streaming I/O");
  expectNoLeaks(dev);
}

TEST_F(Capabilities, MissingDevice) {
  ld::V4l2Capture cap(dev, clock);
  EXPECT_EQ(captureError([&] { cap.open("/dev/video7", {}); }, Kind::NoDevice),
            "/dev/video7: no such device");
  dev.unplug("/dev/video0");
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", {}); }, Kind::NoDevice),
            "/dev/video0: no such device");
  // ReconnectingCapture: a device missing at start is fatal, not retried.
  ld::ReconnectingCapture rc(dev, clock, "/dev/video0", {});
  EXPECT_EQ(captureError([&] { rc.start(); }, Kind::NoDevice), "/dev/video0: no such device");
}

TEST_F(Capabilities, PermissionDeniedAndBusy) {
  ld::V4l2Capture cap(dev, clock);
  dev.failOpen("/dev/video0", EACCES);
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", {}); }, Kind::Unavailable),
            "/dev/video0: permission denied (is the user in the 'video' group?)");
  dev.failOpen("/dev/video0", 0);

  cap.open("/dev/video0", {});
  cap.start();
  ld::V4l2Capture second(dev, clock);  // another process on the same camera
  const std::string msg = captureError([&] { second.open("/dev/video0", {}); }, Kind::Unavailable);
  EXPECT_NE(msg.find("busy"), std::string::npos) << msg;
  cap.close();
  expectNoLeaks(dev);
}

using Formats = Fixture;

TEST_F(Formats, EachFormatIsNegotiated) {
  struct Case {
    uint32_t fourcc, w, h;
    double fps, want_fps;
    uint32_t bytesperline;
  };
  const Case cases[] = {
      {V4L2_PIX_FMT_YUYV, 640, 480, 30, 30, 1280},
      {V4L2_PIX_FMT_YUYV, 320, 240, 15, 15, 640},
      {V4L2_PIX_FMT_YUYV, 1280, 720, 30, 10, 2560},  // only 10 fps offered: the nearest
      {V4L2_PIX_FMT_MJPEG, 1280, 720, 25, 30, 0},
      {V4L2_PIX_FMT_GREY, 640, 480, 30, 30, 640},
  };
  for (const auto& c : cases) {
    ld::V4l2Capture cap(dev, clock);
    const ld::CaptureFormat& f = cap.open("/dev/video0", request(c.fourcc, c.w, c.h, c.fps));
    EXPECT_EQ(f.fourcc, c.fourcc);
    EXPECT_EQ(f.width, c.w);
    EXPECT_EQ(f.height, c.h);
    EXPECT_EQ(f.bytesperline, c.bytesperline);
    EXPECT_DOUBLE_EQ(f.fps, c.want_fps);
    EXPECT_EQ(f.card, "Fake UVC Camera");
    EXPECT_EQ(f.driver, "uvcvideo");
    const v4l2_pix_format cur = dev.currentFormat();
    EXPECT_EQ(cur.pixelformat, c.fourcc);
    EXPECT_EQ(cur.width, c.w);
    ASSERT_EQ(cap.offered().size(), 3u);
  }
  expectNoLeaks(dev);
}

TEST_F(Formats, ZeroKeepsTheCurrentFormat) {
  ld::V4l2Capture cap(dev, clock);
  const auto& f = cap.open("/dev/video0", request(0, 0, 0, 0));
  EXPECT_EQ(f.fourcc, static_cast<uint32_t>(V4L2_PIX_FMT_YUYV));
  EXPECT_EQ(f.width, 640u);
  EXPECT_EQ(f.height, 480u);
  EXPECT_DOUBLE_EQ(f.fps, 30);
  EXPECT_EQ(f.describe(), "YUYV 640x480 @ 30 fps, 4 buffers");
  // Another format with no size: its first offered size.
  cap.open("/dev/video0", request(V4L2_PIX_FMT_MJPEG, 0, 0));
  EXPECT_EQ(cap.format().width, 640u);  // 640x480 is offered in MJPEG too: kept
  cap.open("/dev/video0", request(V4L2_PIX_FMT_YUYV, 1280, 720, 10));
  cap.open("/dev/video0", request(V4L2_PIX_FMT_GREY, 0, 0));
  EXPECT_EQ(cap.format().width, 640u);  // 1280x720 is not offered in GREY: the first size
}

TEST_F(Formats, RefusedFormatListsWhatIsOffered) {
  ld::V4l2Capture cap(dev, clock);
  const std::string offered =
      "it offers: YUYV 640x480, 320x240, 1280x720; MJPEG 1280x720, 640x480, 320x240; GREY 640x480";
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", request(V4L2_PIX_FMT_MJPEG, 1920, 1080)); },
                         Kind::FormatRefused),
            "/dev/video0 does not offer MJPEG 1920x1080; " + offered);
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", request(V4L2_PIX_FMT_UYVY, 640, 480)); },
                         Kind::FormatRefused),
            "/dev/video0 does not offer UYVY 640x480; " + offered);
  EXPECT_FALSE(cap.isOpen());
  expectNoLeaks(dev);
}

TEST_F(Formats, DriverSubstitutionIsDetected) {
  // A driver that enumerates nothing: S_FMT is trusted, and what it
  // substitutes (as real drivers do instead of failing) is caught.
  dev.failIoctl(VIDIOC_ENUM_FMT, EINVAL);
  ld::V4l2Capture cap(dev, clock);
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", request(V4L2_PIX_FMT_MJPEG, 1920, 1080)); },
                         Kind::FormatRefused),
            "/dev/video0 does not offer MJPEG 1920x1080; it offers: no formats (the driver "
            "substituted MJPEG 1280x720)");
  expectNoLeaks(dev);
}

// A manual exposure: automatic exposure off (V4L2_CID_EXPOSURE_AUTO, which
// must come first: the fake refuses the time while it is on, as some drivers
// do), then the time in the control's 100 us, clamped to its range, read back and
// reported; 0 leaves the device's automatic exposure alone.
using Exposure = Fixture;

TEST_F(Exposure, ManualTimeIsSetClampedAndReported) {
  ld::V4l2Capture cap(dev, clock);
  auto r = request(V4L2_PIX_FMT_YUYV, 640, 480);
  cap.open("/dev/video0", r);
  EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_APERTURE_PRIORITY);  // not asked for: untouched
  EXPECT_DOUBLE_EQ(cap.format().exposure_ms, 0);
  struct Case { double ms, set_ms; int32_t units; };
  for (const Case& c : {Case{5, 5, 50}, Case{2.54, 2.5, 25}, Case{500, 204.7, 2047}, Case{0.01, 0.3, 3}}) {
    r.exposure_ms = c.ms;
    const auto& f = cap.open("/dev/video0", r);
    EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_MANUAL) << c.ms;
    EXPECT_EQ(dev.exposure().time, c.units) << c.ms;
    EXPECT_DOUBLE_EQ(f.exposure_ms, c.set_ms) << c.ms;
  }
  r.exposure_ms = 1e300;  // any finite time the command line takes: the longest
  EXPECT_DOUBLE_EQ(cap.open("/dev/video0", r).exposure_ms, 204.7);
  r.exposure_ms = 5;
  EXPECT_EQ(cap.open("/dev/video0", r).describe(), "YUYV 640x480 @ 30 fps, exposure 5 ms, 4 buffers");
  cap.start();
  ld::Frame f;
  ASSERT_TRUE(cap.grab(f, 1000));
  cap.requeue(f);
  cap.close();
  // Closed: the camera's exposure as it was found (automatic).
  EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_APERTURE_PRIORITY);
  EXPECT_EQ(dev.exposure().time, 156);
  expectNoLeaks(dev);
}

// Devices unlike the usual webcam: no automatic exposure switch (the time
// alone, set at once), a coarser step (the nearest step, within the range),
// and a switch without a manual setting, which leaves the time refused: a
// clear error saying so, not a permissions one.
TEST(ExposureDevices, NoSwitchCoarseStepsAndNoManualMode) {
  ld::FakeClock clock;
  auto r = request(V4L2_PIX_FMT_YUYV, 640, 480);
  r.exposure_ms = 5;
  {
    auto spec = ld::FakeCameraSpec::webcam();
    spec.exposure_auto_control = false;
    spec.exposure_step = 5;
    ld::FakeV4l2Device dev(clock, {spec});
    ld::V4l2Capture cap(dev, clock);
    EXPECT_DOUBLE_EQ(cap.open("/dev/video0", r).exposure_ms, 4.8);  // 3 + 5 k nearest 50: 48
    r.exposure_ms = 500;
    EXPECT_DOUBLE_EQ(cap.open("/dev/video0", r).exposure_ms, 204.3);  // the last step in range: 2043
    cap.close();
    EXPECT_EQ(dev.exposure().time, 153);  // 156 put back, on the device's steps
  }
  {
    auto spec = ld::FakeCameraSpec::webcam();
    spec.exposure_manual_mode = false;
    ld::FakeV4l2Device dev(clock, {spec});
    ld::V4l2Capture cap(dev, clock);
    EXPECT_EQ(captureError([&] { cap.open("/dev/video0", r); }, Kind::ControlRefused),
              "/dev/video0 (Fake UVC Camera) refused the exposure time (Permission denied): its automatic "
              "exposure could not be turned off");
    EXPECT_FALSE(cap.isOpen());
    expectNoLeaks(dev);
  }
}

TEST(ExposureMissing, ADeviceWithoutTheControlIsRefused) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.exposure_control = false;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  auto r = request(V4L2_PIX_FMT_YUYV, 640, 480);
  r.exposure_ms = 5;
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", r); }, Kind::ControlRefused),
            "/dev/video0 (Fake UVC Camera) has no manual exposure control (V4L2_CID_EXPOSURE_ABSOLUTE; v4l2-ctl -d "
            "/dev/video0 -l lists its controls): run without the exposure");
  EXPECT_FALSE(cap.isOpen());
  expectNoLeaks(dev);
  r.exposure_ms = 0;  // not asked for: no control needed
  EXPECT_NO_THROW(cap.open("/dev/video0", r));
  cap.close();
}

TEST_F(Exposure, SetAgainAfterTheDeviceCameBack) {
  // A camera unplugged and plugged back powers on with automatic exposure:
  // the reconnecting capture sets the manual time again.
  auto r = request(V4L2_PIX_FMT_YUYV, 640, 480);
  r.exposure_ms = 4;
  ld::ReconnectingCapture rc(dev, clock, "/dev/video0", r, {}, [](const std::string&) {});
  rc.start();
  ld::Frame f;
  ASSERT_TRUE(rc.grab(f, 1000));
  rc.requeue(f);
  dev.unplug();
  EXPECT_FALSE(rc.grab(f, 200));
  dev.replug();
  EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_APERTURE_PRIORITY);
  int polls = 0;
  while (!rc.grab(f, 200)) ASSERT_LT(++polls, 50);
  rc.requeue(f);
  EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(dev.exposure().time, 40);
  rc.stop();
  expectNoLeaks(dev);
}

TEST(FormatNames, RoundTrip) {
  EXPECT_EQ(ld::captureFormatFromName("yuyv"), static_cast<uint32_t>(V4L2_PIX_FMT_YUYV));
  EXPECT_EQ(ld::captureFormatFromName("MJPG"), static_cast<uint32_t>(V4L2_PIX_FMT_MJPEG));
  EXPECT_EQ(ld::captureFormatFromName("gray"), static_cast<uint32_t>(V4L2_PIX_FMT_GREY));
  EXPECT_THROW(ld::captureFormatFromName("h264"), std::invalid_argument);
  EXPECT_EQ(ld::captureFormatName(V4L2_PIX_FMT_MJPEG), "MJPEG");
  EXPECT_EQ(ld::fourccText(V4L2_PIX_FMT_MJPEG), "MJPG");
  EXPECT_EQ(ld::fourccText(0x01020304), "0x01020304");
}

// ---------------------------------------------------------------------------
// Buffers

using Buffers = Fixture;

TEST_F(Buffers, AtLeastFourRequestedAllMappedAndUnmapped) {
  for (unsigned asked : {1u, 4u, 8u}) {
    {
      ld::CaptureRequest r;
      r.buffers = asked;
      ld::V4l2Capture cap(dev, clock);
      const auto& f = cap.open("/dev/video0", r);
      const unsigned want = std::max(4u, asked);
      EXPECT_EQ(dev.stats().requested_buffers, want);
      EXPECT_EQ(f.buffers, want);
      EXPECT_EQ(dev.stats().live_mappings, static_cast<int>(want));
      EXPECT_EQ(dev.stats().open_fds, 1);
      cap.start();
      ld::Frame frame;
      ASSERT_TRUE(cap.grab(frame, 1000));
      cap.requeue(frame);
    }  // the destructor closes
    expectNoLeaks(dev);
  }
}

TEST(BuffersTooFew, OneBufferIsAnErrorWithoutLeaks) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.max_buffers = 1;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  EXPECT_EQ(captureError([&] { cap.open("/dev/video0", {}); }, Kind::Io),
            "/dev/video0: the driver granted 1 buffer(s); capture needs at least 2");
  expectNoLeaks(dev);
}

TEST_F(Buffers, AllHeldIsAProgrammingError) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  std::vector<ld::Frame> held(4);
  for (auto& f : held) ASSERT_TRUE(cap.grab(f, 1000));
  ld::Frame more;
  EXPECT_THROW(cap.grab(more, 1000), std::logic_error);
  EXPECT_THROW(cap.requeue(more), std::logic_error);
  for (auto& f : held) cap.requeue(f);
  EXPECT_TRUE(cap.grab(more, 1000));
}

// ---------------------------------------------------------------------------
// The capture loop

using Loop = Fixture;

TEST_F(Loop, FramesInOrderWithDriverTimestamps) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  const int64_t t0 = clock.monotonicUs();
  cap.start();
  for (uint32_t k = 0; k < 20; ++k) {
    ld::Frame f;
    ASSERT_TRUE(cap.grab(f, 1000)) << k;
    EXPECT_EQ(f.sequence, k);
    EXPECT_EQ(f.seq, k);
    EXPECT_TRUE(f.driver_timestamp);
    // The fake stamps frame k at STREAMON + (k+1) intervals, on CLOCK_MONOTONIC.
    EXPECT_EQ(f.monotonic_us, t0 + (k + 1) * kFrameUs);
    EXPECT_EQ(f.utime, f.monotonic_us + clock.offsetUs());  // wall clock
    EXPECT_EQ(f.bytesused, 640u * 480u * 2u);
    EXPECT_EQ(f.width, 640u);
    EXPECT_EQ(f.bytesperline, 1280u);
    EXPECT_EQ(f.fourcc, static_cast<uint32_t>(V4L2_PIX_FMT_YUYV));
    cap.requeue(f);
  }
  // The fake clock advanced by the poll waits, not more.
  EXPECT_EQ(clock.monotonicUs(), t0 + 20 * kFrameUs);
  EXPECT_EQ(cap.stats().frames, 20);
  EXPECT_EQ(cap.stats().sequence_gaps, 0);
}

TEST_F(Loop, TimestampOfADriverWithoutOneIsTheDequeueTime) {
  ld::FakeClock c;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.timestamp_flags = V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN;
  ld::FakeV4l2Device d(c, {spec});
  ld::V4l2Capture cap(d, c);
  cap.open("/dev/video0", {});
  cap.start();
  c.advanceUs(5 * kFrameUs + 1234);  // frames are waiting: dequeued later than captured
  ld::Frame f;
  ASSERT_TRUE(cap.grab(f, 1000));
  EXPECT_FALSE(f.driver_timestamp);
  EXPECT_EQ(f.monotonic_us, c.monotonicUs());
  EXPECT_EQ(f.utime, c.realtimeUs());
}

TEST_F(Loop, TimeoutAndDroppedFrames) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  ld::Frame f;
  EXPECT_FALSE(cap.grab(f, 10));  // the first frame is due after 33 ms
  // A slow consumer: 10 frame times pass, 4 buffers were filled, 6 frames
  // dropped by the driver. The newest of the four is handed out, the three
  // older go back unseen (stale): frames 0, 1, 2 were 300 ms old and more.
  clock.advanceUs(10 * kFrameUs);
  std::vector<uint32_t> seqs;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(cap.grab(f, 1000));
    seqs.push_back(f.sequence);
    cap.requeue(f);
  }
  EXPECT_EQ(seqs, (std::vector<uint32_t>{3, 10, 11}));
  EXPECT_EQ(cap.stats().stale, 3);
  EXPECT_EQ(cap.stats().sequence_gaps, 6);
  EXPECT_EQ(cap.stats().frames, 3);
  EXPECT_EQ(dev.stats().dropped, 6);
}

TEST_F(Loop, EagainAndEintrAreHandled) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  ld::Frame f;
  dev.failIoctl(VIDIOC_DQBUF, EAGAIN, 2);  // woken, but nothing to dequeue
  EXPECT_FALSE(cap.grab(f, 1000));
  EXPECT_FALSE(cap.grab(f, 1000));
  EXPECT_EQ(cap.stats().spurious, 2);
  ASSERT_TRUE(cap.grab(f, 1000));
  EXPECT_EQ(f.sequence, 0u);
  cap.requeue(f);
  dev.failIoctl(VIDIOC_DQBUF, EINTR, 3);  // a signal: the call is retried
  dev.failIoctl(VIDIOC_QBUF, EINTR, 1);
  ASSERT_TRUE(cap.grab(f, 1000));
  EXPECT_EQ(f.sequence, 1u);
  cap.requeue(f);
  ASSERT_TRUE(cap.grab(f, 1000));
  EXPECT_EQ(f.sequence, 2u);
}

TEST_F(Loop, StopAndStartAgain) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  ld::Frame f;
  ASSERT_TRUE(cap.grab(f, 1000));
  cap.stop();
  cap.requeue(f);  // after STREAMOFF a held frame can still be given back
  EXPECT_FALSE(cap.isStreaming());
  cap.start();
  ASSERT_TRUE(cap.grab(f, 1000));
  EXPECT_EQ(f.sequence, 0u);  // the driver restarts its count on STREAMON
  EXPECT_EQ(dev.stats().streamons, 2);
  EXPECT_EQ(dev.stats().streamoffs, 1);
}

// ---------------------------------------------------------------------------
// Unplugging

using Unplug = Fixture;

TEST_F(Unplug, MidStreamIsReportedAndNothingLeaks) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  ld::Frame f;
  ASSERT_TRUE(cap.grab(f, 1000));
  cap.requeue(f);
  dev.unplug();
  const std::string msg = captureError([&] { cap.grab(f, 1000); }, Kind::DeviceLost);
  EXPECT_EQ(msg, "/dev/video0: device lost (VIDIOC_DQBUF: No such device)");
  cap.close();
  expectNoLeaks(dev);
}

TEST_F(Unplug, WhileHoldingAFrame) {
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  ld::Frame f;
  ASSERT_TRUE(cap.grab(f, 1000));
  dev.unplug();
  EXPECT_EQ(f.data[0], f.data[0]);  // the mapping stays readable until munmap
  captureError([&] { cap.requeue(f); }, Kind::DeviceLost);
  cap.close();
  expectNoLeaks(dev);
}

TEST(Backoff, DoublesFromATenthToTwoSeconds) {
  ld::Backoff b;
  std::vector<int64_t> d;
  for (int i = 0; i < 8; ++i) d.push_back(b.nextDelayUs());
  EXPECT_EQ(d, (std::vector<int64_t>{100000, 200000, 400000, 800000, 1600000, 2000000, 2000000,
                                     2000000}));
  b.reset();
  EXPECT_EQ(b.nextDelayUs(), 100000);
}

TEST_F(Unplug, ReopensWithBackoffWhenTheDeviceComesBack) {
  std::vector<std::string> log;
  ld::ReconnectingCapture rc(dev, clock, "/dev/video0", {}, {},
                             [&](const std::string& s) { log.push_back(s); });
  rc.start();
  ld::Frame f;
  int64_t last_seq = -1;
  for (int i = 0; i < 5; ++i) {
    ASSERT_TRUE(rc.grab(f, 1000));
    last_seq = f.seq;
    rc.requeue(f);
  }
  const size_t opens_before = dev.openAttempts().size();
  dev.unplug();
  const int64_t lost_at = clock.monotonicUs();
  EXPECT_FALSE(rc.grab(f, 200));
  EXPECT_FALSE(rc.connected());
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0],
            "/dev/video0: device lost (VIDIOC_DQBUF: No such device); reopening every 0.1-2 s "
            "until it is back");
  expectNoLeaks(dev);  // closed and unmapped at once

  // Away for 4.9 s of (fake) time: attempts at 0.1, 0.3, 0.7, 1.5, 3.1 s fail,
  // the one at 5.1 s finds it back.
  while (clock.monotonicUs() - lost_at < 4900000) EXPECT_FALSE(rc.grab(f, 200));
  dev.replug();
  int polls = 0;
  while (!rc.grab(f, 200)) ASSERT_LT(++polls, 50);
  EXPECT_TRUE(rc.connected());
  EXPECT_EQ(rc.reconnects(), 1);
  EXPECT_EQ(f.seq, last_seq + 1);  // message numbering continues
  EXPECT_EQ(f.sequence, 0u);       // the driver's restarted
  rc.requeue(f);

  std::vector<int64_t> at;
  for (size_t i = opens_before; i < dev.openAttempts().size(); ++i)
    at.push_back(dev.openAttempts()[i].time_us - lost_at);
  const std::vector<int64_t> want{100000, 300000, 700000, 1500000, 3100000, 5100000};
  ASSERT_EQ(at.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i) EXPECT_EQ(at[i], want[i]) << i;
  for (size_t i = opens_before; i + 1 < dev.openAttempts().size(); ++i)
    EXPECT_EQ(dev.openAttempts()[i].error, ENOENT);
  EXPECT_EQ(dev.openAttempts().back().error, 0);
  // Logged once when lost and once when back, not per attempt.
  ASSERT_EQ(log.size(), 2u);
  EXPECT_EQ(log[1], "/dev/video0: reopened after 6 attempts (5.1 s): YUYV 640x480 @ 30 fps, 4 buffers");
  rc.stop();
  expectNoLeaks(dev);
}

// Stopped and started again (the driver numbers its frames from 0 again):
// the frames' numbering goes on, as across a reconnect.
TEST_F(Unplug, NumberingGoesOnAfterStopAndStart) {
  ld::ReconnectingCapture rc(dev, clock, "/dev/video0", {}, {}, [](const std::string&) {});
  std::vector<int64_t> seqs;
  ld::Frame f;
  for (int run = 0; run < 2; ++run) {
    rc.start();
    for (int calls = 0; seqs.size() < 3u * (run + 1) && calls < 100; ++calls) {
      if (!rc.grab(f, 200)) continue;
      seqs.push_back(f.seq);
      rc.requeue(f);
    }
    EXPECT_EQ(f.sequence, 2u);  // the driver's, from 0 each time
    rc.stop();
  }
  EXPECT_EQ(seqs, (std::vector<int64_t>{0, 1, 2, 3, 4, 5}));
  expectNoLeaks(dev);
}

TEST_F(Unplug, WhileWaitingInPollAndBackByItself) {
  std::vector<std::string> log;
  ld::ReconnectingCapture rc(dev, clock, "/dev/video0", {}, {},
                             [&](const std::string& s) { log.push_back(s); });
  rc.start();
  dev.scheduleUnplug("/dev/video0", 3, 450000);  // after 3 frames, back 0.45 s later
  std::vector<int64_t> seqs;
  ld::Frame f;
  for (int calls = 0; seqs.size() < 8 && calls < 100; ++calls) {
    if (!rc.grab(f, 200)) continue;
    seqs.push_back(f.seq);
    rc.requeue(f);
  }
  EXPECT_EQ(seqs, (std::vector<int64_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(rc.reconnects(), 1);
  // the 3 frames before the unplug all delivered, none captured and lost
  // (the third was lost with its buffer: `--fake-unplug-after 3` published 2)
  EXPECT_EQ(dev.stats("/dev/video0").frames, 8) << "frames captured in all";
  ASSERT_EQ(log.size(), 2u);
  EXPECT_NE(log[0].find("device lost"), std::string::npos) << log[0];
  // Back 0.45 s after the unplug: the attempts at 0.1 and 0.3 s fail, 0.7 s works.
  EXPECT_NE(log[1].find("reopened after 3 attempts (0.7 s)"), std::string::npos) << log[1];
}

TEST_F(Unplug, AnotherCameraPluggedInIsRetriedAndLoggedOnce) {
  // Back comes a device without the format: logged once, retried with backoff.
  std::vector<std::string> log;
  ld::ReconnectingCapture rc(dev, clock, "/dev/video0",
                             request(V4L2_PIX_FMT_MJPEG, 1280, 720), {},
                             [&](const std::string& s) { log.push_back(s); });
  rc.start();
  dev.unplug();
  ld::Frame f;
  EXPECT_FALSE(rc.grab(f, 200));
  dev.replug();
  dev.failIoctl(VIDIOC_S_FMT, EBUSY, 3);  // busy three times, then fine
  int polls = 0;
  while (!rc.grab(f, 200)) ASSERT_LT(++polls, 100);
  ASSERT_EQ(log.size(), 3u);
  EXPECT_EQ(log[1], "still reopening: /dev/video0: busy (another process is streaming from it)");
  EXPECT_NE(log[2].find("reopened after 4 attempts"), std::string::npos) << log[2];
}

// ---------------------------------------------------------------------------
// --list

TEST(ListDevices, FakeWebcamAndItsMetadataNode) {
  ld::FakeClock clock;
  ld::FakeV4l2Device dev(clock, {ld::FakeCameraSpec::webcam(), ld::FakeCameraSpec::metadataNode()});
  const auto devices = ld::listDevices(dev);
  ASSERT_EQ(devices.size(), 2u);
  EXPECT_TRUE(devices[0].capture);
  EXPECT_FALSE(devices[1].capture);
  ASSERT_EQ(devices[0].formats.size(), 3u);
  EXPECT_EQ(devices[0].formats[1].sizes[0].fps, (std::vector<double>{30, 15}));
  EXPECT_TRUE(devices[0].formats[1].compressed);
  EXPECT_EQ(ld::formatDeviceList(devices),
            "/dev/video0: Fake UVC Camera (uvcvideo, usb-0000:00:14.0-1)\n"
            "  YUYV   YUYV 4:2:2\n"
            "    640x480     30 15 fps\n"
            "    320x240     30 15 fps\n"
            "    1280x720    10 fps\n"
            "  MJPEG  Motion-JPEG, compressed\n"
            "    1280x720    30 15 fps\n"
            "    640x480     30 15 fps\n"
            "    320x240     30 15 fps\n"
            "  GREY   8-bit Greyscale\n"
            "    640x480     30 fps\n"
            "/dev/video1: Fake UVC Camera (uvcvideo, usb-0000:00:14.0-1): not a video capture "
            "device (metadata node)\n");
  EXPECT_EQ(dev.stats().open_fds, 0);

  dev.failOpen("/dev/video0", EACCES);
  EXPECT_EQ(ld::formatDeviceList({ld::queryDevice(dev, "/dev/video0")}),
            "/dev/video0: permission denied (is the user in the 'video' group?)\n");
  dev.unplug("/dev/video0");
  dev.unplug("/dev/video1");
  EXPECT_EQ(ld::formatDeviceList(ld::listDevices(dev)), "no V4L2 devices (no /dev/video* nodes)\n");
}

TEST(ListDevices, RangesAreDescribed) {
  ld::V4l2FrameSize s;
  s.width = 1920;
  s.height = 1080;
  s.min_width = 160;
  s.min_height = 120;
  s.step_width = 8;
  s.step_height = 8;
  s.min_fps = 1;
  s.max_fps = 30;
  EXPECT_EQ(s.sizeText(), "160x120-1920x1080 step 8x8");
  EXPECT_EQ(s.fpsText(), "1-30 fps");
  EXPECT_TRUE(s.contains(640, 480));
  EXPECT_FALSE(s.contains(641, 480));
  EXPECT_FALSE(s.contains(2000, 480));
}

// ---------------------------------------------------------------------------
// Frames to image_t

struct Images : ::testing::Test {
  ld::FakeClock clock;

  // Captures one frame of `fourcc` WxH and converts it.
  template <typename Check>
  void captureOne(ld::FakeCameraSpec spec, uint32_t fourcc, uint32_t w, uint32_t h,
                  ld::ImageConversion conv, Check check) {
    ld::FakeV4l2Device dev(clock, {spec});
    ld::V4l2Capture cap(dev, clock);
    cap.open("/dev/video0", request(fourcc, w, h));
    cap.start();
    ld::FrameToImage to(conv);
    ld::image_t msg;
    ld::Frame f;
    for (int k = 0; k < 3; ++k) {  // the third frame, on a warm message
      ASSERT_TRUE(cap.grab(f, 1000));
      to.convert(f, msg);
      if (k < 2) cap.requeue(f);
    }
    EXPECT_EQ(msg.utime, f.utime);
    EXPECT_EQ(msg.width, static_cast<int32_t>(w));
    EXPECT_EQ(msg.height, static_cast<int32_t>(h));
    EXPECT_EQ(msg.size, static_cast<int32_t>(msg.data.size()));
    EXPECT_EQ(ld::imageSeq(msg), std::optional<int64_t>(2));
    EXPECT_EQ(msg.nmetadata, 1);
    check(f, msg, ld::FakeV4l2Device::pattern(w, h, f.sequence));
    cap.requeue(f);
  }
};

TEST_F(Images, YuyvKeepsTheDriverStride) {
  auto spec = ld::FakeCameraSpec::webcam();
  spec.row_padding = 64;
  captureOne(spec, V4L2_PIX_FMT_YUYV, 640, 480, ld::ImageConversion::AsCaptured,
             [](const ld::Frame& f, const ld::image_t& msg, const cv::Mat& want) {
               EXPECT_EQ(f.bytesperline, 640u * 2 + 64);
               EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_YUYV);
               EXPECT_EQ(msg.row_stride, 640 * 2 + 64);
               EXPECT_EQ(msg.size, (640 * 2 + 64) * 479 + 640 * 2);
               EXPECT_EQ(msg.data[640 * 2], 0xEE);  // the padding travels, untouched
               EXPECT_LT(meanAbsDiff(ld::imageToBgr(msg), want), 4.0);
             });
}

TEST_F(Images, MjpegIsBytesusedLong) {
  captureOne(ld::FakeCameraSpec::webcam(), V4L2_PIX_FMT_MJPEG, 640, 480,
             ld::ImageConversion::AsCaptured,
             [](const ld::Frame& f, const ld::image_t& msg, const cv::Mat& want) {
               EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_MJPEG);
               EXPECT_EQ(msg.row_stride, 0);
               EXPECT_EQ(static_cast<size_t>(msg.size), f.bytesused);
               EXPECT_LT(f.bytesused, 640u * 480u * 2u);  // not the whole buffer
               EXPECT_EQ(msg.data[msg.size - 2], 0xFF);   // ends with the JPEG EOI marker
               EXPECT_EQ(msg.data[msg.size - 1], 0xD9);
               EXPECT_LT(meanAbsDiff(ld::imageToBgr(msg), want), 4.0);
             });
}

TEST_F(Images, GreyIsGray) {
  auto spec = ld::FakeCameraSpec::webcam();
  spec.row_padding = 16;
  captureOne(spec, V4L2_PIX_FMT_GREY, 640, 480, ld::ImageConversion::AsCaptured,
             [](const ld::Frame&, const ld::image_t& msg, const cv::Mat& want) {
               EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_GRAY);
               EXPECT_EQ(msg.row_stride, 656);
               cv::Mat gray;
               ld::imageToMat(msg, gray);
               cv::Mat want_gray;
               cv::cvtColor(want, want_gray, cv::COLOR_BGR2GRAY);
               EXPECT_LT(meanAbsDiff(gray, want_gray), 2.0);
             });
}

TEST_F(Images, ConvertedOnRequest) {
  for (uint32_t fourcc : {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_GREY}) {
    SCOPED_TRACE(ld::captureFormatName(fourcc));
    const bool grey = fourcc == V4L2_PIX_FMT_GREY;
    captureOne(ld::FakeCameraSpec::webcam(), fourcc, 640, 480, ld::ImageConversion::Bgr,
               [&](const ld::Frame&, const ld::image_t& msg, const cv::Mat& want) {
                 EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_BGR);
                 EXPECT_EQ(msg.row_stride, 640 * 3);
                 EXPECT_EQ(msg.size, 640 * 480 * 3);
                 cv::Mat ref = want;
                 if (grey) {
                   cv::cvtColor(want, ref, cv::COLOR_BGR2GRAY);
                   cv::cvtColor(ref, ref, cv::COLOR_GRAY2BGR);
                 }
                 EXPECT_LT(meanAbsDiff(ld::imageToBgr(msg), ref), 4.0);
               });
    captureOne(ld::FakeCameraSpec::webcam(), fourcc, 640, 480, ld::ImageConversion::Rgb,
               [&](const ld::Frame&, const ld::image_t& msg, const cv::Mat&) {
                 EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_RGB);
                 // Red comes first: 96 at the pattern's top-left (0.299 * 96 in GREY).
                 EXPECT_NEAR(msg.data[0], grey ? 29 : 96, 6);
               });
    captureOne(ld::FakeCameraSpec::webcam(), fourcc, 640, 480, ld::ImageConversion::Gray,
               [&](const ld::Frame&, const ld::image_t& msg, const cv::Mat& want) {
                 EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_GRAY);
                 EXPECT_EQ(msg.size, 640 * 480);
                 cv::Mat gray, want_gray;
                 ld::imageToMat(msg, gray);
                 cv::cvtColor(want, want_gray, cv::COLOR_BGR2GRAY);
                 EXPECT_LT(meanAbsDiff(gray, want_gray), 3.0);
               });
  }
}

TEST_F(Images, WarmMessageIsReused) {
  ld::FakeV4l2Device dev(clock);
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", {});
  cap.start();
  ld::FrameToImage to;
  ld::image_t msg;
  ld::Frame f;
  const uint8_t* data = nullptr;
  const uint8_t* seq = nullptr;
  for (int k = 0; k < 30; ++k) {
    ASSERT_TRUE(cap.grab(f, 1000));
    to.convert(f, msg);
    cap.requeue(f);
    if (k == 0) {
      data = msg.data.data();
      seq = msg.metadata.at(0).value.data();
    }
    EXPECT_EQ(msg.data.data(), data);
    EXPECT_EQ(msg.metadata.at(0).value.data(), seq);
    EXPECT_EQ(ld::imageSeq(msg), std::optional<int64_t>(k));
  }
}

TEST_F(Images, TruncatedFramesAreRefused) {
  ld::Frame f;
  std::vector<uint8_t> bytes(100);
  f.data = bytes.data();
  f.bytesused = bytes.size();
  f.fourcc = V4L2_PIX_FMT_YUYV;
  f.width = 640;
  f.height = 480;
  f.bytesperline = 1280;
  ld::image_t msg;
  EXPECT_THROW(ld::FrameToImage().convert(f, msg), ld::ImageFormatError);
  f.fourcc = V4L2_PIX_FMT_MJPEG;
  EXPECT_THROW(ld::FrameToImage(ld::ImageConversion::Bgr).convert(f, msg), ld::ImageFormatError);
  EXPECT_EQ(ld::imageConversionFromName("GREY"), ld::ImageConversion::Gray);
  EXPECT_THROW(ld::imageConversionFromName("hsv"), std::invalid_argument);
  // A JPEG whose data was damaged in transfer but ends right: refused when
  // converted (cv::imdecode filled the lost part with grey and it went on)
  ld::image_t jpeg = ld::matToImage(ld::FakeV4l2Device::pattern(320, 240, 7), ld::image_t::PIXEL_FORMAT_MJPEG, 0);
  std::vector<uint8_t> damaged(jpeg.data.begin(), jpeg.data.begin() + static_cast<long>(jpeg.data.size() / 2));
  damaged.push_back(0xFF);
  damaged.push_back(0xD9);
  f.data = damaged.data();
  f.bytesused = damaged.size();
  f.width = 320;
  f.height = 240;
  try {
    ld::FrameToImage(ld::ImageConversion::Bgr).convert(f, msg);
    ADD_FAILURE() << "a damaged JPEG converted";
  } catch (const ld::ImageFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("the JPEG data is damaged (libjpeg: Corrupt JPEG data"), std::string::npos)
        << e.what();
  }
}

// ---------------------------------------------------------------------------
// What real UVC cameras do that the plain webcam does not

// The Logitech C920 sets its exposure time again at STREAMON, automatic
// exposure off or not: the manual time is set again once streaming, at
// every start, and close() still puts back what the camera had.
TEST(Quirks, ExposureResetAtStreamonIsSetAgain) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.resets_exposure_at_streamon = true;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  openWithExposure(cap);
  cap.start();
  EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(dev.exposure().time, 50);  // (156, the default, without the second setting)
  cap.stop();
  cap.start();
  EXPECT_EQ(dev.exposure().time, 50);
  cap.close();
  EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_APERTURE_PRIORITY);
  EXPECT_EQ(dev.exposure().time, 156);
  expectNoLeaks(dev);
}

// A camera that takes no control while streaming (EBUSY) keeps the
// exposure set before STREAMON, and starts; one that also resets it at
// STREAMON cannot run with it, and says so.
TEST(Quirks, ControlsRefusedWhileStreaming) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.controls_busy_while_streaming = true;
  {
    ld::FakeV4l2Device dev(clock, {spec});
    ld::V4l2Capture cap(dev, clock);
    openWithExposure(cap);
    cap.start();
    EXPECT_EQ(dev.exposure().mode, V4L2_EXPOSURE_MANUAL);
    EXPECT_EQ(dev.exposure().time, 50);
    EXPECT_EQ(cap.format().exposure_ms, 5);
    cap.stop();
    cap.start();
    EXPECT_EQ(dev.exposure().time, 50);
    cap.close();
    EXPECT_EQ(dev.exposure().time, 156);  // (put back once streaming stopped)
    expectNoLeaks(dev);
  }
  spec.resets_exposure_at_streamon = true;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  openWithExposure(cap);
  EXPECT_EQ(captureError([&] { cap.start(); }, Kind::ControlRefused),
            "/dev/video0 (Fake UVC Camera) takes no exposure control while streaming, and STREAMON changed "
            "its exposure time from 5 to 15.6 ms: run without the exposure");
  cap.close();
  expectNoLeaks(dev);
}

// The fake camera, with what some firmware does once streaming: S_CTRL
// answers `refuse_errno`, and STREAMON may turn automatic exposure on again.
class StreamingControlQuirks : public ld::V4l2Io {
 public:
  StreamingControlQuirks(ld::FakeV4l2Device& dev, int refuse_errno, bool auto_on_at_streamon,
                         bool gone_after_refusal = false)
      : dev_(dev), refuse_(refuse_errno), auto_on_(auto_on_at_streamon), gone_(gone_after_refusal) {}
  int open(const char* path, int flags) override { return dev_.open(path, flags); }
  int close(int fd) override { return dev_.close(fd); }
  int ioctl(int fd, unsigned long request, void* arg) override {
    if (request == VIDIOC_S_CTRL && streaming_) {
      errno = refuse_;
      refused_ = true;
      return -1;
    }
    if (request == VIDIOC_G_CTRL && refused_ && gone_) {  // (unplugged just then)
      errno = ENODEV;
      return -1;
    }
    const int rc = dev_.ioctl(fd, request, arg);
    if (rc == 0 && request == VIDIOC_STREAMON) {
      streaming_ = true;
      if (auto_on_) {
        v4l2_control c{};
        c.id = V4L2_CID_EXPOSURE_AUTO;
        c.value = V4L2_EXPOSURE_APERTURE_PRIORITY;
        dev_.ioctl(fd, VIDIOC_S_CTRL, &c);
      }
    }
    if (rc == 0 && request == VIDIOC_STREAMOFF) streaming_ = false;
    return rc;
  }
  void* mmap(void* addr, size_t length, int prot, int flags, int fd, off_t offset) override {
    return dev_.mmap(addr, length, prot, flags, fd, offset);
  }
  int munmap(void* addr, size_t length) override { return dev_.munmap(addr, length); }
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override { return dev_.poll(fds, nfds, timeout_ms); }
  std::vector<std::string> deviceNodes() override { return dev_.deviceNodes(); }

 private:
  ld::FakeV4l2Device& dev_;
  int refuse_;
  bool auto_on_, gone_;
  bool streaming_ = false, refused_ = false;
};

// Only EBUSY is a camera that takes no control while streaming: one that
// turns automatic exposure on again at STREAMON is refused naming it, and a
// control the firmware refuses (EIO) while streaming is refused as before (a
// review: any refusal was taken for EBUSY, and the mode never looked at).
TEST(Quirks, OnlyABusyControlKeepsTheExposureSetBefore) {
  for (const auto& [err, auto_on, starts] : {std::tuple{EBUSY, false, true}, std::tuple{EBUSY, true, false},
                                             std::tuple{EIO, false, false}, std::tuple{EIO, true, false}}) {
    ld::FakeClock clock;
    ld::FakeV4l2Device dev(clock);
    StreamingControlQuirks io(dev, err, auto_on);
    ld::V4l2Capture cap(io, clock);
    openWithExposure(cap);
    std::string why;
    if (starts)
      EXPECT_NO_THROW(cap.start()) << err << " " << auto_on;
    else
      why = captureError([&] { cap.start(); }, Kind::ControlRefused);
    EXPECT_EQ(why.empty(), starts) << err << " " << auto_on << ": " << why;
    if (err == EBUSY && auto_on) {
      EXPECT_EQ(why, "/dev/video0 (Fake UVC Camera) takes no exposure control while streaming, and STREAMON turned "
                     "its automatic exposure on again: run without the exposure");
    }
    if (err == EIO) {
      EXPECT_NE(why.find("refused to turn its automatic exposure off (Input/output error)"), std::string::npos) << why;
    }
    cap.close();
    expectNoLeaks(dev);
  }
}

// Both changed at STREAMON are said together; a device gone while the
// exposure is looked at after the refusal is a lost device.
TEST(Quirks, BusyControlsWhenStreamonChangedBothOrTheDeviceWent) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.resets_exposure_at_streamon = true;
  for (bool gone : {false, true}) {
    ld::FakeV4l2Device dev(clock, {spec});
    StreamingControlQuirks io(dev, EBUSY, true, gone);
    ld::V4l2Capture cap(io, clock);
    openWithExposure(cap);
    if (gone)
      captureError([&] { cap.start(); }, Kind::DeviceLost);
    else
      EXPECT_EQ(captureError([&] { cap.start(); }, Kind::ControlRefused),
                "/dev/video0 (Fake UVC Camera) takes no exposure control while streaming, and STREAMON turned its "
                "automatic exposure on again and changed its exposure time from 5 to 15.6 ms: run without the "
                "exposure");
    cap.close();
    expectNoLeaks(dev);
  }
}

// A stream that stops while the device stays (firmware, USB), against a
// reconnecting capture that has handed out its first frame; what it logs is
// kept.
struct Stall : ::testing::Test {
  ld::FakeClock clock;
  ld::FakeV4l2Device dev{clock};
  std::vector<std::string> log;
  ld::ReconnectingCapture rc{dev, clock, "/dev/video0", request(V4L2_PIX_FMT_YUYV, 640, 480), {},
                             [this](const std::string& s) { log.push_back(s); }};
  ld::Frame f;
  void SetUp() override {
    rc.start();
    ASSERT_TRUE(rc.grab(f, 1000));
    rc.requeue(f);
  }
};

// No good frame for 2 s is a lost stream, reopened as an unplugged device is.
TEST_F(Stall, AStalledStreamIsReopened) {
  EXPECT_EQ(rc.stallLimitUs(), 2000000);  // (10 frames at 30 fps are less)
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE(rc.grab(f, 1000));
    rc.requeue(f);
  }
  dev.stall();
  const int64_t t0 = clock.monotonicUs();
  int polls = 0;
  while (rc.connected()) {
    EXPECT_FALSE(rc.grab(f, 200));
    ASSERT_LT(++polls, 100);
  }
  EXPECT_GE(clock.monotonicUs() - t0, 2000000);
  EXPECT_LT(clock.monotonicUs() - t0, 2300000);
  ASSERT_EQ(log.size(), 1u);
  EXPECT_EQ(log[0].rfind("/dev/video0: no good frame for 2.", 0), 0u) << log[0];
  EXPECT_NE(log[0].find(" s while streaming (the camera stalled); reopening every 0.1-2 s"), std::string::npos)
      << log[0];
  while (!rc.grab(f, 200)) ASSERT_LT(++polls, 200);
  EXPECT_EQ(rc.reconnects(), 1);
  EXPECT_EQ(rc.totals().frames, 4);  // (counted across the reopening)
  rc.requeue(f);
  rc.stop();
  EXPECT_EQ(rc.totals().frames, 4);  // (and after the stop, as the exit line reads them)
  expectNoLeaks(dev);
}

// A camera that stalls again right after each reopening (its firmware
// stays wedged): reopened with a growing backoff, said once, not every 2 s.
TEST_F(Stall, AStreamThatStaysStalledIsReopenedQuietlyWithBackoff) {
  dev.stall("/dev/video0", true);
  std::vector<int64_t> reopened_at;  // when each reopening happened
  int reconnects = 0;
  for (int polls = 0; polls < 2000 && reopened_at.size() < 4; ++polls) {
    EXPECT_FALSE(rc.grab(f, 200));
    if (rc.reconnects() > reconnects) {
      reconnects = rc.reconnects();
      reopened_at.push_back(clock.monotonicUs());
    }
  }
  ASSERT_EQ(reopened_at.size(), 4u);
  // each cycle: the 2 s limit, then a backoff that grows (0.1, 0.3, 0.7, ...)
  for (size_t i = 2; i < reopened_at.size(); ++i)
    EXPECT_GT(reopened_at[i] - reopened_at[i - 1], reopened_at[i - 1] - reopened_at[i - 2]) << i;
  ASSERT_EQ(log.size(), 2u);  // lost, reopened; then nothing until a good frame
  rc.stop();
  expectNoLeaks(dev);
}

// Firmware that refuses a control answers EIO (uvcvideo), older kernels
// EILSEQ: the control is refused, the device is not lost.
TEST(Quirks, ExposureRefusedByTheFirmwareIsNotALostDevice) {
  for (const int err : {EIO, EILSEQ}) {
    ld::FakeClock clock;
    ld::FakeV4l2Device dev(clock);
    ld::V4l2Capture cap(dev, clock);
    auto r = request(V4L2_PIX_FMT_YUYV, 640, 480);
    r.exposure_ms = 5;
    dev.failIoctl(VIDIOC_S_CTRL, err);
    EXPECT_EQ(captureError([&] { cap.open("/dev/video0", r); }, Kind::ControlRefused),
              "/dev/video0 (Fake UVC Camera) refused to turn its automatic exposure off (" +
                  std::string(std::strerror(err)) + "): run without the exposure");
    expectNoLeaks(dev);
  }
}

// A driver that never sets bytesused for its raw frames (some capture
// cards): its frames are whole. One that has set it hands out an empty
// buffer as no frame.
TEST(Quirks, RawFramesOfADriverThatNeverSetsBytesused) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.raw_bytesused_zero = true;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", request(V4L2_PIX_FMT_YUYV, 640, 480));
  cap.start();
  ld::Frame f;
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(cap.grab(f, 1000)) << i;
    EXPECT_EQ(f.bytesused, 640u * 480u * 2u);
    cap.requeue(f);
  }
  EXPECT_EQ(cap.stats().truncated, 0);
  cap.close();
  expectNoLeaks(dev);
}

// uvcvideo checks the size of raw frames alone: an MJPEG frame cut short
// comes without the error flag. It is skipped and counted, not handed out.
TEST(Quirks, MjpegCutShortWithoutTheErrorFlagIsSkipped) {
  ld::FakeClock clock;
  auto spec = ld::FakeCameraSpec::webcam();
  spec.mjpeg_cut_every = 3;
  ld::FakeV4l2Device dev(clock, {spec});
  ld::V4l2Capture cap(dev, clock);
  cap.open("/dev/video0", request(V4L2_PIX_FMT_MJPEG, 640, 480));
  cap.start();
  ld::Frame f;
  int good = 0, polls = 0;
  while (good < 10) {
    ASSERT_LT(++polls, 100);
    if (!cap.grab(f, 1000)) continue;
    EXPECT_TRUE(ld::jpegComplete(f.data, f.bytesused)) << f.sequence;
    EXPECT_NE(f.sequence % 3, 2u) << "the cut frame handed out";
    ++good;
    cap.requeue(f);
  }
  EXPECT_GE(cap.stats().truncated, 4);
  EXPECT_EQ(cap.stats().errored, 0);
  EXPECT_EQ(cap.stats().sequence_gaps, 0);  // (a frame cut short is no frame the driver dropped)
  EXPECT_EQ(dev.stats().dropped, 0);
  cap.close();
  expectNoLeaks(dev);
}

// Devices that are not the plain webcam: a media-controller camera (the
// Raspberry Pi's unicam: streaming alone fails with "Broken pipe"), a USB
// bus without the bandwidth (uvcvideo's ENOSPC at STREAMON), a format that
// lists no sizes (capture cards: the driver's reply is trusted).
TEST(Quirks, MediaControllerBandwidthAndUnlistedSizes) {
  ld::FakeClock clock;
  {
    auto spec = ld::FakeCameraSpec::webcam();
    spec.device_caps |= V4L2_CAP_IO_MC;
    spec.driver = "unicam";
    ld::FakeV4l2Device dev(clock, {spec});
    ld::V4l2Capture cap(dev, clock);
    EXPECT_EQ(captureError([&] { cap.open("/dev/video0", request(V4L2_PIX_FMT_YUYV, 640, 480)); },
                           Kind::NotCapture),
              "/dev/video0 (Fake UVC Camera) is a media-controller camera (unicam): its pipeline needs libcamera "
              "(libcamerify ld-camera ...) or the legacy camera driver");
    expectNoLeaks(dev);
  }
  {
    ld::FakeV4l2Device dev(clock);
    ld::V4l2Capture cap(dev, clock);
    cap.open("/dev/video0", request(V4L2_PIX_FMT_YUYV, 640, 480));
    dev.failIoctl(VIDIOC_STREAMON, ENOSPC);
    EXPECT_EQ(captureError([&] { cap.start(); }, Kind::Io),
              "/dev/video0: not enough USB bandwidth for YUYV 640x480 @ 30 fps, 4 buffers (VIDIOC_STREAMON: No "
              "space left on device): use MJPEG, a smaller size or rate, or another USB port or controller");
    cap.close();
    expectNoLeaks(dev);
  }
  {
    auto spec = ld::FakeCameraSpec::webcam();
    for (auto& fmt : spec.formats)
      if (fmt.fourcc == V4L2_PIX_FMT_GREY) fmt.sizes.clear();
    ld::FakeV4l2Device dev(clock, {spec});
    ld::V4l2Capture cap(dev, clock);
    const auto& got = cap.open("/dev/video0", request(V4L2_PIX_FMT_GREY, 320, 240));
    EXPECT_EQ(got.width, 320u);
    EXPECT_EQ(got.height, 240u);
    cap.close();
    expectNoLeaks(dev);
  }
}

// ---------------------------------------------------------------------------
// A real camera, when this machine has one

TEST(RealDevice, CapturesAFewFrames) {
  ld::SystemV4l2Io io;
  const auto nodes = io.deviceNodes();
  if (nodes.empty()) GTEST_SKIP() << "no /dev/video* on this machine";
  const auto devices = ld::listDevices(io);
  std::cout << ld::formatDeviceList(devices);
  const ld::V4l2DeviceInfo* cam = nullptr;
  for (const auto& d : devices)
    if (d.capture && !d.formats.empty() && !d.formats[0].sizes.empty()) {
      cam = &d;
      break;
    }
  if (!cam) GTEST_SKIP() << "no usable video capture device among " << nodes.size() << " nodes";
  ld::V4l2Capture cap(io);
  const auto& fmt0 = cam->formats[0];
  try {
    cap.open(cam->path, request(fmt0.fourcc, fmt0.sizes[0].width, fmt0.sizes[0].height, 0));
  } catch (const CaptureError& e) {
    if (e.kind() == Kind::Unavailable) GTEST_SKIP() << e.what();
    throw;
  }
  std::cout << cam->path << ": " << cap.format().describe() << "\n";
  cap.start();
  int got = 0;
  for (int tries = 0; got < 3 && tries < 10; ++tries) {
    ld::Frame f;
    if (!cap.grab(f, 2000)) continue;
    EXPECT_GT(f.bytesused, 0u);
    EXPECT_EQ(f.width, cap.format().width);
    EXPECT_GT(f.utime, 1500000000000000);  // after 2017: a wall-clock time
    cap.requeue(f);
    ++got;
  }
  EXPECT_EQ(got, 3);
}

// ---------------------------------------------------------------------------
// ld-camera, the process

struct ProcessRun {
  int status = -1;
  std::string err;
};

ProcessRun runCamera(const std::string& args, const std::string& dir, double stop_after_s = 0) {
  const std::string err = dir + "/stderr.txt";
  std::string cmd = std::string(LD_BIN_DIR) + "/ld-camera " + args + " 2> " + err + " > " +
                    dir + "/stdout.txt";
  if (stop_after_s > 0)
    cmd = "timeout --preserve-status -s INT " + std::to_string(stop_after_s) + " " + cmd;
  ProcessRun r;
  const int s = std::system(cmd.c_str());
  r.status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  r.err = ss.str();
  return r;
}

std::string tempDir() {
  std::string t = ::testing::TempDir() + "ld_camera_XXXXXX";
  if (!mkdtemp(t.data())) return ::testing::TempDir();
  return t;
}

TEST(Process, ErrorsAndExitCodes) {
  const std::string dir = tempDir();
  ProcessRun r = runCamera("--device /dev/video-none-here", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.err, "ld-camera: /dev/video-none-here: no such device\n");
  // a format or size the device does not offer: status 2, an argument a
  // restart will not mend (it was 1, and ld-run restarted it for ever)
  r = runCamera("--fake --format mjpeg --size 1920x1080", dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err.rfind("ld-camera: /dev/video0 does not offer MJPEG 1920x1080; it offers: YUYV", 0),
            0u) << r.err;
  // (--frame-size is --size: the other programs' --size is the landmark's side)
  r = runCamera("--fake --format mjpeg --frame-size 1920x1080", dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err.rfind("ld-camera: /dev/video0 does not offer MJPEG 1920x1080", 0), 0u) << r.err;
  // an LCM URL that cannot be: said before the camera is opened (the
  // device's error came first, and the URL's only once it was mended), and a
  // camera that fails leaves no log behind a file:// URL
  r = runCamera("--device /dev/video-none-here --lcm-url udpm://239.255.76.67", dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "ld-camera: LCM URL udpm://239.255.76.67: no port (udpm://GROUP:PORT, e.g. "
                   "udpm://239.255.76.67:7667?ttl=0)\n");
  r = runCamera("--device /dev/video-none-here --lcm-url 'file://" + dir + "/never.lcm?mode=w'", dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_FALSE(std::filesystem::exists(dir + "/never.lcm"));
  EXPECT_EQ(runCamera("--format h264", dir).status, 2);
  EXPECT_EQ(runCamera("--size 640by480", dir).status, 2);
  EXPECT_EQ(runCamera("--no-such-option", dir).status, 2);
  r = runCamera("--exposure -1", dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--exposure: must be >= 0, not -1"), std::string::npos) << r.err;
  // the test aids: numbers checked, and only with --fake; a size of the
  // right form out of range says so
  for (const auto& [args, says] : std::vector<std::pair<std::string, std::string>>{
           {"--fake --fake-unplug-after -1", "--fake-unplug-after: must be >= 0, not -1"},
           {"--fake --fake-unplug-after 3 --fake-replug-after nan", "--fake-replug-after: 'nan' is not a number"},
           {"--fake-unplug-after 5", "--fake-unplug-after is for --fake"},
           {"--fake --fake-replug-after 2", "--fake-replug-after needs --fake-unplug-after"},
           {"--fake --size 100000x100000", "--size: 100000x100000 is out of 1x1 .. 16384x16384"},
           {"--fake --channel ''", "--channel needs a channel name"}}) {
    r = runCamera(args, dir);
    EXPECT_EQ(r.status, 2) << args;
    EXPECT_NE(r.err.find(says), std::string::npos) << args << ": " << r.err;
  }
  // A manual exposure: said at start, with the device's own value when it
  // differs and a word when it is longer than a frame.
  r = runCamera("--fake --exposure 500 --lcm-url memq://", dir, 1.0);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("YUYV 640x480 @ 30 fps, exposure 204.7 ms, 4 buffers"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("asked for an exposure of 500 ms; the device set 204.7 ms"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("is longer than a frame at 30 fps"), std::string::npos) << r.err;
  r = runCamera("--fake --list", dir);
  EXPECT_EQ(r.status, 0);
  std::ifstream out(dir + "/stdout.txt");
  std::string first;
  std::getline(out, first);
  EXPECT_EQ(first, "/dev/video0: Fake UVC Camera (uvcvideo, usb-0000:00:14.0-1)");
}

TEST(Process, PublishesFramesAndSurvivesAnUnplug) {
  const std::string dir = tempDir();
  const std::string log = dir + "/images.lcm";
  // Unplugged after 10 frames, back 0.3 s later; stopped by SIGINT at 2 s.
  const ProcessRun r = runCamera("--fake --fake-unplug-after 10 --fake-replug-after 0.3 --lcm-url "
                          "'file://" + log + "?mode=w' --channel CAM",
                          dir, 2.0);
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("ld-camera: /dev/video0 (Fake UVC Camera): YUYV 640x480 @ 30 fps, 4 "
                       "buffers -> CAM, as captured"),
            std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ld-camera: /dev/video0: device lost"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ld-camera: /dev/video0: reopened after"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ld-camera: stopped after"), std::string::npos) << r.err;

  lcm::LogFile file(log, "r");
  ASSERT_TRUE(file.good());
  int64_t n = 0, prev_seq = -1, prev_utime = 0;
  ld::image_t msg;
  while (const lcm::LogEvent* ev = file.readNextEvent()) {
    ASSERT_EQ(ev->channel, "CAM");
    ASSERT_EQ(msg.decode(ev->data, 0, ev->datalen), ev->datalen);
    EXPECT_EQ(msg.pixelformat, ld::image_t::PIXEL_FORMAT_YUYV);
    EXPECT_EQ(msg.row_stride, 1280);
    EXPECT_EQ(msg.size, 640 * 480 * 2);
    const auto seq = ld::imageSeq(msg);
    ASSERT_TRUE(seq.has_value());
    EXPECT_GT(*seq, prev_seq);
    EXPECT_GT(msg.utime, prev_utime);
    prev_seq = *seq;
    prev_utime = msg.utime;
    ++n;
  }
  // Frames before and after the unplug (at 30 fps, minus 0.3 s away and
  // the backoff; generous bounds: the machine may be busy).
  EXPECT_GT(n, 12);
}

}  // namespace
