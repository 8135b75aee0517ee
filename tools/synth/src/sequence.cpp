// Sequences: a robot's camera driving past a wall with landmarks on it.
//
// World frame: x along the wall (to the right at the start), y down, z
// towards the wall. The floor is the plane y = camera height; the wall is the
// plane z = wall distance. The camera starts left of the first landmark
// looking ahead along the wall, drives past all of them while turning its
// heading from looking ahead to looking back, comes a little closer to the
// wall half way, and wobbles slightly as a robot does.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>

#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/artwork.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_layout.hpp"
#include "ld/synth.hpp"
#include "synth_detail.hpp"

namespace ld::synth {

using detail::Rand;

namespace {

constexpr double kWallHeight = 2.7;      // floor to ceiling, metres
constexpr double kWallMargin = 2.5;      // wall beyond the path on each side
constexpr double kMaxSpeed = 0.8;        // m/s: a short sequence covers the middle of the path
constexpr double kFloorPpm = 200;        // floor texture
constexpr double kFloorBehind = 1.5;     // floor behind the start line
constexpr double kApproach = 0.3;        // closest approach to the wall half way
constexpr double kExposure = 1.0 / 125;  // shutter time for motion blur, seconds
constexpr double kPathMargin = 1.3;      // path starts and ends this far beyond the landmarks
constexpr double kHeading = 15.0;        // heading swings from +this (ahead) to -this (back), degrees

// A rectangle of texture pixels of the wall texture covering world x in
// [x0, x1] and heights [top, bottom] (y down), grown by `grow` metres.
cv::Rect wallRect(double x0, double x1, double y0, double y1, double wall_x0, double wall_y0,
                  double grow, double ppm) {
  return cv::Rect(static_cast<int>((x0 - grow - wall_x0) * ppm),
                  static_cast<int>((y0 - grow - wall_y0) * ppm),
                  static_cast<int>((x1 - x0 + 2 * grow) * ppm),
                  static_cast<int>((y1 - y0 + 2 * grow) * ppm));
}

}  // namespace

Sequence::Sequence(const SequenceOptions& options) : options_(options) {
  const SequenceOptions& o = options_;
  if (o.frames < 1) throw std::invalid_argument("sequence: frames must be at least 1");
  if (!(o.fps > 0) || !std::isfinite(o.fps)) throw std::invalid_argument("sequence: fps must be positive");
  if (o.landmarks < 0 || o.landmarks > 100)
    throw std::invalid_argument("sequence: landmarks must be 0..100");
  if (!(o.side_m > 0.01 && o.side_m <= 2.0))
    throw std::invalid_argument("sequence: landmark side must be 0.01..2 m");
  if (o.camera.size.width < 16 || o.camera.size.height < 16)
    throw std::invalid_argument("sequence: camera image size too small");
  if (!o.payloads.empty() && static_cast<int>(o.payloads.size()) != o.landmarks)
    throw std::invalid_argument("sequence: " + std::to_string(o.payloads.size()) +
                                " payloads for " + std::to_string(o.landmarks) + " landmarks");

  Rand r(detail::mix(o.seed, 100));
  camera_height_ = r.uni(0.35, 0.6);
  wall_z_ = r.uni(1.7, 2.2);
  const double spacing = r.uni(0.8, 1.0);
  const int K = o.landmarks;

  // Landmarks on the wall, at about camera height or a little above.
  std::vector<cv::Vec3d> centres;
  for (int k = 0; k < K; ++k) {
    const double x = (k - (K - 1) / 2.0) * spacing + r.uni(-0.08, 0.08);
    const double y = -r.uni(0.0, 0.3);
    LandmarkPlacement lm;
    lm.id = k;
    lm.payload = o.payloads.empty() ? "room-" + std::to_string(101 + k) : o.payloads[static_cast<size_t>(k)];
    lm.side_m = o.side_m;
    lm.ecc = o.ecc;
    // (a payload no QR code holds: refused here, before anything is written;
    // it failed at the first frame, the truth file emptied)
    ld::artwork::encodeQr(lm.payload, lm.ecc);
    lm.rvec = detail::toRvec(detail::rotZ(r.uni(-4, 4)));  // hung by hand
    lm.tvec = {x, y, wall_z_};
    world_landmarks_.push_back(lm);
    centres.push_back(lm.tvec);
  }
  x_start_ = K ? centres.front()[0] - kPathMargin : -1.0;
  x_end_ = K ? centres.back()[0] + kPathMargin : 1.0;
  // At most kMaxSpeed: a sequence too short for the whole path drives the
  // middle part of it.
  const double duration = o.frames > 1 ? (o.frames - 1) / o.fps : 0.0;
  const double covered = std::min(1.0, kMaxSpeed * duration / (x_end_ - x_start_));
  s0_ = 0.5 - covered / 2;
  s1_ = 0.5 + covered / 2;
  // The wall: painted in pieces about 2.5 m wide, then distractors and cards
  // on it, kept off the landmarks. Its texture has about as many pixels per
  // metre as the image has at 1.5 m (within 300..700), fewer on a wall too
  // long for OpenCV's remap (under 32767 px a side: 91 landmarks at 400 px/m
  // were beyond it).
  const double wx0 = x_start_ - kWallMargin, wx1 = x_end_ + kWallMargin;
  const double ppm = std::min(std::clamp(o.camera.K(0, 0) / 1.5, 300.0, 700.0), 32000.0 / (wx1 - wx0));
  const double wy0 = camera_height_ - kWallHeight;
  Surface wall;
  wall.size_m = {wx1 - wx0, kWallHeight};
  wall.texture.create(static_cast<int>(wall.size_m.height * ppm),
                      static_cast<int>(wall.size_m.width * ppm), CV_8UC3);
  detail::paintWall(wall.texture, ppm, r);
  const cv::Rect all(0, 0, wall.texture.cols, wall.texture.rows);
  for (double x = 0; x < wall.texture.cols; x += 2.5 * ppm) {
    cv::Mat piece = wall.texture(cv::Rect(static_cast<int>(x), 0, static_cast<int>(2.5 * ppm), wall.texture.rows) & all);
    detail::paintBackground(piece, Background::Office, ppm, false, r, false);
  }
  std::vector<cv::Rect> avoid;
  for (const auto& c : centres)
    avoid.push_back(wallRect(c[0] - o.side_m / 2, c[0] + o.side_m / 2, c[1] - o.side_m / 2,
                             c[1] + o.side_m / 2, wx0, wy0, 0.12, ppm));
  const double fip_px = o.side_m * layout::kSquareSide / layout::kUnits * ppm;
  const int distractors = static_cast<int>(2.5 * wall.size_m.width);
  detail::paintDistractors(wall.texture, distractors, {fip_px}, avoid, ppm, r);
  const artwork::Colours ink = printedInk();
  const int cards = std::max(1, K / 2);
  for (int i = 0; i < cards; ++i) {
    for (int attempt = 0; attempt < 40; ++attempt) {
      const double side = o.side_m * r.uni(0.8, 1.2);
      const double cx = r.uni(x_start_, x_end_), cy = -r.uni(-0.1, 0.5);
      const cv::Rect rc = wallRect(cx - side / 2, cx + side / 2, cy - side / 2, cy + side / 2, wx0, wy0, 0, ppm);
      const cv::Rect grown(rc.x - rc.width / 2, rc.y - rc.height / 2, 2 * rc.width, 2 * rc.height);
      bool bad = (rc & all) != rc;
      for (const auto& a : avoid) bad = bad || (grown & a).area() > 0;
      if (bad) continue;
      cv::Mat card = detail::cardTexture(r.integer(0, 2), 18 * std::max(1, rc.width / 18 + 1), ink, r);
      cv::resize(card, card, rc.size(), 0, 0, cv::INTER_AREA);
      card.copyTo(wall.texture(rc));
      avoid.push_back(rc);
      break;
    }
  }
  wall.tvec = {(wx0 + wx1) / 2, wy0 + kWallHeight / 2, wall_z_};
  makeMipmaps(wall);
  world_surfaces_.push_back(wall);

  // The floor, seen from above: texture x = world x, texture y = -world z.
  Surface floor;
  floor.size_m = {wx1 - wx0, wall_z_ + kFloorBehind};
  floor.texture.create(static_cast<int>(floor.size_m.height * kFloorPpm),
                       static_cast<int>(floor.size_m.width * kFloorPpm), CV_8UC3);
  detail::paintFloor(floor.texture, kFloorPpm, r);
  floor.rvec = detail::toRvec(cv::Matx33d(1, 0, 0, 0, 0, 1, 0, -1, 0));
  floor.tvec = {(wx0 + wx1) / 2, camera_height_, (wall_z_ - kFloorBehind) / 2};
  makeMipmaps(floor);
  world_surfaces_.push_back(floor);

  // Lighting for the whole sequence; the camera's optics and sensor.
  lighting_.gain = r.uni(0.85, 1.15);
  lighting_.colour_temp_k = r.uni(4500, 6500);
  lighting_.gradient = r.uni(0.05, 0.25);
  lighting_.gradient_angle_deg = r.uni(0, 360);
  degradation_.defocus_sigma_px = r.uni(0.3, 0.7);
  degradation_.noise_sigma = r.uni(1.5, 3.0);
}

int64_t Sequence::utime(int i) const {
  return options_.start_utime + static_cast<int64_t>(std::llround(i * 1e6 / options_.fps));
}

void Sequence::cameraPose(int i, cv::Matx33d& R_world_camera, cv::Vec3d& position) const {
  // Fractional frames are used for motion blur; see scene().
  const double fi = i;
  const int n = options_.frames;
  const double s = s0_ + (s1_ - s0_) * (n > 1 ? fi / (n - 1) : 0.5);
  const double t = fi / options_.fps;
  const double heading = kHeading * std::cos(M_PI * s);  // degrees, + looks along +x
  position = {x_start_ + (x_end_ - x_start_) * s, 0.004 * std::sin(2 * M_PI * 1.7 * t),
              kApproach * std::sin(M_PI * s)};
  R_world_camera = detail::rotY(heading) * detail::rotX(0.5 * std::sin(2 * M_PI * 1.1 * t + 1)) *
                   detail::rotZ(0.8 * std::sin(2 * M_PI * 0.7 * t));
}

SceneSpec Sequence::scene(int i) const {
  const SequenceOptions& o = options_;
  cv::Matx33d R;
  cv::Vec3d C;
  cameraPose(i, R, C);
  const cv::Matx33d Rt = R.t();
  const auto toCamera = [&](const cv::Vec3d& rvec, const cv::Vec3d& tvec, cv::Vec3d& r_out, cv::Vec3d& t_out) {
    r_out = detail::toRvec(Rt * detail::fromRvec(rvec));
    t_out = Rt * (tvec - C);
  };

  SceneSpec spec;
  spec.camera = o.camera;
  spec.background = Background::Plain;  // beyond the wall's ends, if ever seen
  spec.distractors = 0;
  spec.landmark_like_cards = 0;
  spec.printed_ink = true;
  spec.lighting = lighting_;
  spec.degradation = degradation_;
  spec.seed = detail::mix(o.seed, 77);
  spec.noise_seed = detail::mix(o.seed, 1000 + static_cast<uint64_t>(i)) | 1;
  for (const auto& wl : world_landmarks_) {
    LandmarkPlacement lm = wl;
    toCamera(wl.rvec, wl.tvec, lm.rvec, lm.tvec);
    spec.landmarks.push_back(lm);
  }
  for (const auto& ws : world_surfaces_) {
    Surface s = ws;  // shares the texture
    toCamera(ws.rvec, ws.tvec, s.rvec, s.tvec);
    spec.surfaces.push_back(s);
  }

  // Motion blur: how fast the wall point at the image centre moves through
  // the image, times the exposure.
  const cv::Vec3d axis = R * cv::Vec3d(0, 0, 1);
  if (axis[2] > 0.05 && o.frames > 1) {
    const cv::Vec3d P = C + axis * ((wall_z_ - C[2]) / axis[2]);
    const auto imageOf = [&](int j, cv::Point2d& q) {
      cv::Matx33d Rj;
      cv::Vec3d Cj;
      cameraPose(j, Rj, Cj);
      const cv::Vec3d v = o.camera.K * (Rj.t() * (P - Cj));
      q = {v[0] / v[2], v[1] / v[2]};
    };
    cv::Point2d a, b;
    const int j0 = std::max(0, i - 1), j1 = std::min(o.frames - 1, i + 1);
    imageOf(j0, a);
    imageOf(j1, b);
    const cv::Point2d per_frame = (b - a) / std::max(1, j1 - j0);
    const double px_per_s = cv::norm(per_frame) * o.fps;
    spec.degradation.motion_px = px_per_s * kExposure;
    spec.degradation.motion_angle_deg = std::atan2(per_frame.y, per_frame.x) * 180 / M_PI;
  }
  return spec;
}

SequenceStats writeSequence(const SequenceOptions& options) {
  int32_t pixelformat = 0;
  std::unique_ptr<Sequence> seq;
  try {
    pixelformat = pixelFormatFromName(options.pixel_format);
    seq = std::make_unique<Sequence>(options);
  } catch (const std::exception& e) {
    throw std::runtime_error(e.what());
  }
  namespace fs = std::filesystem;
  std::ofstream truth;
  if (!options.out_dir.empty()) {
    std::error_code ec;
    fs::create_directories(options.out_dir, ec);
    if (ec || !fs::is_directory(options.out_dir))
      throw std::runtime_error("cannot create folder " + options.out_dir +
                               (ec ? ": " + ec.message() : ""));
    const std::string path = (fs::path(options.out_dir) / "truth.jsonl").string();
    truth.open(path);
    if (!truth) throw std::runtime_error("cannot write " + path);
  }
  std::unique_ptr<lcm::LogFile> log;
  if (!options.log_path.empty()) {
    log = std::make_unique<lcm::LogFile>(options.log_path, "w");
    if (!log->good()) throw std::runtime_error("cannot write LCM log " + options.log_path);
  }

  SequenceStats stats;
  std::vector<uint8_t> buf;
  char name[32];
  for (int i = 0; i < seq->frames(); ++i) {
    const Frame frame = render(seq->scene(i));
    const int64_t utime = seq->utime(i);
    std::snprintf(name, sizeof name, "%06d.png", i);
    bool any = false;
    for (const auto& t : frame.truth) any = any || t.in_view;
    stats.frames_with_landmark_in_view += any;
    if (truth.is_open()) {
      truth << truthJsonLine(name, frame.bgr.size(), frame.truth, i, utime) << "\n";
      if (!truth)
        throw std::runtime_error("write to " + options.out_dir + "/truth.jsonl failed: " + std::strerror(errno ? errno : EIO));
      if (options.write_png) {
        const std::string path = (fs::path(options.out_dir) / name).string();
        bool ok = false;
        try {
          ok = cv::imwrite(path, frame.bgr);
        } catch (const cv::Exception&) {
          ok = false;
        }
        if (!ok) throw std::runtime_error("cannot write " + path);
      }
    }
    if (log) {
      image_t msg;
      try {
        msg = matToImage(frame.bgr, pixelformat, utime, i, options.jpeg_quality);
      } catch (const std::exception& e) {
        throw std::runtime_error(std::string("cannot encode frame as ") + options.pixel_format + ": " + e.what());
      }
      setImageSeq(msg, i);
      buf.resize(static_cast<size_t>(msg.getEncodedSize()));
      msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
      lcm::LogEvent ev;
      ev.eventnum = i;
      ev.timestamp = utime;
      ev.channel = options.channel;
      ev.datalen = static_cast<int32_t>(buf.size());
      ev.data = buf.data();
      if (log->writeEvent(&ev) != 0) throw std::runtime_error("write to " + options.log_path + " failed");
    }
    ++stats.frames;
  }
  if (truth.is_open()) {
    truth.close();
    if (!truth)
      throw std::runtime_error("write to " + options.out_dir + "/truth.jsonl failed: " + std::strerror(errno ? errno : EIO));
  }
  // (the log's last bytes go out here: a full disk shows now, not unseen when it closes)
  if (log && (std::fflush(log->getFilePtr()) != 0 || std::ferror(log->getFilePtr())))
    throw std::runtime_error("write to " + options.log_path + " failed: " + std::strerror(errno));
  return stats;
}

}  // namespace ld::synth
