// ld-play: publishes the images of an LCM log at a fixed rate, as a camera
// would: each frame gets the current time as utime and a fresh sequence
// number, and the log is played back and forth for as long as asked (to
// its end, back to its start, and on: a jump back to the first frame was a
// cut no tracker can see). Optionally converts
// the frames first (say MJPEG in the log, raw BGR on the bus), so that a
// small log drives a long benchmark or a bandwidth test.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <thread>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/file_checks.hpp"
#include "ld/lcm_log_reader.hpp"
#include "ld/image_convert.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/message_publisher.hpp"

namespace {

// The most image bytes read into memory before playing (2 GiB: 2300 frames of
// 640x480 BGR, 350 of 1080p).
constexpr size_t kMaxPreloadBytes = size_t{2} << 30;

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

int64_t wallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-play: a log's images published at a fixed rate with fresh utime and seq."};
  std::string log_path, url = ld::defaultLcmUrl(), channel = "IMAGE", out_channel, format = "keep";
  double fps = 30, duration = 0;
  int64_t frames = 0, first_seq = 0;
  int quality = 90;
  app.add_option("log", log_path, "LCM log with ld.image_t messages")->required();
  app.add_option("--lcm-url", url, "LCM URL")->capture_default_str();
  app.add_option("--channel", channel, "image channel in the log (and on the bus)")->capture_default_str();
  app.add_option("--out-channel", out_channel, "publish on this channel instead");
  app.add_option("--fps", fps, "frames per second (0.001 to 1000)")
      ->check(ld::cli::Between(0.001, 1000))
      ->capture_default_str();
  // (neither given: the log once)
  auto* frames_opt = app.add_option("--frames", frames, "frames to publish, playing the log back and forth (default: the log once)")
                         ->check(ld::cli::Between(1, 1e12));
  app.add_option("--duration", duration, "seconds to publish, playing the log back and forth (default: the log once)")
      ->check(ld::cli::Positive)
      ->excludes(frames_opt);
  app.add_option("--format", format, "keep, or convert to bgr, rgb, rgba, bgra, gray, yuyv, uyvy, mjpeg")
      ->capture_default_str()
      ->check(ld::cli::Parses("FORMAT", [](const std::string& f) {
        try {
          if (f != "keep") (void)ld::pixelFormatFromName(f);
        } catch (const std::exception&) {  // (keep too, which the format's own list leaves out)
          throw std::invalid_argument("must be keep, or a pixel format to convert to (bgr, rgb, rgba, bgra, gray, "
                                      "yuyv, uyvy, mjpeg), not '" + f + "'");
        }
      }));
  app.add_option("--quality", quality, "JPEG quality for mjpeg")->capture_default_str()->check(ld::cli::Between(1, 100));
  app.add_option("--first-seq", first_seq, "sequence number of the first frame (0 or more)")
      ->capture_default_str()
      ->check(ld::cli::NonNegative);
  auto* out_opt = app.get_option("--out-channel");
  LD_CLI_PARSE(app, argc, argv);
  if (channel.empty() || (out_opt->count() && out_channel.empty()))
    return ld::cli::usage(argv[0], std::string(channel.empty() ? "--channel" : "--out-channel") +
                                       " needs a channel name");
  if (out_channel.empty()) out_channel = channel;
  // (a duration at this rate beyond a trillion frames is no run: it wrapped to none)
  if (duration > 0 && !(duration * fps <= 1e12)) {
    std::ostringstream m;
    m << "--duration " << duration << " at --fps " << fps << " is over 1e12 frames";
    return ld::cli::usage(argv[0], m.str());
  }

  // (seq counts on from it, frame after frame, without end: it wrapped to
  // negative numbers past 2^63)
  if (first_seq > (int64_t{1} << 62))
    return ld::cli::usage(argv[0], "--first-seq: must be at most 2^62 (" + std::to_string(int64_t{1} << 62) +
                                       "), not " + std::to_string(first_seq));
  const int32_t pixelformat = format == "keep" ? -1 : ld::pixelFormatFromName(format);  // (checked by the option)
  // (a duration under half a frame is still a frame, not the log once)
  if (frames == 0 && duration > 0) frames = std::max<int64_t>(1, std::llround(duration * fps));
  // The frames are read and converted before the first is published, so that
  // the rate holds (an MJPEG encode of a 1080p frame takes 10 ms): as many as
  // are played, up to kMaxPreloadBytes (a 10 minute log at 30 frames/s is
  // 16 GB of 640x480 BGR).
  std::vector<ld::image_t> images;
  size_t preloaded_bytes = 0;
  bool cut = false, crop_said = false;
  ld::ChannelCounts log_channels;  // (named where none is on the channel)
  {
    const ld::LcmLogCheck start = ld::checkLcmLogStart(log_path);
    if (start.start != ld::LcmLogStart::Events) {
      std::cerr << "ld-play: log " << log_path << " " << start.problem << "\n";
      return 2;
    }
    ld::LcmLogReader log(log_path);
    if (!log.good()) {
      std::cerr << "ld-play: cannot read log " << log_path << "\n";
      return 2;
    }
    while ((frames == 0 || static_cast<int64_t>(images.size()) < frames) && log.next()) {
      ++log_channels[log.channel];
      if (log.channel != channel) continue;
      if (preloaded_bytes >= kMaxPreloadBytes) {
        cut = true;
        break;
      }
      ld::image_t img;
      std::string why;
      if (!ld::decodeMessage(log.data.data(), log.data.size(), img, &why)) {
        std::cerr << "ld-play: skipping message " << log.messages() << ": " << why << "\n";
        continue;
      }
      // every frame must be an image its readers can read (kept as it is,
      // or converted): a broken one is skipped here, not published
      try {
        cv::Mat bgr = ld::imageToBgr(img);
        if (pixelformat != -1 && img.pixelformat != pixelformat) {
          // (two pixels share their colour in YUYV and UYVY: an odd width
          // loses its last column, as ld-log-images does; every frame was
          // skipped, and the run ended with no images)
          if (ld::pixelsInPairs(pixelformat) && bgr.cols % 2 && bgr.cols > 1) {
            if (!crop_said)
              std::cerr << "ld-play: note: " << bgr.cols << " px wide frames are cropped to " << bgr.cols - 1
                        << " for " << ld::pixelFormatName(pixelformat) << " (its pixels come in pairs)\n";
            crop_said = true;
            bgr = bgr.colRange(0, bgr.cols - 1);
          }
          img = ld::matToImage(bgr, pixelformat, img.utime, -1, quality);
        }
      } catch (const std::exception& e) {
        std::cerr << "ld-play: skipping message " << log.messages() << ": " << e.what() << "\n";
        continue;
      }
      ld::setImageSeq(img, 0);  // (its entry made now, with room for any number: playing allocates nothing)
      preloaded_bytes += img.data.size();
      images.push_back(std::move(img));
    }
    if (cut)
      std::cerr << "ld-play: note: the log's first " << images.size() << " images (" << (preloaded_bytes >> 20)
                << " MiB" << (pixelformat != -1 ? " converted" : "")
                << (frames > 0 ? ") are played, back and forth" : ") are played, and the rest of the log is not")
                << ": more would not fit in memory (" << (kMaxPreloadBytes >> 20) << " MiB)\n";
    if (!log.problem().empty())  // a cut log: what it holds is played
      std::cerr << "ld-play: warning: " << log_path << ": " << log.problem() << "\n";
  }
  if (images.empty()) {
    std::cerr << "ld-play: no " << channel << " images in " << log_path
              << (log_channels.empty() ? "" : " (its channels: " + ld::describeChannels(log_channels) + ")") << "\n";
    return 2;
  }
  if (frames == 0) frames = static_cast<int64_t>(images.size());

  if (!ld::lcmUrlUsable(url, "ld-play")) return 2;
  lcm::LCM lcm(url);
  ld::MessagePublisher publisher(lcm);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-play")) return status;
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  const auto period = std::chrono::duration<double>(1.0 / fps);
  const auto t0 = std::chrono::steady_clock::now();
  int64_t sent = 0, late = 0, failed = 0;
  auto last = t0;
  for (int64_t k = 0; k < frames && !g_stop; ++k) {
    const auto due = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(period * k);
    const auto now = std::chrono::steady_clock::now();
    if (now < due) {
      // (in slices: SIGTERM stops it at once, not when the next frame is due)
      while (!g_stop && std::chrono::steady_clock::now() < due)
        std::this_thread::sleep_until(std::min(due, std::chrono::steady_clock::now() + std::chrono::milliseconds(50)));
      if (g_stop) break;
    } else if (now - due > period) {
      ++late;
    }
    // (back and forth: 0 1 2 3 2 1 0 1 ... A loop from the last frame to the
    // first was a scene cut the tracker could not see: it gave the last
    // frame's ids, and the payloads read under them, to the first frame's
    // landmarks, and a track kept another landmark's payload for seconds)
    const size_t n = images.size(), turn = n > 1 ? 2 * n - 2 : 1, p = static_cast<size_t>(k) % turn;
    ld::image_t& img = images[p < n ? p : turn - p];
    img.utime = wallMicros();
    ld::setImageSeq(img, first_seq + k);
    if (publisher.publish(out_channel, img) == 0) ++sent;
    else ++failed;
    last = std::chrono::steady_clock::now();
  }
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // the rate: frames after the first over the time from the first to the last
  const double span = std::chrono::duration<double>(last - t0).count();
  const double rate = sent > 1 && span > 0 ? static_cast<double>(sent - 1) / span : 0.0;
  // (the frames' size and format, or that they vary: a log of several runs)
  std::string kind = std::to_string(images[0].width) + "x" + std::to_string(images[0].height) + " " +
                     ld::pixelFormatName(images[0].pixelformat);
  for (const auto& img : images)
    if (img.width != images[0].width || img.height != images[0].height || img.pixelformat != images[0].pixelformat) {
      kind = "sizes or formats vary; the first " + kind;
      break;
    }
  // (a rate needs two frames: one alone has none, said "-", not 0.00)
  char rate_text[32] = "-";
  if (sent > 1 && span > 0) std::snprintf(rate_text, sizeof rate_text, "%.2f", rate);
  std::fprintf(stderr,
               "ld-play: published %lld frame%s (%s) in %.2f s, %s frames/s; %lld late, %lld "
               "failed\n",
               static_cast<long long>(sent), sent == 1 ? "" : "s", kind.c_str(), s, rate_text,
               static_cast<long long>(late), static_cast<long long>(failed));
  return g_stop || failed == 0 ? 0 : 1;
}
