// ld-detect: landmarks in image files, as JSON Lines (docs/landmark.md).
#include <algorithm>
#include <cerrno>
#include <cstring>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <set>

#include <sys/stat.h>

#include <CLI/CLI.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ld/cli.hpp"
#include "ld/adaptive.hpp"
#include "ld/detector.hpp"
#include "ld/detector_options.hpp"
#include "ld/file_checks.hpp"
#include "ld/landmark_json.hpp"
#include "ld/qr_reader.hpp"

namespace fs = std::filesystem;

namespace {

// Bytes that are not UTF-8 (a file name's or a QR payload's) come out as
// U+FFFD rather than ending the run.
constexpr auto kReplace = nlohmann::ordered_json::error_handler_t::replace;

// Whether an 8-bit image has no colour: one channel, or its first three
// alike in every pixel (a grey JPEG or PNG read as colour).
bool noColour(const cv::Mat& img) {
  if (img.channels() == 1) return true;
  if (img.channels() < 3 || img.depth() != CV_8U) return false;
  const int n = img.channels();
  for (int y = 0; y < img.rows; ++y) {
    const uint8_t* p = img.ptr<uint8_t>(y);
    for (int x = 0; x < img.cols; ++x, p += n)
      if (p[0] != p[1] || p[1] != p[2]) return false;
  }
  return true;
}

// Files as given; folders expanded to their image files in name order
// (ld::listImageFolder). The folders that gave none go into `empty`, those
// that could not be listed into `unlisted` (with why); files of image kinds
// OpenCV does not read, left out, are said on stderr (HEIC photos were
// passed over without a word).
std::vector<std::string> expandInputs(const std::vector<std::string>& inputs, std::vector<std::string>& empty,
                                      std::vector<std::string>& unlisted) {
  std::vector<std::string> files, dir, unread;
  for (const auto& in : inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      if (const std::string why = ld::listImageFolder(in, dir, unread); !why.empty()) {
        unlisted.push_back(in + ": " + why);
        continue;
      }
      if (!unread.empty()) std::cerr << "ld-detect: note: " << in << ": " << ld::describeUnreadImages(unread) << "\n";
      if (dir.empty()) empty.push_back(in);
      files.insert(files.end(), dir.begin(), dir.end());
    } else {
      files.push_back(in);
    }
  }
  return files;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-detect: find landmarks in images; JSON Lines on stdout (see README)."};
  std::vector<std::string> inputs;
  std::string draw_dir, out_file;
  bool summary = false, decode = false, explain = false;
  app.add_option("IMAGES", inputs, "image files or folders");
  ld::DetectorOptions detector_options;
  detector_options.addTo(app);
  app.add_option("--draw", draw_dir, "write overlay images into this folder");
  app.add_option("-o,--output", out_file, "write JSON Lines here instead of stdout");
  app.add_flag("--decode", decode, "read each landmark's QR payload too (zbar)");
  app.add_flag("--explain", explain,
               "say on stderr, per image, what each stage kept and why groups of squares shaped as a landmark were refused, "
               "and what each look after the first pass looked at, found and refused");
  app.add_flag("--summary", summary, "print a summary (frames, landmarks, detect_ms) on stderr");
  LD_CLI_PARSE(app, argc, argv);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);  // our own one-line errors

  ld::AdaptiveDetector detector;  // with --adaptive: frames are corrected before detection
  try {
    detector = detector_options.makeAdaptive();
  } catch (const std::exception& e) {
    std::cerr << "ld-detect: " << e.what() << "\n";
    return 2;
  }
  // (the calibration as given: a photo its Exif orientation turned upright
  // gets it turned with it where it fits the photo as stored)
  std::optional<ld::CameraModel> camera;
  if (!detector_options.camera_file.empty()) camera = ld::CameraModel::load(detector_options.camera_file);
  if ((app.count("--draw") && draw_dir.empty()) || (app.count("--output") && out_file.empty()))
    return ld::cli::usage(argv[0], std::string(draw_dir.empty() && app.count("--draw") ? "--draw" : "--output") +
                                       " needs a path, not \"\"");
  if (inputs.empty()) return ld::cli::usage(argv[0], "no input: give image files or folders");
  std::vector<std::string> empty_folders, unlisted;
  const auto files = expandInputs(inputs, empty_folders, unlisted);
  if (!unlisted.empty()) {
    std::cerr << "ld-detect: cannot list the folder " << unlisted.front() << "\n";
    return 2;
  }
  if (files.empty() || !empty_folders.empty()) {  // (a folder without images, even beside others: named)
    std::string named;
    for (const auto& in : files.empty() ? inputs : empty_folders) named += (named.empty() ? "" : ", ") + in;
    std::cerr << "ld-detect: no image files in " << named << " (folders are searched for "
              << ld::imageFileExtensions() << ")\n";
    return 2;
  }
  // What it writes must not be what it reads: -o naming an input would
  // empty it before it is read, and --draw into an input's folder would put
  // an overlay over an input of the same name.
  // Each image's overlay, named after it: one per image, a name already
  // taken (frames/1.png and other/1.png) gets the next free -N.
  std::vector<fs::path> overlays;
  if (!draw_dir.empty()) {
    std::set<std::string> names;
    for (const auto& f : files) {
      std::string name = fs::path(f).stem().string();
      for (int k = 2; !names.insert(name).second; ++k) name = fs::path(f).stem().string() + "-" + std::to_string(k);
      overlays.push_back(fs::path(draw_dir) / (name + ".png"));
    }
  }
  {
    std::set<fs::path> in;  // (resolved: the same file however it is written)
    std::set<std::pair<dev_t, ino_t>> in_ids;  // (and the files themselves: a hard link is another name)
    const auto id = [](const std::string& f, std::pair<dev_t, ino_t>& out) {
      struct stat st {};
      if (::stat(f.c_str(), &st) != 0) return false;
      out = {st.st_dev, st.st_ino};
      return true;
    };
    for (const auto& f : files) {
      in.insert(ld::resolvedPath(f));
      if (std::pair<dev_t, ino_t> i; id(f, i)) in_ids.insert(i);
    }
    const auto isInput = [&](const std::string& f) {
      std::pair<dev_t, ino_t> i;
      return in.count(ld::resolvedPath(f)) > 0 || (id(f, i) && in_ids.count(i) > 0);
    };
    if (!out_file.empty() && isInput(out_file))
      return ld::cli::usage(argv[0], "-o " + out_file + " is one of the input images: it would be emptied");
    // (nor the calibration or the parameters it reads)
    for (const auto& [option, file] : {std::pair<const char*, const std::string*>{"--camera", &detector_options.camera_file},
                                       {"--params", &detector_options.params_file}})
      if (!out_file.empty() && !file->empty() && ld::sameFile(out_file, *file))
        return ld::cli::usage(argv[0], "-o " + out_file + " is the " + option + " file: it would be written over");
    for (const auto& dst : overlays)
      if (isInput(dst.string()))
        return ld::cli::usage(argv[0], "--draw " + draw_dir + " would write its overlay over the input " +
                                           dst.string() + ": draw into another folder");
    // (nor one of its outputs the other: -o as an overlay's name, or as the
    // --draw folder itself)
    if (!out_file.empty() && !draw_dir.empty()) {
      if (ld::sameFile(out_file, draw_dir))
        return ld::cli::usage(argv[0], "-o " + out_file + " is the --draw folder: name a file");
      for (const auto& dst : overlays)
        if (ld::sameFile(out_file, dst.string()))
          return ld::cli::usage(argv[0], "-o " + out_file + " is the name of an overlay --draw writes (" +
                                             dst.string() + "): it would be written over");
    }
  }
  if (!draw_dir.empty()) {  // created when missing, and written in, as ld-view's --out
    const std::string problem = ld::prepareOutputFolder(draw_dir);
    if (!problem.empty()) {
      std::cerr << "ld-detect: --draw: " << problem << "\n";
      return 2;
    }
  }

  std::ofstream file;
  if (!out_file.empty()) {
    if (const std::string problem = ld::prepareOutputFile(out_file); !problem.empty()) {
      std::cerr << "ld-detect: cannot write " << out_file << ": " << problem << "\n";
      return 2;
    }
    file.open(out_file);
    if (!file) {
      std::cerr << "ld-detect: cannot write " << out_file << ": " << std::strerror(errno) << "\n";
      return 2;
    }
  }
  std::ostream& out = out_file.empty() ? std::cout : file;

  ld::QrReader qr;
  std::vector<ld::Landmark> found;
  int failed = 0, with_landmarks = 0, total_landmarks = 0, draw_failed = 0, grey = 0;
  bool draw_full = false;  // (an overlay met a full disk)
  std::vector<double> times;
  std::string pose_error;       // the last frame's Detection::pose_error
  ld::ImageTurn camera_turn;    // how the detector's calibration is turned now
  std::string turn_refused;     // why the calibration could not turn, said once
  // (one line for a file that failed, and the run goes on)
  const auto fileFailed = [&](const std::string& path, const std::string& why) {
    std::cerr << "ld-detect: " << path << ": " << why << "\n";
    out << nlohmann::ordered_json{{"image", path}, {"error", why}}.dump(-1, ' ', false, kReplace) << "\n";
    ++failed;
  };
  for (const auto& path : files) {
    cv::Mat img;
    // (memory that runs out on a large image is that image's failure: the
    // run aborted, and the files after it were never read)
    const auto outOfMemory = [](const std::string& doing, const char* what) {
      return "out of memory " + doing + " (" + what + ")";
    };
    std::string read_why;
    ld::ImageTurn turn;
    try {
      read_why = ld::readImageFile(path, img, turn);
    } catch (const std::bad_alloc& e) {
      read_why = outOfMemory("reading it", e.what());
    }
    if (!read_why.empty()) {
      fileFailed(path, read_why);
      continue;
    }
    // A phone's portrait photo, stored landscape as the sensor took it and
    // turned upright by its Exif orientation (or upside down, or mirrored):
    // the camera's calibration, of the sensor's images as stored, turned with
    // it where it fits the photo as stored (a portrait photo's pose was
    // refused as another aspect ratio; an upside-down one's was off by the
    // principal point's offset, reflected, 6 cm at 0.9 m in a review's).
    if (camera) {
      ld::ImageTurn want;
      if (turn.any() && camera->fits(turn.stored)) want = turn;
      if (want.quarter_turns_cw != camera_turn.quarter_turns_cw || want.mirrored != camera_turn.mirrored) {
        ld::CameraModel turned = *camera;
        if (want.any()) {
          if (const std::string why_not = camera->turned(want.quarter_turns_cw, want.mirrored, turned);
              !why_not.empty()) {
            if (why_not != turn_refused)
              std::cerr << "ld-detect: " << path << ": its Exif orientation turns it, and the camera calibration "
                        << "cannot be turned with it: " << why_not << "\n";
            turn_refused = why_not;  // (`turned` is left as the calibration given)
          }
        }
        detector.detector().setCamera(turned, detector_options.side_m);
        camera_turn = want;
      }
    }
    ld::Explanation why;
    const auto t0 = std::chrono::steady_clock::now();
    // A step on the image: false, its failure said, when memory ran out
    // (`doing`) or OpenCV refused (`refused`).
    const auto step = [&](const char* doing, const char* refused, const auto& run) {
      try {
        run();
        return true;
      } catch (const std::bad_alloc& e) {
        fileFailed(path, outOfMemory(doing, e.what()));
      } catch (const cv::Exception& e) {
        fileFailed(path, e.code == cv::Error::StsNoMem ? outOfMemory(doing, e.err.c_str())
                                                       : std::string(refused) + " (OpenCV: " + e.err + ")");
      }
      return false;
    };
    const ld::Detection* detected = nullptr;
    if (!step("detecting in it", "cannot detect in it",
              [&] { detected = &(explain ? detector.detect(img, why) : detector.detect(img)); }))
      continue;
    const ld::Detection& det = *detected;
    // (what explaining took is not detection time)
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() - why.ms;
    // (a calibration that does not fit the frames: said once, and again when it changes)
    if (det.pose_error != pose_error) {
      pose_error = det.pose_error;
      if (!pose_error.empty()) std::cerr << "ld-detect: " << path << ": " << pose_error << "\n";
    }
    found.assign(det.landmarks.begin(), det.landmarks.end());
    // A grey image (a monochrome camera's, a photo in black and white):
    // nothing found, and nothing said, even by --explain. Said for the
    // first, counted at the end.
    if (found.empty() && noColour(img) && ++grey == 1)
      std::cerr << "ld-detect: " << path << ": a grey image (no colour in it): landmarks are found by their blue "
                << "and red squares, so none can be found in it\n";
    if (decode && !step("reading its codes", "cannot read its codes", [&] {
          for (auto& lm : found)
            if (const auto r = qr.decode(img, lm.corners)) lm.payload = r->payload;
        }))
      continue;
    nlohmann::ordered_json j{{"image", path}, {"width", img.cols}, {"height", img.rows},
                     {"detect_ms", std::round(ms * 1000.0) / 1000.0}};
    j["landmarks"] = nlohmann::ordered_json::array();
    for (const auto& lm : found) j["landmarks"].push_back(ld::toJson(lm));
    out << j.dump(-1, ' ', false, kReplace) << "\n";
    if (explain) {
      out.flush();  // the explanation after its image's line when both go to the terminal
      std::string text = path + ": " + std::to_string(found.size()) + (found.size() == 1 ? " landmark" : " landmarks");
      if (detector.enabled()) {
        const auto& a = detector.adapter();
        text += cv::format("; adaptive gains B %.2f G %.2f R %.2f%s", a.gains()[0], a.gains()[1], a.gains()[2],
                           a.glareCorrected() ? ", glare veil subtracted" : "");
      }
      std::cerr << text << "\n" << ld::describe(why, detector.detector().params(), "  ") << "\n";
    }
    times.push_back(ms);
    with_landmarks += !found.empty();
    total_landmarks += static_cast<int>(found.size());
    if (!draw_dir.empty() && draw_full) {
      ++draw_failed;  // (the disk is full: not drawn, counted)
    } else if (!draw_dir.empty()) {
      ld::drawLandmarks(img, found);
      const fs::path& dst = overlays[static_cast<size_t>(&path - files.data())];
      int e = 0;  // (written whole, or no cut PNG left behind as if whole: writeWholeFile)
      try {
        std::vector<uint8_t> png;
        if (cv::imencode(".png", img, png)) ld::writeWholeFile(dst.string(), std::string(png.begin(), png.end()), &e);
        else e = EIO;
      } catch (const cv::Exception&) {
        e = EIO;
      } catch (const std::bad_alloc&) {  // (a huge image's PNG: that overlay alone)
        e = ENOMEM;
      }
      if (e != 0) {  // (a full disk: the overlays are not all there; status 1 at the end)
        // (once the disk or the quota is full, the overlays after it are not
        // tried: a line for each frame said the same thing, and left empty files)
        const bool full = e == ENOSPC || e == EDQUOT;
        std::cerr << "ld-detect: cannot write " << dst.string() << ": " << std::strerror(e)
                  << (full ? "; the overlays after it are not drawn" : "") << "\n";
        ++draw_failed;
        draw_full = full;
      }
    }
  }
  if (grey > 1) std::cerr << "ld-detect: " << grey << " grey images in all: no landmark can be found in them\n";
  out.flush();
  if (!out) {  // (a full disk: the results are not all there)
    std::cerr << "ld-detect: write to " << (out_file.empty() ? std::string("stdout") : out_file)
              << " failed: " << std::strerror(errno) << "\n";
    return 1;
  }
  if (summary) {
    std::sort(times.begin(), times.end());
    // nearest rank: the smallest time that q of the images take at most
    const auto pct = [&](double q) {
      const auto rank = static_cast<size_t>(std::ceil(q * static_cast<double>(times.size())));
      return times[std::clamp<size_t>(rank, 1, times.size()) - 1];
    };
    const auto count = [](size_t n, const char* one, const char* many) {
      return std::to_string(n) + " " + (n == 1 ? one : many);
    };
    std::string line = "ld-detect: " + count(times.size(), "image", "images") + ", " +
                       std::to_string(with_landmarks) + " with landmarks, " +
                       count(static_cast<size_t>(total_landmarks), "landmark", "landmarks");
    if (!times.empty())
      line += cv::format(", %.2f per image; detect_ms median %.3f, p95 %.3f, max %.3f",
                         static_cast<double>(total_landmarks) / static_cast<double>(times.size()), pct(0.5),
                         pct(0.95), times.back());
    line += "; " + std::to_string(failed) + " unreadable" +
            (draw_failed ? "; " + std::to_string(draw_failed) + " overlays not written" : std::string()) +
            "; backend " + detector.detector().backendInfo();
    std::cerr << line << "\n";
  }
  return failed > 0 || draw_failed > 0 ? 1 : 0;
}
