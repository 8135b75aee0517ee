// The tracker on ld-synth sequences (a robot driving past a wall of
// landmarks, turning its heading): first on the exact ground truth with
// random misses, then on what the detector finds in the rendered frames.
// Every landmark keeps one id: zero id switches.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <tuple>

#include "ld/detector.hpp"
#include "ld/synth.hpp"
#include "ld/tracker.hpp"

namespace {

cv::Point2f toF(const cv::Point2d& p) { return {static_cast<float>(p.x), static_cast<float>(p.y)}; }

ld::Landmark fromTruth(const ld::synth::LandmarkTruth& t) {
  ld::Landmark lm;
  lm.fip_tl = toF(t.fip_tl);
  lm.fip_tr = toF(t.fip_tr);
  lm.fip_bl = toF(t.fip_bl);
  lm.ap = toF(t.ap);
  for (size_t i = 0; i < 4; ++i) lm.corners[i] = toF(t.corners[i]);
  lm.score = 1;
  return lm;
}

// Id switches as in test_tracker.cpp: a track id given to a second landmark,
// or a landmark changing id although it was detected less than the lifetime
// ago.
class SwitchCounter {
 public:
  explicit SwitchCounter(int64_t lifetime_us) : lifetime_us_(lifetime_us) {}
  void observe(int truth_id, int64_t track_id, int64_t utime) {
    auto lm = landmark_of_.emplace(track_id, truth_id).first;
    if (lm->second != truth_id) {
      ++switches;
      std::printf("track %lld went from landmark %d to %d at utime %lld\n",
                  static_cast<long long>(track_id), lm->second, truth_id,
                  static_cast<long long>(utime));
      lm->second = truth_id;
    }
    auto [it, first] = id_of_.emplace(truth_id, track_id);
    if (!first && it->second != track_id) {
      if (utime - last_seen_[truth_id] < lifetime_us_) {
        ++switches;
        std::printf("landmark %d went from track %lld to %lld at utime %lld\n", truth_id,
                    static_cast<long long>(it->second), static_cast<long long>(track_id),
                    static_cast<long long>(utime));
      }
      it->second = track_id;
    }
    last_seen_[truth_id] = utime;
    ++observations;
  }
  int switches = 0;
  int observations = 0;
  size_t landmarks() const { return id_of_.size(); }

 private:
  int64_t lifetime_us_;
  std::map<int64_t, int> landmark_of_;
  std::map<int, int64_t> id_of_, last_seen_;
};

int64_t trackOf(const std::vector<ld::Track>& tracks, int d) {
  for (const auto& t : tracks)
    if (t.detection_index == d) return t.id;
  return -1;
}

// `seconds` of driving at `fps` frames per second: the same drive at any
// frame rate, with larger steps between frames at lower rates.
ld::synth::SequenceOptions sequenceOptions(double seconds, double fps, int landmarks,
                                           uint64_t seed) {
  ld::synth::SequenceOptions o;
  o.out_dir.clear();
  o.write_png = false;
  o.frames = static_cast<int>(std::lround(seconds * fps));
  o.fps = fps;
  o.landmarks = landmarks;
  o.seed = seed;
  return o;
}

TEST(TrackerSequence, GroundTruthWithMissesHasNoIdSwitch) {
  // 10 s of the drive past the wall at 30, 10 and 5 frames/s; 15% of the
  // landmarks in view are missed at random.
  for (double fps : {30.0, 10.0, 5.0})
    for (uint64_t seed : {1, 2, 3}) {
      ld::synth::Sequence seq(sequenceOptions(10.0, fps, 5, seed));
      ld::Tracker tracker;
      SwitchCounter counter(1'000'000);
      std::mt19937_64 rng(seed);
      std::bernoulli_distribution miss(0.15);
      std::normal_distribution<double> noise(0.0, 0.3);
      std::map<int, cv::Point2d> prev;
      double max_step_sizes = 0;
      for (int i = 0; i < seq.frames(); ++i) {
        const ld::synth::SceneSpec scene = seq.scene(i);
        std::vector<ld::Landmark> dets;
        std::vector<int> truth_ids;
        for (const auto& placement : scene.landmarks) {
          const ld::synth::LandmarkTruth t = ld::synth::truthFor(scene.camera, placement);
          const cv::Point2d tc = (t.fip_tl + t.fip_tr + t.fip_bl + t.ap) * 0.25;
          if (t.in_view && prev.count(t.id))
            max_step_sizes = std::max(max_step_sizes,
                                      cv::norm(tc - prev[t.id]) / cv::norm(t.corners[1] - t.corners[0]));
          if (t.in_view) prev[t.id] = tc; else prev.erase(t.id);
          if (!t.in_view || miss(rng)) continue;
          ld::Landmark lm = fromTruth(t);
          const cv::Point2f n(static_cast<float>(noise(rng)), static_cast<float>(noise(rng)));
          lm.fip_tl += n;
          lm.fip_tr += n;
          lm.fip_bl += n;
          lm.ap += n;
          for (auto& c : lm.corners) c += n;
          dets.push_back(lm);
          truth_ids.push_back(t.id);
        }
        // (with the image's size, as ld-tracker passes it: the side rule at work)
        const auto& tracks = tracker.update(dets, seq.utime(i), scene.camera.size);
        for (size_t d = 0; d < dets.size(); ++d)
          counter.observe(truth_ids[d], trackOf(tracks, static_cast<int>(d)), seq.utime(i));
      }
      EXPECT_EQ(counter.switches, 0) << fps << " frames/s, seed " << seed;
      EXPECT_GE(counter.landmarks(), 3u) << fps << " frames/s, seed " << seed;
      std::printf("%g frames/s, seed %llu: %d observations of %zu landmarks, %lld tracks, largest "
                  "step %.2f sizes\n", fps, static_cast<unsigned long long>(seed),
                  counter.observations, counter.landmarks(),
                  static_cast<long long>(tracker.stats().tracks_created), max_step_sizes);
    }
}

// Large landmarks (0.45 and 0.6 m on a wall 1.7-2.2 m away: a quarter to a
// third of the image wide, about 1.5 sizes apart), every one in view
// detected: one that leaves the image through one side keeps its id while
// the next comes in through the other. An audit saw the newcomer take the
// id (and ld-qr-reader keep the first one's payload on it for seconds): the
// coasting landmark's gate, grown to over two and a half sizes and measured
// from where it was last seen too, reached across the image, past the
// landmarks still followed. Not held beyond this: at 0.75-0.9 m (half the
// image) one landmark leaving as its neighbour comes in, both within the
// plain gate of two sizes, still swaps now and then.
TEST(TrackerSequence, LargeLandmarksLeavingAndComingInKeepTheirIds) {
  int views = 0;
  for (double side : {0.45, 0.6})
    for (uint64_t seed = 1; seed <= 12; ++seed) {
      ld::synth::SequenceOptions o = sequenceOptions(6.0, 30.0, seed % 2 ? 5 : 6, seed);
      o.side_m = side;
      ld::synth::Sequence seq(o);
      ld::Tracker tracker;
      SwitchCounter counter(1'000'000);
      for (int i = 0; i < seq.frames(); ++i) {
        const ld::synth::SceneSpec scene = seq.scene(i);
        std::vector<ld::Landmark> dets;
        std::vector<int> truth_ids;
        for (const auto& placement : scene.landmarks) {
          const ld::synth::LandmarkTruth t = ld::synth::truthFor(scene.camera, placement);
          if (!t.in_view) continue;
          dets.push_back(fromTruth(t));
          truth_ids.push_back(t.id);
        }
        const auto& tracks = tracker.update(dets, seq.utime(i), scene.camera.size);
        for (size_t d = 0; d < dets.size(); ++d)
          counter.observe(truth_ids[d], trackOf(tracks, static_cast<int>(d)), seq.utime(i));
      }
      views += counter.observations;
      EXPECT_EQ(counter.switches, 0) << side << " m, seed " << seed;
    }
  EXPECT_GT(views, 2000);
}

// The detections of rendered frames, matched to the ground truth by their
// centre (within a third of the landmark's size); detections matching no
// landmark are false positives and are tracked like the rest.
struct SequenceResult {
  int switches = 0, in_view = 0, detected = 0, false_positives = 0;
  size_t landmarks = 0;
  int64_t tracks = 0;
  double max_step_px = 0, max_step_sizes = 0;  // largest motion of a landmark between frames
};

SequenceResult detectAndTrack(double seconds, double fps, int landmarks, uint64_t seed,
                              const ld::TrackerParams& params = {}) {
  ld::synth::Sequence seq(sequenceOptions(seconds, fps, landmarks, seed));
  ld::Detector detector;
  ld::Tracker tracker(params);
  SwitchCounter counter(static_cast<int64_t>(params.max_lifetime_s * 1e6));
  SequenceResult r;
  std::map<int, cv::Point2d> prev;
  for (int i = 0; i < seq.frames(); ++i) {
    const ld::synth::Frame frame = ld::synth::render(seq.scene(i));
    for (const auto& t : frame.truth) {
      const cv::Point2d tc = (t.fip_tl + t.fip_tr + t.fip_bl + t.ap) * 0.25;
      if (t.in_view && prev.count(t.id)) {
        const double step = cv::norm(tc - prev[t.id]);
        const double size = cv::norm(t.corners[1] - t.corners[0]);
        r.max_step_px = std::max(r.max_step_px, step);
        r.max_step_sizes = std::max(r.max_step_sizes, step / size);
      }
      if (t.in_view) prev[t.id] = tc; else prev.erase(t.id);
    }
    const ld::Detection& det = detector.detect(frame.bgr);
    const auto& tracks = tracker.update(det.landmarks, seq.utime(i), frame.bgr.size());
    for (const auto& t : frame.truth) r.in_view += t.in_view;
    for (size_t d = 0; d < det.landmarks.size(); ++d) {
      const cv::Point2f c = ld::landmarkCentre(det.landmarks[d]);
      const double size = ld::landmarkSize(det.landmarks[d]);
      int truth_id = -1;
      for (const auto& t : frame.truth) {
        const cv::Point2d tc = (t.fip_tl + t.fip_tr + t.fip_bl + t.ap) * 0.25;
        if (std::hypot(tc.x - c.x, tc.y - c.y) < size / 3) truth_id = t.id;
      }
      if (truth_id < 0) {
        ++r.false_positives;
        continue;
      }
      ++r.detected;
      counter.observe(truth_id, trackOf(tracks, static_cast<int>(d)), seq.utime(i));
    }
  }
  r.switches = counter.switches;
  r.landmarks = counter.landmarks();
  r.tracks = tracker.stats().tracks_created;
  std::printf("%g frames/s, %d frames: %d landmark views (fully in view), %d detections of "
              "them, %d false positives, %zu landmarks, %lld tracks, %d id switches; largest "
              "step %.1f px (%.2f sizes)\n",
              fps, seq.frames(), r.in_view, r.detected, r.false_positives, r.landmarks,
              static_cast<long long>(r.tracks), r.switches, r.max_step_px, r.max_step_sizes);
  return r;
}

TEST(TrackerSequence, DetectorOnRenderedSequenceHasNoIdSwitch) {
  // 6 s of the drive past the wall at 30, 10 and 5 frames/s: the same motion
  // blur, larger steps between frames at lower rates.
  for (auto [fps, landmarks, seed] : {std::tuple{30.0, 4, 7}, {10.0, 6, 8}, {5.0, 6, 9}}) {
    const SequenceResult r = detectAndTrack(6.0, fps, landmarks, static_cast<uint64_t>(seed));
    EXPECT_EQ(r.switches, 0) << fps << " frames/s";
    EXPECT_GE(r.landmarks, 3u);
    EXPECT_GE(r.detected, r.in_view / 2);  // the detector found enough for the test to mean something
  }
}

}  // namespace
