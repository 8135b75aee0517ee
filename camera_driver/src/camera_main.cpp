// ld-camera: captures a V4L2 webcam (mmap streaming) and publishes each frame
// as an ld.image_t on IMAGE, as captured (YUYV, MJPEG, GREY stay compact) or
// converted to BGR/RGB/GRAY. `--list` prints the devices. A device that
// disappears while streaming is reopened with backoff until it is back.
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <vector>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/fake_v4l2.hpp"
#include "ld/frame_image.hpp"
#include "ld/image_convert.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_publisher.hpp"
#include "ld/v4l2_capture.hpp"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

bool parseSize(const std::string& text, uint32_t& w, uint32_t& h) {
  const auto wh = ld::cli::parseSize(text);
  if (!wh || wh->first < 1 || wh->second < 1 || wh->first > 16384 || wh->second > 16384) return false;
  w = static_cast<uint32_t>(wh->first);
  h = static_cast<uint32_t>(wh->second);
  return true;
}

// The fake's second node, next to the camera as UVC makes it: /dev/video0 -> /dev/video1.
std::string metadataNodeOf(const std::string& device) {
  size_t i = device.size();
  while (i > 0 && std::isdigit(static_cast<unsigned char>(device[i - 1]))) --i;
  if (i == device.size()) return device + "-meta";
  return device.substr(0, i) + std::to_string(std::stol(device.substr(i)) + 1);
}

void say(const std::string& line) { std::cerr << "ld-camera: " << line << std::endl; }

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "ld-camera: V4L2 webcam frames to ld.image_t messages on IMAGE (see README).\n"
      "Frames go out as captured (YUYV, MJPEG, GREY) unless --convert is given."};
  std::string device = "/dev/video0", format = "yuyv", size = "640x480", channel = "IMAGE";
  std::string url = ld::defaultLcmUrl(), convert = "none";
  double fps = 30, exposure_ms = 0;
  unsigned buffers = 4;
  bool list = false, verbose = false, fake = false;
  int64_t fake_unplug_after = -1;
  double fake_replug_after = 1.0;
  app.add_option("--device", device, "V4L2 device node")->capture_default_str();
  app.add_option("--format", format, "capture format: yuyv, mjpeg or grey")
      ->check(CLI::IsMember({"yuyv", "mjpeg", "mjpg", "grey", "gray"}, CLI::ignore_case))
      ->capture_default_str();
  // (--frame-size too: the other programs' --size is the landmark's side,
  // and a robot.json gives both: a user audit)
  app.add_option("--size,--frame-size", size, "frame size, WIDTHxHEIGHT")
      ->check(CLI::Validator(
          [](std::string& s) {
            uint32_t w, h;
            if (parseSize(s, w, h)) return std::string();
            return ld::cli::parseSize(s) ? s + " is out of 1x1 .. 16384x16384"
                                         : std::string("expected WIDTHxHEIGHT, e.g. 640x480");
          },
          "WxH"))
      ->capture_default_str();
  app.add_option("--fps", fps, "frame rate; the nearest rate the device offers is used")
      ->check(ld::cli::Positive)
      ->capture_default_str();
  app.add_option("--exposure", exposure_ms,
                 "manual exposure time, milliseconds (automatic exposure off; short keeps a moving robot's "
                 "frames sharp; put back as it was when ld-camera stops); 0: leave the device's exposure as it is")
      ->check(ld::cli::NonNegative)
      ->capture_default_str();
  app.add_option("--buffers", buffers, "mmap buffers to request")
      ->check(ld::cli::Between(4, 32))
      ->capture_default_str();
  app.add_option("--channel", channel, "LCM channel of the images")->capture_default_str();
  app.add_option("--lcm-url", url, "LCM URL")->capture_default_str();
  app.add_option("--convert", convert,
                 "publish as captured (none) or decoded and converted to bgr, rgb or gray")
      ->check(CLI::IsMember({"none", "bgr", "rgb", "gray", "grey"}, CLI::ignore_case))
      ->capture_default_str();
  app.add_flag("--list", list, "list the V4L2 devices with their formats, sizes and rates");
  app.add_flag("-v,--verbose", verbose, "print a status line every 5 s");
  app.add_flag("--fake", fake,
               "test/demo aid: capture from a built-in fake webcam at --device (a moving "
               "test pattern) instead of a real V4L2 device")
      ->group("Test aids");
  auto* unplug = app.add_option("--fake-unplug-after", fake_unplug_after,
                                "with --fake: unplug the fake webcam after this many frames")
                     ->group("Test aids")
                     ->check(ld::cli::NonNegative);
  auto* replug = app.add_option("--fake-replug-after", fake_replug_after,
                                "with --fake-unplug-after: plug it back after this many seconds")
                     ->group("Test aids")
                     ->capture_default_str()
                     ->check(ld::cli::NonNegative);
  LD_CLI_PARSE(app, argc, argv);
  if ((unplug->count() || replug->count()) && !fake)
    return ld::cli::usage(argv[0], std::string(unplug->count() ? "--fake-unplug-after" : "--fake-replug-after") +
                                       " is for --fake");
  if (replug->count() && !unplug->count())
    return ld::cli::usage(argv[0], "--fake-replug-after needs --fake-unplug-after");
  if (const std::string p = ld::channelProblem({}, {"--channel", channel}, "ld-camera's"); !p.empty())
    return ld::cli::usage(argv[0], p);

  ld::CaptureRequest request;
  ld::ImageConversion conversion;
  try {
    request.fourcc = ld::captureFormatFromName(format);
    parseSize(size, request.width, request.height);
    request.fps = fps;
    request.exposure_ms = exposure_ms;
    request.buffers = buffers;
    conversion = ld::imageConversionFromName(convert);
  } catch (const std::exception& e) {
    say(e.what());
    return 2;
  }

  std::unique_ptr<ld::V4l2Io> io;
  if (fake) {
    auto dev = std::make_unique<ld::FakeV4l2Device>(
        ld::systemClock(), std::vector<ld::FakeCameraSpec>{ld::FakeCameraSpec::webcam(device),
                                                           ld::FakeCameraSpec::metadataNode(
                                                               metadataNodeOf(device))});
    if (fake_unplug_after >= 0)
      dev->scheduleUnplug(device, fake_unplug_after,
                          static_cast<int64_t>(std::llround(fake_replug_after * 1e6)));
    io = std::move(dev);
  } else {
    io = std::make_unique<ld::SystemV4l2Io>();
  }

  if (list) {
    const auto devices = ld::listDevices(*io);
    std::cout << ld::formatDeviceList(devices);
    return devices.empty() ? 1 : 0;
  }

  // (a URL LCM cannot take is said before the camera is opened and started;
  // the bus itself is opened once the camera runs, so that a camera that
  // fails leaves no empty log behind a file:// URL)
  if (!ld::lcmUrlUsable(url, "ld-camera")) return 2;
  ld::ReconnectingCapture capture(*io, ld::systemClock(), device, request, {}, say);
  try {
    const ld::CaptureFormat& f = capture.start();
    say(device + " (" + f.card + "): " + f.describe() + " -> " + channel +
        (conversion == ld::ImageConversion::AsCaptured
             ? std::string(", as captured")
             : ", converted to " + ld::imageConversionName(conversion)));
    if (f.fps > 0 && std::fabs(f.fps - fps) > 0.01)
      say("asked for " + number(fps) + " fps; the device runs at " + number(f.fps) + " fps");
    if (exposure_ms > 0 && std::fabs(f.exposure_ms - exposure_ms) > 0.05)
      say("asked for an exposure of " + number(exposure_ms) + " ms; the device set " + number(f.exposure_ms) + " ms");
    if (f.fps > 0 && f.exposure_ms > 1000 / f.fps)
      say("an exposure of " + number(f.exposure_ms) + " ms is longer than a frame at " + number(f.fps) +
          " fps: the device may lower its rate");
  } catch (const ld::CaptureError& e) {
    say(e.what());
    // A format, size or control the device does not offer, or a node that is
    // no capture device: the arguments', which a restart will not mend
    // (status 2: ld-run and systemd do not restart it; ld-run restarted it
    // for ever). A missing, busy or failing device may come back: 1.
    using K = ld::CaptureError::Kind;
    return e.kind() == K::FormatRefused || e.kind() == K::ControlRefused || e.kind() == K::NotCapture ? 2 : 1;
  }
  lcm::LCM lcm(url);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-camera")) return status;
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  ld::FrameToImage converter(conversion);
  ld::image_t msg;
  ld::MessagePublisher publisher(lcm);  // (its buffer kept: nothing allocated once warm)
  ld::Frame frame;
  int64_t published = 0, bad = 0, last_published = 0;
  int64_t skipped_said = 0, skipped_lines = 0;  // frames the capture skipped (flagged, cut short), said so far
  auto last_status = std::chrono::steady_clock::now();
  while (!g_stop) {
    bool got = false;
    try {
      got = capture.grab(frame, 200);
    } catch (const std::exception& e) {
      say(e.what());
      return 1;
    }
    // (frames the driver flagged bad or that came cut short: skipped by the
    // capture, said here, rate-limited as bad input is)
    const ld::CaptureStats totals = capture.totals();
    if (totals.errored + totals.truncated > skipped_said) {
      skipped_said = totals.errored + totals.truncated;
      if (ld::printBadLine(++skipped_lines))
        say("skipped frames: " + std::to_string(totals.errored) + " flagged bad by the driver (lost USB packets?), " +
            std::to_string(totals.truncated) + " cut short " + ld::badSoFar(skipped_lines, "such lines"));
    }
    if (got) {
      bool ok = true;
      try {
        converter.convert(frame, msg);
      } catch (const ld::ImageFormatError& e) {
        ok = false;
        ++bad;
        if (ld::printBadLine(bad)) say("dropped frame: " + std::string(e.what()) + " " + ld::badSoFar(bad));
      }
      capture.requeue(frame);  // the message holds a copy: give the buffer back first
      if (ok) {
        publisher.publish(channel, msg);
        ++published;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (verbose && now - last_status > std::chrono::seconds(5)) {
      const ld::CaptureStats t = capture.totals();
      const double s = std::chrono::duration<double>(now - last_status).count();
      std::fprintf(stderr,
                   "ld-camera: %.1f frames/s, %lld published, %lld skipped to stay current, %lld dropped by "
                   "the driver, %lld flagged bad, %lld cut short, %lld bad, %d reconnects%s\n",
                   (published - last_published) / s, static_cast<long long>(published),
                   static_cast<long long>(t.stale),
                   static_cast<long long>(t.sequence_gaps),
                   static_cast<long long>(t.errored),
                   static_cast<long long>(t.truncated), static_cast<long long>(bad),
                   capture.reconnects(), capture.connected() ? "" : " (device away)");
      last_published = published;
      last_status = now;
    }
  }
  capture.stop();
  const ld::CaptureStats t = capture.totals();
  std::fprintf(stderr,
               "ld-camera: stopped after %lld frames (%lld skipped to stay current, %lld dropped by the driver, "
               "%lld flagged bad, %lld cut short, %lld bad, %d reconnects)\n",
               static_cast<long long>(published), static_cast<long long>(t.stale),
               static_cast<long long>(t.sequence_gaps),
               static_cast<long long>(t.errored), static_cast<long long>(t.truncated),
               static_cast<long long>(bad), capture.reconnects());
  return 0;
}
