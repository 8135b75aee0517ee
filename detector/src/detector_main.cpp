// ld-detector: subscribes to IMAGE, publishes the landmarks of each frame on
// LANDMARKS. Always works on the newest frame and counts the frames it skipped.
#include <atomic>
#include <chrono>
#include <csignal>
#include <ctime>
#include <cstdio>
#include <iostream>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/adaptive.hpp"
#include "ld/detector.hpp"
#include "ld/detector_options.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_msg.hpp"
#include "ld/latest_message.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/message_publisher.hpp"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-detector: IMAGE in, LANDMARKS out (see README)."};
  std::string url = ld::defaultLcmUrl(), in_channel = "IMAGE", out_channel = "LANDMARKS";
  bool verbose = false;
  app.add_option("--lcm-url", url, "LCM URL")->capture_default_str();
  app.add_option("--in", in_channel, "image channel")->capture_default_str();
  app.add_option("--out", out_channel, "landmarks channel")->capture_default_str();
  ld::DetectorOptions detector_options;
  detector_options.addTo(app);
  app.add_flag("-v,--verbose", verbose, "print a status line every 5 s");
  double explain_s = 0;
  app.add_option("--explain", explain_s,
                 "every this many seconds, explain one frame on stderr as ld-detect --explain does (what each "
                 "stage kept, why groups of squares were refused, what each later look found); 0: never, "
                 "at most 86400 (a day)")
      ->check(ld::cli::Between(0, 86400));  // (1e10 s overflowed the clock: every frame explained)
  LD_CLI_PARSE(app, argc, argv);
  if (const std::string p = ld::channelProblem({{"--in", in_channel}}, {"--out", out_channel}, "the detector's");
      !p.empty())
    return ld::cli::usage(argv[0], p);

  ld::AdaptiveDetector detector;  // with --adaptive: frames are corrected before detection
  try {
    detector = detector_options.makeAdaptive();
  } catch (const ld::BackendUnavailable& e) {
    // (a GPU whose driver is not up yet, at boot: a supervisor starts it
    // again; 2 is for what a restart will not mend)
    std::cerr << "ld-detector: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ld-detector: " << e.what() << "\n";
    return 2;
  }

  if (!ld::lcmUrlUsable(url, "ld-detector")) return 2;
  lcm::LCM lcm(url);
  ld::MessagePublisher publisher(lcm);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-detector")) return status;
  // The GPU compiles its shaders on their first use: a frame of coloured
  // noise runs them all before the camera's first frame comes, which was late
  // by that much (47 ms on llvmpipe; "auto" times its warm-ups apart). The
  // plain detector: the adaptive one would learn the noise's colours.
  if (detector.detector().params().backend == "gles") {
    cv::Mat noise(480, 640, CV_8UC3);
    cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(256));
    (void)detector.detector().detect(noise);
  }
  if (verbose) std::fprintf(stderr, "ld-detector: backend %s\n", detector.detector().backendInfo().c_str());
  // (said once, -v or not: nothing in its log told whether --adaptive, say
  // from a unit's LD_DETECTOR_ARGS, was taken)
  if (detector.enabled()) std::fprintf(stderr, "ld-detector: adaptive lighting on (the frames' colours corrected before detection)\n");
  // backend "auto" on a GPU: -v says its choice too, once made
  bool choosing = verbose && detector.detector().choosingBackend();
  // Each frame is decoded and checked as it arrives (decoding copies it
  // once, as keeping its bytes did); the JPEG data of an MJPEG frame is
  // checked only by decoding it, later.
  ld::LatestMessage<ld::image_t> latest("ld-detector", in_channel, "frame", ld::imageProblem, ld::imageSeq);
  latest.queueOn(lcm.subscribe(in_channel, &ld::LatestMessage<ld::image_t>::onMessage, &latest));
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  cv::Mat bgr;
  ld::landmark_list_t out;
  int64_t processed = 0, last_processed = 0;
  auto last_status = std::chrono::steady_clock::now();
  auto next_explain = last_status;
  ld::Explanation why_frame;
  std::string pose_error;  // the last frame's Detection::pose_error
  int64_t pose_errors = 0;  // times it changed to a new one
  auto last_pump = std::chrono::steady_clock::now();
  // (the processor time the last frame took: a detector slow on its own,
  // not stopped or starved, is no stall)
  const auto threadCpu = [] {
    timespec t{};
    ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return std::chrono::seconds(t.tv_sec) + std::chrono::nanoseconds(t.tv_nsec);
  };
  std::chrono::nanoseconds busy{0};
  bool grey_said = false;  // (GRAY frames: said once)
  while (!g_stop) {
    // waits, then drains the queue: only the newest message is processed
    if (!ld::pumpLcm(lcm, 200, g_stop, "ld-detector")) return 1;
    // (after a stall, the rest of the kernel's backlog too: the newest frame
    // is then the camera's latest, not one from the middle of it)
    last_pump = ld::catchUpAfterStall(
        lcm, last_pump + std::chrono::duration_cast<std::chrono::steady_clock::duration>(busy), g_stop);
    busy = std::chrono::nanoseconds(0);
    const auto cpu0 = threadCpu();
    if (g_stop) break;
    if (const ld::image_t* newest = latest.take()) {
      const ld::image_t& image = *newest;  // (handlers run in pumpLcm alone: it stays while processed)
      try {
        // (a camera set to a grey format, a monochrome one: nothing found,
        // and nothing said)
        if (image.pixelformat == ld::image_t::PIXEL_FORMAT_GRAY && !grey_said) {
          std::fprintf(stderr,
                       "ld-detector: GRAY frames have no colour: landmarks are found by their blue and red squares, so "
                       "none can be found in them (is the camera set to a grey format?)\n");
          grey_said = true;
        }
        ld::imageToBgr(image, bgr);
        // Now and then, on --explain, the frame's explanation (it costs about
        // two detections more, and is not counted in the published timings).
        const bool explain = explain_s > 0 && std::chrono::steady_clock::now() >= next_explain;
        const ld::Detection& det = explain ? detector.detect(bgr, why_frame) : detector.detect(bgr);
        // (a calibration that does not fit the frames: said once, and again
        // when it changes, as bad input is: frames whose size keeps changing
        // would otherwise say it for every frame)
        if (det.pose_error != pose_error) {
          pose_error = det.pose_error;
          if (!pose_error.empty() && ld::printBadLine(++pose_errors))
            std::cerr << "ld-detector: " << pose_error
                      << (pose_errors == ld::kBadLinesInFull
                              ? " (from here on every " + std::to_string(ld::kBadLinesEvery) + "th is printed)"
                              : std::string())
                      << "\n";
        }
        if (explain) {
          next_explain = std::chrono::steady_clock::now() +
                         std::chrono::microseconds(static_cast<int64_t>(explain_s * 1e6));
          // (with --adaptive, the adapter's gains and veil, as ld-detect --explain gives them)
          const std::string adapted =
              detector.enabled() ? cv::format("; adaptive gains B %.2f G %.2f R %.2f%s", detector.adapter().gains()[0],
                                              detector.adapter().gains()[1], detector.adapter().gains()[2],
                                              detector.adapter().glareCorrected() ? ", glare veil subtracted" : "")
                                 : std::string();
          std::fprintf(stderr, "ld-detector: frame %lld (utime %lld): %zu landmark%s%s\n%s\n",  // (one block per frame)
                       static_cast<long long>(ld::imageSeq(image).value_or(-1)), static_cast<long long>(image.utime),
                       det.landmarks.size(), det.landmarks.size() == 1 ? "" : "s", adapted.c_str(),
                       ld::describe(why_frame, detector.detector().params(), "  ").c_str());
        }
        ld::toListMessage(det, image.utime, ld::imageSeq(image).value_or(-1), bgr.cols, bgr.rows,
                          detector.detector().backend(), latest.skipped(), out);
        publisher.publish(out_channel, out);
        ++processed;
        if (choosing && !detector.detector().choosingBackend()) {
          std::fprintf(stderr, "ld-detector: backend %s\n", detector.detector().backendInfo().c_str());
          choosing = false;
        }
      } catch (const std::exception& e) {
        latest.reportBad(e.what());
      }
    }
    busy = threadCpu() - cpu0;
    const auto now = std::chrono::steady_clock::now();
    if (verbose && now - last_status > std::chrono::seconds(5)) {
      const double s = std::chrono::duration<double>(now - last_status).count();
      std::fprintf(stderr, "ld-detector: %.1f frames/s, %lld processed, %lld skipped, %lld bad, %lld missing\n",
                   (processed - last_processed) / s, static_cast<long long>(processed),
                   static_cast<long long>(latest.skipped()), static_cast<long long>(latest.bad()),
                   static_cast<long long>(latest.missing()));
      last_processed = processed;
      last_status = now;
    }
  }
  // (missing: frames whose seq never came, lost before this process)
  std::fprintf(stderr, "ld-detector: stopped after %lld frames (%lld skipped, %lld bad, %lld missing)\n",
               static_cast<long long>(processed), static_cast<long long>(latest.skipped()),
               static_cast<long long>(latest.bad()), static_cast<long long>(latest.missing()));
  return 0;
}
