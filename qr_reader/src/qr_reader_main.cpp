// ld-qr-reader: joins IMAGE and LANDMARKS_TRACKED by frame, decodes each
// track's QR code (once, then re-checked rarely; undecoded tracks retried at
// a bounded rate) and publishes the known payloads on LANDMARK_CODES.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>

#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/message_publisher.hpp"
#include "ld/qr_code_list_t.hpp"
#include "ld/qr_track_reader.hpp"
#include "ld/qr_tracks.hpp"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

// Reads the (utime, seq) of a message without decoding it whole: decoding
// the list is cheap, the image's header is read by a full decode only later.
struct Inputs {
  ld::FrameMatcher matcher;
  ld::image_t header_probe;
  ld::landmark_list_t list_probe;
  ld::QueueFit image_queue, list_queue;  // (their subscriptions' queues: ld::QueueFit)
  int64_t images = 0, lists = 0;         // good ones come
  int64_t bad_images = 0, bad_lists = 0;  // (each channel's lines thinned out on their own)

  void onImage(const lcm::ReceiveBuffer* rb, const std::string& ch) {
    image_queue.fit(rb->data_size);
    const auto* p = static_cast<const uint8_t*>(rb->data);
    if (!ld::decodeMessage(p, rb->data_size, header_probe, &why)) return reportBad(ch, why, bad_images);
    // (its pixels are decoded only if a track needs reading)
    if (const std::string problem = ld::imageProblem(header_probe); !problem.empty())
      return reportBad(ch, problem, bad_images);
    ++images;
    matcher.addImage({header_probe.utime, ld::imageSeq(header_probe).value_or(-1)}, p, rb->data_size);
  }
  void onList(const lcm::ReceiveBuffer* rb, const std::string& ch) {
    list_queue.fit(rb->data_size);
    const auto* p = static_cast<const uint8_t*>(rb->data);
    if (!ld::decodeMessage(p, rb->data_size, list_probe, &why)) return reportBad(ch, why, bad_lists);
    ++lists;
    matcher.addList({list_probe.utime, list_probe.seq}, p, rb->data_size);
  }
  /// Says a bad message of one channel, `bad` being that channel's count: a
  /// flood on one does not thin out the other's lines.
  void reportBad(const std::string& ch, const std::string& what, int64_t& bad) {
    ++bad;
    if (ld::printBadLine(bad))
      std::cerr << "ld-qr-reader: dropped message on " << ch << ": " << what << " "
                << ld::badSoFar(bad, ("bad on " + ch).c_str()) << "\n";
  }
  int64_t bad() const { return bad_images + bad_lists; }
  std::string why;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-qr-reader: IMAGE + LANDMARKS_TRACKED in, LANDMARK_CODES out (see README)."};
  std::string url = ld::defaultLcmUrl(), image_ch = "IMAGE", tracks_ch = "LANDMARKS_TRACKED",
              out_ch = "LANDMARK_CODES";
  ld::QrTrackReaderParams params;
  ld::QrScheduleParams& sched = params.schedule;
  bool verbose = false;
  app.add_option("--lcm-url", url, "LCM URL")->capture_default_str();
  app.add_option("--image", image_ch, "image channel")->capture_default_str();
  app.add_option("--tracks", tracks_ch, "tracked landmarks channel")->capture_default_str();
  app.add_option("--out,--codes", out_ch, "codes channel (--codes: ld-view's name for it)")->capture_default_str();
  app.add_option("--retry-interval", sched.retry_interval_s, "seconds between tries of an undecoded track")
      ->capture_default_str()
      ->check(ld::cli::Positive);
  app.add_option("--recheck-interval", sched.recheck_interval_s, "seconds between re-reads of a decoded track")
      ->capture_default_str()
      ->check(ld::cli::Positive);
  app.add_option("--max-decodes", sched.max_decodes_per_frame, "decode attempts per frame")
      ->capture_default_str()
      ->check(ld::cli::Between(1, 100));
  app.add_option("--decode-budget-ms", params.decode_budget_ms,
                 "milliseconds of decoding per frame: once spent, the frame's other due tracks wait for the next "
                 "(the first decode always runs)")
      ->capture_default_str()
      ->check(ld::cli::Between(1, 10000));
  app.add_option("--stack-frames", params.stack_frames,
                 "frames of an undecoded track averaged in the sheet's frame and read when single "
                 "frames fail (0: off)")
      ->capture_default_str()
      ->check(ld::cli::Between(0, 64));
  app.add_option("--look-interval", params.look_interval_s,
                 "seconds between looks at a read track's modules against those it was read from: a landmark "
                 "showing another code is read again at once (0: off)")
      ->capture_default_str()
      ->check(ld::cli::Between(0, 1e6));
  int nice_steps = 10;
  app.add_option("--nice", nice_steps,
                 "run this many steps of nice below the priority it was started with, so that the detector "
                 "and the tracker on the same cores come first (0: as started)")
      ->capture_default_str()
      ->check(ld::cli::Between(0, 19));
  app.add_flag("-v,--verbose", verbose,
               "print each newly read payload, and each track whose stacked frames a jump dropped");
  LD_CLI_PARSE(app, argc, argv);
  if (const std::string p =
          ld::channelProblem({{"--image", image_ch}, {"--tracks", tracks_ch}}, {"--out", out_ch}, "the reader's");
      !p.empty())
    return ld::cli::usage(argv[0], p);

  // (before LCM starts its receive thread, which inherits it)
  if (nice_steps > 0) {
    errno = 0;
    const int now = getpriority(PRIO_PROCESS, 0);
    if (errno != 0 || setpriority(PRIO_PROCESS, 0, std::min(now + nice_steps, 19)) != 0)
      std::cerr << "ld-qr-reader: note: --nice " << nice_steps << " not applied (" << std::strerror(errno)
                << "): it runs at the priority it was started with\n";
  }
  if (!ld::lcmUrlUsable(url, "ld-qr-reader")) return 2;
  lcm::LCM lcm(url);
  ld::MessagePublisher publisher(lcm);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-qr-reader")) return status;
  Inputs in;
  in.image_queue = ld::QueueFit(lcm.subscribe(image_ch, &Inputs::onImage, &in));
  in.list_queue = ld::QueueFit(lcm.subscribe(tracks_ch, &Inputs::onList, &in));
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  ld::QrTrackReader tracks(params, std::cerr, verbose);
  ld::FrameMatcher::Pair pair;
  ld::image_t image;
  ld::landmark_list_t list;
  ld::qr_code_list_t out;
  bool untracked_said = false;                     // said that the lists carry no track ids
  bool unjoined_said = false;                      // said that no image and list ever joined
  constexpr int64_t kUnjoinedNote = 60;            // images, and lists, come unjoined before that is said
  int64_t frames = 0;
  while (!g_stop) {
    // waits, then drains the queue: only the newest message is processed
    if (!ld::pumpLcm(lcm, 200, g_stop, "ld-qr-reader")) return 1;
    if (g_stop) break;
    // (nothing ever joined: the images and the lists are of different frames)
    // (or no image at all, the likelier mistake: --image names no channel in use)
    if (!unjoined_said && in.matcher.matched() == 0 && in.lists >= kUnjoinedNote &&
        (in.images >= kUnjoinedNote || in.images == 0)) {
      if (in.images == 0)
        std::cerr << "ld-qr-reader: note: " << in.lists << " lists on " << tracks_ch << " and no image on " << image_ch
                  << " yet: --image must be the channel of the images the tracked landmarks were found in\n";
      else
        std::cerr << "ld-qr-reader: note: " << in.images << " images on " << image_ch << " and " << in.lists
                  << " lists on " << tracks_ch << " and none of the same frame (utime and seq) yet: --image must be "
                  << "the images the tracked landmarks were found in\n";
      unjoined_said = true;
    }
    if (!in.matcher.takeNewest(pair)) continue;
    const int ni = static_cast<int>(pair.image.size()), nl = static_cast<int>(pair.list.size());
    if (image.decode(pair.image.data(), 0, ni) != ni || list.decode(pair.list.data(), 0, nl) != nl)
      continue;  // checked on arrival already
    ++frames;
    // (landmarks without track ids: the detector's lists, not the tracker's)
    if (!untracked_said && list.nlandmarks > 0 &&
        std::all_of(list.landmarks.begin(), list.landmarks.end(), [](const auto& lm) { return lm.track_id < 0; })) {
      std::cerr << "ld-qr-reader: the landmarks on " << tracks_ch << " carry no track ids (from backend '"
                << list.backend << "'): --tracks must name the tracker's output (LANDMARKS_TRACKED); nothing is "
                << "read until then\n";
      untracked_said = true;
    }
    try {
      tracks.process(image, list, out);
    } catch (const ld::ImageFormatError& e) {
      in.reportBad(image_ch, e.what(), in.bad_images);
      continue;
    }
    publisher.publish(out_ch, out);
  }
  std::fprintf(stderr,
               "ld-qr-reader: stopped after %lld frames, %lld tracks read (%lld from stacked frames), "
               "%lld changed (their landmark showed another code), %lld skipped, %lld late, %lld unmatched, %lld bad\n",
               static_cast<long long>(frames), static_cast<long long>(tracks.tracksRead()),
               static_cast<long long>(tracks.tracksReadStacked()), static_cast<long long>(tracks.tracksChanged()),
               static_cast<long long>(in.matcher.skipped()), static_cast<long long>(in.matcher.late()),
               static_cast<long long>(in.matcher.unmatchedDropped()), static_cast<long long>(in.bad()));
  return 0;
}
