// ld-log-images: an image folder or a video file as an LCM log of ld.image_t
// on IMAGE, with timestamps at a chosen frame rate, for lcm-logplayer.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "ld/cli.hpp"
#include "ld/file_checks.hpp"
#include "ld/image_convert.hpp"

namespace fs = std::filesystem;

int main(int argc, char** argv) {
  CLI::App app{"ld-log-images: images or a video as an LCM log of IMAGE messages."};
  std::string input, output, channel = "IMAGE", format = "mjpeg";
  double fps = 30.0;
  int64_t start_utime = 0;
  int quality = 90;
  app.add_option("input", input, "image folder (name order), one image, or a video file")->required();
  app.add_option("output", output, "LCM log to write")->required();
  auto* fps_opt = app.add_option("--fps", fps,
                                 "frame rate of the timestamps (default: a video's own timestamps, images 30)")
                       ->check(ld::cli::Between(0.1, 1000.0));
  auto* start_opt = app.add_option("--start-utime", start_utime,
                                   "utime of the first frame, whole microseconds since 1970, 0 to 2^62 (default: now)")
      ->check(ld::cli::StartUtime);
  app.add_option("--format", format, "pixel format: gray, rgb, bgr, rgba, bgra, yuyv, uyvy, mjpeg")
      ->capture_default_str()->check(ld::cli::Parses("FORMAT", ld::pixelFormatFromName));
  app.add_option("--quality", quality, "JPEG quality for mjpeg")->check(ld::cli::Between(1, 100))
      ->capture_default_str();
  app.add_option("--channel", channel, "channel name")->capture_default_str();
  LD_CLI_PARSE(app, argc, argv);
  if (channel.empty()) return ld::cli::usage(argv[0], "--channel: an empty channel name");
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);  // our own one-line errors

  const int32_t pixelformat = ld::pixelFormatFromName(format);  // (checked by the option)
  if (!start_opt->count())  // (a 0 given is 0: it was taken as not given)
    start_utime = std::chrono::duration_cast<std::chrono::microseconds>(
                      std::chrono::system_clock::now().time_since_epoch()).count();

  std::vector<std::string> files;
  cv::VideoCapture video;
  std::error_code ec;
  if (fs::is_directory(input, ec)) {
    // (a link whose file is gone, a loop of links or a pipe with an image's
    // name is listed too, and reading it says so: they were passed over
    // without a word; so are HEIC photos and other kinds OpenCV does not read)
    std::vector<std::string> unread;
    if (const std::string why = ld::listImageFolder(input, files, unread); !why.empty()) {
      std::cerr << "ld-log-images: cannot list the folder " << input << ": " << why << "\n";  // (not "no images")
      return 2;
    }
    if (!unread.empty()) std::cerr << "ld-log-images: note: " << input << ": " << ld::describeUnreadImages(unread) << "\n";
    if (files.empty()) {
      std::cerr << "ld-log-images: no image files in " << input << " (folders are searched for "
                << ld::imageFileExtensions() << ")\n";
      return 2;
    }
  } else if (!fs::exists(input, ec)) {
    std::cerr << "ld-log-images: " << input << " does not exist\n";
    return 2;
  } else if (ld::checkLcmLogStart(input).start == ld::LcmLogStart::Events) {
    // (FFmpeg finds the JPEG frames of an MJPEG log and takes it as a video:
    // re-encoded, restamped, and with the same output, written over)
    std::cerr << "ld-log-images: " << input << " is an LCM log already (ld-play or lcm-logplayer replays it; "
              << "ld-log-images makes logs of images and videos)\n";
    return 2;
  } else if (ld::isImageFileName(input)) {  // one image: a log of one frame
    cv::Mat probe;
    if (const std::string why = ld::readImageFile(input, probe); !why.empty()) {
      std::cerr << "ld-log-images: " << input << ": " << why << "\n";
      return 2;
    }
    files.push_back(input);
  } else if (!video.open(input, cv::CAP_FFMPEG) && !video.open(input, cv::CAP_GSTREAMER)) {
    // (files' backends only: OpenCV's default order also asks gPhoto2, which
    // enumerates every USB device for a camera to open instead of the file)
    std::cerr << "ld-log-images: cannot open " << input << " as a video\n";
    return 2;
  }

  // Checked before anything is written (never over an input image or
  // video: only an LCM log is written over), written under a temporary name
  // and renamed when whole, so a failed run leaves an earlier log as it was.
  if (const std::string problem = ld::prepareLogOutputFile(output); !problem.empty()) {
    std::cerr << "ld-log-images: " << output << " " << problem << "\n";
    return 2;
  }
  ld::PendingFile pending(output);
  lcm::LogFile log(pending.tempPath(), "w");
  if (!log.good()) {
    std::cerr << "ld-log-images: cannot write " << output << ": " << std::strerror(errno) << "\n";
    return 2;
  }
  // A video's frames are stamped by its own clock (a 10 frames/s or a
  // phone's variable-rate video was replayed at 30 frames/s): each frame's
  // time in it from the first's, where the container gives times that go
  // forward; else its frame rate; --fps overrides both.
  bool own_clock = false;
  if (video.isOpened() && !fps_opt->count()) {
    own_clock = true;
    if (const double rate = video.get(cv::CAP_PROP_FPS); rate >= 0.1 && rate <= 1000) fps = rate;
  }
  double first_ms = -1, last_ms = -1;  // the video's times of its first and last frames
  int64_t last_utime = 0, untimed = 0;  // (untimed: frames of a video without a time of their own)
  std::vector<uint8_t> buf;
  int64_t seq = 0, skipped = 0, unlogged = 0;
  bool crop_said = false, big_said = false;
  for (size_t i = 0;; ++i) {
    cv::Mat frame;
    if (!files.empty()) {
      if (i >= files.size()) break;
      if (const std::string why = ld::readImageFile(files[i], frame); !why.empty()) {
        std::cerr << "ld-log-images: " << files[i] << ": " << why << ", skipped\n";
        ++skipped;
        continue;
      }
    } else if (!video.read(frame) || frame.empty()) {
      break;
    }
    // A frame that cannot be an image_t of the format (a side over 32768 px,
    // an MJPEG frame over 2^25 pixels, a YUYV frame 1 px wide): said and
    // skipped (ld-log-images died of it, leaving its partial log behind).
    const auto unloggable = [&](const std::string& why) {
      std::cerr << "ld-log-images: " << (files.empty() ? "frame " + std::to_string(i) + " of " + input : files[i])
                << ": cannot be logged as " << format << ": " << why << ", skipped\n";
      ++unlogged;
    };
    const bool pairs = ld::pixelsInPairs(pixelformat);
    if (pairs && frame.cols < 2) {
      unloggable("it is 1 px wide, and the format's pixels come in pairs");
      continue;
    }
    if (pairs && frame.cols % 2) {
      // (two pixels share their colour in YUYV and UYVY: an odd width loses its last column)
      if (!crop_said)
        std::cerr << "ld-log-images: note: " << frame.cols << " px wide frames are cropped to " << frame.cols - 1
                  << " for " << format << " (its pixels come in pairs)\n";
      crop_said = true;
      frame = frame.colRange(0, frame.cols - 1).clone();
    }
    int64_t utime = start_utime + static_cast<int64_t>(std::llround(seq * 1e6 / fps));
    if (own_clock) {
      // (a frame without a time that goes forward, as the last frames of an
      // H.264 video with B-frames, which FFmpeg gives at 0 as it drains its
      // decoder: a frame interval after the last, counted)
      const double ms = video.get(cv::CAP_PROP_POS_MSEC);
      if (std::isfinite(ms) && ms >= 0 && (first_ms < 0 || ms > last_ms)) {
        if (first_ms < 0) first_ms = ms;
        last_ms = ms;
        utime = start_utime + static_cast<int64_t>(std::llround((ms - first_ms) * 1e3));
      } else if (seq > 0) {
        utime = last_utime + static_cast<int64_t>(std::llround(1e6 / fps));
        last_ms += 1e3 / fps;
        ++untimed;
      }
    }
    if (seq > 0 && utime <= last_utime) utime = last_utime + 1;
    last_utime = utime;
    ld::image_t msg;
    try {
      msg = ld::matToImage(frame, pixelformat, utime, seq, quality);
    } catch (const std::exception& e) {  // (ImageFormatError; OpenCV's encoder's cv::Exception)
      std::string why = e.what();
      if (why.rfind("matToImage: ", 0) == 0) why.erase(0, 12);
      unloggable(why);
      continue;
    }
    // (a raw frame larger than the set's LCM receive buffer, 8 MiB, may be
    // lost whole on the bus, each time, with nothing said where it is sent)
    if (!big_said && msg.pixelformat != ld::image_t::PIXEL_FORMAT_MJPEG && msg.size > (8 << 20)) {
      std::cerr << "ld-log-images: note: " << frame.cols << "x" << frame.rows << " frames are "
                << (msg.size + (1 << 19)) / (1 << 20) << " MiB each as " << format
                << ", more than the set's LCM receive buffer (8 MiB): a replay over LCM may lose them "
                   "(--format mjpeg makes them about a tenth)\n";
      big_said = true;
    }
    buf.resize(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm::LogEvent ev;
    ev.eventnum = seq;
    ev.timestamp = utime;
    ev.channel = channel;
    ev.datalen = static_cast<int32_t>(buf.size());
    ev.data = buf.data();
    errno = 0;
    if (log.writeEvent(&ev) != 0) {
      std::cerr << "ld-log-images: write to " << output << " failed"
                << (errno ? std::string(": ") + std::strerror(errno) : "") << "\n";
      return 1;
    }
    ++seq;
  }
  if (seq == 0) {  // no empty log left behind (and what was at the output stays)
    std::cerr << "ld-log-images: no frame could be " << (unlogged ? "logged" : "read") << " from " << input << "; "
              << output << " not written\n";
    return 1;
  }
  if (std::fflush(log.getFilePtr()) != 0 || std::ferror(log.getFilePtr())) {
    std::cerr << "ld-log-images: write to " << output << " failed: " << std::strerror(errno) << "\n";
    return 1;
  }
  if (const std::string problem = pending.commit(); !problem.empty()) {
    std::cerr << "ld-log-images: " << problem << "\n";
    return 1;
  }
  // A video cut short or damaged: OpenCV stops at the first frame it cannot
  // decode (FFmpeg may say why on its own line); say how far it got.
  if (video.isOpened()) {
    const double said = video.get(cv::CAP_PROP_FRAME_COUNT);  // (the container's count; an estimate for some)
    if (said > 0 && static_cast<double>(seq) < said - 1)
      std::cerr << "ld-log-images: note: " << input << " says it holds " << static_cast<long long>(said)
                << " frames and " << seq << " could be read (a file cut short or damaged?)\n";
  }
  std::cout << "wrote " << seq << (seq == 1 ? " frame" : " frames") << " to " << output << " (" << format << ", "
            << (own_clock ? "the video's own timestamps, " + cv::format("%.3g", fps) + " fps" +
                                (untimed ? cv::format("; %lld frames without a time of their own stamped a frame apart",
                                                      static_cast<long long>(untimed))
                                         : std::string())
                          : cv::format("%g", fps) + " fps")
            << ")" << (skipped ? ", " + std::to_string(skipped) + " unreadable skipped" : "")
            << (unlogged ? ", " + std::to_string(unlogged) + " that could not be logged skipped" : "") << "\n";
  return 0;
}
