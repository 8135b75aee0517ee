// ld-bench: the paper's Tables I and II for this machine. Median ms per stage
// of our detector at three resolutions on ld-synth scenes, on each backend
// asked for (CPU; GLES with its upload and read-back shown apart, as the
// paper's "+transfer"), and in the same run, on the same scenes with markers
// of the same printed size at the same poses, AprilTag 3 (tag36h11, one
// thread, default decimation) and OpenCV's ArUco (DICT_4X4_50); and what
// --adaptive (the lighting adapter in front of the CPU detector) costs on
// the same scenes. Prints Markdown tables.
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <sstream>

#include <CLI/CLI.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/cli.hpp"
#include "ld/adaptive.hpp"
#include "ld/detector.hpp"
#include "ld/file_checks.hpp"
#include "ld/markers.hpp"
#include "ld/synth.hpp"
#include "ld/tracker_bench.hpp"

namespace {

using Clock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct Scene {
  ld::synth::Frame ours, tag, aruco;
};

struct Row {
  std::string name;
  std::string backend;
  std::map<std::string, std::vector<double>> stages;
  std::vector<double> total, apriltag, aruco;
  int truths = 0, found = 0, found_tag = 0, found_aruco = 0;
};

std::string fmt(double v, int prec = 3) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

// A row's parameters: the --params file's, with the row's front end and
// backend. (A paper file's sigma for its own kernel means nothing to the
// fast front end, which has no blur there: it refused the row, and ld-bench
// aborted after rendering.)
ld::DetectorParams rowParams(const ld::DetectorParams& base, const std::string& front_end, const std::string& backend) {
  ld::DetectorParams p = base;
  p.front_end = front_end;
  p.backend = backend;
  if (front_end == "fast" && p.blur_kernel == -1) p.blur_sigma = 0;
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-bench: detection time per stage against AprilTag 3 and ArUco (see README)."};
  int frames = 20, repeats = 15;
  uint64_t seed = 1;
  double side_m = 0.15;
  std::string markdown;
  std::vector<std::string> resolutions{"640x480", "1280x720", "1920x1080"};
  bool with_paper = true;
  std::vector<std::string> backends{"cpu", "gles"};
  // (bounded: the scenes are held rendered, and every timing)
  app.add_option("--frames", frames, "scenes per resolution, 1 to 1000")
      ->check(ld::cli::Between(1, 1000))
      ->capture_default_str();
  app.add_option("--repeats", repeats, "timed runs per scene, 1 to 10000 (the median is kept)")
      ->check(ld::cli::Between(1, 10000))
      ->capture_default_str();
  app.add_option("--seed", seed, "scene seed")->capture_default_str()->check(ld::cli::Seed);
  app.add_option("--size", side_m, "printed side S of landmarks and markers, metres")
      ->check(ld::cli::Between(0.01, 2.0))
      ->capture_default_str();
  const CLI::Validator wxh(
      [](std::string& text) {
        const auto wh = ld::cli::parseSize(text);
        if (!wh) return "'" + text + "' is not WIDTHxHEIGHT";
        const auto [w, h] = *wh;
        return w >= 64 && h >= 48 && w <= 8192 && h <= 8192 ? std::string()
                                                          : "'" + text + "' is out of 64x48 .. 8192x8192";
      },
      "WxH");
  app.add_option("--resolutions", resolutions, "WxH list")->delimiter(',')->check(wxh)->capture_default_str();
  app.add_option("--markdown", markdown, "also write the tables to this file");
  app.add_flag("!--no-paper", with_paper, "skip the paper front-end row");
  app.add_option("--backend", backends,
                 "backends to measure, a list of cpu, gles, auto (gles rows are left out, with a note, "
                 "where no EGL context can be made; gles takes a software renderer too, auto only a GPU)")
      ->delimiter(',')
      ->check(CLI::IsMember({"cpu", "gles", "auto"}))
      ->capture_default_str();
  std::vector<int> tracker_counts{10, 50, 200};
  int tracker_repeats = 100;
  app.add_option("--tracker-landmarks", tracker_counts, "landmark counts of the tracker rows, a list (1 to 1000 each)")
      ->delimiter(',')
      ->check(ld::cli::Between(1, 1000))
      ->capture_default_str();
  app.add_option("--tracker-repeats", tracker_repeats, "timed runs per tracker row, 1 to 1000000")
      ->check(ld::cli::Between(1, 1000000))
      ->capture_default_str();
  std::string params_file;
  app.add_option("--params", params_file,
                 "detector parameters (YAML) every row starts from (each row sets its own front_end and backend)");
  LD_CLI_PARSE(app, argc, argv);
  // (a closed pipe is said, status 1, as a full disk is: not a silent
  // death by SIGPIPE after minutes of measuring)
  std::signal(SIGPIPE, SIG_IGN);
  ld::DetectorParams base;
  if (!params_file.empty()) {
    try {
      base = ld::DetectorParams::load(params_file);
    } catch (const std::exception& e) {
      std::cerr << "ld-bench: " << e.what() << "\n";
      return 2;
    }
  }
  // Where the tables go, checked before the run (minutes) rather than after it.
  if (const std::string clash = ld::outputsClash({{"--markdown", markdown}}, {{"--params", params_file}});
      !clash.empty())
    return ld::cli::usage(argv[0], clash);
  if (!markdown.empty()) {
    const std::string problem = ld::prepareOutputFile(markdown);
    if (!problem.empty()) {
      std::cerr << "ld-bench: cannot write " << markdown << ": " << problem << "\n";
      return 2;
    }
  }

  cv::setNumThreads(1);
  ld::markers::Detector tag_detector(ld::markers::Kind::AprilTag);  // one thread, default decimation
  ld::markers::Detector aruco_detector(ld::markers::Kind::Aruco);

  std::ostringstream md;
  // the command as given, so the table says how to measure it again
  std::string command = "ld-bench";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool plain = !a.empty() && a.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789-_.,/=:+") == std::string::npos;
    command += " " + (plain ? a : "'" + a + "'");
  }
  md << "Measured by `" << command << "`: "
     << "median of per-scene medians, one thread, ms. Scenes: ld-synth, 1-2 landmarks of "
     << side_m << " m at 0.8-2.5 m, yaw within +-45 deg, any roll, random lighting, noise and JPEG; "
     << "AprilTag (tag36h11) and ArUco (4x4) markers of the same printed size at the same poses.\n\n";
  md << "| resolution | backend | front end | upload | blur | saturation | edges | readback | contours | colour | geometry | second look | faint look | corners | total | FPS | AprilTag 3 | x ours | ArUco | x ours | found: ours / AprilTag / ArUco |\n";
  md << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::vector<std::string> table1, table2, notes, adaptive_rows;
  // GLES availability, once (a context made and dropped).
  std::string gles_why;
  if (std::find(backends.begin(), backends.end(), "gles") != backends.end()) {
    ld::DetectorParams probe = base;
    probe.backend = "gles";
    try {
      ld::Detector d(probe);
    } catch (const std::exception& e) {
      gles_why = e.what();
      notes.push_back("GLES rows left out: " + gles_why + ".");
    }
  }

  ld::cli::dropRepeats(resolutions);  // (a resolution given twice: one row)
  for (const auto& res : resolutions) {
    const auto wh = *ld::cli::parseSize(res);  // (checked by the option)
    const int w = static_cast<int>(wh.first), h = static_cast<int>(wh.second);
    const ld::CameraModel camera = ld::CameraModel::pinhole({w, h}, 600.0 * w / 640.0);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> U(0, 1);
    std::vector<Scene> scenes;
    for (int i = 0; i < frames; ++i) {
      std::vector<ld::synth::LandmarkPlacement> lms;
      const int n = 1 + static_cast<int>(U(rng) * 2);
      for (int k = 0; k < n; ++k) {
        const double nx = n == 1 ? (U(rng) - 0.5) : (k == 0 ? -0.45 : 0.45) + (U(rng) - 0.5) * 0.2;
        lms.push_back(ld::synth::placeLandmark(camera, 0.8 + 1.7 * U(rng), -45 + 90 * U(rng),
                                               -10 + 20 * U(rng), -180 + 360 * U(rng), nx,
                                               (U(rng) - 0.5) * 0.8, side_m,
                                               "bench-" + std::to_string(k), k));
      }
      ld::synth::SceneSpec spec = ld::synth::randomConditions(camera, lms, seed * 1000 + static_cast<uint64_t>(i));
      Scene s;
      s.ours = ld::synth::render(spec);
      const int tex = 540;
      for (size_t k = 0; k < spec.landmarks.size(); ++k)
        spec.landmarks[k].texture = ld::markers::sheetTexture(ld::markers::Kind::AprilTag, static_cast<int>(k), tex);
      s.tag = ld::synth::render(spec);
      for (size_t k = 0; k < spec.landmarks.size(); ++k)
        spec.landmarks[k].texture = ld::markers::sheetTexture(ld::markers::Kind::Aruco, static_cast<int>(k), tex);
      s.aruco = ld::synth::render(spec);
      scenes.push_back(std::move(s));
    }

    std::vector<std::string> front_ends{"fast"};
    if (with_paper) front_ends.push_back("paper");
    bool markers_done = false;  // AprilTag and ArUco: once per resolution
    std::map<std::string, double> cpu_filter;  // front end -> CPU filter ms (Table I)
    for (const auto& fe : front_ends)
    for (const auto& be : backends) {
      if (be == "gles" && !gles_why.empty()) continue;
      const ld::DetectorParams params = rowParams(base, fe, be);
      ld::Detector detector(params);
      Row row;
      const auto noteBackend = [&] {
        const std::string info = res + ", " + fe + ": " + detector.backendInfo() + ".";
        if (row.backend.rfind("gles", 0) == 0 || be == "auto") notes.push_back(info);
      };
      const bool markers = fe == "fast" && !markers_done;
      markers_done = markers_done || markers;
      for (const Scene& s : scenes) {
        std::map<std::string, std::vector<double>> per;
        std::vector<double> tot, at, ar;
        // warm-up (the GLES backend's first frames also choose its shader
        // path, and then "auto"'s choose between the GPU and the CPU)
        const bool first = &s == &scenes.front();
        for (int k = 0; k < (first ? 12 : 1) || (first && detector.choosingBackend() && k < 500); ++k)
          detector.detect(s.ours.bgr);
        if (first) row.backend = std::string(detector.backend()) + (be == "auto" ? " (auto)" : "");
        for (int r = 0; r < repeats; ++r) {
          const auto t0 = Clock::now();
          const ld::Detection& det = detector.detect(s.ours.bgr);
          tot.push_back(msSince(t0));
          for (const auto& st : det.stages) per[st.name].push_back(st.ms);
        }
        row.total.push_back(median(tot));
        for (auto& [name, v] : per) row.stages[name].push_back(median(v));
        const ld::Detection& det = detector.detect(s.ours.bgr);
        for (const auto& t : s.ours.truth) {
          if (!t.in_view) continue;
          ++row.truths;
          row.found += std::any_of(det.landmarks.begin(), det.landmarks.end(),
                                   [&](const ld::Landmark& d) { return ld::matchesTruth(d, {t.fip_tl, t.fip_tr, t.fip_bl, t.ap}); });
        }
        if (!markers) continue;
        // AprilTag and ArUco take gray images (conversion not timed).
        cv::Mat gray;
        // Markers of the same printed size at the same poses, each found by
        // its own detector; the id and the quad must match the truth.
        const auto timeMarkers = [&](ld::markers::Detector& d, const ld::synth::Frame& f,
                                     std::vector<double>& times, int& found) {
          cv::cvtColor(f.bgr, gray, cv::COLOR_BGR2GRAY);
          std::vector<ld::markers::Found> quads;
          for (int r = 0; r <= repeats; ++r) {
            const auto t0 = Clock::now();
            quads = d.detect(gray);
            if (r > 0) times.push_back(msSince(t0));  // the first run warms up
          }
          for (const auto& t : f.truth) {
            if (!t.in_view) continue;
            found += std::any_of(quads.begin(), quads.end(), [&](const ld::markers::Found& q) {
              return q.id == t.id && ld::markers::matches(q.corners, t.corners);
            });
          }
        };
        timeMarkers(tag_detector, s.tag, at, row.found_tag);
        timeMarkers(aruco_detector, s.aruco, ar, row.found_aruco);
        row.apriltag.push_back(median(at));
        row.aruco.push_back(median(ar));
      }
      noteBackend();
      const double total = median(row.total);
      // The median of one stage over the scenes (-1: it did not run), and of
      // a sum of stages per scene.
      auto stageMs = [&](std::initializer_list<const char*> names) {
        std::vector<double> sum;
        bool any = false;
        for (const char* n : names) {
          auto it = row.stages.find(n);
          if (it == row.stages.end()) continue;
          any = true;
          sum.resize(it->second.size(), 0.0);
          for (size_t i = 0; i < it->second.size(); ++i) sum[i] += it->second[i];
        }
        return any ? median(sum) : -1.0;
      };
      auto stage = [&](std::initializer_list<const char*> names) {
        const double v = stageMs(names);
        return v < 0 ? std::string("-") : fmt(v);
      };
      md << "| " << res << " | " << row.backend << " | " << fe << " | " << stage({"upload"}) << " | "
         << stage({"blur"}) << " | " << stage({"saturation"}) << " | " << stage({"edges", "hysteresis"})
         << " | " << stage({"readback"}) << " | " << stage({"contours"}) << " | " << stage({"colour"})
         << " | " << stage({"geometry"}) << " | " << stage({"second look"}) << " | " << stage({"faint look"}) << " | "
         << stage({"corners"}) << " | "
         << fmt(total) << " | "
         << fmt(1000.0 / total, 0) << " | ";
      // Table I: the filters (blur, saturation, edges; the hysteresis of the
      // GLES paper front end included) and, for GLES, the transfers.
      const double filters = std::max(0.0, stageMs({"blur", "saturation", "edges", "hysteresis"}));
      const double transfer = std::max(0.0, stageMs({"upload", "readback"}));
      if (be == "cpu") {
        cpu_filter[fe] = filters;
      } else if (be == "gles") {
        const auto cpu = cpu_filter.find(fe);
        table1.push_back("| " + res + " | " + fe + " | " + (cpu == cpu_filter.end() ? "-" : fmt(cpu->second)) +
                         " | " + fmt(filters) + " | +" + fmt(stageMs({"upload"})) + " +" +
                         fmt(stageMs({"readback"})) + " | " + fmt(filters + transfer) + " | " + fmt(total) + " |");
      }
      if (markers) {
        const double at = median(row.apriltag), ar = median(row.aruco);
        md << fmt(at) << " | " << fmt(at / total, 1) << " | " << fmt(ar) << " | "
           << fmt(ar / total, 1) << " | " << row.found << " / " << row.found_tag << " / "
           << row.found_aruco << " of " << row.truths << " |\n";
      } else {
        md << "- | - | - | - | " << row.found << " of " << row.truths << " |\n";
      }
      if (w == 640 && h == 480) {
        double filter = 0, geometry = 0;
        for (auto& [name, v] : row.stages)
          ((name == "upload" || name == "blur" || name == "saturation" || name == "edges" ||
            name == "hysteresis" || name == "readback" || name == "contours")
               ? filter : geometry) += median(v);
        table2.push_back("| " + row.backend + " | " + fe + " | " + fmt(filter) + " | " + fmt(geometry) + " | " +
                         fmt(total) + " | " + fmt(1000.0 / total, 0) + " |");
      }
    }
    // --adaptive: the adapter's correction, then the CPU detector on its
    // output. The adapter keeps its estimate from frame to frame, as on a
    // camera's video; each scene is one such video of a still frame.
    {
      ld::Detector detector(rowParams(base, "fast", "cpu"));
      std::vector<double> correction, total;
      int found = 0, truths = 0, veiled = 0;
      for (const Scene& s : scenes) {
        ld::LightingAdapter adapter;
        std::vector<double> c, t;
        for (int r = 0; r < repeats + 1; ++r) {
          const auto t0 = Clock::now();
          const cv::Mat& img = adapter.correct(s.ours.bgr);
          detector.setGlareCorrected(adapter.strongVeil());  // (as ld::AdaptiveDetector does)
          const double ms = msSince(t0);
          const ld::Detection& det = detector.detect(img);
          const double all = msSince(t0);
          adapter.observe(s.ours.bgr, det);
          if (r == 0) {  // the first frame warms up, and is the one counted
            veiled += adapter.glareCorrected();
            for (const auto& tr : s.ours.truth) {
              if (!tr.in_view) continue;
              ++truths;
              found += std::any_of(det.landmarks.begin(), det.landmarks.end(), [&](const ld::Landmark& d) {
                return ld::matchesTruth(d, {tr.fip_tl, tr.fip_tr, tr.fip_bl, tr.ap});
              });
            }
            continue;
          }
          c.push_back(ms);
          t.push_back(all);
        }
        correction.push_back(median(c));
        total.push_back(median(t));
      }
      adaptive_rows.push_back("| " + res + " | " + fmt(median(correction)) + " | " + fmt(median(total)) + " | " +
                              fmt(1000.0 / median(total), 0) + " | " + std::to_string(veiled) + " of " +
                              std::to_string(scenes.size()) + " | " + std::to_string(found) + " of " +
                              std::to_string(truths) + " |");
    }
  }
  md << "\nGLES rows: upload = the frame into a texture through a pixel buffer; readback = one byte a "
        "pixel back (labels, or edge candidates; with a blur in the fast front end the blurred image too); "
        "edges includes the paper front end's hysteresis, on the CPU. Every GPU stage ends in glFinish.\n";
  if (!notes.empty()) md << "\nGLES backend:\n\n";
  for (const auto& n : notes) md << "- " << n << "\n";
  if (!table1.empty()) {
    md << "\nTable I: the filters (blur + saturation + edges) on the CPU and on the GPU, with the "
          "GPU's transfers (upload + readback) apart, ms.\n\n"
       << "| resolution | front end | CPU filters | GLES filters | +transfer (up +down) | GLES filters + transfer | GLES total |\n"
       << "|---|---|---|---|---|---|---|\n";
    for (const auto& r : table1) md << r << "\n";
  }
  if (!table2.empty()) {
    md << "\nTable II (640x480): filter = upload + blur + saturation + edges + readback + contours; "
          "geometry = the rest (stage medians, so filter + geometry need not equal the total's median).\n\n"
       << "| backend | front end | filter | geometry | total | FPS |\n|---|---|---|---|---|---|\n";
    for (const auto& r : table2) md << r << "\n";
  }
  md << "\n--adaptive (CPU, fast front end): median ms of the lighting adapter's correction (colour gains "
        "and glare veil) and of correction + detection, on the same scenes; frames where a veil was "
        "subtracted somewhere; landmarks found.\n\n"
     << "| resolution | correction | correction + detection | FPS | veil subtracted | found |\n"
     << "|---|---|---|---|---|---|\n";
  for (const auto& r : adaptive_rows) md << r << "\n";
  // The tracker (section IV): one assignment and one update per frame.
  md << "\n" << ld::trackerTable(tracker_counts, tracker_repeats, seed);
  std::cout << md.str();
  if (!markdown.empty()) {
    if (const std::string why = ld::writeWholeFile(markdown, md.str()); !why.empty()) {
      std::cerr << "ld-bench: cannot write " << markdown << ": " << why << "\n";
      return 1;
    }
  }
  return ld::cli::outputStatus(argv[0]);
}
