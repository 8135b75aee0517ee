// TrackerParams: validation and YAML/XML files (cv::FileStorage).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include "ld/tracker.hpp"

#include "ld/config_file.hpp"

namespace ld {
namespace {

constexpr const char* kKeys[] = {"max_lifetime_s", "max_distance", "coast_distance_growth",
                                 "max_size_ratio", "predict",      "velocity_smoothing",
                                 "min_hits",       "report_coasting"};

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error("tracker parameters " + path + ": " + what);
}

double readNumber(const cv::FileNode& n, const std::string& path) {
  if (!n.isInt() && !n.isReal()) fail(path, "key '" + n.name() + "' must be a number");
  return n.isInt() ? static_cast<double>(static_cast<int>(n)) : static_cast<double>(n);
}

int readInt(const cv::FileNode& n, const std::string& path) {
  if (!n.isInt()) fail(path, "key '" + n.name() + "' must be an integer");
  return static_cast<int>(n);
}

bool readBool(const cv::FileNode& n, const std::string& path) {
  if (n.isInt()) {
    const int v = static_cast<int>(n);
    if (v == 0 || v == 1) return v == 1;
  } else if (n.isString()) {
    const std::string s = configString(n);
    if (s == "true" || s == "True" || s == "TRUE") return true;
    if (s == "false" || s == "False" || s == "FALSE") return false;
  }
  fail(path, "key '" + n.name() + "' must be true/false or 1/0");
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

}  // namespace

TrackerParams TrackerParams::load(const std::string& path) {
  // (an empty file is refused as the detector's is: a file cut short or
  // never written; `{}` gives the defaults)
  const cv::FileStorage fs = openConfigFile(path, "tracker parameters");
  TrackerParams p;
  const cv::FileNode root = fs.root();
  if (!root.isMap() && !root.empty()) fail(path, "top level is not a map of parameters");
  try {
    for (auto it = root.begin(); it != root.end(); ++it) {
      const cv::FileNode n = *it;
      const std::string key = n.name();
      if (key == "max_lifetime_s") p.max_lifetime_s = readNumber(n, path);
      else if (key == "max_distance") p.max_distance = readNumber(n, path);
      else if (key == "coast_distance_growth") p.coast_distance_growth = readNumber(n, path);
      else if (key == "max_size_ratio") p.max_size_ratio = readNumber(n, path);
      else if (key == "predict") p.predict = readBool(n, path);
      else if (key == "velocity_smoothing") p.velocity_smoothing = readNumber(n, path);
      else if (key == "min_hits") p.min_hits = readInt(n, path);
      else if (key == "report_coasting") p.report_coasting = readBool(n, path);
      else {
        std::string known;
        for (const char* k : kKeys) known += std::string(known.empty() ? "" : ", ") + k;
        fail(path, "unknown key '" + key + "' (known: " + known + ")");
      }
    }
  } catch (const cv::Exception& e) {
    fail(path, "malformed (" + e.err + ")");
  }
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    fail(path, e.what());
  }
  return p;
}

void TrackerParams::save(const std::string& path) const {
  std::ofstream f(path);
  f << toYaml();
  if (!f) throw std::runtime_error("tracker parameters " + path + ": cannot write");
}

std::string TrackerParams::toYaml() const {
  const char* b[] = {"false", "true"};
  return std::string("%YAML:1.0\n---\n") +
         "# ld-tracker parameters; tracker/include/ld/tracker.hpp documents each.\n" +
         "# Seconds a landmark is kept while not detected.\n" +
         "max_lifetime_s: " + num(max_lifetime_s) + "\n" +
         "# Largest match distance, in landmark sizes.\n" +
         "max_distance: " + num(max_distance) + "\n" +
         "# Extra match distance per second a landmark has been unseen (sizes/s).\n" +
         "coast_distance_growth: " + num(coast_distance_growth) + "\n" +
         "# Largest ratio of the sizes of a match.\n" +
         "max_size_ratio: " + num(max_size_ratio) + "\n" +
         "# Constant-velocity prediction of position and size.\n" +
         "predict: " + b[predict] + "\n" +
         "# Weight (0..1] of the newest measured velocity.\n" +
         "velocity_smoothing: " + num(velocity_smoothing) + "\n" +
         "# Detections before a track is reported.\n" +
         "min_hits: " + std::to_string(min_hits) + "\n" +
         "# Report tracks not detected in the frame (visible = false).\n" +
         "report_coasting: " + b[report_coasting] + "\n";
}

void TrackerParams::validate() const {
  auto bad = [](const std::string& what) { throw std::invalid_argument(what); };
  // (counted in whole microseconds: under half of one it rounded to 0, and
  // every track expired, renumbered, each frame)
  if (!(max_lifetime_s >= 1e-6) || !std::isfinite(max_lifetime_s))
    bad("max_lifetime_s must be a number of seconds, at least 1e-6 (a microsecond)");
  // (bounded: a gate of 1e307 sizes overflowed the assignment's gains)
  if (!(max_distance > 0 && max_distance <= 1000)) bad("max_distance must be in (0, 1000] (landmark sizes)");
  if (!(coast_distance_growth >= 0 && coast_distance_growth <= 1000))
    bad("coast_distance_growth must be in [0, 1000] (landmark sizes per second)");
  if (!(max_size_ratio >= 1 && max_size_ratio <= 1000)) bad("max_size_ratio must be in [1, 1000]");
  if (!(velocity_smoothing > 0 && velocity_smoothing <= 1))
    bad("velocity_smoothing must be in (0, 1]");
  if (min_hits < 1 || min_hits > 1000) bad("min_hits must be in [1, 1000]");
}

}  // namespace ld
