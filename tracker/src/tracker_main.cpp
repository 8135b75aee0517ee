// ld-tracker: subscribes to LANDMARKS, publishes LANDMARKS_TRACKED: the same
// frames (utime, seq) with a stable track id per landmark, and the landmarks
// that are briefly not detected (coasting, visible = false) at their
// predicted position. Always works on the newest message and counts the ones
// it skipped.
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/latest_message.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/message_publisher.hpp"
#include "ld/tracker.hpp"
#include "ld/tracker_msg.hpp"

namespace {

constexpr int32_t kMaxLandmarks = 1000;  // in one list

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-tracker: LANDMARKS in, LANDMARKS_TRACKED out (see README)."};
  std::string url = ld::defaultLcmUrl(), in_channel = "LANDMARKS", out_channel = "LANDMARKS_TRACKED";
  std::string params_file;
  ld::TrackerParams cli;  // values of the parameter options (only those given are used)
  bool no_predict = false, no_coasting = false, print_params = false, verbose = false;
  app.add_option("--lcm-url", url, "LCM URL")->capture_default_str();
  app.add_option("--in", in_channel, "landmarks channel (from ld-detector)")->capture_default_str();
  app.add_option("--out", out_channel, "tracked landmarks channel")->capture_default_str();
  app.add_option("--params", params_file, "tracker parameters (YAML); the options below override it");
  auto* o_life = app.add_option("--max-lifetime", cli.max_lifetime_s,
                                "seconds a landmark is kept while not detected (default 1)")
                     ->check(ld::cli::Positive);
  auto* o_dist = app.add_option("--max-distance", cli.max_distance,
                                "largest match distance, in landmark sizes (default 2; up to 1000)")
                     ->check(ld::cli::PositiveUpTo(1000));
  auto* o_ratio = app.add_option("--max-size-ratio", cli.max_size_ratio,
                                 "largest size ratio of a match (default 1.5)")
                      ->check(ld::cli::Between(1, 1000));
  auto* o_hits = app.add_option("--min-hits", cli.min_hits,
                                "detections before a track is published (default 1)")
                     ->check(ld::cli::Between(1, 1000));
  app.add_flag("--no-predict", no_predict, "no constant-velocity prediction (the paper's tracker)");
  app.add_flag("--no-coasting", no_coasting, "publish only the landmarks detected in each frame");
  app.add_flag("--print-params", print_params, "print the effective parameters as YAML and exit");
  app.add_flag("-v,--verbose", verbose, "print a status line every 5 s");
  LD_CLI_PARSE(app, argc, argv);
  if (const std::string p = ld::channelProblem({{"--in", in_channel}}, {"--out", out_channel}, "the tracker's");
      !p.empty())
    return ld::cli::usage(argv[0], p);

  ld::TrackerParams params;
  try {
    if (!params_file.empty()) params = ld::TrackerParams::load(params_file);
    if (o_life->count()) params.max_lifetime_s = cli.max_lifetime_s;
    if (o_dist->count()) params.max_distance = cli.max_distance;
    if (o_ratio->count()) params.max_size_ratio = cli.max_size_ratio;
    if (o_hits->count()) params.min_hits = cli.min_hits;
    if (no_predict) params.predict = false;
    if (no_coasting) params.report_coasting = false;
    params.validate();
  } catch (const std::exception& e) {
    std::cerr << "ld-tracker: " << e.what() << "\n";
    return 2;
  }
  if (print_params) {
    std::cout << params.toYaml();
    return 0;
  }
  ld::Tracker tracker(params);

  if (!ld::lcmUrlUsable(url, "ld-tracker")) return 2;
  lcm::LCM lcm(url);
  ld::MessagePublisher publisher(lcm);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-tracker")) return status;
  // (a list far beyond what a detector finds, about 130 landmarks at its
  // candidate cap: the assignment's time and memory grow with its square
  // and cube, 6 s and 400 MB for 5000)
  ld::LatestMessage<ld::landmark_list_t> latest(
      "ld-tracker", in_channel, "message", [&in_channel](const ld::landmark_list_t& m) {
        return m.nlandmarks <= kMaxLandmarks
                   ? std::string()
                   : "message on " + in_channel + " is a list of " + std::to_string(m.nlandmarks) +
                         " landmarks (frame " + std::to_string(m.seq) + "), more than the " +
                         std::to_string(kMaxLandmarks) + " the tracker takes";
      },
      {},
      // (the list waiting, again: tracked once, counted as repeated, not as
      // a newer list that skipped it; unstamped lists are left to StillTimeWatch)
      [](const ld::landmark_list_t& a, const ld::landmark_list_t& b) {
        return a.utime != 0 && a.seq >= 0 && a.utime == b.utime && a.seq == b.seq;
      });
  latest.queueOn(lcm.subscribe(in_channel, &ld::LatestMessage<ld::landmark_list_t>::onMessage, &latest));
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  ld::landmark_list_t out;
  ld::StillTimeWatch still;
  std::vector<ld::Landmark> detections;
  int64_t processed = 0, last_processed = 0, resets = 0, rejected = 0, rejected_lists = 0, late = 0, repeated = 0;
  int64_t last_utime = 0, last_seq = -1;  // the frame tracked last
  auto last_status = std::chrono::steady_clock::now();
  while (!g_stop) {
    // waits, then drains the queue: only the newest message is processed
    if (!ld::pumpLcm(lcm, 200, g_stop, "ld-tracker")) return 1;
    if (g_stop) break;
    if (const ld::landmark_list_t* newest = latest.take()) {
      const ld::landmark_list_t& in = *newest;  // (handlers run in pumpLcm alone: it stays while tracked)
      // (the list of the frame tracked last, again: a recording replayed onto
      // the running set, a bridge that repeats; tracked twice, every track
      // aged a frame more. Lists without a time are left to StillTimeWatch.)
      if (in.utime != 0 && in.seq >= 0 && in.seq == last_seq && in.utime == last_utime) {
        if (ld::printBadLine(++repeated))
          std::cerr << "ld-tracker: frame " << in.seq << " (utime " << in.utime
                    << ") came again: tracked once (a recording played onto the running set, or a publisher "
                       "that repeats its frames' utime and seq?) "
                    << ld::badSoFar(repeated, "repeated") << "\n";
        continue;
      }
      const auto t0 = std::chrono::steady_clock::now();
      if (still.note(in.utime))
        std::cerr << "ld-tracker: 10 lists in a row with utime " << in.utime
                  << ": lifetimes count time from it, so tracks unseen do not expire while it stands still "
                     "(does the publisher stamp its frames?)\n";
      ld::landmarksFromList(in, detections);
      const auto& tracks = tracker.update(detections, in.utime, cv::Size(in.width, in.height));
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      // (landmarks with positions that are not numbers, or under a pixel:
      // not tracked; said as bad input is, and counted)
      if (tracker.stats().rejected_detections > rejected) {
        const int64_t n = tracker.stats().rejected_detections - rejected;
        rejected = tracker.stats().rejected_detections;
        if (ld::printBadLine(++rejected_lists))
          std::cerr << "ld-tracker: " << n << (n == 1 ? " landmark" : " landmarks") << " of the list on "
                    << in_channel << " for frame " << in.seq << " (utime " << in.utime
                    << ") not tracked: corners not finite or under a pixel apart "
                    << ld::badSoFar(rejected_lists, "lists with such landmarks") << "\n";
      }
      if (tracker.stats().late_frames > late) {  // (a message that came late: nothing to publish)
        late = tracker.stats().late_frames;
        if (ld::printBadLine(late))
          std::cerr << "ld-tracker: frame " << in.seq << " (utime " << in.utime
                    << ") came after a newer one: not tracked " << ld::badSoFar(late, "late") << "\n";
        continue;
      }
      // (thinned as bad input is: two publishers on the channel whose clocks
      // differ restart the tracks again and again, 15 lines a second)
      if (tracker.stats().resets > resets) {
        resets = tracker.stats().resets;
        if (ld::printBadLine(resets))
          std::cerr << "ld-tracker: utime " << in.utime
                    << " is older than the previous frame's by more than 1 s, or the third frame in a row from "
                       "behind (a log replayed again, the clock stepped back, or two publishers on "
                    << in_channel << " with clocks apart): tracks restarted "
                    << ld::badSoFar(resets, "restarts") << "\n";
      }
      last_utime = in.utime;  // (tracked: not late)
      last_seq = in.seq;
      ld::toTrackedListMessage(tracks, in, ms, latest.skipped(), out);
      publisher.publish(out_channel, out);
      ++processed;
    }
    const auto now = std::chrono::steady_clock::now();
    if (verbose && now - last_status > std::chrono::seconds(5)) {
      const double s = std::chrono::duration<double>(now - last_status).count();
      const auto& st = tracker.stats();
      std::fprintf(stderr,
                   "ld-tracker: %.1f frames/s, %lld processed, %lld skipped, %lld bad, "
                   "%zu in pool, %lld tracks so far\n",
                   (processed - last_processed) / s, static_cast<long long>(processed),
                   static_cast<long long>(latest.skipped()), static_cast<long long>(latest.bad()),
                   tracker.poolSize(), static_cast<long long>(st.tracks_created));
      last_processed = processed;
      last_status = now;
    }
  }
  std::fprintf(stderr,
               "ld-tracker: stopped after %lld frames (%lld skipped, %lld bad, %lld %s not tracked, %lld late, "
               "%lld repeated), "
               "%lld tracks\n",
               static_cast<long long>(processed), static_cast<long long>(latest.skipped()),
               static_cast<long long>(latest.bad()), static_cast<long long>(rejected),
               rejected == 1 ? "landmark" : "landmarks", static_cast<long long>(late),
               static_cast<long long>(repeated + latest.repeated()),
               static_cast<long long>(tracker.stats().tracks_created));
  return 0;
}
