#include "ld/bus_monitor.hpp"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <numeric>

#include <lcm/lcm-cpp.hpp>

#include "ld/image_convert.hpp"
#include "ld/image_t.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"

namespace ld {
namespace {

double round3(double v) { return std::round(v * 1000.0) / 1000.0; }

nlohmann::ordered_json payloadsJson(const std::vector<std::pair<std::string, int64_t>>& payloads) {
  auto a = nlohmann::ordered_json::array();
  for (const auto& [payload, seq] : payloads) a.push_back({{"payload", payload}, {"from_seq", seq}});
  return a;
}

double rate(int64_t n, int64_t a_us, int64_t b_us) {
  const double s = static_cast<double>(b_us - a_us) * 1e-6;
  return n > 1 && s > 0 ? (static_cast<double>(n) - 1) / s : 0;
}

// The kernel's receive time when LCM has it, else now.
int64_t receivedAt(const lcm::ReceiveBuffer* rb) {
  if (rb->recv_utime > 0) return rb->recv_utime;
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

Percentiles percentiles(std::vector<double> v) {
  Percentiles p;
  p.count = v.size();
  if (v.empty()) return p;
  std::sort(v.begin(), v.end());
  const auto rank = [&](double q) {
    const size_t k = static_cast<size_t>(std::ceil(q * static_cast<double>(v.size())));
    return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
  };
  p.p50 = rank(0.50);
  p.p90 = rank(0.90);
  p.p99 = rank(0.99);
  p.max = v.back();
  p.mean = std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  return p;
}

void LatencyHistogram::add(int64_t us) {
  if (fine_.empty()) {
    fine_.assign(2 * kFine, 0);
    coarse_.assign(kFine, 0);
  }
  min_us_ = count_ == 0 ? us : std::min(min_us_, us);
  max_us_ = count_ == 0 ? us : std::max(max_us_, us);
  ++count_;
  sum_us_ += static_cast<double>(us);
  if (us < kFine) ++fine_[static_cast<size_t>(std::max(us, -kFine) + kFine)];
  else ++coarse_[static_cast<size_t>(std::min((us - kFine) / 1000, kFine - 1))];
}

Percentiles LatencyHistogram::percentiles() const {
  Percentiles p;
  p.count = count_;
  if (count_ == 0) return p;
  const auto rank = [&](double q) {
    // (the value of rank ceil(q n), 1-based, as ld::percentiles takes it)
    const auto k = std::max<size_t>(1, static_cast<size_t>(std::ceil(q * static_cast<double>(count_))));
    size_t seen = fine_[0];
    if (seen >= k) return static_cast<double>(min_us_) * 1e-3;
    for (size_t i = 1; i < fine_.size(); ++i)
      if ((seen += fine_[i]) >= k) return static_cast<double>(static_cast<int64_t>(i) - kFine) * 1e-3;
    for (size_t i = 0; i + 1 < coarse_.size(); ++i)
      if ((seen += coarse_[i]) >= k) return static_cast<double>(kFine + 1000 * static_cast<int64_t>(i)) * 1e-3;
    return static_cast<double>(max_us_) * 1e-3;
  };
  p.p50 = rank(0.50);
  p.p90 = rank(0.90);
  p.p99 = rank(0.99);
  p.max = static_cast<double>(max_us_) * 1e-3;
  p.mean = sum_us_ / static_cast<double>(count_) * 1e-3;
  return p;
}

BusMonitor::BusMonitor(BusChannels channels) : ch_(std::move(channels)) {}

void BusMonitor::subscribe(lcm::LCM& lcm) {
  queues_[0] = QueueFit(lcm.subscribe(ch_.image, &BusMonitor::onImage, this));
  queues_[1] = QueueFit(lcm.subscribe(ch_.landmarks, &BusMonitor::onLandmarks, this));
  queues_[2] = QueueFit(lcm.subscribe(ch_.tracked, &BusMonitor::onTracked, this));
  queues_[3] = QueueFit(lcm.subscribe(ch_.codes, &BusMonitor::onCodes, this));
  lcm.subscribe("LCM_SELF_TEST", &BusMonitor::onSelfTest, this);
}

int64_t BusMonitor::messages(const std::string& channel) const {
  for (const auto& [name, c] : {std::pair<const std::string&, const ChannelCount&>{ch_.image, images_},
                                {ch_.landmarks, landmarks_},
                                {ch_.tracked, tracked_},
                                {ch_.codes, codes_}})
    if (name == channel) return c.total;
  return 0;
}

void BusMonitor::count(ChannelCount& c, Micros rx_us) {
  if (c.total == 0) c.first = rx_us;
  c.last = rx_us;
  ++c.total;
  ++c.window;
}

// An image the detector refuses (a size that does not match its format, an
// unknown format, an odd YUYV width, JPEG headers that are no frame) is a
// bad image, not an image never tracked: the same checks as the detector's
// (ld::checkImage), on the pixels copied into a kept buffer. (A JPEG whose
// data is damaged shows only when decoded, which the detector does alone.)
void BusMonitor::onImage(const lcm::ReceiveBuffer* rb, const std::string&) {
  queues_[0].fit(rb->data_size);
  if (!decodeMessage(rb->data, rb->data_size, image_buf_) || !imageProblem(image_buf_).empty()) {
    ++bad_;
    ++bad_images_;
    return;
  }
  imageSeen(image_buf_.utime, imageSeq(image_buf_).value_or(-1), receivedAt(rb));
}

void BusMonitor::onSelfTest(const lcm::ReceiveBuffer* rb, const std::string&) {
  ++self_tests_;
  last_self_test_us_ = receivedAt(rb);
}

void BusMonitor::onLandmarks(const lcm::ReceiveBuffer* rb, const std::string&) {
  queues_[1].fit(rb->data_size);
  if (decodeMessage(rb->data, rb->data_size, list_buf_)) landmarksSeen(list_buf_, receivedAt(rb));
  else ++bad_;
}

void BusMonitor::onTracked(const lcm::ReceiveBuffer* rb, const std::string&) {
  queues_[2].fit(rb->data_size);
  if (decodeMessage(rb->data, rb->data_size, list_buf_)) trackedSeen(list_buf_, receivedAt(rb));
  else ++bad_;
}

void BusMonitor::onCodes(const lcm::ReceiveBuffer* rb, const std::string&) {
  queues_[3].fit(rb->data_size);
  if (decodeMessage(rb->data, rb->data_size, codes_buf_)) codesSeen(codes_buf_, receivedAt(rb));
  else ++bad_;
}

void BusMonitor::imageSeen(int64_t utime, int64_t seq, Micros rx_us) {
  count(images_, rx_us);
  // (an image of a frame seen before: the log replayed again, ld-run
  // restarting its replay source from the start; the lists of this pass
  // are no repeats of the last pass's)
  if (recent_images_.seenBefore(utime, seq)) {
    recent_images_.clear();
    recent_images_.seenBefore(utime, seq);
    recent_landmarks_.clear();
    recent_tracked_.clear();
    recent_codes_.clear();
  }
  const bool live = !utimes_logged_ && utime <= rx_us && rx_us - utime <= kLiveUtimeUs;
  pending_[{utime, seq}] = PendingImage{rx_us, live ? utime : rx_us};
  // Frames never tracked (skipped by the detector) are forgotten after 5 s.
  while (!pending_.empty()) {
    auto oldest = std::min_element(pending_.begin(), pending_.end(), [](const auto& a, const auto& b) {
      return a.second.received < b.second.received;
    });
    if (rx_us - oldest->second.received < 5'000'000) break;
    pending_.erase(oldest);
    ++unmatched_images_;
  }
}

void BusMonitor::landmarksSeen(const landmark_list_t& list, Micros rx_us) {
  if (recent_landmarks_.seenBefore(list.utime, list.seq)) {
    ++repeated_;
    return;
  }
  count(landmarks_, rx_us);
  det_skipped_.update(list.frames_skipped);
}

void BusMonitor::trackedSeen(const landmark_list_t& list, Micros rx_us) {
  if (recent_tracked_.seenBefore(list.utime, list.seq)) {
    ++repeated_;
    return;
  }
  count(tracked_, rx_us);
  ++tracked_frames_;
  trk_skipped_.update(list.frames_skipped);
  ages_.clear();
  for (const auto& lm : list.landmarks)
    if (lm.track_id >= 0) ages_.emplace_back(lm.track_id, lm.age);
  if (restarts_.note(ages_)) run_starts_.push_back(list.utime);
  const int run = static_cast<int>(run_starts_.size());
  FrameRecord f;
  f.utime = list.utime;
  f.seq = list.seq;
  f.run = run;
  const auto it = pending_.find({list.utime, list.seq});
  if (it != pending_.end()) {
    f.latency_ms = static_cast<double>(rx_us - it->second.origin) * 1e-3;
    ++(it->second.origin == it->second.received ? from_arrival_ : from_capture_);
    latencies_.add(rx_us - it->second.origin);
    if (window_ms_.size() >= kWindowMax) window_ms_.clear();
    window_ms_.push_back(f.latency_ms);
    ++matched_;
    pending_.erase(it);
  }
  for (const auto& lm : list.landmarks) {
    if (lm.track_id < 0) continue;
    bool is_new = false;
    TrackInfo& info = track(run, lm.track_id, is_new);
    info.seenIn(list.seq, is_new);
    if (lm.visible) {
      ++info.frames_visible;
      ++f.landmarks;
      f.ids.push_back(lm.track_id);
    } else {
      ++info.frames_coasting;
    }
    if (lm.has_payload) setPayload(run, lm.track_id, lm.payload, list.seq);
  }
  ++histogram_[f.landmarks];
  frames_.push_back(std::move(f));
  if (frames_.size() > kFramesKept) {
    frames_.pop_front();
    ++frames_left_out_;
  }
}

int64_t BusMonitor::qrSkippedAll() const {
  // (at the end: the frames after the last answered were not answered either)
  return qr_skipped_ + static_cast<int64_t>(frames_left_out_ + frames_.size() - qr_settled_);
}

BusMonitor::TrackInfo& BusMonitor::track(int run, int64_t id, bool& is_new) {
  auto [it, made] = tracks_.try_emplace({run, id});
  is_new = made;
  it->second.last_list = tracked_frames_;
  if (!made || tracks_.size() <= kTracksKept + kTracksKept / 10) return it->second;
  // Over the bound by a tenth: the longest unseen go, down to kTracksKept
  // (now and then, each time a tenth of the bound, not one at every new track).
  std::vector<int64_t> lasts;
  lasts.reserve(tracks_.size());
  for (const auto& [key, t] : tracks_) lasts.push_back(t.last_list);
  const size_t drop = tracks_.size() - kTracksKept;
  std::nth_element(lasts.begin(), lasts.begin() + static_cast<std::ptrdiff_t>(drop - 1), lasts.end());
  const int64_t cutoff = lasts[drop - 1];  // (the drop-th oldest; ties kept or dropped together)
  const std::pair<int, int64_t> key{run, id};
  for (auto t = tracks_.begin(); t != tracks_.end();)
    if (t->second.last_list <= cutoff && t->first != key) {
      if (t->first.first == static_cast<int>(run_starts_.size())) restarts_.forget(t->first.second);
      t = tracks_.erase(t);
      ++tracks_left_out_;
    } else {
      ++t;
    }
  return tracks_.at(key);
}

void BusMonitor::setPayload(int run, int64_t id, const std::string& payload, int64_t seq) {
  bool is_new = false;
  TrackInfo& t = track(run, id, is_new);
  if (is_new) t.seenIn(seq, true);  // (known through a code first: its list was lost, or comes later)
  if (t.payloads.empty()) ++tracks_read_;
  // (one id, two landmarks: the tracker gave it to another, its payload
  // read as well; each in turn, with the frame it came from)
  if (t.payloads.empty() || t.payloads.back().first != payload) t.payloads.emplace_back(payload, seq);
}

void BusMonitor::codesSeen(const qr_code_list_t& codes, Micros rx_us) {
  if (recent_codes_.seenBefore(codes.utime, codes.seq)) {
    ++repeated_;
    return;
  }
  count(codes_, rx_us);
  // The frame's list, the newest of its utime and seq among the last 600.
  size_t found = frames_.size();
  for (size_t k = frames_.size(), n = 0; k-- > 0 && n < 600; ++n)
    if (frames_[k].utime == codes.utime && frames_[k].seq == codes.seq) {
      found = k;
      break;
    }
  // The reader answers lists in order, so the lists before it that it did
  // not answer it skipped: they are settled, for a list among the last 300
  // not settled yet (as they are read, not by the clock: a monitor behind on
  // its own queue counted frames skipped whose answer it had not read yet).
  // (qr_settled_ counts from the first frame, frames_ from the first kept)
  const size_t found_from_first = frames_left_out_ + found;
  if (found < frames_.size() && found_from_first >= qr_settled_ && frames_.size() - found <= 300) {
    qr_skipped_ += static_cast<int64_t>(found_from_first - qr_settled_);
    qr_settled_ = found_from_first + 1;
  }
  // The codes' track ids are those of the message's own frame's list: the
  // tracker run that tracked that frame (a log replayed again repeats its
  // frames' times, and by time alone a code of the second pass went to the
  // run that tracked the first, an operator's audit: two tracks that never
  // were, the real one unread). A frame no longer among them (or whose list
  // was lost): the run whose start came before its time. (Not the frame a
  // code was read from: a payload read long ago is listed with that old
  // frame.)
  const int run =
      found < frames_.size()
          ? frames_[found].run
          : static_cast<int>(std::upper_bound(run_starts_.begin(), run_starts_.end(), codes.utime) - run_starts_.begin());
  for (const auto& c : codes.codes) setPayload(std::max(1, run), c.track_id, c.payload, c.seq);
}

std::string BusMonitor::statusLine(Micros now_us) {
  const double s = last_status_us_ == 0 ? 0 : static_cast<double>(now_us - last_status_us_) * 1e-6;
  const auto hz = [&](ChannelCount& c) {
    const double r = s > 0 ? static_cast<double>(c.window) / s : 0;
    c.window = 0;
    return r;
  };
  const double hi = hz(images_), hl = hz(landmarks_), ht = hz(tracked_), hc = hz(codes_);
  const Percentiles p = percentiles(window_ms_);
  window_ms_.clear();
  last_status_us_ = now_us;
  // (no frame tracked in the window: nothing was timed, "-" as for a QR
  // reader not heard, not 0.00 ms)
  char e2e[64] = "e2e -";
  if (p.count > 0) std::snprintf(e2e, sizeof e2e, "e2e p50 %.2f ms p99 %.2f ms", p.p50, p.p99);
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "%s %.1f/s  %s %.1f/s  %s %.1f/s  %s %.1f/s | %s | "
                "skipped det %lld trk %lld qr %s | tracks %zu, %lld read",
                ch_.image.c_str(), hi, ch_.landmarks.c_str(), hl, ch_.tracked.c_str(), ht,
                ch_.codes.c_str(), hc, e2e, static_cast<long long>(det_skipped_.sum),
                static_cast<long long>(trk_skipped_.sum),
                codes_.total > 0 ? std::to_string(qr_skipped_).c_str() : "-",
                tracks_.size() + static_cast<size_t>(tracks_left_out_), static_cast<long long>(tracks_read_));
  return buf;
}

nlohmann::ordered_json BusMonitor::summary() const {
  using J = nlohmann::ordered_json;
  J j;
  J chans = J::object();
  for (const auto& [name, c] : {std::pair<std::string, const ChannelCount*>{ch_.image, &images_},
                                {ch_.landmarks, &landmarks_},
                                {ch_.tracked, &tracked_},
                                {ch_.codes, &codes_}})
    chans[name] = {{"messages", c->total}, {"rate_hz", round3(rate(c->total, c->first, c->last))}};
  j["channels"] = chans;
  j["frames"] = {{"images", images_.total},
                 {"tracked", tracked_frames_},
                 {"matched", matched_},
                 {"unmatched_images", unmatched_images_ + static_cast<int64_t>(pending_.size())},
                 {"detector_skipped", det_skipped_.sum},
                 {"tracker_skipped", trk_skipped_.sum},
                 {"qr_reader_skipped",
                  codes_.total > 0 ? J(qrSkippedAll()) : J(nullptr)},
                 {"bad_messages", bad_},
                 {"bad_images", bad_images_},
                 {"repeated_messages", repeated_}};
  double sum = 0;
  int maxn = 0;
  J hist = J::object();
  for (const auto& [n, frames] : histogram_) {
    sum += static_cast<double>(n) * static_cast<double>(frames);
    maxn = std::max(maxn, n);
    hist[std::to_string(n)] = frames;
  }
  j["landmarks_per_frame"] = {
      {"mean", round3(tracked_frames_ > 0 ? sum / static_cast<double>(tracked_frames_) : 0)},
      {"max", maxn},
      {"histogram", hist}};
  const Percentiles p = latencies_.percentiles();
  j["latency_ms"] = {{"count", p.count},   {"p50", round3(p.p50)}, {"p90", round3(p.p90)},
                     {"p99", round3(p.p99)}, {"max", round3(p.max)}, {"mean", round3(p.mean)},
                     {"from", p.count == 0          ? J(nullptr)
                              : from_arrival_ == 0 ? J("capture")
                              : from_capture_ == 0 ? J("arrival")
                                                   : J("capture and arrival")}};
  J tracks = J::array();
  for (const auto& [key, t] : tracks_) {
    tracks.push_back({{"id", key.second},
                      {"tracker_run", key.first},
                      {"payload", t.payloads.empty() ? J(nullptr) : J(t.payloads.back().first)},
                      {"payload_changes", t.payloads.empty() ? 0 : static_cast<int>(t.payloads.size()) - 1},
                      {"payloads", payloadsJson(t.payloads)},
                      {"first_seq", t.first_seq},
                      {"last_seq", t.last_seq},
                      {"frames_visible", t.frames_visible},
                      {"frames_coasting", t.frames_coasting}});
  }
  j["tracker_restarts"] = restarts_.restarts();
  j["tracks"] = tracks;
  j["tracks_left_out"] = tracks_left_out_;
  j["payloads_decoded"] = tracks_read_;
  J per = J::array();
  for (const auto& f : frames_)
    per.push_back({{"seq", f.seq},
                   {"utime", f.utime},
                   {"latency_ms", f.latency_ms < 0 ? J(nullptr) : J(round3(f.latency_ms))},
                   {"landmarks", f.landmarks},
                   {"ids", f.ids},
                   {"tracker_run", f.run}});
  j["per_frame"] = per;
  j["per_frame_left_out"] = frames_left_out_;
  return j;
}

}  // namespace ld
