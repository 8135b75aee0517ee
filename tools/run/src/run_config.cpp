#include "ld/run_config.hpp"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <stdexcept>
#include <type_traits>

#include <yaml-cpp/yaml.h>

namespace ld {
namespace {

using Json = nlohmann::json;

void checkKeys(const Json& j, const std::string& where, const std::set<std::string>& allowed) {
  if (!j.is_object()) throw std::runtime_error(where + ": expected an object");
  for (const auto& [k, v] : j.items())
    if (!allowed.count(k)) throw std::runtime_error(where + ": unknown key \"" + k + "\"");
}

template <typename T>
void get(const Json& j, const char* key, const std::string& where, T& out) {
  if (!j.contains(key)) return;
  const Json& v = j.at(key);
  if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
    // a number written as text (YAML's scalars come as text)
    if (v.is_string()) {
      const std::string& text = v.get_ref<const std::string&>();
      char* end = nullptr;
      const double d = std::strtod(text.c_str(), &end);
      if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(d))
        throw std::runtime_error(where + "." + key + ": \"" + text + "\" is not a number");
      out = static_cast<T>(d);
      return;
    }
  }
  try {
    out = v.get<T>();
  } catch (const Json::exception&) {
    throw std::runtime_error(where + "." + key + ": wrong type");
  }
}

// A YAML document as JSON: maps, sequences, and scalars as text, but for
// plain true/false (booleans) and null/~ (null). Numbers stay text (get()
// reads them where a number is expected), so args keep what was written.
Json fromYaml(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Map: {
      Json o = Json::object();
      for (const auto& kv : n) o[kv.first.as<std::string>()] = fromYaml(kv.second);
      return o;
    }
    case YAML::NodeType::Sequence: {
      Json a = Json::array();
      for (const auto& e : n) a.push_back(fromYaml(e));
      return a;
    }
    case YAML::NodeType::Scalar: {
      const std::string& text = n.Scalar();
      if (n.Tag() != "!") {  // plain (not quoted)
        if (text == "true") return true;
        if (text == "false") return false;
        if (text == "null" || text == "~") return nullptr;
      }
      return text;
    }
    default:
      return nullptr;
  }
}

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

WorkerConfig worker(const Json& j, const std::string& where, WorkerConfig w) {
  checkKeys(j, where, {"enabled", "program", "args"});
  get(j, "enabled", where, w.enabled);
  get(j, "program", where, w.program);
  get(j, "args", where, w.args);
  return w;
}

std::string quoteRegex(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (std::string("\\^$.|?*+()[]{}").find(c) != std::string::npos) out += '\\';
    out += c;
  }
  return out;
}

}  // namespace

RunConfig RunConfig::fromJson(const Json& j) {
  RunConfig c;
  checkKeys(j, "config", {"lcm_url", "channels", "source", "detector", "tracker", "qr_reader",
                          "record", "restart"});
  get(j, "lcm_url", "config", c.lcm_url);
  if (j.contains("channels")) {
    const Json& ch = j["channels"];
    checkKeys(ch, "channels", {"image", "landmarks", "tracked", "codes"});
    get(ch, "image", "channels", c.channels.image);
    get(ch, "landmarks", "channels", c.channels.landmarks);
    get(ch, "tracked", "channels", c.channels.tracked);
    get(ch, "codes", "channels", c.channels.codes);
  }
  if (j.contains("source")) {
    const Json& s = j["source"];
    checkKeys(s, "source", {"type", "args", "log", "speed", "channels", "fps", "duration_s", "format"});
    get(s, "type", "source", c.source);
    if (c.source != "camera" && c.source != "replay" && c.source != "play" && c.source != "none")
      throw std::runtime_error("source.type: \"" + c.source + "\" is not camera, replay, play or none");
    std::vector<std::string> args;
    get(s, "args", "source", args);
    (c.source == "camera" ? c.camera_args : c.source_args) = args;
    get(s, "log", "source", c.log);
    get(s, "speed", "source", c.speed);
    get(s, "channels", "source", c.replay_channels);
    get(s, "fps", "source", c.play_fps);
    get(s, "duration_s", "source", c.play_duration_s);
    get(s, "format", "source", c.play_format);
  }
  if (j.contains("detector")) c.detector = worker(j["detector"], "detector", c.detector);
  if (j.contains("tracker")) c.tracker = worker(j["tracker"], "tracker", c.tracker);
  if (j.contains("qr_reader")) c.qr_reader = worker(j["qr_reader"], "qr_reader", c.qr_reader);
  if (j.contains("record")) {
    const Json& r = j["record"];
    checkKeys(r, "record", {"file", "channels"});
    get(r, "file", "record", c.record);
    get(r, "channels", "record", c.record_channels);
  }
  if (j.contains("restart")) {
    const Json& r = j["restart"];
    checkKeys(r, "restart", {"initial_s", "max_s", "stable_after_s"});
    get(r, "initial_s", "restart", c.restart.initial_s);
    get(r, "max_s", "restart", c.restart.max_s);
    get(r, "stable_after_s", "restart", c.restart.stable_after_s);
    if (!(c.restart.initial_s > 0) || c.restart.max_s < c.restart.initial_s)
      throw std::runtime_error("restart: need 0 < initial_s <= max_s");
  }
  if (!(c.speed > 0)) throw std::runtime_error("source.speed: must be > 0");
  if (!(c.play_fps > 0)) throw std::runtime_error("source.fps: must be > 0");
  return c;
}

RunConfig RunConfig::load(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot read config " + path);
  Json j;
  if (endsWith(path, ".yaml") || endsWith(path, ".yml")) {
    try {
      j = fromYaml(YAML::Load(f));
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(path + ": not valid YAML: line " + std::to_string(e.mark.line + 1) + ", column " +
                               std::to_string(e.mark.column + 1) + ": " + e.msg);
    }
    if (j.is_null()) j = Json::object();  // an empty file: every default
  } else {
    try {
      j = Json::parse(f, nullptr, true, /*ignore_comments=*/true);
    } catch (const Json::exception& e) {  // parse_error, and out_of_range for a number like 3e333
      throw std::runtime_error(path + ": not valid JSON: " + e.what());
    }
  }
  try {
    return fromJson(j);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

std::vector<ProcessSpec> buildProcessSpecs(const RunConfig& cfg, const std::string& url,
                                           const std::string& self_dir) {
  const BusChannels& ch = cfg.channels;
  std::vector<ProcessSpec> specs;
  const auto prog = [&](const std::string& name) { return resolveProgram(name, self_dir); };
  const auto add = [&](const std::string& name, ProcessRole role, std::vector<std::string> argv,
                       const std::vector<std::string>& extra) {
    argv.insert(argv.end(), extra.begin(), extra.end());
    specs.push_back({name, std::move(argv), role});
  };
  if (!cfg.record.empty()) {
    const std::string chans =
        cfg.record_channels.empty()
            ? quoteRegex(ch.landmarks) + "|" + quoteRegex(ch.tracked) + "|" + quoteRegex(ch.codes)
            : cfg.record_channels;
    // -a: a restarted recorder appends to what it wrote before (ld-run removes the old file first)
    add("recorder", ProcessRole::Recorder,
        {prog("lcm-logger"), "--lcm-url=" + url, "--channel=" + chans, "-a", "-q", cfg.record}, {});
  }
  if (cfg.detector.enabled)
    add("detector", ProcessRole::Worker,
        {prog(cfg.detector.program), "--lcm-url", url, "--in", ch.image, "--out", ch.landmarks},
        cfg.detector.args);
  if (cfg.tracker.enabled)
    add("tracker", ProcessRole::Worker,
        {prog(cfg.tracker.program), "--lcm-url", url, "--in", ch.landmarks, "--out", ch.tracked},
        cfg.tracker.args);
  if (cfg.qr_reader.enabled)
    add("qr-reader", ProcessRole::Worker,
        {prog(cfg.qr_reader.program), "--lcm-url", url, "--image", ch.image, "--tracks", ch.tracked,
         "--out", ch.codes},
        cfg.qr_reader.args);
  if (cfg.source == "camera") {
    add("camera", ProcessRole::Worker, {prog("ld-camera"), "--lcm-url", url, "--channel", ch.image},
        cfg.camera_args);
  } else if (cfg.source == "replay") {
    if (cfg.log.empty()) throw std::runtime_error("replay: no log file given");
    std::vector<std::string> argv{prog("lcm-logplayer"), "--lcm-url=" + url,
                                  "--speed=" + std::to_string(cfg.speed),
                                  "--regexp=" + (cfg.replay_channels.empty()
                                                     ? "^" + quoteRegex(ch.image) + "$"
                                                     : cfg.replay_channels)};
    argv.insert(argv.end(), cfg.source_args.begin(), cfg.source_args.end());
    argv.push_back(cfg.log);
    add("replay", ProcessRole::Source, argv, {});
  } else if (cfg.source == "play") {
    if (cfg.log.empty()) throw std::runtime_error("play: no log file given");
    std::vector<std::string> argv{prog("ld-play"), cfg.log, "--lcm-url", url, "--channel", ch.image,
                                  "--fps", std::to_string(cfg.play_fps), "--format", cfg.play_format};
    if (cfg.play_duration_s > 0) {
      argv.push_back("--duration");
      argv.push_back(std::to_string(cfg.play_duration_s));
    }
    add("play", ProcessRole::Source, argv, cfg.source_args);
  } else if (cfg.source != "none") {
    throw std::runtime_error("unknown source \"" + cfg.source + "\"");
  }
  return specs;
}

}  // namespace ld
