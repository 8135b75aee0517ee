// ld-eval: detection and QR decode rates on ld-synth sweeps, as tables
// (markdown) and plots (PNG). See README, "Evaluating".
#include <filesystem>
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/cli.hpp"
#include "ld/eval.hpp"
#include "ld/file_checks.hpp"
#include "ld/markers.hpp"
#include "ld/plot.hpp"

namespace {

// The sides ld-generate prints (0.01 to 2 m): a side evaluated must be one a
// user can print.
const CLI::Validator kPrintableSide = ld::cli::Between(0.01, 2);

using Series = ld::PlotSeries;

// A result that could not be written all (a full disk): status 1, as ld-detect
// and ld-dump say it, where a refused option or input is 2.
struct WriteError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A line chart of rates written as a PNG (ld/plot.hpp).
void plot(const std::string& path, const std::string& title, const std::string& xlabel,
          const std::vector<Series>& series) {
  if (!cv::imwrite(path, ld::drawRatePlot(title, xlabel, series))) throw WriteError("cannot write plot " + path);
}

// Points given on the command line, in rising order, each once (a plot's
// line then runs one way).
std::vector<double> sortedUnique(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
  return v;
}

// The height the camera's view spans at `d` metres, in metres.
double viewHeightM(const ld::CameraModel& camera, double d) { return d * camera.size.height / camera.K(1, 1); }

// The sweep's points, from `from` to `to` by `step`, and `to` where the
// step does not reach it; at most kMaxPoints
// (a step of 1e-9 would ask for billions: a usage error naming the count).
constexpr double kMaxPoints = 1000;
std::vector<double> range(double from, double to, double step) {
  if (!(step > 0) || !(to >= from)) throw std::invalid_argument("bad range: need from <= to and step > 0");
  double n = std::floor((to - from) / step + 1e-9) + 1;
  if (to - (from + (n - 1) * step) > step / 100) n += 1;  // (the end, below)
  if (!(n <= kMaxPoints)) {
    std::ostringstream m;
    m << "--step " << step << " from " << from << " to " << to << " makes " << n << " sweep points (at most "
      << kMaxPoints << ")";
    throw ld::cli::UsageError(m.str());
  }
  std::vector<double> v;
  for (int k = 0;; ++k) {
    const double x = from + k * step;
    if (x > to + 1e-9) break;
    v.push_back(std::round(x * 1e6) / 1e6);
  }
  // (the end too, where the step does not reach it: `yaw --step 100` swept
  // -80 and 20, never +80; `--to 6 --step 1.5` stopped at 5; a last point
  // within a hundredth of a step of it is moved onto it instead)
  const double end = std::round(to * 1e6) / 1e6;
  if (end - v.back() > step / 100) v.push_back(end);
  else v.back() = end;
  return v;
}

std::string pct(int n, int d) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", d ? 100.0 * n / d : 0.0);
  return b;
}

std::string cm(double m) {
  char b[32];
  std::snprintf(b, sizeof b, "%g cm", m * 100);
  return b;
}

struct Common {
  std::string camera_file, params_file, markdown, png, backend, misses;
  bool compare = false;
  int trials = 20;
  uint64_t seed = 1;
  // The sweep's options (each subcommand calls it once its own refusals
  // are past; the first call empties --misses' list of an earlier run).
  ld::eval::SweepOptions options() const {
    ld::eval::SweepOptions o;
    if (!camera_file.empty()) o.camera = ld::CameraModel::load(camera_file);
    if (!params_file.empty()) o.params = ld::DetectorParams::load(params_file);
    if (!backend.empty()) o.params.backend = backend;
    o.trials = trials;
    o.seed = seed;
    o.misses_dir = misses;
    if (o.params.backend != "cpu" && !backend_said) {  // (the tables are the same whatever ran them)
      backend_said = true;
      const std::string info = ld::Detector(o.params).backendInfo();  // (throws where gles cannot be had)
      std::cerr << "ld-eval: our detector on the " << o.params.backend << " backend: " << info
                << (info.find("timing it") != std::string::npos
                        ? " (each sweep point's detector chooses on its first frames)"
                        : "")
                << "\n";
    }
    if (!misses.empty() && !misses_started) ld::eval::startMisses(misses), misses_started = true;
    return o;
  }
  mutable bool misses_started = false;
  mutable bool backend_said = false;
};

void addCommon(CLI::App* app, Common& c, bool png = true) {
  app->add_option("--camera", c.camera_file, "camera calibration (OpenCV YAML/XML, ROS camera_info, opencv_interactive-calibration); default 640x480, f = 600 px");
  app->add_option("--params", c.params_file, "detector parameters (YAML)");
  app->add_option("--backend", c.backend, "our detector's backend: cpu, gles or auto, as ld-detect's (default: the "
                                          "params file's, else cpu)")
      ->check(CLI::IsMember({"cpu", "gles", "auto"}));
  app->add_option("--trials", c.trials, "frames per sweep point")->check(ld::cli::Positive)->capture_default_str();
  app->add_option("--seed", c.seed, "scene seed (0 or more)")->capture_default_str()->check(ld::cli::Seed);
  app->add_option("--markdown", c.markdown, "also write the table to this file");
  if (png) app->add_option("--png", c.png, "write a plot");
  app->add_option("--misses", c.misses,
                  "write each frame where our detector missed the landmark, found it but did not read its "
                  "payload, or found landmarks among distractors into this folder (PNG), with a line per frame in "
                  "its misses.jsonl (kind, pose, light, the truth's centres): for ld-detect --explain");
}

// The QR sweeps' --stack: frames read as ld-qr-reader reads a track (0-64, as its --stack-frames).
void addStack(CLI::App* app, int& frames, const std::string& what) {
  app->add_option("--stack,--stack-frames", frames, what)
      ->capture_default_str()
      ->check(ld::cli::Between(0, 64))
      // (one frame is a single frame: its columns repeated the single-frame ones;
      // read as a number, as the option reads it: 01 and +1 too)
      ->check(CLI::Validator(
          [](const std::string& v) {
            int n = -1;
            return CLI::detail::lexical_cast(v, n) && n == 1
                       ? std::string("1 frame is what the single-frame figures count: 0 (none), or 2 to 64")
                       : std::string();
          },
          "", "not 1"));
}

// The QR sweeps' --ecc: the error correction of the printed codes, as ld-generate's.
void addEcc(CLI::App* app, std::string& level) {
  app->add_option("--ecc", level, "QR error correction of the printed codes, as ld-generate's: auto, L, M, Q, H")
      ->capture_default_str()
      ->check(ld::cli::Parses("LEVEL", ld::artwork::parseQrEcc));
}

// The detection sweeps (yaw, distance) also measure the markers.
void addCompare(CLI::App* app, Common& c) {
  app->add_flag("--compare", c.compare,
                "also AprilTag 3 (tag36h11) and ArUco (4x4) markers of the same printed size at the same poses");
}

// Yaw within a quarter turn: at 90 degrees the sheet is seen edge on.
const CLI::Validator kYaw = ld::cli::Between(0, 89);

// One side swept over distance (qr, pose): --side, --from, --to, --step, --max-yaw.
void addDistanceSweep(CLI::App* app, double& side, double& from, double& to, double& step, double& max_yaw) {
  app->add_option("--side,--size", side, "printed side S, metres")->capture_default_str()->check(kPrintableSide);
  app->add_option("--from", from, "first distance, metres")->capture_default_str()->check(ld::cli::Positive);
  app->add_option("--to", to, "last distance, metres")->capture_default_str()->check(ld::cli::Positive);
  app->add_option("--step", step, "metres between sweep points")->capture_default_str()->check(ld::cli::Positive);
  app->add_option("--max-yaw", max_yaw, "yaw drawn within +-this, degrees")->capture_default_str()->check(kYaw);
}

// An output file can be written where it is asked for (its missing folders made).
void requireWritable(const std::string& path, const char* option) {
  if (path.empty()) return;
  const std::string why = ld::prepareOutputFile(path);
  if (!why.empty()) throw std::runtime_error(std::string(option) + " " + path + ": " + why);
}

// lighting's plot of one sweep: --png's name with the sweep's before .png
// (the name's .png, any case, after it)
std::string sweepPlotPath(const std::string& png, const std::string& sweep) {
  return png.substr(0, png.size() - 4) + "_" + sweep + ".png";
}

void emit(const Common& c, const std::string& table) {
  std::cout << table << std::flush;
  if (!c.markdown.empty()) {
    if (const std::string why = ld::writeWholeFile(c.markdown, table); !why.empty())
      throw WriteError("cannot write " + c.markdown + ": " + why);
  }
}

// A sweep point's line on stderr as it ends, named by its series (the
// side, marker or payload kind: a table has several, swept one after the
// other): its yaw (or, for sweeps over distance or blur, the range yaw is
// drawn within), and what was decoded when the sweep reads QR codes (alone
// and, with --stack, over the frames).
std::function<void(const ld::eval::Point&)> progress(const std::string& series, double yaw_within, bool decode,
                                                     int stack_frames = 0) {
  return [series, yaw_within, decode, stack_frames](const ld::eval::Point& p) {
    char blur[32] = "", yaw[32], decoded[64] = "";
    if (p.motion_px >= 0) std::snprintf(blur, sizeof blur, ", blur %g px", p.motion_px);
    if (yaw_within > 0) std::snprintf(yaw, sizeof yaw, "yaw within +-%g", yaw_within);
    else std::snprintf(yaw, sizeof yaw, "yaw %+.0f", p.yaw_deg);
    if (decode && stack_frames > 0)
      std::snprintf(decoded, sizeof decoded, ", decoded %d, over %d frames %d", p.decoded, stack_frames,
                    p.decoded_stacked);
    else if (decode) std::snprintf(decoded, sizeof decoded, ", decoded %d", p.decoded);
    std::fprintf(stderr, "  %s, %.2f m, %s%s: detected %d/%d%s\n", series.c_str(), p.distance_m, yaw, blur,
                 p.detected, p.trials, decoded);
  };
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-eval: detection and QR decode rates on ld-synth sweeps (see README)."};
  app.require_subcommand(1);

  Common yc;
  std::vector<double> y_sides{0.09, 0.15}, y_dists{1.5, 2.5};
  double y_max = 80, y_step = 10;
  auto* yaw = app.add_subcommand("yaw", "detection rate against horizontal viewing angle (paper, Fig. 8)");
  addCommon(yaw, yc);
  addCompare(yaw, yc);
  yaw->add_option("--side,--size", y_sides, "printed sides S, metres (one per series; default 0.09 0.15)")->check(kPrintableSide);
  yaw->add_option("--distance", y_dists, "distance per side, metres (default 1.5 2.5)")->check(ld::cli::Positive);
  yaw->add_option("--max-yaw", y_max, "sweep from -this to +this, degrees")->capture_default_str()->check(kYaw);
  yaw->add_option("--step", y_step, "degrees between sweep points")->capture_default_str()->check(ld::cli::Positive);

  Common dc;
  std::vector<double> d_sides{0.09, 0.15};
  double d_from = 0.5, d_to = 5.0, d_step = 0.5, d_yaw = 30;
  auto* dist = app.add_subcommand("distance", "detection rate against distance for several sizes");
  addCommon(dist, dc);
  addCompare(dist, dc);
  dist->add_option("--side,--size", d_sides, "printed sides S, metres (default 0.09 0.15)")->check(kPrintableSide);
  dist->add_option("--from", d_from, "first distance, metres")->capture_default_str()->check(ld::cli::Positive);
  dist->add_option("--to", d_to, "last distance, metres")->capture_default_str()->check(ld::cli::Positive);
  dist->add_option("--step", d_step, "metres between sweep points")->capture_default_str()->check(ld::cli::Positive);
  dist->add_option("--max-yaw", d_yaw, "yaw drawn within +-this, degrees")->capture_default_str()->check(kYaw);

  Common qc;
  double q_side = 0.15, q_from = 0.3, q_to = 1.2, q_step = 0.1, q_yaw = 40;
  auto* qr = app.add_subcommand("qr", "QR decode rate against distance, short and long payloads");
  addCommon(qr, qc);
  addDistanceSweep(qr, q_side, q_from, q_to, q_step, q_yaw);
  int q_stack = 0;
  addStack(qr, q_stack,
           "also read each trial's QR from this many frames averaged, as ld-qr-reader does for an undecoded "
           "track (the landmark moved a fraction of a pixel between frames); 0: single frames");
  std::string q_ecc = "auto";
  addEcc(qr, q_ecc);

  Common sc;
  double s_detect = 3.0, s_read = 1.0, s_yaw = 30;
  std::vector<double> s_sides{0.05, 0.07, 0.09, 0.12, 0.15, 0.20, 0.25, 0.30, 0.40};
  int s_payload = 20;
  auto* size = app.add_subcommand("size", "the smallest landmark detected at X m and read at Y m (>= 95 %)");
  addCommon(size, sc);
  size->add_option("--detect-at", s_detect, "distance the landmark must be detected at, metres")
      ->capture_default_str()
      ->check(ld::cli::Positive);
  size->add_option("--read-at", s_read, "distance its QR must be read at, metres")
      ->capture_default_str()
      ->check(ld::cli::Positive);
  size->add_option("--max-yaw", s_yaw, "yaw drawn within +-this, degrees")->capture_default_str()->check(kYaw);
  size->add_option("--payload-bytes", s_payload, "payload length to read")
      ->capture_default_str()
      ->check(ld::cli::Between(1, 1000));
  size->add_option("--side,--size", s_sides, "candidate sides, metres (default 5 to 40 cm)")->check(kPrintableSide);
  int s_stack = 0;
  addStack(size, s_stack,
           "count a QR read when read over this many frames, as ld-qr-reader reads a track (a moving camera); "
           "0: from single frames");
  std::string s_ecc = "auto";
  addEcc(size, s_ecc);

  Common lc;
  double l_side = 0.15, l_dist = 1.5, l_yaw = 40;
  int l_fp_frames = 100;
  auto* light = app.add_subcommand("lighting", "fixed defaults against adaptive lighting: colour temperature, level, glare");
  addCommon(light, lc);
  light->add_option("--side,--size", l_side, "printed side S, metres")->capture_default_str()->check(kPrintableSide);
  light->add_option("--distance", l_dist, "metres")->capture_default_str()->check(ld::cli::Positive);
  light->add_option("--max-yaw", l_yaw, "yaw drawn within +-this, degrees")->capture_default_str()->check(kYaw);
  light->add_option("--fp-frames", l_fp_frames, "distractor frames per condition for false positives")
      ->capture_default_str()
      ->check(ld::cli::NonNegative);
  light->get_option("--png")->description(
      "write a plot per sweep run: FILE's name with _temperature, _gain and _glare before .png");
  std::vector<std::string> l_sweeps{"temperature", "gain", "glare"};
  light->add_option("--sweeps", l_sweeps, "which sweeps, comma-separated: temperature, gain, glare (default all)")
      ->delimiter(',')
      ->check(CLI::IsMember({"temperature", "gain", "glare"}));
  std::vector<double> l_glare{0.0, 0.3, 0.6, 0.9, 1.2};
  auto* l_glare_opt = light->add_option("--glare", l_glare,
                    "the glare sweep's strengths, comma-separated: the hot spot's peak in linear light, 1 = white "
                    "(default 0,0.3,0.6,0.9,1.2; measured in rising order, each once)")
      ->delimiter(',')
      ->check(ld::cli::Between(0.0, 3.0));

  Common mc;
  std::vector<double> m_sides{0.09, 0.15}, m_dists{1.5, 1.5};
  double m_to = 20, m_step = 2.5, m_yaw = 30;
  auto* motion = app.add_subcommand("motion", "detection rate against motion blur (a robot turning or driving)");
  addCommon(motion, mc);
  addCompare(motion, mc);
  motion->add_option("--side,--size", m_sides, "printed sides S, metres (one per series; default 0.09 0.15)")
      ->check(kPrintableSide);
  motion->add_option("--distance", m_dists, "distance per side, metres (default 1.5 1.5)")->check(ld::cli::Positive);
  motion->add_option("--to", m_to, "longest blur, pixels (from 0)")->capture_default_str()->check(ld::cli::Positive);
  motion->add_option("--step", m_step, "pixels between sweep points")->capture_default_str()->check(ld::cli::Positive);
  motion->add_option("--max-yaw", m_yaw, "yaw drawn within +-this, degrees")->capture_default_str()->check(kYaw);

  Common pc;
  double p_side = 0.15, p_from = 0.5, p_to = 3.5, p_step = 0.5, p_yaw = 40;
  int p_align = 10;
  auto* pose = app.add_subcommand("pose", "pose accuracy against distance: corners, rotation and distance errors");
  addCommon(pose, pc, false);
  addCompare(pose, pc);
  addDistanceSweep(pose, p_side, p_from, p_to, p_step, p_yaw);
  pose->add_option("--align", p_align,
                   "also our detector with sheet alignment (align_iterations) of this many iterations, as a detector "
                   "computing a pose runs by default; 0: the centroids' row alone")
      ->capture_default_str()
      ->check(ld::cli::Between(0, 100));

  LD_CLI_PARSE(app, argc, argv);
  try {
    // (the glare sweep's strengths without the glare sweep were dropped without a word)
    if (light->parsed() && l_glare_opt->count() > 0 &&
        std::find(l_sweeps.begin(), l_sweeps.end(), "glare") == l_sweeps.end())
      throw ld::cli::UsageError("--glare gives the glare sweep's strengths, and --sweeps leaves that sweep out");
    // Where the results go, checked before the sweep (minutes) rather than after it.
    for (const auto& [c, sub] : std::vector<std::pair<const Common*, CLI::App*>>{
             {&yc, yaw}, {&dc, dist}, {&qc, qr}, {&sc, size}, {&lc, light}, {&mc, motion}, {&pc, pose}}) {
      if (!sub->parsed()) continue;
      for (const auto& [opt, path] : {std::pair<const char*, const std::string*>{"--markdown", &c->markdown},
                                      {"--png", &c->png}})
        if (sub->get_option_no_throw(opt) && sub->count(opt) && path->empty())
          throw ld::cli::UsageError(std::string(opt) + " needs a path, not \"\"");
      if (!c->png.empty() && !ld::hasExtension(c->png, ".png"))
        throw ld::cli::UsageError("--png " + c->png + ": the plot is a PNG, its name must end in .png");
      // (not over the calibration or the parameters the sweep reads, nor one
      // output over another: lighting's plots are --png's name with each
      // sweep's before .png, --misses' list is misses.jsonl in its folder)
      std::vector<ld::NamedFile> outputs{{"--markdown", c->markdown}};
      if (sub == light) {
        for (const auto& sweep : l_sweeps)
          if (!c->png.empty()) outputs.push_back({"--png", sweepPlotPath(c->png, sweep)});
      } else {
        outputs.push_back({"--png", c->png});
      }
      if (!c->misses.empty()) outputs.push_back({"--misses", (std::filesystem::path(c->misses) / "misses.jsonl").string()});
      if (const std::string clash =
              ld::outputsClash(outputs, {{"--camera", c->camera_file}, {"--params", c->params_file}});
          !clash.empty())
        throw ld::cli::UsageError(clash);
      requireWritable(c->markdown, "--markdown");
      requireWritable(c->png, "--png");
      if (sub == light)  // (the plots it writes, whose names are longer than --png's)
        for (const auto& sweep : l_sweeps)
          if (!c->png.empty()) requireWritable(sweepPlotPath(c->png, sweep), "--png");
      if (sub->count("--misses") && c->misses.empty()) throw ld::cli::UsageError("--misses needs a folder, not \"\"");
      if (!c->misses.empty())  // (its list emptied by options())
        if (const std::string why = ld::prepareOutputFolder(c->misses); !why.empty())
          throw std::runtime_error("--misses " + c->misses + ": not a folder that can be made: " + why);
    }
    if ((dist->parsed() && d_from > d_to) || (qr->parsed() && q_from > q_to) || (pose->parsed() && p_from > p_to))
      throw ld::cli::UsageError("--from must not be beyond --to");
    if (yaw->parsed() || dist->parsed() || motion->parsed()) {
      // One column and one plotted series per (side, target). The sweep's
      // variable: yaw at each side's distance, distance, or blur at each
      // side's distance.
      enum class By { kYaw, kDistance, kMotion };
      const By by = yaw->parsed() ? By::kYaw : motion->parsed() ? By::kMotion : By::kDistance;
      struct Sweep {
        const Common& c;
        const std::vector<double>& sides;
        const std::vector<double>* dists;  // one per side, or none (distance is the variable)
        std::vector<double> xs;
        const char *column, *title, *axis;
      };
      const Sweep sw =
          by == By::kYaw      ? Sweep{yc, y_sides, &y_dists, range(-y_max, y_max, y_step), "yaw (deg)",
                                      "Detection rate against yaw", "yaw (degrees)"}
          : by == By::kMotion ? Sweep{mc, m_sides, &m_dists, range(0, m_to, m_step), "motion blur (px)",
                                      "Detection rate against motion blur", "blur length (pixels)"}
                              : Sweep{dc, d_sides, nullptr, range(d_from, d_to, d_step), "distance (m)",
                                      "Detection rate against distance", "distance (m)"};
      if (by == By::kDistance) ld::cli::dropRepeats(d_sides);  // (a side given twice: one series)
      if (by == By::kMotion && !motion->count("--distance") && m_sides.size() != m_dists.size())
        m_dists.assign(m_sides.size(), 1.5);  // (the default distance, the same for every side)
      if (sw.dists && sw.dists->size() != sw.sides.size())
        throw ld::cli::UsageError("give one --distance per --side (" + std::to_string(sw.sides.size()) +
                                  (sw.sides.size() == 1 ? " side, " : " sides, ") + std::to_string(sw.dists->size()) +
                                  (sw.dists->size() == 1 ? " distance" : " distances") +
                                  (by == By::kYaw && !yaw->count("--distance")
                                       ? ": the default distances 1.5 2.5 go with the default sides 0.09 0.15)"
                                       : ")"));
      const Common& c = sw.c;
      const std::vector<double>& xs = sw.xs;
      std::vector<std::string> targets{"landmark"};
      if (c.compare) targets.insert(targets.end(), {"apriltag", "aruco"});
      std::vector<Series> series;
      std::vector<std::vector<ld::eval::Point>> all;
      for (size_t i = 0; i < sw.sides.size(); ++i)
        for (const auto& target : targets) {
          auto o = c.options();
          o.side_m = sw.sides[i];
          o.target = target;
          std::ostringstream name;
          name << cm(sw.sides[i]);
          if (sw.dists) name << " at " << (*sw.dists)[i] << " m";
          if (target != "landmark") name << " " << ld::markers::name(ld::markers::parse(target));
          const std::string label =  // (the distance is on the line)
              (target == "landmark" ? "landmark" : ld::markers::name(ld::markers::parse(target))) + " " +
              cm(sw.sides[i]);
          all.push_back(by == By::kYaw ? ld::eval::overYaw(o, (*sw.dists)[i], xs, progress(label, 0, o.decode))
                        : by == By::kMotion
                            ? ld::eval::overMotion(o, (*sw.dists)[i], xs, m_yaw, progress(label, m_yaw, o.decode))
                            : ld::eval::overDistance(o, xs, d_yaw, progress(label, d_yaw, o.decode)));
          Series sr{name.str(), {}};
          for (const auto& p : all.back())
            sr.points.emplace_back(by == By::kYaw ? p.yaw_deg : by == By::kMotion ? p.motion_px : p.distance_m,
                                   p.detectRate());
          series.push_back(sr);
        }
      std::ostringstream t;
      t << "| " << sw.column << " |";
      for (const auto& sr : series) t << " " << sr.name << " |";
      t << "\n|---|";
      for (size_t i = 0; i < series.size(); ++i) t << "---|";
      t << "\n";
      for (size_t k = 0; k < xs.size(); ++k) {
        t << "| " << xs[k] << " |";
        for (const auto& pts : all) t << " " << pct(pts[k].detected, pts[k].trials) << " % |";
        t << "\n";
      }
      // (a landmark larger than the view gave a silent 0 %, as the size
      // table already says: its rates there measure no detector)
      const auto view_h = [&](double d) { return viewHeightM(c.options().camera, d); };
      for (size_t i = 0; i < sw.sides.size(); ++i) {
        const double side = sw.sides[i];
        if (sw.dists) {
          const double d = (*sw.dists)[i];
          if (side * 1.2 > view_h(d))
            t << "\nat " << d << " m the view is " << cv::format("%.2f", view_h(d)) << " m high: a " << cm(side)
              << " landmark (with its white margin) hardly fits in it, and its rates measure no detector\n";
        } else {
          double closest_cut = -1;
          for (const double d : xs)
            if (side * 1.2 > view_h(d)) closest_cut = std::max(closest_cut, d);
          if (closest_cut > 0)
            t << "\nup to " << closest_cut << " m a " << cm(side) << " landmark (with its white margin) hardly fits "
              << "in the view (" << cv::format("%.2f", view_h(closest_cut)) << " m high at " << closest_cut
              << " m): its rates there measure no detector\n";
        }
      }
      emit(c, t.str());
      if (!c.png.empty()) plot(c.png, sw.title, sw.axis, series);
    } else if (qr->parsed()) {
      const std::vector<double> ds = range(q_from, q_to, q_step);
      auto o = qc.options();
      o.side_m = q_side;
      o.decode = true;
      o.stack_frames = q_stack;
      o.ecc = ld::artwork::parseQrEcc(q_ecc);
      // payloadFor's kinds: 0-2 are 8-23 bytes, 3-4 are 99-100 bytes.
      struct Kind { std::string name; int first, count; };
      const std::vector<Kind> kinds{{"8-23 bytes", 0, 3}, {"99-100 bytes", 3, 2}};
      std::vector<Series> series;
      std::vector<std::vector<ld::eval::Point>> all;
      for (const auto& k : kinds) {
        o.payload = [k](int i) { return ld::eval::payloadFor(5 * i + k.first + i % k.count); };
        o.misses_tag = k.first == 0 ? "short" : "long";
        all.push_back(ld::eval::overDistance(o, ds, q_yaw, progress(k.name, q_yaw, o.decode, q_stack)));
        Series s{k.name, {}};
        for (const auto& p : all.back()) s.points.emplace_back(p.distance_m, p.decodeRate());
        series.push_back(s);
      }
      const std::string stacked = "over " + std::to_string(q_stack) + " frames";
      if (q_stack > 0)
        for (size_t k = 0; k < kinds.size(); ++k) {
          Series s{kinds[k].name + ", " + stacked, {}};
          for (const auto& p : all[k]) s.points.emplace_back(p.distance_m, p.stackedDecodeRate());
          series.push_back(s);
        }
      std::ostringstream t;
      t << "| distance (m) | detected | decoded, " << kinds[0].name << " | decoded, " << kinds[1].name;
      if (q_stack > 0)
        t << " | " << stacked << ", " << kinds[0].name << " | " << stacked << ", " << kinds[1].name;
      t << " | wrong payloads |\n|---|---|---|---|" << (q_stack > 0 ? "---|---|" : "") << "---|\n";
      for (size_t k = 0; k < ds.size(); ++k) {
        const auto& a = all[0][k];
        const auto& b = all[1][k];
        t << "| " << ds[k] << " | " << pct(a.detected + b.detected, a.trials + b.trials) << " % | "
          << pct(a.decoded, a.trials) << " % | " << pct(b.decoded, b.trials) << " % | ";
        if (q_stack > 0)
          t << pct(a.decoded_stacked, a.trials) << " % | " << pct(b.decoded_stacked, b.trials) << " % | ";
        t << a.wrong_payload + b.wrong_payload << " |\n";
      }
      // What was measured, and what was printed: the codes' module size
      // decides the distance they read from (--ecc changed the table
      // without a word in it).
      t << "\n" << cm(q_side) << " landmarks, yaw within +-" << q_yaw << " deg, " << qc.trials
        << " frames a point for each payload length, seed " << qc.seed << "; the largest code of each:";
      for (size_t k = 0; k < kinds.size(); ++k) {
        ld::artwork::QrCode largest;
        for (int i = 0; i < 1000; ++i) {  // (every payload a frame may draw: payloadFor's indices below 5000)
          const ld::artwork::QrCode qr =
              ld::artwork::encodeQr(ld::eval::payloadFor(5 * i + kinds[k].first + i % kinds[k].count), o.ecc);
          if (qr.version > largest.version) largest = qr;
        }
        t << (k ? ";" : "") << " " << kinds[k].name << ": " << ld::artwork::describeQr(largest, q_side * 1000);
      }
      t << "\n";
      emit(qc, t.str());
      if (!qc.png.empty()) plot(qc.png, "QR decode rate against distance (" + cm(q_side) + ")", "distance (m)", series);
    } else if (light->parsed()) {
      struct Sweep { std::string name, png_suffix, unit; std::vector<double> values; double ld::eval::SweepOptions::*field; };
      const std::vector<Sweep> sweeps{
          {"colour temperature", "temperature", "K", {2000, 2700, 3200, 4000, 5000, 6500, 8000, 10000}, &ld::eval::SweepOptions::colour_temp_k},
          {"light level (gain)", "gain", "", {0.15, 0.2, 0.3, 0.4, 0.6, 0.8, 1.0, 1.3}, &ld::eval::SweepOptions::gain},
          {"glare on the landmark", "glare", "", sortedUnique(l_glare), &ld::eval::SweepOptions::glare}};
      std::ostringstream t;
      for (const auto& sw : sweeps) {
        if (std::find(l_sweeps.begin(), l_sweeps.end(), sw.png_suffix) == l_sweeps.end()) continue;
        t << "| " << sw.name << " | fixed: detected | adaptive: detected | fixed: false per frame | adaptive: false per frame |\n"
          << "|---|---|---|---|---|\n";
        std::vector<Series> series{{"fixed defaults", {}}, {"adaptive", {}}};
        for (double v : sw.values) {
          ld::eval::SweepOptions o = lc.options();
          o.side_m = l_side;
          o.*(sw.field) = v;
          // both detectors on the same frames: each scene rendered once
          const auto points = ld::eval::measureFixedAndAdaptive(o, l_dist, 0, l_yaw);
          const auto fp = ld::eval::falsePositivesFixedAndAdaptive(o, l_fp_frames);
          double rate[2];
          // (no distractor frames rendered: no false-positive figure, "-")
          const auto false_rate = [&](int a) { return l_fp_frames > 0 ? cv::format("%.3f", fp[a]) : std::string("-"); };
          for (int a = 0; a < 2; ++a) {
            rate[a] = points[static_cast<size_t>(a)].detectRate();
            series[static_cast<size_t>(a)].points.emplace_back(v, rate[a]);
            std::fprintf(stderr, "  %s %g %s: detected %.0f %%, false %s/frame\n", sw.name.c_str(), v,
                         a ? "adaptive" : "fixed", 100 * rate[a], false_rate(a).c_str());
          }
          char row[256];
          std::snprintf(row, sizeof row, "| %g%s%s | %.1f %% | %.1f %% | %s | %s |\n", v, sw.unit.empty() ? "" : " ",
                        sw.unit.c_str(),
                        100 * rate[0], 100 * rate[1], false_rate(0).c_str(), false_rate(1).c_str());
          t << row;
        }
        t << "\n";
        if (!lc.png.empty()) {
          const std::string path = sweepPlotPath(lc.png, sw.png_suffix);
          plot(path, "Detection rate against " + sw.name, sw.name + (sw.unit.empty() ? "" : " (" + sw.unit + ")"), series);
        }
      }
      emit(lc, t.str());
    } else if (pose->parsed()) {
      // One row per (distance, detector): ours from the centroids alone
      // (align_iterations 0), ours with --align steps of sheet alignment
      // (what a detector computing a pose does by default; the parameters'
      // own align_iterations when they set one above 0), AprilTag 3 and
      // ArUco with --compare; the pose from each one's four corners by the
      // same solver.
      const std::vector<double> ds = range(p_from, p_to, p_step);
      auto o = pc.options();
      o.side_m = p_side;
      o.pose = true;
      struct Row {
        std::string name;
        ld::eval::SweepOptions o;
      };
      std::vector<Row> rows{{"ours, centroids", o}};
      rows[0].o.params.align_iterations = 0;
      rows[0].o.misses_tag = "centroids";
      if (o.params.align_iterations > 0 || p_align > 0) {
        rows.push_back({"ours, sheet alignment", o});
        if (o.params.align_iterations <= 0) rows.back().o.params.align_iterations = p_align;
        rows.back().o.misses_tag = "aligned";
      }
      if (pc.compare)
        for (const char* target : {"apriltag", "aruco"}) {
          rows.push_back({ld::markers::name(ld::markers::parse(target)), o});
          rows.back().o.target = target;
        }
      std::vector<std::vector<ld::eval::Point>> all;
      for (const Row& r : rows) all.push_back(ld::eval::overDistance(r.o, ds, p_yaw, progress(r.name, p_yaw, r.o.decode)));
      const auto pair = [](const std::vector<double>& v, double scale, int digits) {
        if (v.empty()) return std::string("-");
        char b[64];
        std::snprintf(b, sizeof b, "%.*f / %.*f", digits, scale * ld::eval::quantile(v, 0.5), digits,
                      scale * ld::eval::quantile(v, 0.9));
        return std::string(b);
      };
      std::ostringstream t;
      t << "| distance (m) | detector | found | corners, median / 90th pct (px) | rotation, median / 90th pct "
           "(deg) | distance, median / 90th pct (%) |\n|---|---|---|---|---|---|\n";
      for (size_t k = 0; k < ds.size(); ++k)
        for (size_t i = 0; i < rows.size(); ++i) {
          const ld::eval::Point& p = all[i][k];
          t << "| " << ds[k] << " | " << rows[i].name << " | " << pct(p.detected, p.trials) << " % | "
            << pair(p.pose_errors.corner_px, 1, 3) << " | " << pair(p.pose_errors.rotation_deg, 1, 2) << " | "
            << pair(p.pose_errors.distance_frac, 100, 2) << " |\n";
        }
      t << "\n" << cm(p_side) << (pc.compare ? " landmarks and markers of the same printed size at the same poses"
                                             : " landmarks")
        << ", yaw within +-" << p_yaw << " deg, " << pc.trials << (pc.trials == 1 ? " frame" : " frames")
        << " per distance; each pose from the four outer corners by "
        << "cv::solvePnP (SOLVEPNP_IPPE_SQUARE); errors over the frames where each found its target\n";
      emit(pc, t.str());
    } else if (size->parsed()) {
      auto o = sc.options();
      o.ecc = ld::artwork::parseQrEcc(s_ecc);
      s_sides = sortedUnique(s_sides);  // (a side given twice: once)
      std::ostringstream t;
      const std::string read_how = s_stack > 0 ? " over " + std::to_string(s_stack) + " frames" : "";
      t << "| side | detected at " << s_detect << " m | read at " << s_read << " m" << read_how
        << " |\n|---|---|---|\n";
      double answer = -1;
      std::vector<Series> series{{"detected at " + cv::format("%g", s_detect) + " m", {}},
                                 {"read at " + cv::format("%g", s_read) + " m" + read_how, {}}};
      for (double side : s_sides) {
        o.side_m = side;
        o.decode = false;
        o.misses_tag = "detect";
        const auto det = ld::eval::measure(o, s_detect, 0, s_yaw);
        progress("landmark " + cm(side) + " detected", s_yaw, false)(det);
        o.decode = true;
        o.misses_tag = "read";
        o.payload = [s_payload](int i) {
          std::string p = "id-" + std::to_string(i) + "-";
          while (static_cast<int>(p.size()) < s_payload) p += static_cast<char>('a' + p.size() % 26);
          return p;
        };
        o.stack_frames = s_stack;
        const auto rd = ld::eval::measure(o, s_read, 0, s_yaw);
        progress("landmark " + cm(side) + " read", s_yaw, true, s_stack)(rd);
        o.stack_frames = 0;
        const int read = s_stack > 0 ? rd.decoded_stacked : rd.decoded;
        t << "| " << cm(side) << " | " << pct(det.detected, det.trials) << " % | "
          << pct(read, rd.trials) << " % |\n";
        series[0].points.emplace_back(side * 100, det.detectRate());
        series[1].points.emplace_back(side * 100, rd.trials ? static_cast<double>(read) / rd.trials : 0.0);
        if (answer < 0 && det.detectRate() >= 0.95 && read >= 0.95 * rd.trials) answer = side;
        if (answer > 0 && sc.png.empty()) break;  // (a plot shows every candidate)
      }
      // (the smallest candidate: a smaller landmark may do too; none: the
      // candidates may not even fit in the view that close)
      const double view_h = viewHeightM(o.camera, std::min(s_detect, s_read));
      std::string verdict = answer > 0 ? "smallest landmark: " + cm(answer) : "no candidate side reaches 95 %";
      if (answer > 0 && answer == s_sides.front())
        verdict += " or less (the smallest candidate; --side tries others)";
      t << "\n" << verdict << " (detected at " << s_detect << " m and read at " << s_read << " m" << read_how
        << " in 95 % of frames, " << sc.trials << " a side, yaw within +-" << s_yaw << " deg)\n";
      if (answer < 0 && s_sides.front() * 1.2 > view_h)
        t << "at " << std::min(s_detect, s_read) << " m the view is " << cv::format("%.2f", view_h)
          << " m high: even a " << cm(s_sides.front()) << " landmark (with its white margin) hardly fits in it\n";
      // What was printed on it: the code's size decides the reading distance.
      const std::string sample = o.payload(0);
      const double side = answer > 0 ? answer : s_sides.back();
      t << (answer > 0 ? "its QR: " : "the QR of the largest candidate: ") << sample.size() << " bytes, "
        << ld::artwork::describeQr(ld::artwork::encodeQr(sample, o.ecc), side * 1000) << " on a " << cm(side)
        << " landmark\n";
      emit(sc, t.str());
      if (!sc.png.empty())
        plot(sc.png, "Detection and QR read rate against landmark side", "landmark side (cm)", series);
      return answer > 0 ? 0 : 3;
    }
  } catch (const ld::cli::UsageError& e) {
    return ld::cli::usage(argv[0], e.what());
  } catch (const WriteError& e) {
    std::cerr << "ld-eval: " << e.what() << "\n";
    return 1;
  } catch (const ld::eval::MissesError& e) {  // (a frame not kept: as a table not written)
    std::cerr << "ld-eval: " << e.what() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "ld-eval: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
