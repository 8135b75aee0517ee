// ld-qr-reader: joins IMAGE and LANDMARKS_TRACKED by frame, decodes each
// track's QR code (once, then re-checked rarely; undecoded tracks retried at
// a bounded rate) and publishes the known payloads on LANDMARK_CODES.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <unordered_map>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/qr_code_list_t.hpp"
#include "ld/qr_reader.hpp"
#include "ld/qr_tracks.hpp"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

// A tracked landmark's pattern corners (TL, TR, BR, BL) as the reader takes them.
std::array<cv::Point2f, 4> cornersOf(const ld::landmark_t& lm) {
  std::array<cv::Point2f, 4> corners;
  for (size_t i = 0; i < 4; ++i) corners[i] = {lm.corners[i][0], lm.corners[i][1]};
  return corners;
}

// Reads the (utime, seq) of a message without decoding it whole: decoding
// the list is cheap, the image's header is read by a full decode only later.
struct Inputs {
  ld::FrameMatcher matcher;
  ld::image_t header_probe;
  ld::landmark_list_t list_probe;
  int64_t bad = 0;

  void onImage(const lcm::ReceiveBuffer* rb, const std::string& ch) {
    const auto* p = static_cast<const uint8_t*>(rb->data);
    if (!ld::decodeMessage(p, rb->data_size, header_probe, &why)) return reportBad(ch, why);
    try {
      ld::checkImage(header_probe);  // its pixels are decoded only if a track needs reading
    } catch (const ld::ImageFormatError& e) {
      return reportBad(ch, e.what());
    }
    matcher.addImage({header_probe.utime, ld::imageSeq(header_probe).value_or(-1)}, p, rb->data_size);
  }
  void onList(const lcm::ReceiveBuffer* rb, const std::string& ch) {
    const auto* p = static_cast<const uint8_t*>(rb->data);
    if (!ld::decodeMessage(p, rb->data_size, list_probe, &why)) return reportBad(ch, why);
    matcher.addList({list_probe.utime, list_probe.seq}, p, rb->data_size);
  }
  void reportBad(const std::string& ch, const std::string& what) {
    ++bad;
    if (ld::printBadLine(bad))
      std::cerr << "ld-qr-reader: dropped message on " << ch << ": " << what << " " << ld::badSoFar(bad) << "\n";
  }
  std::string why;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-qr-reader: IMAGE + LANDMARKS_TRACKED in, LANDMARK_CODES out (see README)."};
  std::string url = ld::defaultLcmUrl(), image_ch = "IMAGE", tracks_ch = "LANDMARKS_TRACKED",
              out_ch = "LANDMARK_CODES";
  ld::QrScheduleParams sched;
  bool verbose = false;
  app.add_option("--lcm-url", url, "LCM URL")->capture_default_str();
  app.add_option("--image", image_ch, "image channel")->capture_default_str();
  app.add_option("--tracks", tracks_ch, "tracked landmarks channel")->capture_default_str();
  app.add_option("--out", out_ch, "codes channel")->capture_default_str();
  app.add_option("--retry-interval", sched.retry_interval_s, "seconds between tries of an undecoded track")
      ->capture_default_str()
      ->check(ld::cli::Positive);
  app.add_option("--recheck-interval", sched.recheck_interval_s, "seconds between re-reads of a decoded track")
      ->capture_default_str()
      ->check(ld::cli::Positive);
  app.add_option("--max-decodes", sched.max_decodes_per_frame, "decode attempts per frame")
      ->capture_default_str()
      ->check(ld::cli::Between(1, 100));
  double budget_ms = 30;
  app.add_option("--decode-budget-ms", budget_ms,
                 "milliseconds of decoding per frame: once spent, the frame's other due tracks wait for the next "
                 "(the first decode always runs)")
      ->capture_default_str()
      ->check(ld::cli::Between(1, 10000));
  int stack_frames = 8;
  app.add_option("--stack-frames", stack_frames,
                 "frames of an undecoded track averaged in the sheet's frame and read when single "
                 "frames fail (0: off)")
      ->capture_default_str()
      ->check(ld::cli::Between(0, 64));
  app.add_flag("-v,--verbose", verbose,
               "print each newly read payload, and each track whose stacked frames a jump dropped");
  LD_CLI_PARSE(app, argc, argv);
  if (const std::string p =
          ld::channelProblem({{"--image", image_ch}, {"--tracks", tracks_ch}}, {"--out", out_ch}, "the reader's");
      !p.empty())
    return ld::cli::usage(argv[0], p);

  if (!ld::lcmUrlUsable(url, "ld-qr-reader")) return 2;
  lcm::LCM lcm(url);
  if (const int status = ld::lcmOpenStatus(lcm, url, "ld-qr-reader")) return status;
  Inputs in;
  lcm.subscribe(image_ch, &Inputs::onImage, &in);
  lcm.subscribe(tracks_ch, &Inputs::onList, &in);
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  ld::QrReader reader;
  ld::QrReader stack_reader;  // its own buffers: the stacks' views have their own size
  ld::QrTrackBook book(sched);
  ld::StillTimeWatch still;
  std::vector<std::pair<int64_t, float>> tried_ms;  // (this frame's decodes: track id, ms)
  ld::FrameMatcher::Pair pair;
  ld::image_t image;
  ld::landmark_list_t list;
  ld::qr_code_list_t out;
  cv::Mat bgr;
  std::vector<int64_t> ids;
  std::vector<std::pair<int64_t, int32_t>> ages;  // (track id, age) of every track of the frame
  bool untracked_said = false;                     // said that the lists carry no track ids
  bool unjoined_said = false;                      // said that no image and list ever joined
  constexpr int64_t kUnjoinedNote = 60;            // messages dropped unjoined before that is said
  // Undecoded tracks' frames, averaged (ld::QrStack); at most kMaxStacks.
  constexpr size_t kMaxStacks = 32;
  constexpr int kMinStackFrames = 3;
  std::unordered_map<int64_t, ld::QrStack> stacks;
  int64_t frames = 0, decoded = 0, decoded_stacked = 0;
  while (!g_stop) {
    // waits, then drains the queue: only the newest message is processed
    if (!ld::pumpLcm(lcm, 200, g_stop, "ld-qr-reader")) return 1;
    if (g_stop) break;
    // (nothing ever joined: the images and the lists are of different frames)
    if (frames == 0 && !unjoined_said && in.matcher.unmatchedDropped() >= kUnjoinedNote) {
      std::cerr << "ld-qr-reader: note: " << in.matcher.unmatchedDropped() << " images and lists on " << image_ch
                << " and " << tracks_ch << " and none of the same frame (utime and seq) yet: --image must be "
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
    ids.clear();
    ages.clear();
    for (const auto& lm : list.landmarks) {
      if (lm.visible && lm.track_id >= 0) ids.push_back(lm.track_id);
      if (lm.track_id >= 0) ages.emplace_back(lm.track_id, lm.age);
    }
    // (a tracker that restarted numbers its tracks from 1 again: what was
    // read under the old ids belongs to other landmarks)
    if (book.noteAges(ages)) {
      stacks.clear();
      std::cerr << "ld-qr-reader: track ids started again (a track is younger than it can be: the tracker "
                   "restarted); the payloads read so far are forgotten\n";
    }
    // (a read track whose landmark jumped is another landmark now: the
    // tracker moved its id over; what was read is forgotten and read again)
    for (const auto& lm : list.landmarks) {
      if (lm.track_id < 0) continue;
      const std::array<cv::Point2f, 4> c = cornersOf(lm);
      double side = 0;
      for (int i = 0; i < 4; ++i) side += cv::norm(c[static_cast<size_t>((i + 1) % 4)] - c[static_cast<size_t>(i)]) / 4;
      const cv::Point2f centre = (c[0] + c[1] + c[2] + c[3]) * 0.25f;
      const auto forgotten = book.follow(lm.track_id, lm.age, lm.visible, centre.x, centre.y, side);
      if (forgotten && verbose)
        std::cerr << "ld-qr-reader: track " << lm.track_id << " jumped by more than its landmark's size: \""
                  << *forgotten << "\" is forgotten and the track read again (ids moved?)\n";
    }
    if (still.note(list.utime))
      std::cerr << "ld-qr-reader: 10 frames in a row with utime " << list.utime
                << ": retries and re-reads count time from it, so a track not read at once is not tried again "
                   "while it stands still (does the publisher stamp its frames?)\n";
    const std::vector<int64_t> todo = book.schedule(ids, list.utime);
    for (auto it = stacks.begin(); it != stacks.end();) {  // tracks gone or read: their stacks go
      const ld::landmark_t* listed = nullptr;  // visible or coasting
      for (const auto& lm : list.landmarks)
        if (lm.track_id == it->first) listed = &lm;
      if (!listed || book.payload(it->first)) {
        it = stacks.erase(it);
        continue;
      }
      // where the track is in every frame: a jump is another landmark
      if (it->second.follow(cornersOf(*listed)) && verbose)
        std::cerr << "ld-qr-reader: track " << it->first
                  << " jumped by more than its landmark's side: its stacked frames start again (ids swapped?)\n";
      ++it;
    }
    if (!todo.empty()) {
      try {
        ld::imageToBgr(image, bgr);
      } catch (const ld::ImageFormatError& e) {
        in.reportBad(image_ch, e.what());
        continue;
      }
    }
    out.codes.clear();
    // The due tracks in the schedule's order (undecoded first, least
    // recently tried first), while the frame's budget lasts: the ones left
    // stay due and lead the next frame's schedule. (In the list's order, the
    // first unreadable track took the budget every frame.)
    ld::DecodeBudget budget(budget_ms);
    tried_ms.clear();
    for (const int64_t id : todo) {
      const auto lm = std::find_if(list.landmarks.begin(), list.landmarks.end(),
                                   [&](const ld::landmark_t& l) { return l.track_id == id && l.visible; });
      if (lm == list.landmarks.end() || !budget.allows(std::chrono::steady_clock::now())) continue;
      const std::array<cv::Point2f, 4> corners = cornersOf(*lm);
      const auto t0 = std::chrono::steady_clock::now();
      auto r = reader.decode(bgr, corners);
      bool from_stack = false;
      if (!r && stack_frames > 0 && !book.payload(id) && (stacks.count(id) || stacks.size() < kMaxStacks)) {
        ld::QrStack& stack = stacks.try_emplace(id, stack_frames).first->second;
        if (stack.add(bgr, corners) && stack.frames() >= std::min(kMinStackFrames, stack_frames))
          from_stack = static_cast<bool>(r = stack.decode(stack_reader));
      }
      tried_ms.emplace_back(id, std::chrono::duration<float, std::milli>(std::chrono::steady_clock::now() - t0).count());
      const bool is_new = r && !book.payload(id);
      decoded_stacked += is_new && from_stack;
      book.record(id, list.utime, list.seq, r ? std::optional<std::string>(r->payload) : std::nullopt);
      if (is_new) {
        ++decoded;  // (its stack goes with the next frame's pruning)
        if (verbose)
          std::cerr << "ld-qr-reader: track " << id << " reads \"" << r->payload << "\""
                    << (from_stack ? " (from its stacked frames)" : "") << "\n";
      }
    }
    for (const auto& lm : list.landmarks) {
      if (lm.track_id < 0) continue;
      if (const auto* k = book.payload(lm.track_id)) {
        ld::qr_code_t c{};
        c.track_id = lm.track_id;
        c.payload = k->payload;
        c.utime = k->utime;
        c.seq = k->seq;
        for (int i = 0; i < 4; ++i)
          for (int j = 0; j < 2; ++j) c.corners[i][j] = lm.corners[i][j];
        const auto t = std::find_if(tried_ms.begin(), tried_ms.end(), [&](const auto& p) { return p.first == lm.track_id; });
        c.decode_ms = t == tried_ms.end() ? 0.0f : t->second;
        out.codes.push_back(std::move(c));
      }
    }
    out.utime = list.utime;
    out.seq = list.seq;
    out.ncodes = static_cast<int32_t>(out.codes.size());
    lcm.publish(out_ch, &out);
  }
  std::fprintf(stderr,
               "ld-qr-reader: stopped after %lld frames, %lld tracks read (%lld from stacked frames), "
               "%lld skipped, %lld unmatched, %lld bad\n",
               static_cast<long long>(frames), static_cast<long long>(decoded),
               static_cast<long long>(decoded_stacked),
               static_cast<long long>(in.matcher.skipped()),
               static_cast<long long>(in.matcher.unmatchedDropped()), static_cast<long long>(in.bad));
  return 0;
}
