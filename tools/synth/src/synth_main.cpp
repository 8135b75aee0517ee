// ld-synth: synthetic test data with exact ground truth.
//
//   ld-synth scene --out DIR [--count N] [--yaw -70:70] ...   still frames + truth.jsonl
//   ld-synth sequence --out DIR [--frames N] [--log F.lcmlog] a moving camera: frames,
//                                                              truth.jsonl, an LCM log
//
// Every value option of `scene` takes a number (fixed) or a range "a:b"
// (drawn uniformly per frame). Errors: one line on stderr, exit code 2.
#include <cerrno>
#include <cstring>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <random>
#include <regex>
#include <stdexcept>
#include <sstream>
#include <string>

#include <CLI/CLI.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/cli.hpp"
#include "ld/file_checks.hpp"
#include "ld/image_convert.hpp"
#include "ld/synth.hpp"

namespace fs = std::filesystem;
using namespace ld::synth;

namespace {

using ld::cli::UsageError;

class Random {
 public:
  explicit Random(uint64_t seed) : eng_(seed) {}
  double uni() { return static_cast<double>(eng_() >> 11) * 0x1.0p-53; }
  double uni(double a, double b) { return a + (b - a) * uni(); }
  uint64_t next() { return eng_(); }

 private:
  std::mt19937_64 eng_;
};

// "a" (fixed) or "a:b" (uniform per frame).
struct Range {
  double lo = 0, hi = 0;
  double draw(Random& r) const { return lo == hi ? lo : r.uni(lo, hi); }
};

Range parseRange(const std::string& name, const std::string& text) {
  const auto num = [&](const std::string& s) {
    const std::optional<double> v = ld::cli::parseNumber(s);
    if (!v) throw UsageError("--" + name + ": '" + text + "' is not a number or a range a:b");
    return *v;
  };
  const size_t colon = text.find(':');
  Range r;
  if (colon == std::string::npos) {
    r.lo = r.hi = num(text);
  } else {
    r.lo = num(text.substr(0, colon));
    r.hi = num(text.substr(colon + 1));
    if (r.lo > r.hi) throw UsageError("--" + name + ": range " + text + " is empty (a > b)");
  }
  return r;
}

void requireWithin(const std::string& name, const Range& r, double lo, double hi) {
  if (r.lo < lo || r.hi > hi) {
    std::ostringstream range;
    range << lo << ":" << hi;
    throw UsageError("--" + name + " must lie within " + range.str());
  }
}

ld::CameraModel makeCamera(const std::string& file, const std::string& resolution) {
  std::optional<cv::Size> size;
  if (!resolution.empty()) {
    const auto wh = ld::cli::parseSize(resolution);
    if (!wh) throw UsageError("--resolution: '" + resolution + "' is not WIDTHxHEIGHT");
    if (wh->first < 16 || wh->second < 16 || wh->first > 16384 || wh->second > 16384)
      throw UsageError("--resolution: " + resolution + " is out of 16x16 .. 16384x16384");
    size = cv::Size(static_cast<int>(wh->first), static_cast<int>(wh->second));
  }
  ld::CameraModel cam;
  if (!file.empty()) {
    cam = ld::CameraModel::load(file);  // throws with a one-line reason ("cannot open: No such file ...")
    // (another aspect ratio is another crop of the sensor: the detector
    // refuses such a calibration, so frames made with it scaled would lie)
    if (size && !cam.fits(*size))
      throw UsageError("--resolution: " + resolution + " is another aspect ratio than the camera file's " +
                       std::to_string(cam.size.width) + "x" + std::to_string(cam.size.height) +
                       " (another crop of the sensor, whose intrinsics do not scale)");
    if (size) cam = cam.scaledTo(*size);
  } else {
    const cv::Size s = size.value_or(cv::Size(640, 480));
    cam = ld::CameraModel::pinhole(s, 600.0 * s.width / 640.0);
  }
  return cam;
}

// Frames of an earlier run left in `dir` (NNNNNN.png or .jpg that this run,
// `count` frames as `extension`, did not write): said in a note, as
// ld-generate says of earlier pages; truth.jsonl lists this run's alone.
// With `written` false (sequence --no-png) every frame there is an earlier
// run's, and the truth names frames of those names that this run did not
// write: said so (the truth paired with them without a word).
void noteLeftoverFrames(const std::string& dir, int count, const std::string& extension, bool written = true) {
  static const std::regex frame_name("([0-9]{6})\\.(png|jpg)");
  int left = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::smatch m;
    const std::string name = e.path().filename().string();
    if (!std::regex_match(name, m, frame_name)) continue;
    const bool named_so = "." + m[2].str() == extension;  // (as the truth names its frames)
    if (written ? !named_so || std::stoi(m[1].str()) >= count : named_so) ++left;
  }
  if (left && !written)
    std::cerr << "ld-synth: note: " << left << " frame" << (left == 1 ? "" : "s") << " of an earlier run "
              << (left == 1 ? "is" : "are") << " left in " << dir << ": truth.jsonl names frames that this run "
              << "did not write (--no-png), and they are not its frames\n";
  else if (left)
    std::cerr << "ld-synth: note: " << left << " frame" << (left == 1 ? "" : "s") << " of an earlier run "
              << (left == 1 ? "is" : "are") << " left in " << dir << " (truth.jsonl lists this run's " << count
              << ")\n";
}

// Whether `path` names a file a run writes in `out`: truth.jsonl, or one of
// its `count` frames (NNNNNN`extension`; none when `extension` is "").
bool writtenInOut(const std::string& path, const std::string& out, int count, const std::string& extension) {
  if (path.empty() || out.empty()) return false;
  const fs::path p = ld::resolvedPath(path);
  if (p.parent_path() != ld::resolvedPath(out)) return false;
  const std::string name = p.filename().string();
  if (name == "truth.jsonl") return true;
  return !extension.empty() && name.size() == 6 + extension.size() && name.substr(6) == extension &&
         std::all_of(name.begin(), name.begin() + 6, [](char c) { return c >= '0' && c <= '9'; }) &&
         std::stoi(name.substr(0, 6)) < count;
}

// --write-camera FILE: checked before anything is written. Not a file the
// run writes in --out, nor its log, nor the --camera file it reads (the
// calibration would be written over by its scaled copy).
void checkCameraOut(const std::string& path, const std::string& out, int count, const std::string& extension,
                    const std::string& log, const std::string& camera_in) {
  if (path.empty()) return;
  if (writtenInOut(path, out, count, extension))
    throw UsageError("--write-camera " + path + " is a file this run writes in --out " + out);
  if (!log.empty() && ld::sameFile(path, log)) throw UsageError("--write-camera " + path + " is the --log file");
  if (!camera_in.empty() && ld::sameFile(path, camera_in))
    throw UsageError("--write-camera " + path + " is the --camera file this run reads");
  if (const std::string problem = ld::prepareOutputFile(path); !problem.empty())
    throw std::runtime_error("--write-camera " + path + " " + problem);
}

// The camera the frames were rendered with, as OpenCV's calibration sample
// writes one: what ld-detect, ld-detector and ld-eval take as --camera, to
// give poses for the run's frames or log.
void writeCamera(const ld::CameraModel& camera, const std::string& path) {
  if (path.empty()) return;
  camera.save(path);
  std::cout << "camera (" << camera.size.width << "x" << camera.size.height << ", f = " << camera.K(0, 0)
            << " px) written to " << path << "\n";
}

void makeFolder(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw std::runtime_error("cannot create folder " + dir + (ec ? ": " + ec.message() : ""));
}

// ---------------------------------------------------------------------------
// scene

struct SceneArgs {
  std::string out, camera, resolution, payload, background, lighting = "random", degrade = "mild", write_camera;
  ld::artwork::QrEcc ecc = ld::artwork::QrEcc::Auto;
  int count = 1, landmarks = 1, cards = 0;
  std::optional<int> distractors;
  uint64_t seed = 1;
  std::string size = "0.15", distance = "1.5", yaw = "0", pitch = "0", roll = "0", x, y = "-0.5:0.5";
  std::string defocus, motion, noise, jpeg;
  bool no_landmark = false, nominal = false, jpg = false, payload_given = false;
};

Background backgroundFrom(const std::string& s) {
  if (s == "plain") return Background::Plain;
  if (s == "office") return Background::Office;
  if (s == "clutter") return Background::Clutter;
  throw UsageError("--background must be plain, office or clutter, not '" + s + "'");
}

void applyLighting(const std::string& preset, SceneSpec& spec, Random& r) {
  Lighting& l = spec.lighting;
  if (preset == "random") return;  // randomConditions' mild variation
  l = Lighting{};
  l.gradient = r.uni(0, 0.15);
  l.gradient_angle_deg = r.uni(0, 360);
  if (preset == "normal") {
    l.gain = r.uni(0.9, 1.1);
    l.colour_temp_k = r.uni(5500, 6500);
  } else if (preset == "dim") {
    l.gain = r.uni(0.3, 0.45);
    l.colour_temp_k = r.uni(3500, 5000);
    l.gradient = r.uni(0.1, 0.3);
    spec.degradation.noise_sigma *= 1.8;  // the sensor's gain goes up
  } else if (preset == "tungsten") {
    l.gain = r.uni(0.8, 1.0);
    l.colour_temp_k = r.uni(2700, 3200);
  } else if (preset == "glare") {
    l.gain = r.uni(0.9, 1.1);
    l.colour_temp_k = r.uni(5000, 6500);
    l.glare = r.uni(0.6, 1.2);
    l.glare_radius = r.uni(0.08, 0.2);
    // Near a landmark, where it hurts.
    if (!spec.landmarks.empty()) {
      const LandmarkTruth t = truthFor(spec.camera, spec.landmarks[0]);
      const cv::Point2d c = (t.fip_tl + t.ap) / 2;
      l.glare_centre = {c.x / spec.camera.size.width + r.uni(-0.15, 0.15),
                        c.y / spec.camera.size.height + r.uni(-0.15, 0.15)};
    } else {
      l.glare_centre = {r.uni(0.2, 0.8), r.uni(0.2, 0.8)};
    }
  } else {
    throw UsageError("--lighting must be normal, dim, tungsten, glare or random, not '" + preset + "'");
  }
}

void applyDegradation(const SceneArgs& a, SceneSpec& spec, Random& r) {
  Degradation& d = spec.degradation;
  if (a.degrade == "none") {
    d = Degradation{};
  } else if (a.degrade == "strong") {
    d.defocus_sigma_px = r.uni(0.5, 1.5);
    d.motion_px = r.uni(0, 4);
    d.motion_angle_deg = r.uni(0, 180);
    d.noise_sigma = r.uni(3, 8);
    d.jpeg_quality = static_cast<int>(r.uni(50, 80));
  } else if (a.degrade != "mild") {
    throw UsageError("--degrade must be none, mild or strong, not '" + a.degrade + "'");
  }
  // (each checked against its range: a JPEG quality of 150, a negative
  // blur, or a blur of a million pixels are not a degradation)
  const auto within = [](const char* name, const std::string& text, double lo, double hi) {
    const Range range = parseRange(name, text);
    requireWithin(name, range, lo, hi);
    return range;
  };
  if (!a.defocus.empty()) d.defocus_sigma_px = within("defocus", a.defocus, 0, 50).draw(r);
  if (!a.motion.empty()) {
    d.motion_px = within("motion", a.motion, 0, 200).draw(r);
    d.motion_angle_deg = r.uni(0, 180);
  }
  if (!a.noise.empty()) d.noise_sigma = within("noise", a.noise, 0, 100).draw(r);
  if (!a.jpeg.empty()) {
    const Range q = within("jpeg", a.jpeg, 0, 100);
    if (q.lo != std::floor(q.lo) || q.hi != std::floor(q.hi))
      throw UsageError("--jpeg: a whole quality 0..100, not '" + a.jpeg + "'");
    d.jpeg_quality = static_cast<int>(std::lround(q.draw(r)));
  }
}

int runScene(const SceneArgs& a) {
  const ld::CameraModel camera = makeCamera(a.camera, a.resolution);
  // (read, then written over by the truth or a frame)
  if (writtenInOut(a.camera, a.out, a.count, a.jpg ? ".jpg" : ".png"))
    throw UsageError("--camera " + a.camera + " is a file this run writes in --out " + a.out +
                     ": it would be written over");
  checkCameraOut(a.write_camera, a.out, a.count, a.jpg ? ".jpg" : ".png", "", a.camera);
  const Range size = parseRange("size", a.size), dist = parseRange("distance", a.distance),
              yaw = parseRange("yaw", a.yaw), pitch = parseRange("pitch", a.pitch),
              roll = parseRange("roll", a.roll), ny = parseRange("y", a.y);
  requireWithin("size", size, 0.01, 2.0);
  requireWithin("distance", dist, 0.05, 100.0);
  requireWithin("yaw", yaw, -89.9, 89.9);
  requireWithin("pitch", pitch, -89.9, 89.9);
  requireWithin("roll", roll, -360, 360);
  requireWithin("y", ny, -1.5, 1.5);
  std::optional<Range> nx;
  if (!a.x.empty()) {
    nx = parseRange("x", a.x);
    requireWithin("x", *nx, -1.5, 1.5);
  }
  if (a.count < 1) throw UsageError("--count must be at least 1");
  // (as sequence and ld-generate: an empty payload is no code; it was room-101 without a word)
  if (a.payload_given && a.payload.empty()) throw UsageError("--payload: an empty payload (a QR code holds 1 byte or more)");
  if (a.landmarks < 0 || a.landmarks > 20) throw UsageError("--landmarks must be 0..20");
  if (a.cards < 0 || a.cards > 50) throw UsageError("--cards must be 0..50");
  if (a.distractors && (*a.distractors < 0 || *a.distractors > 500))
    throw UsageError("--distractors must be 0..500");
  std::optional<Background> background;
  if (!a.background.empty()) background = backgroundFrom(a.background);
  // Check the presets once before any work.
  {
    Random probe(0);
    SceneSpec s;
    applyLighting(a.lighting, s, probe);
    applyDegradation(a, s, probe);
  }

  const int K = a.no_landmark ? 0 : a.landmarks;
  // Every frame's scene, before anything is written: a run refused (a
  // payload no QR code holds, landmarks with no room) leaves an earlier
  // run's frames and truth.jsonl as they were (it emptied the truth).
  // Placing costs little beside rendering; the same draws, so the same frames.
  const auto payloadOf = [&](int k) {
    return a.payload.empty() ? "room-" + std::to_string(101 + k) : K == 1 ? a.payload : a.payload + "-" + std::to_string(k);
  };
  for (int k = 0; k < K; ++k) ld::artwork::encodeQr(payloadOf(k), a.ecc);  // (throws, naming why)
  std::vector<SceneSpec> specs;
  specs.reserve(static_cast<size_t>(a.count));
  Random r(a.seed);
  for (int i = 0; i < a.count; ++i) {
    // Poses: each landmark's retried until it is in view and overlaps none
    // placed before it (one still out of view after 200 tries is kept, as
    // --x 1 asks). One that overlaps another in its last try starts the
    // frame's poses over, 20 times at most, then the run is refused (the one
    // drawn over was counted as in view, and its miss as the detector's).
    // A frame placed at its first round draws what it drew before.
    std::vector<LandmarkPlacement> lms;
    std::vector<cv::Rect> boxes;  // (lms' bounding boxes in the image)
    constexpr int kRounds = 20, kTries = 200;
    int crowded = -1;  // the landmark that overlapped another in the last round
    for (int round = 0; round < kRounds && (round == 0 || crowded >= 0); ++round) {
      lms.clear();
      boxes.clear();
      crowded = -1;
      for (int k = 0; k < K && crowded < 0; ++k) {
        const std::string payload = payloadOf(k);
        LandmarkPlacement best;
        cv::Rect box;  // (best's)
        bool overlap = false;  // (the last try's)
        for (int attempt = 0; attempt < kTries; ++attempt) {
          double x;
          if (nx) {
            x = nx->draw(r);
          } else {
            const double w = 1.6 / K;  // K horizontal slots across the image
            x = -0.8 + w * (k + r.uni(0.2, 0.8));
          }
          best = placeLandmark(camera, dist.draw(r), yaw.draw(r), pitch.draw(r), roll.draw(r), x,
                               ny.draw(r), size.draw(r), payload, k);
          best.ecc = a.ecc;
          overlap = false;
          const LandmarkTruth t = truthFor(camera, best);
          box = cv::boundingRect(std::vector<cv::Point2f>(t.corners.begin(), t.corners.end()));
          if (!t.in_view) continue;
          for (const cv::Rect& o : boxes) overlap = overlap || (box & o).area() > 0;
          if (!overlap) break;
        }
        if (overlap) crowded = k;
        lms.push_back(best);
        boxes.push_back(box);
      }
    }
    if (crowded >= 0)
      throw std::runtime_error("frame " + std::to_string(i) + ": landmark " + std::to_string(crowded + 1) + " of " +
                               std::to_string(K) + " overlapped another in each of " + std::to_string(kTries) +
                               " poses drawn, " + std::to_string(kRounds) + " times over: ask for fewer " +
                               "landmarks, or give them room (--x, --y, --distance, --size)");
    SceneSpec spec = randomConditions(camera, lms, r.next());
    if (background) spec.background = *background;
    if (a.distractors) spec.distractors = *a.distractors;
    spec.landmark_like_cards = a.cards;
    spec.printed_ink = !a.nominal;
    applyDegradation(a, spec, r);
    applyLighting(a.lighting, spec, r);
    specs.push_back(std::move(spec));
  }

  makeFolder(a.out);
  const std::string truth_path = (fs::path(a.out) / "truth.jsonl").string();
  std::ofstream truth(truth_path);
  if (!truth) throw std::runtime_error("cannot write " + truth_path);
  int in_view = 0, total = 0;
  for (int i = 0; i < a.count; ++i) {
    const Frame frame = render(specs[static_cast<size_t>(i)]);

    char name[32];
    std::snprintf(name, sizeof name, a.jpg ? "%06d.jpg" : "%06d.png", i);
    const std::string path = (fs::path(a.out) / name).string();
    bool ok = false;
    try {
      ok = cv::imwrite(path, frame.bgr, {cv::IMWRITE_JPEG_QUALITY, 95});
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (!ok) throw std::runtime_error("cannot write " + path);
    errno = 0;
    truth << truthJsonLine(name, frame.bgr.size(), frame.truth) << "\n";
    if (!truth) throw std::runtime_error("write to " + truth_path + " failed: " + std::strerror(errno ? errno : EIO));
    for (const auto& t : frame.truth) {
      ++total;
      in_view += t.in_view;
    }
  }
  // (what the stream held back goes out at its close: a full disk showed
  // there alone, and the run said "wrote 2 frames" over an empty truth)
  errno = 0;
  truth.close();
  if (truth.fail()) throw std::runtime_error("write to " + truth_path + " failed: " + std::strerror(errno ? errno : EIO));
  std::cout << "wrote " << a.count << (a.count == 1 ? " frame" : " frames") << " to " << a.out << " ("
            << in_view << " of " << total << " landmarks fully in view)\n";
  writeCamera(camera, a.write_camera);
  noteLeftoverFrames(a.out, a.count, a.jpg ? ".jpg" : ".png");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);  // our own one-line errors
  CLI::App app{"ld-synth: synthetic landmark scenes and sequences with exact ground truth"};
  app.require_subcommand(1);

  SceneArgs sa;
  auto* scene = app.add_subcommand("scene", "still frames with landmarks at chosen poses: DIR/000000.png ..., DIR/truth.jsonl");
  scene->add_option("--out,-o", sa.out, "output folder")->required();
  scene->add_option("--count,--frames,-n", sa.count, "number of frames")->capture_default_str();
  scene->add_option("--seed", sa.seed, "random seed (same seed, same bytes)")->capture_default_str()->check(ld::cli::Seed);
  scene->add_option("--camera", sa.camera, "camera calibration (OpenCV YAML/XML, ROS camera_info, opencv_interactive-calibration; default: 640x480, f = 600 px)");
  scene->add_option("--write-camera", sa.write_camera,
                    "also write the camera the frames are rendered with to this file (OpenCV YAML: --camera of ld-detect, ld-detector, ld-eval)");
  scene->add_option("--resolution,--frame-size", sa.resolution, "image size WxH (scales the camera; f = 600 px per 640 without --camera)");
  scene->add_option("--size", sa.size, "landmark side S in metres, or a range a:b")->capture_default_str();
  scene->add_option("--distance", sa.distance, "distance to the sheet's centre, metres")->capture_default_str();
  scene->add_option("--yaw", sa.yaw, "degrees about the sheet's vertical axis; + turns its right edge towards the camera")->capture_default_str();
  scene->add_option("--pitch", sa.pitch, "degrees about its horizontal axis; + turns its top edge towards the camera")->capture_default_str();
  scene->add_option("--roll", sa.roll, "degrees in its plane, + is clockwise in the image")->capture_default_str();
  scene->add_option("--x", sa.x, "normalised image x of the centre, -1.5..1.5: -1 and 1 are the image's edges, "
                                  "beyond them partly out of view (default: spread over the width)");
  scene->add_option("--y", sa.y, "normalised image y of the centre, -1.5..1.5 (-1 and 1: the edges)")
      ->capture_default_str();
  scene->add_option("--landmarks,-k", sa.landmarks, "landmarks per frame")->capture_default_str();
  scene->add_option("--payload,-p", sa.payload, "QR text (with several landmarks: TEXT-0, TEXT-1, ...; default room-101, ...)");
  std::string ecc_text = "auto", q_ecc_text = "auto";
  scene->add_option("--ecc", ecc_text, "QR error correction of the landmarks' codes, as ld-generate's: auto, L, M, Q, H")
      ->capture_default_str()
      ->check(ld::cli::Parses("LEVEL", ld::artwork::parseQrEcc));
  scene->add_option("--background", sa.background, "plain, office or clutter (default: office or clutter at random)");
  scene->add_option("--distractors", sa.distractors, "colourful distractors (default: 3..10 at random)");
  scene->add_option("--cards", sa.cards, "landmark-like cards (red square in the middle / next to TL, colours swapped)")->capture_default_str();
  scene->add_option("--lighting", sa.lighting, "normal, dim, tungsten, glare or random")->capture_default_str();
  scene->add_option("--degrade", sa.degrade, "none, mild (defocus, noise, JPEG at random) or strong")->capture_default_str();
  scene->add_option("--defocus", sa.defocus, "Gaussian defocus sigma, px (overrides --degrade)");
  scene->add_option("--motion", sa.motion, "motion blur length, px (overrides --degrade)");
  scene->add_option("--noise", sa.noise, "sensor noise sigma at mid grey (overrides --degrade)");
  scene->add_option("--jpeg", sa.jpeg, "JPEG quality, 0 = none (overrides --degrade)");
  scene->add_flag("--no-landmark", sa.no_landmark, "no landmark at all (false-positive tests)");
  scene->add_flag("--nominal-colours", sa.nominal, "pure #0000FF / #FF0000 artwork colours instead of printed ink");
  scene->add_flag("--jpg", sa.jpg, "write frames as JPEG (quality 95) instead of PNG");

  SequenceOptions qo;
  std::string q_camera, q_resolution, q_write_camera;
  auto* sequence = app.add_subcommand("sequence", "a camera driving past a wall with landmarks: frames, truth.jsonl, LCM log");
  sequence->add_option("--out,-o", qo.out_dir, "output folder for frames and truth.jsonl");
  sequence->add_option("--frames,--count,-n", qo.frames, "number of frames")
      ->capture_default_str()
      ->check(ld::cli::Between(1, 100000));
  sequence->add_option("--fps", qo.fps, "frame rate of the timestamps (0.1 to 1000)")->capture_default_str()->check(ld::cli::Between(0.1, 1000));
  sequence->add_option("--log", qo.log_path, "LCM log of ld.image_t to write");
  sequence->add_option("--channel", qo.channel, "channel in the log")->capture_default_str();
  sequence->add_option("--format", qo.pixel_format, "pixel format in the log: bgr, rgb, bgra, rgba, gray, yuyv, uyvy, mjpeg")
      ->capture_default_str()
      ->check(ld::cli::Parses("FORMAT", ld::pixelFormatFromName));
  sequence->add_option("--quality", qo.jpeg_quality, "JPEG quality for mjpeg")
      ->check(ld::cli::Between(1, 100))
      ->capture_default_str();
  sequence->add_option("--landmarks,-k", qo.landmarks, "landmarks on the wall (ids 0..K-1)")->capture_default_str();
  sequence->add_option("--payload,-p", qo.payloads, "QR text of each landmark (repeat; default room-101, room-102, ...)");
  sequence->add_option("--ecc", q_ecc_text, "QR error correction of the landmarks' codes, as ld-generate's: auto, L, M, Q, H")
      ->capture_default_str()
      ->check(ld::cli::Parses("LEVEL", ld::artwork::parseQrEcc));
  sequence->add_option("--size", qo.side_m, "landmark side S in metres (0.01 to 2)")
      ->capture_default_str()
      ->check(ld::cli::Between(0.01, 2));
  sequence->add_option("--seed", qo.seed, "random seed (same seed, same bytes)")->capture_default_str()->check(ld::cli::Seed);
  sequence->add_option("--start-utime", qo.start_utime, "utime of the first frame, whole microseconds (0 to 2^62)")
      ->capture_default_str()
      ->check(ld::cli::StartUtime);
  sequence->add_option("--camera", q_camera, "camera calibration (OpenCV YAML/XML, ROS camera_info, opencv_interactive-calibration; default: 640x480, f = 600 px)");
  sequence->add_option("--resolution,--frame-size", q_resolution, "image size WxH");
  sequence->add_option("--write-camera", q_write_camera,
                       "also write the camera the frames are rendered with to this file (OpenCV YAML: --camera of ld-detect, ld-detector, ld-eval)");
  bool no_png = false;
  sequence->add_flag("--no-png", no_png, "no PNG frames (truth.jsonl and the log only)");

  LD_CLI_PARSE(app, argc, argv);

  std::string log_name, pending_name;  // sequence --log, and the temporary name it is written under
  try {
    if (scene->parsed()) {
      sa.payload_given = scene->count("--payload") > 0;
      sa.ecc = ld::artwork::parseQrEcc(ecc_text);
      return runScene(sa);
    }
    qo.ecc = ld::artwork::parseQrEcc(q_ecc_text);
    if (qo.out_dir.empty() && qo.log_path.empty()) throw UsageError("sequence: give --out, --log or both");
    if (qo.channel.empty()) throw UsageError("--channel: an empty channel name");
    qo.camera = makeCamera(q_camera, q_resolution);
    // What the log's image_t cannot hold, found at the first frame's
    // encoding before, after the frame was rendered and written: an odd
    // width in YUYV or UYVY, an MJPEG frame over its pixel limit
    // (--resolution keeps the sides within image_t's).
    if (!qo.log_path.empty()) {
      const cv::Size sz = qo.camera.size;
      const int32_t f = ld::pixelFormatFromName(qo.pixel_format);
      if (ld::pixelsInPairs(f) && sz.width % 2 != 0)
        throw UsageError("--format " + qo.pixel_format + " needs an even width, and the frames are " +
                         std::to_string(sz.width) + " px wide");
      if (f == ld::image_t::PIXEL_FORMAT_MJPEG && int64_t{sz.width} * sz.height > ld::kMaxMjpegPixels)
        throw UsageError("--format mjpeg takes " + std::to_string(ld::kMaxMjpegPixels) +
                         " pixels a frame at most, and the frames are " +
                         std::to_string(sz.width) + "x" + std::to_string(sz.height));
    }
    qo.write_png = !no_png;
    // The log is checked before anything is written, written under a
    // temporary name and renamed when whole: a failed run leaves an earlier
    // log as it was, and nothing is written over a file that is not a log.
    std::optional<ld::PendingFile> pending_log;
    // (nor over a file this run writes in --out: the frames and truth.jsonl
    // were written, then replaced by the log, status 0)
    const std::string frames_as = qo.write_png ? ".png" : "";
    if (writtenInOut(qo.log_path, qo.out_dir, qo.frames, frames_as))
      throw UsageError("--log " + qo.log_path + " is a file this run writes in --out " + qo.out_dir);
    // (the calibration too: read, then written over)
    if (writtenInOut(q_camera, qo.out_dir, qo.frames, frames_as))
      throw UsageError("--camera " + q_camera + " is a file this run writes in --out " + qo.out_dir +
                       ": it would be written over");
    checkCameraOut(q_write_camera, qo.out_dir, qo.frames, frames_as, qo.log_path, q_camera);
    if (!qo.log_path.empty()) {
      if (const std::string problem = ld::prepareLogOutputFile(qo.log_path); !problem.empty())
        throw std::runtime_error("--log " + qo.log_path + " " + problem);
      pending_log.emplace(qo.log_path);
      log_name = qo.log_path;
      qo.log_path = pending_name = pending_log->tempPath();
    }
    if (qo.payloads.size() > 0 && static_cast<int>(qo.payloads.size()) != qo.landmarks) {
      if (sequence->count("--landmarks") == 0) qo.landmarks = static_cast<int>(qo.payloads.size());
    }
    const SequenceStats st = writeSequence(qo);
    if (pending_log) {
      qo.log_path = sequence->get_option("--log")->as<std::string>();
      if (const std::string problem = pending_log->commit(); !problem.empty()) throw std::runtime_error(problem);
    }
    std::cout << "wrote " << st.frames << (st.frames == 1 ? " frame" : " frames");
    if (!qo.out_dir.empty()) std::cout << " to " << qo.out_dir;
    if (!qo.log_path.empty())
      std::cout << (qo.out_dir.empty() ? " to " : " and ") << qo.log_path << " (" << qo.pixel_format << ")";
    std::cout << "; a landmark fully in view in " << st.frames_with_landmark_in_view << " of them\n";
    writeCamera(qo.camera, q_write_camera);
    if (!qo.out_dir.empty()) noteLeftoverFrames(qo.out_dir, st.frames, ".png", qo.write_png);
    return 0;
  } catch (const UsageError& e) {
    return ld::cli::usage(argv[0], e.what());
  } catch (const std::exception& e) {
    // (the log is written under a temporary name: said by its own)
    std::string what = e.what();
    if (!pending_name.empty())
      for (size_t at = what.find(pending_name); at != std::string::npos; at = what.find(pending_name, at))
        what.replace(at, pending_name.size(), log_name);
    std::cerr << "ld-synth: " << what << "\n";
    return 2;
  }
}
