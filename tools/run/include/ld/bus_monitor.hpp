// Watches the process set's channels on the bus and measures it: message
// rates, end-to-end latency, frames the detector and tracker skipped, tracks
// and their payloads (a tracker that restarts numbers its tracks from 1
// again: its tracks are told apart by a run number, ld/track_restarts.hpp).
//
// End-to-end latency is from the image's capture (or publication) to the
// LANDMARKS_TRACKED list of the same frame (matched by utime and seq)
// reaching this process, on the wall clock: the list's time is the kernel's
// receive time (SO_TIMESTAMP, which LCM passes on as recv_utime), the
// image's its utime, which ld-camera sets to the capture time and ld-play to
// the time it publishes: both clocks must be one (the camera on this
// machine, or machines kept in step by NTP/PTP; a camera clock behind adds
// its lag, one ahead makes every frame "arrival"). An image whose utime is
// not a time of the last second (lcm-logplayer replays the logged utimes),
// or any image where the source is known to be a log (setUtimesLogged:
// ld-run's replay source, whose log may have been made a moment ago), is
// timed from its arrival instead, which LCM (1.3.1, as built here) does
// not take from the kernel for a message of several datagrams (an image):
// it is when LCM's receive thread read the last one, which a loaded machine
// delays, so replays' latencies can read low. ld-run prints its status line
// and writes its summary.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ld/image_t.hpp"
#include "ld/lcm_url.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/qr_code_list_t.hpp"
#include "ld/track_restarts.hpp"

namespace lcm {
class LCM;
class ReceiveBuffer;
}  // namespace lcm

namespace ld {

struct BusChannels {
  std::string image = "IMAGE";
  std::string landmarks = "LANDMARKS";
  std::string tracked = "LANDMARKS_TRACKED";
  std::string codes = "LANDMARK_CODES";
};

/// Percentiles of a sample (nearest rank); all zero for an empty sample.
struct Percentiles {
  size_t count = 0;
  double p50 = 0, p90 = 0, p99 = 0, max = 0, mean = 0;
};
Percentiles percentiles(std::vector<double> values);

/// Latencies of a run of any length, counted in bins of whole microseconds:
/// exact from -65.536 to 65.536 ms (a replay's latency under load can read
/// negative), then to the millisecond up to 65.6 s (each value read as its
/// bin's lower edge), and beyond either end in one bin read as the smallest
/// or the largest; the count, the mean and the largest are exact. Its
/// percentiles are those of ld::percentiles (nearest rank) over the same
/// values in milliseconds, to the bit within +-65.536 ms. Fixed memory (768
/// KiB once the first comes): a vector of every latency grew 8 bytes a
/// frame, 20 MB a day at 30 frames/s.
class LatencyHistogram {
 public:
  void add(int64_t us);
  Percentiles percentiles() const;
  size_t count() const { return count_; }

 private:
  static constexpr int64_t kFine = 65536;  // 1-us bins within +-kFine, 1-ms bins above
  std::vector<uint32_t> fine_;    // [us + kFine]; [0]: kFine us or more below 0
  std::vector<uint32_t> coarse_;  // [(us - kFine) / 1000]; the last: all beyond
  size_t count_ = 0;
  double sum_us_ = 0;
  int64_t min_us_ = 0, max_us_ = 0;
};

class BusMonitor {
 public:
  using Micros = int64_t;  ///< wall-clock time, microseconds (LCM's recv_utime)

  explicit BusMonitor(BusChannels channels = {});
  /// The images' utimes are a log's (ld-run's replay source): every frame is
  /// timed from its image's arrival, even a utime of the last second (a log
  /// made a moment before its replay).
  void setUtimesLogged(bool logged) { utimes_logged_ = logged; }
  /// Subscribes the four channels on `lcm` (the object must outlive it).
  void subscribe(lcm::LCM& lcm);

  // What the handlers record; public so tests can feed a monitor directly.
  void imageSeen(int64_t utime, int64_t seq, Micros rx_us);  ///< rx_us: when it arrived
  void landmarksSeen(const landmark_list_t& list, Micros rx_us);
  void trackedSeen(const landmark_list_t& list, Micros rx_us);
  void codesSeen(const qr_code_list_t& codes, Micros rx_us);

  /// Rates since the previous call, latency over that window, skipped
  /// frames, tracks and payloads read, as one line.
  std::string statusLine(Micros now_us);

  /// Everything measured since the start:
  /// {"channels": {name: {"messages", "rate_hz"}},
  ///  "frames": {"images", "tracked", "matched", "unmatched_images", "detector_skipped",
  ///             "tracker_skipped", "qr_reader_skipped" (tracked frames no codes message
  ///             came for; null when none came at all), "bad_messages", "bad_images", "repeated_messages"},
  ///  "landmarks_per_frame": {"mean", "max", "histogram": {"n": frames}},
  ///  "latency_ms": {"count", "p50", "p90", "p99", "max", "mean", "from"}, from: "capture"
  ///               (every frame timed from its utime), "arrival", "capture and arrival", or
  ///               null (no frame timed),
  ///  "tracker_restarts",
  ///  "tracks": [{"id", "tracker_run", "payload" (the last), "payload_changes",
  ///              "payloads": [{"payload", "from_seq"}] (each in turn, from the frame it was
  ///              first listed or read in), "first_seq", "last_seq" (the lowest and highest
  ///              frame it was listed in, or read in before any), "frames_visible",
  ///              "frames_coasting"}],
  ///  "tracks_left_out", "payloads_decoded",
  ///  "per_frame": [{"seq", "utime", "latency_ms"|null, "landmarks", "ids", "tracker_run"}],
  ///  "per_frame_left_out"}
  /// tracker_run counts the tracker's runs from 1 (a track is its id and run).
  /// per_frame holds the last kFramesKept tracked frames; per_frame_left_out
  /// counts the earlier ones; tracks holds the kTracksKept most recently
  /// listed or read, tracks_left_out counts the others (payloads_decoded and
  /// every other figure count them all).
  nlohmann::ordered_json summary() const;

  /// One of the four channels' good messages so far (0 for a channel it
  /// does not follow).
  int64_t messages(const std::string& channel) const;

  int64_t trackedFrames() const { return tracked_frames_; }
  /// Lists and codes messages of a frame their channel had already carried
  /// (counted once, the repeats left out of every figure).
  int64_t repeatedMessages() const { return repeated_; }
  /// Messages on the codes channel.
  int64_t codesMessages() const { return codes_.total; }
  int64_t imageFrames() const { return images_.total; }
  /// Messages on the image channel that are no image (not counted as images).
  int64_t badImages() const { return bad_images_; }
  /// LCM_SELF_TEST messages seen (each process sends one, repeated every
  /// 100 ms until its own copy comes back) and when the last came.
  int64_t selfTests() const { return self_tests_; }
  Micros lastSelfTest() const { return last_self_test_us_; }
  size_t latencyCount() const { return latencies_.count(); }
  /// The tracked frames kept for the summary's per_frame (the codes' joins
  /// look among the last 600 of them): 20 minutes at 30 frames/s, about 4 MB,
  /// and about 40 MB more while the summary is written (measured: 93 MB at
  /// the most against 57 MB all along).
  static constexpr size_t kFramesKept = 36000;
  /// The tracks kept for the summary's tracks, the most recently seen (a
  /// robot driving past landmarks makes tens of thousands a day): about 2 MB.
  static constexpr size_t kTracksKept = 10000;
  /// An image's utime within this long before its arrival is its capture or
  /// publication time; older (a replayed log), it is not. (A log replayed
  /// within a second of its making would look live: see setUtimesLogged.)
  static constexpr Micros kLiveUtimeUs = 1'000'000;

 private:
  struct ChannelCount {
    int64_t total = 0, window = 0;
    Micros first = 0, last = 0;
  };
  struct TrackInfo {
    // the lowest and highest frame it was listed in (or read in, when a
    // code came before any list: a list of an earlier frame can come after it)
    int64_t first_seq = 0, last_seq = 0;
    void seenIn(int64_t seq, bool first) {
      first_seq = first ? seq : std::min(first_seq, seq);
      last_seq = first ? seq : std::max(last_seq, seq);
    }
    int64_t frames_visible = 0, frames_coasting = 0;
    int64_t last_list = 0;  // the tracked list (counted from the first) it was last listed or read in
    // each payload in turn, from the frame it came from (the last is the
    // track's; one more than one: changes)
    std::vector<std::pair<std::string, int64_t>> payloads;
  };
  struct FrameRecord {
    int64_t utime = 0, seq = 0;
    int run = 1;             // the tracker's run
    double latency_ms = -1;  // < 0: the image was not seen
    int landmarks = 0;       // visible
    std::vector<int64_t> ids;
  };
  // The frames (utime, seq) of a channel's last 600 messages: one seen again
  // is a repeat (a recording holding the set's outputs played onto it, two
  // trackers), unless its image came again too (imageSeen: a log replayed
  // again, whose second pass is frames of their own). Unstamped ones (utime
  // 0 or no seq) are never repeats.
  class RecentFrames {
   public:
    void clear() {
      set_.clear();
      order_.clear();
    }
    bool seenBefore(int64_t utime, int64_t seq) {
      if (utime == 0 || seq < 0) return false;
      const std::pair<int64_t, int64_t> k{utime, seq};
      if (!set_.insert(k).second) return true;
      order_.push_back(k);
      if (order_.size() > 600) {
        set_.erase(order_.front());
        order_.pop_front();
      }
      return false;
    }

   private:
    std::set<std::pair<int64_t, int64_t>> set_;
    std::deque<std::pair<int64_t, int64_t>> order_;
  };
  // Cumulative skip counters of a publisher that may restart (counter drops).
  struct SkipCounter {
    int64_t last = 0, sum = 0;
    void update(int64_t v) {
      sum += v >= last ? v - last : v;
      last = v;
    }
  };

  void count(ChannelCount& c, Micros rx_us);
  void setPayload(int run, int64_t id, const std::string& payload, int64_t seq);
  // Tracked frames the QR reader did not answer, at the end of a run
  // (qr_skipped_: those before the last it answered).
  int64_t qrSkippedAll() const;
  void onImage(const lcm::ReceiveBuffer* rb, const std::string& channel);
  void onLandmarks(const lcm::ReceiveBuffer* rb, const std::string& channel);
  void onTracked(const lcm::ReceiveBuffer* rb, const std::string& channel);
  void onCodes(const lcm::ReceiveBuffer* rb, const std::string& channel);
  void onSelfTest(const lcm::ReceiveBuffer* rb, const std::string& channel);

  BusChannels ch_;
  ChannelCount images_, landmarks_, tracked_, codes_;
  Micros last_status_us_ = 0;
  struct PendingImage {
    Micros received = 0;  // when it arrived (see the top)
    Micros origin = 0;    // what its latency is timed from: its utime, or its arrival
  };
  std::map<std::pair<int64_t, int64_t>, PendingImage> pending_;  // by (utime, seq)
  bool utimes_logged_ = false;
  int64_t from_capture_ = 0, from_arrival_ = 0;  // latencies timed from a utime, from an arrival
  int64_t self_tests_ = 0;
  Micros last_self_test_us_ = 0;
  size_t qr_settled_ = 0;  // tracked frames (counted from the first) up to the last the QR reader answered
  int64_t qr_skipped_ = 0;
  int64_t tracked_frames_ = 0, matched_ = 0, unmatched_images_ = 0, bad_ = 0;
  int64_t bad_images_ = 0;  // of bad_: on the image channel (not counted as images)
  RecentFrames recent_images_, recent_landmarks_, recent_tracked_, recent_codes_;
  int64_t repeated_ = 0;  // messages of a frame already seen on their channel (not counted)
  SkipCounter det_skipped_, trk_skipped_;
  LatencyHistogram latencies_;
  // the current status window's (at most kWindowMax: a window of more
  // frames, status lines off or an interval over half an hour at 30
  // frames/s, covers its last ones)
  std::vector<double> window_ms_;
  static constexpr size_t kWindowMax = 65536;
  std::map<std::pair<int, int64_t>, TrackInfo> tracks_;  // (tracker run, id); the last kTracksKept seen
  int64_t tracks_left_out_ = 0;                           // tracks no longer in tracks_
  int64_t tracks_read_ = 0;                               // tracks a payload came for, all
  // (it forgets a track when tracks_ leaves it out, not by a count of lists:
  // a restarted tracker's id 1 is told from the last run's only while that
  // is known, and tracks_ keeps the last run's id 1 far longer than 3000
  // lists, ld-qr-reader's bound, where the two merged)
  TrackRestartWatch restarts_;
  // a track of (run, id), made when new, kept among the most recently seen
  TrackInfo& track(int run, int64_t id, bool& is_new);
  std::vector<int64_t> run_starts_{INT64_MIN};  // utime of each tracker run's first list (run r: [r - 1])
  std::vector<std::pair<int64_t, int32_t>> ages_;
  std::map<int, int64_t> histogram_;
  std::deque<FrameRecord> frames_;  // the last kFramesKept
  size_t frames_left_out_ = 0;      // tracked frames before frames_.front()
  QueueFit queues_[4];  // image, landmarks, tracked, codes (ld::QueueFit)
  image_t image_buf_;  // (decoded and checked as the detector does, into kept buffers)
  landmark_list_t list_buf_;
  qr_code_list_t codes_buf_;
};

}  // namespace ld
