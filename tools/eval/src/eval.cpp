#include "ld/eval.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <stdexcept>

#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/adaptive.hpp"
#include "ld/markers.hpp"
#include "ld/qr_reader.hpp"
#include "ld/synth.hpp"

namespace ld::eval {

std::string payloadFor(int i) {
  const std::string n = std::to_string(i);
  switch (i % 5) {
    case 0:
      return "room-" + n;
    case 1:
      return "salle-" + n + " \xc3\xa9t\xc3\xa9 caf\xc3\xa9";  // "été café"
    case 2:
      return "\xce\xba\xcf\x8c\xce\xbc\xce\xb2\xce\xbf\xcf\x82-" + n +  // "κόμβος-"
             " \xe6\x9d\xb1\xe4\xba\xac";                           // "東京"
    case 3: {  // long ASCII: exactly 100 bytes
      std::string s = "https://example.org/building-7/floor-2/corridor-B/landmark?id=" + n + "&v=";
      while (s.size() < 100) s += static_cast<char>('a' + s.size() % 26);
      return s;
    }
    default: {  // long UTF-8: at most 100 bytes, whole characters only
      std::string s = "dock-" + n + " ";
      const std::string ch[] = {"\xc3\xa9", "\xc3\xbc", "\xce\xb1", "\xe6\x97\xa5", "x"};
      for (int k = 0;; ++k) {
        const std::string& c = ch[k % 5];
        if (s.size() + c.size() > 100) break;
        s += c;
      }
      return s;
    }
  }
}

namespace {

uint64_t pointSeed(uint64_t seed, double distance_m, double yaw_deg) {
  const auto d = static_cast<uint64_t>(std::llround(distance_m * 1000.0));
  const auto y = static_cast<uint64_t>(std::llround((yaw_deg + 360.0) * 10.0));
  return seed * 0x9E3779B97F4A7C15ull ^ (d * 1000003ull + y);
}

void applyLighting(const SweepOptions& o, synth::SceneSpec& spec) {
  if (o.colour_temp_k > 0) spec.lighting.colour_temp_k = o.colour_temp_k;
  if (o.gain > 0) spec.lighting.gain = o.gain;
  if (o.glare >= 0) {
    spec.lighting.glare = o.glare;
    if (!spec.landmarks.empty()) {  // on the landmark, where it hurts
      const synth::LandmarkTruth t = synth::truthFor(spec.camera, spec.landmarks[0]);
      const cv::Point2d c = (t.fip_tl + t.ap) / 2;
      spec.lighting.glare_centre = {c.x / spec.camera.size.width, c.y / spec.camera.size.height};
    }
  }
}

// The fixed or the adaptive detector, as the options say; for pose sweeps
// with the camera and side set, as a user's detector computing poses has
// them (its centres undistorted with the camera's distortion, its sheet
// alignment through it).
AdaptiveDetector makeDetector(const SweepOptions& o) {
  AdaptiveDetector d(Detector(o.params), o.adaptive);
  if (o.pose) d.detector().setCamera(o.camera, o.side_m);
  return d;
}

// Every trial is an independent frame: the adapter starts afresh on each.
const Detection& detectFresh(AdaptiveDetector& detector, const cv::Mat& bgr) {
  detector.adapter().reset();
  return detector.detect(bgr);
}

}  // namespace

namespace {

// What a trial's QR gave over o.stack_frames frames, as ld-qr-reader reads
// an undecoded track: the first frame (already rendered, its corners found)
// and the scene rendered again with its own sensor noise, the landmark moved
// by up to a third of a pixel, each found by the detector (frames where it
// is not are left out); each further frame read alone, and their mean
// or the vote of their pixel-model fits (ld::QrStack).
struct FramesRead {
  std::vector<std::string> alone;
  std::optional<std::string> stack;  // the stack's read: the frames' mean, or their fits' vote
};
FramesRead readOverFrames(const SweepOptions& o, synth::SceneSpec spec, const synth::LandmarkPlacement& lm,
                          const std::array<cv::Point2f, 4>& corners, const cv::Mat& first,
                          AdaptiveDetector& detector, QrReader& reader, QrReader& stack_reader) {
  FramesRead read;
  QrStack stack(o.stack_frames);
  // each frame's pixel-model fit (where the reader ran it) into the stack's vote
  if (stack.add(first, corners)) stack.addFit(reader);  // (the reader's last decode was this frame's)
  std::mt19937_64 rng(spec.seed * 0x9E3779B97F4A7C15ULL + 1);  // the trial's own: the sweep's draws stay as they are
  std::uniform_real_distribution<double> U(-1, 1);
  const cv::Vec3d t = lm.tvec;  // the sheet's centre in the camera frame
  const double px = t[2] / o.camera.K(0, 0) / 3;  // a third of a pixel at the sheet's depth
  for (int f = 1; f < o.stack_frames; ++f) {
    spec.landmarks[0] = lm;
    spec.landmarks[0].tvec = t + cv::Vec3d(px * U(rng), px * U(rng), 0);
    spec.noise_seed = rng() | 1;
    const synth::Frame frame = synth::render(spec);
    const synth::LandmarkTruth& truth = frame.truth[0];
    for (const Landmark& d : detectFresh(detector, frame.bgr).landmarks)
      if (matchesTruth(d, {truth.fip_tl, truth.fip_tr, truth.fip_bl, truth.ap})) {
        if (const auto r = reader.decode(frame.bgr, d.corners)) read.alone.push_back(r->payload);
        if (stack.add(frame.bgr, d.corners)) stack.addFit(reader);
        break;
      }
  }
  if (const auto r = stack.decode(stack_reader)) read.stack = r->payload;
  return read;
}

// Frames kept in o.misses_dir (SweepOptions::misses_dir).
struct Trial {
  double yaw_deg, pitch_deg, roll_deg;
  int index;
};

// A number in a kept frame's name (+ 0.0: no "-0").
std::string nameNumber(double v) { return cv::format("%g", v + 0.0); }

// Which of ours a kept frame is from.
const char* detectorName(const AdaptiveDetector& d) { return d.enabled() ? "adaptive" : "fixed"; }

// The sweep point's light and blur in a kept frame's name.
std::string lightTags(const SweepOptions& o) {
  const auto& g = nameNumber;
  std::string tags;
  if (o.colour_temp_k > 0) tags += "_" + g(o.colour_temp_k) + "K";
  if (o.gain > 0) tags += "_gain" + g(o.gain);
  if (o.glare >= 0) tags += "_glare" + g(o.glare);
  if (o.motion_px >= 0) tags += "_motion" + g(o.motion_px);
  return tags;
}

// A number rounded to `places` decimals for the list (NaN and infinities: null).
nlohmann::ordered_json rounded(double v, int places) {
  if (!std::isfinite(v)) return nullptr;
  if (places == 0) return static_cast<long long>(std::llround(v));
  const double f = std::pow(10.0, places);
  return std::round(v * f) / f + 0.0;
}

nlohmann::ordered_json pointJson(const cv::Point2d& p) { return {rounded(p.x, 2), rounded(p.y, 2)}; }

// The four centres (TL, TR, BL, AP) as LANDMARK.md names them.
nlohmann::ordered_json centresJson(const cv::Point2d& tl, const cv::Point2d& tr, const cv::Point2d& bl,
                                   const cv::Point2d& ap) {
  return {{"fip_tl", pointJson(tl)}, {"fip_tr", pointJson(tr)}, {"fip_bl", pointJson(bl)}, {"ap", pointJson(ap)}};
}

// The frame as `name` (PNG) and `line` appended to misses.jsonl.
void keepFrame(const SweepOptions& o, const std::string& name, const cv::Mat& bgr, const nlohmann::ordered_json& line) {
  const std::filesystem::path dir(o.misses_dir);
  bool written = false;
  try {
    written = cv::imwrite((dir / name).string(), bgr);
  } catch (const cv::Exception&) {
  }
  if (!written) throw MissesError("--misses: cannot write " + (dir / name).string());
  std::ofstream f(dir / "misses.jsonl", std::ios::app);
  f << line.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace) << "\n";
  f.close();
  if (!f) throw MissesError("--misses: cannot write " + (dir / "misses.jsonl").string() + ": " + std::strerror(errno));
}

// A trial of a landmark sweep our detector `who` ("fixed" or "adaptive")
// missed (`read`: empty) or found without reading its payload (`read`: what
// the frame alone read, or null), into o.misses_dir.
void writeMiss(const SweepOptions& o, double distance_m, double yaw_point_deg, const Trial& trial, const char* who,
               const synth::SceneSpec& spec, const synth::Frame& frame, const std::string& payload = {},
               const std::optional<nlohmann::ordered_json>& read = std::nullopt) {
  const auto& g = nameNumber;
  std::string name = "side" + g(o.side_m * 100) + "_" + g(distance_m) + "m_yaw" + (yaw_point_deg >= 0 ? "+" : "") +
                     g(yaw_point_deg) + lightTags(o) +
                     cv::format("_seed%llu_trial%03d", static_cast<unsigned long long>(o.seed), trial.index);
  if (!o.misses_tag.empty()) name += "_" + o.misses_tag;
  name += std::string("_") + who + (read ? "_unread" : "") + ".png";
  const synth::LandmarkTruth& t = frame.truth[0];
  nlohmann::ordered_json line{{"image", name},
                              {"kind", read ? "not read" : "not detected"},
                              {"detector", who},
                              {"tag", o.misses_tag},
                              {"side_m", rounded(o.side_m, 4)},
                              {"distance_m", rounded(distance_m, 4)},
                              {"yaw_deg", rounded(trial.yaw_deg, 3)},
                              {"pitch_deg", rounded(trial.pitch_deg, 3)},
                              {"roll_deg", rounded(trial.roll_deg, 3)},
                              {"seed", o.seed},
                              {"trial", trial.index},
                              {"colour_temp_k", rounded(spec.lighting.colour_temp_k, 0)},
                              {"gain", rounded(spec.lighting.gain, 3)},
                              {"glare", rounded(spec.lighting.glare, 3)},
                              {"motion_px", rounded(spec.degradation.motion_px, 2)},
                              {"truth", centresJson(t.fip_tl, t.fip_tr, t.fip_bl, t.ap)}};
  if (read) {
    line["payload"] = payload;
    line["read"] = *read;
  }
  keepFrame(o, name, frame.bgr, line);
}

// A distractor frame (no landmark) where our detector `who` found
// landmarks, into o.misses_dir.
void writeFalseLandmarks(const SweepOptions& o, int index, const char* who, const synth::SceneSpec& spec,
                         const synth::Frame& frame, const std::vector<Landmark>& found) {
  const std::string name = "distractors" + lightTags(o) +
                           cv::format("_seed%llu_frame%03d_", static_cast<unsigned long long>(o.seed), index) + who +
                           ".png";
  nlohmann::ordered_json landmarks = nlohmann::ordered_json::array();
  for (const Landmark& lm : found) landmarks.push_back(centresJson(lm.fip_tl, lm.fip_tr, lm.fip_bl, lm.ap));
  const nlohmann::ordered_json line{{"image", name},
                                    {"kind", "false landmarks"},
                                    {"detector", who},
                                    {"seed", o.seed},
                                    {"frame", index},
                                    {"colour_temp_k", rounded(spec.lighting.colour_temp_k, 0)},
                                    {"gain", rounded(spec.lighting.gain, 3)},
                                    {"glare", rounded(spec.lighting.glare, 3)},
                                    {"landmarks", landmarks}};
  keepFrame(o, name, frame.bgr, line);
}

// With options.pose, the errors of `corners` and the pose from them against the truth `t` into `p`.
void addPoseErrors(const SweepOptions& o, const std::array<cv::Point2f, 4>& corners, const synth::LandmarkTruth& t,
                   Point& p) {
  if (o.pose) p.pose_errors.add(corners, poseFromCorners(corners, o.camera, o.side_m), t);
}

// The trials at one sweep point, every frame scored by each of `detectors`
// (ours, one Point each), or by the options' marker detector when the target
// is a marker (one Point).
std::vector<Point> measureOn(const SweepOptions& o, std::vector<AdaptiveDetector>& detectors, double distance_m,
                             double yaw_deg, double yaw_jitter_deg) {
  const bool marker = o.target != "landmark";
  std::unique_ptr<markers::Detector> marker_detector;
  cv::Mat marker_texture, gray;
  if (marker) {
    marker_detector = std::make_unique<markers::Detector>(markers::parse(o.target));
    marker_texture = markers::sheetTexture(marker_detector->kind(), 0, 540);
  }
  QrReader reader;
  // the stack's mean decoded as ld-qr-reader decodes it (QrTrackReader)
  QrReader stack_reader(QrStack::readerParams());
  std::mt19937_64 rng(pointSeed(o.seed, distance_m, yaw_deg));
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<Point> points(marker ? 1 : detectors.size());
  for (Point& p : points) p.distance_m = distance_m, p.yaw_deg = yaw_deg, p.motion_px = o.motion_px;
  for (int k = 0; k < o.trials; ++k) {
    const double yaw = yaw_deg + (2 * U(rng) - 1) * yaw_jitter_deg;
    const double roll = o.any_roll ? U(rng) * 360 - 180 : 0;
    const double pitch = (2 * U(rng) - 1) * o.max_pitch_deg;
    const double nx = U(rng) - 0.5, ny = U(rng) - 0.5;
    const std::string payload = o.payload(static_cast<int>(rng() % 1000));
    auto lm = synth::placeLandmark(o.camera, distance_m, yaw, pitch, roll, nx, ny, o.side_m, payload);
    if (!synth::truthFor(o.camera, lm).in_view)
      lm = synth::placeLandmark(o.camera, distance_m, yaw, pitch, roll, 0, 0, o.side_m, payload);
    lm.ecc = o.ecc;
    if (marker) lm.texture = marker_texture;
    synth::SceneSpec spec = synth::randomConditions(o.camera, {lm}, rng());
    applyLighting(o, spec);
    if (o.motion_px >= 0) {  // (drawn only then: the other sweeps' scenes stay as they were)
      spec.degradation.motion_px = o.motion_px;
      spec.degradation.motion_angle_deg = 180 * U(rng);
    }
    const synth::Frame frame = synth::render(spec);
    const synth::LandmarkTruth& t = frame.truth[0];
    for (Point& p : points) ++p.trials;
    if (marker) {
      cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
      for (const auto& f : marker_detector->detect(gray))
        if (f.id == 0 && markers::matches(f.corners, t.corners)) {
          ++points[0].detected;
          addPoseErrors(o, f.corners, t, points[0]);  // (in our order: ld/markers.hpp)
          break;
        }
      continue;
    }
    for (size_t i = 0; i < detectors.size(); ++i) {
      Point& p = points[i];
      const Detection& det = detectFresh(detectors[i], frame.bgr);
      const int detected_before = p.detected;
      for (const Landmark& d : det.landmarks) {
        if (!matchesTruth(d, {t.fip_tl, t.fip_tr, t.fip_bl, t.ap})) continue;
        ++p.detected;
        addPoseErrors(o, d.corners, t, p);
        if (o.decode) {
          const auto r = reader.decode(frame.bgr, d.corners);
          bool right = r && r->payload == payload, wrong = r && r->payload != payload;
          p.decoded += right;
          if (o.stack_frames > 0) {
            const FramesRead more = readOverFrames(o, spec, lm, d.corners, frame.bgr, detectors[i], reader, stack_reader);
            for (const std::string& s : more.alone) (s == payload ? right : wrong) = true;
            if (more.stack) (*more.stack == payload ? right : wrong) = true;
            p.decoded_stacked += right;
            p.decoded_stack += more.stack == payload;
          }
          p.wrong_payload += wrong;  // once per trial, whichever frame or the stack gave it
          if (!right && !o.misses_dir.empty())
            writeMiss(o, distance_m, yaw_deg, {yaw, pitch, roll, k}, detectorName(detectors[i]), spec, frame, payload,
                      r ? nlohmann::ordered_json(r->payload) : nlohmann::ordered_json(nullptr));
        }
        break;
      }
      if (p.detected == detected_before && !o.misses_dir.empty())
        writeMiss(o, distance_m, yaw_deg, {yaw, pitch, roll, k}, detectorName(detectors[i]), spec, frame);
    }
  }
  return points;
}

// False landmarks per frame of each of `detectors` on the same scenes.
std::vector<double> falsePositivesOn(const SweepOptions& o, std::vector<AdaptiveDetector>& detectors, int frames) {
  std::mt19937_64 rng(pointSeed(o.seed, 0, -999));
  std::vector<int> found(detectors.size(), 0);
  for (int k = 0; k < frames; ++k) {
    synth::SceneSpec spec = synth::randomConditions(o.camera, {}, rng());
    spec.background = k % 2 ? synth::Background::Clutter : synth::Background::Office;
    spec.distractors = 8 + static_cast<int>(rng() % 8);
    spec.landmark_like_cards = static_cast<int>(rng() % 3);
    applyLighting(o, spec);
    const synth::Frame frame = synth::render(spec);
    for (size_t i = 0; i < detectors.size(); ++i) {
      const Detection& det = detectFresh(detectors[i], frame.bgr);
      found[i] += static_cast<int>(det.landmarks.size());
      if (!det.landmarks.empty() && !o.misses_dir.empty())
        writeFalseLandmarks(o, k, detectorName(detectors[i]), spec, frame, det.landmarks);
    }
  }
  std::vector<double> rate(detectors.size(), 0.0);
  for (size_t i = 0; i < detectors.size(); ++i) rate[i] = frames > 0 ? static_cast<double>(found[i]) / frames : 0.0;
  return rate;
}

// The fixed defaults and the adaptive detector, in that order.
std::vector<AdaptiveDetector> fixedAndAdaptive(const SweepOptions& o) {
  std::vector<AdaptiveDetector> v;
  v.emplace_back(Detector(o.params), false);
  v.emplace_back(Detector(o.params), true);
  return v;
}

}  // namespace

void startMisses(const std::string& dir) {
  const auto list = std::filesystem::path(dir) / "misses.jsonl";
  std::ofstream f(list, std::ios::trunc);
  f.close();
  if (!f) throw std::runtime_error("--misses " + dir + ": cannot write " + list.string() + ": " + std::strerror(errno));
}

Point measure(const SweepOptions& o, double distance_m, double yaw_deg, double yaw_jitter_deg) {
  std::vector<AdaptiveDetector> detectors;  // ours; markers have their own
  if (o.target == "landmark") detectors.push_back(makeDetector(o));
  return measureOn(o, detectors, distance_m, yaw_deg, yaw_jitter_deg)[0];
}

std::array<Point, 2> measureFixedAndAdaptive(const SweepOptions& o, double distance_m, double yaw_deg,
                                             double yaw_jitter_deg) {
  if (o.target != "landmark") throw std::invalid_argument("measureFixedAndAdaptive: only for landmarks");
  std::vector<AdaptiveDetector> detectors = fixedAndAdaptive(o);
  const auto p = measureOn(o, detectors, distance_m, yaw_deg, yaw_jitter_deg);
  return {p[0], p[1]};
}

std::vector<Point> overYaw(const SweepOptions& o, double distance_m, const std::vector<double>& yaws,
                           const std::function<void(const Point&)>& progress) {
  std::vector<Point> out;
  for (double y : yaws) {
    out.push_back(measure(o, distance_m, y));
    if (progress) progress(out.back());
  }
  return out;
}

std::vector<Point> overDistance(const SweepOptions& o, const std::vector<double>& distances,
                                double max_abs_yaw_deg, const std::function<void(const Point&)>& progress) {
  std::vector<Point> out;
  for (double d : distances) {
    out.push_back(measure(o, d, 0.0, max_abs_yaw_deg));
    if (progress) progress(out.back());
  }
  return out;
}

std::vector<Point> overMotion(const SweepOptions& o, double distance_m, const std::vector<double>& blurs,
                              double max_abs_yaw_deg, const std::function<void(const Point&)>& progress) {
  SweepOptions at = o;
  std::vector<Point> out;
  for (double px : blurs) {
    at.motion_px = px;
    out.push_back(measure(at, distance_m, 0.0, max_abs_yaw_deg));
    if (progress) progress(out.back());
  }
  return out;
}

double falsePositivesPerFrame(const SweepOptions& o, int frames) {
  std::vector<AdaptiveDetector> detectors;
  detectors.push_back(makeDetector(o));
  return falsePositivesOn(o, detectors, frames)[0];
}

std::array<double, 2> falsePositivesFixedAndAdaptive(const SweepOptions& o, int frames) {
  std::vector<AdaptiveDetector> detectors = fixedAndAdaptive(o);
  const auto r = falsePositivesOn(o, detectors, frames);
  return {r[0], r[1]};
}

Point total(const std::vector<Point>& points) {
  Point t;
  for (const Point& p : points) {
    t.trials += p.trials;
    t.detected += p.detected;
    t.decoded += p.decoded;
    t.wrong_payload += p.wrong_payload;
  }
  return t;
}

void PoseErrors::add(const std::array<cv::Point2f, 4>& corners, const std::optional<Pose>& pose,
                     const synth::LandmarkTruth& t) {
  double e = 0;
  for (int i = 0; i < 4; ++i) e += cv::norm(cv::Point2d(corners[i]) - t.corners[i]) / 4;
  corner_px.push_back(e);
  if (!pose) return;
  cv::Matx33d R, Rt;
  cv::Rodrigues(pose->rvec, R);
  cv::Rodrigues(t.rvec, Rt);
  rotation_deg.push_back(std::acos(std::clamp((cv::trace(R.t() * Rt) - 1) / 2, -1.0, 1.0)) * 180 / CV_PI);
  distance_frac.push_back(std::abs(pose->distance - t.distance) / t.distance);
}

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(std::clamp(q, 0.0, 1.0) * values.size()));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

}  // namespace ld::eval
