#include "ld/run_config.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include <yaml-cpp/yaml.h>

#include "ld/config_file.hpp"
#include "ld/image_convert.hpp"
#include "ld/lcm_url.hpp"

namespace ld {
namespace {

// A file path as a program's argument: one that starts with '-' as "./-..."
// (lcm-logplayer took "-r.lcmlog" for its options, refused them, and the
// replay was restarted for ever).
std::string asArgument(const std::string& path) { return path.rfind('-', 0) == 0 ? "./" + path : path; }

using Json = nlohmann::json;

void checkKeys(const Json& j, const std::string& where, const std::set<std::string>& allowed) {
  if (!j.is_object()) throw std::runtime_error(where + ": expected an object");
  for (const auto& [k, v] : j.items())
    if (!allowed.count(k)) throw std::runtime_error(where + ": unknown key \"" + k + "\"");
}

// Reads the tree's values into RunConfig's fields. A YAML file's scalars
// arrive as text (but for plain true, false and null), so from YAML a number
// is read from its text and args keep what was written; JSON keeps its types
// strict.
struct Reader {
  bool yaml = false;

  static std::string shown(const Json& v) {
    return v.is_string() ? "\"" + v.get<std::string>() + "\"" : v.dump(-1, ' ', false, Json::error_handler_t::replace);
  }

  template <typename T>
  void get(const Json& j, const char* key, const std::string& where, T& out) const {
    if (!j.contains(key)) return;
    const Json& v = j.at(key);
    const std::string name = where + "." + key;
    if constexpr (std::is_same_v<T, bool>) {
      if (!v.is_boolean()) throw std::runtime_error(name + ": expected true or false, got " + shown(v));
      out = v.get<bool>();
    } else if constexpr (std::is_arithmetic_v<T>) {
      if (v.is_number()) {
        out = v.get<T>();
        return;
      }
      if (yaml && v.is_string()) {  // decimal text: 2, 0.5, 1e3 (not 0x10, not .inf)
        const std::string& text = v.get_ref<const std::string&>();
        char* end = nullptr;
        const double d = std::strtod(text.c_str(), &end);
        const bool decimal = !text.empty() && text.find_first_not_of("+-.0123456789eE") == std::string::npos;
        if (decimal && end == text.c_str() + text.size() && std::isfinite(d)) {
          out = static_cast<T>(d);
          return;
        }
      }
      throw std::runtime_error(name + ": expected a number, got " + shown(v));
    } else if constexpr (std::is_same_v<T, std::string>) {
      if (!v.is_string()) throw std::runtime_error(name + ": expected text, got " + shown(v));
      out = v.get<std::string>();
    } else {
      static_assert(std::is_same_v<T, std::vector<std::string>>);
      out.clear();
      if (yaml && v.is_null()) return;  // "args:" with nothing after it
      if (!v.is_array()) throw std::runtime_error(name + ": expected a list, got " + shown(v));
      for (const Json& e : v) {
        if (e.is_string()) out.push_back(e.get<std::string>());
        else if (yaml && e.is_boolean()) out.push_back(e.get<bool>() ? "true" : "false");  // as written
        else throw std::runtime_error(name + ": expected text in the list, got " + shown(e));
      }
    }
  }

  WorkerConfig worker(const Json& j, const std::string& where, WorkerConfig w) const {
    checkKeys(j, where, {"enabled", "program", "args"});
    get(j, "enabled", where, w.enabled);
    get(j, "program", where, w.program);
    get(j, "args", where, w.args);
    return w;
  }
};

// A scalar's text, which must be UTF-8 (YAML is Unicode text, but yaml-cpp
// passes any bytes): nlohmann's serializer checks it.
std::string textOf(const YAML::Node& n) {
  try {
    (void)Json(n.Scalar()).dump();
  } catch (const Json::type_error&) {
    throw std::runtime_error("line " + std::to_string(n.Mark().line + 1) + ": text that is not UTF-8");
  }
  return n.Scalar();
}

// A YAML document as JSON: maps (text keys), sequences, and scalars as text,
// but for plain (untagged, unquoted) true, false, null and ~. Aliases are
// followed: at most kMaxYamlValues values in all, so that a few lines of
// nested aliases cannot expand into gigabytes.
constexpr size_t kMaxYamlValues = 100000;
Json fromYaml(const YAML::Node& n, size_t& count) {
  if (++count > kMaxYamlValues)
    throw std::runtime_error("more than " + std::to_string(kMaxYamlValues) + " values (aliases that expand?)");
  switch (n.Type()) {
    case YAML::NodeType::Map: {
      Json o = Json::object();
      for (const auto& kv : n) {
        if (!kv.first.IsScalar())
          throw std::runtime_error("line " + std::to_string(kv.first.Mark().line + 1) + ": a key must be text");
        const std::string key = textOf(kv.first);
        if (o.contains(key))
          throw std::runtime_error("line " + std::to_string(kv.first.Mark().line + 1) + ": key \"" + key +
                                   "\" is given twice");
        o[key] = fromYaml(kv.second, count);
      }
      return o;
    }
    case YAML::NodeType::Sequence: {
      Json a = Json::array();
      for (const auto& e : n) a.push_back(fromYaml(e, count));
      return a;
    }
    case YAML::NodeType::Scalar: {
      const std::string text = textOf(n);
      if (n.Tag() == "?") {  // plain: no quotes, no tag
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

// A number for another program's command line, as exact as the double
// (std::to_string's six decimals made a speed of 1e-7 "0.000000").
// (six significant digits for a size: 0.03, where 17 wrote 0.029999999999999999)
std::string number(double v, int digits = 17) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*g", digits, v);
  return text;
}

bool endsWith(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
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

RunConfig RunConfig::fromJson(const Json& j) { return fromTree(j, false); }

RunConfig RunConfig::fromTree(const Json& j, bool yaml) {
  const Reader reader{yaml};
  const auto get = [&reader](const Json& tree, const char* key, const std::string& where, auto& out) {
    reader.get(tree, key, where, out);
  };
  const auto worker = [&reader](const Json& tree, const std::string& where, WorkerConfig w) {
    return reader.worker(tree, where, w);
  };
  // (a channel pattern lcm-logger or lcm-logplayer takes: an empty one is none given)
  const auto requirePattern = [](const char* key, const std::string& pattern, const char* program) {
    if (const std::string why = channelPatternError(pattern); !pattern.empty() && !why.empty())
      throw std::runtime_error(std::string(key) + ": " + pattern + " is no regular expression " + program +
                               " can read (" + why + ")");
  };
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
    for (const auto& [key, name] : {std::pair<const char*, const std::string*>{"image", &c.channels.image},
                                    {"landmarks", &c.channels.landmarks},
                                    {"tracked", &c.channels.tracked},
                                    {"codes", &c.channels.codes}})
      if (name->empty()) throw std::runtime_error(std::string("channels.") + key + ": a channel name, not \"\"");
  }
  // Each channel is published on by one process and subscribed to by
  // another, which LCM reads as a regular expression: a name that takes
  // another ("CAM(1)" takes CAM1) fed the set nothing, without a word; and
  // one channel for two types of message (images, landmark lists, codes)
  // made every message of one type a bad one of the other. (The detector's
  // lists as the tracked ones, the tracker left out, are one type.)
  {
    struct Role {
      const char* key;
      const std::string* name;
      int type;
    };
    const Role roles[] = {{"image", &c.channels.image, 0},
                          {"landmarks", &c.channels.landmarks, 1},
                          {"tracked", &c.channels.tracked, 1},
                          {"codes", &c.channels.codes, 2}};
    for (size_t i = 0; i < std::size(roles); ++i) {
      const Role& r = roles[i];
      if (!channelNameTakesItself(*r.name))
        throw std::runtime_error(std::string("channels.") + r.key + ": " + *r.name +
                                 " is read by LCM's subscriptions as a regular expression that does not take the "
                                 "name itself: name it with letters, digits and _ - / . alone");
      for (size_t k = 0; k < i; ++k)
        if (*roles[k].name == *r.name && roles[k].type != r.type)
          throw std::runtime_error(std::string("channels.") + r.key + ": " + *r.name + " is also channels." +
                                   roles[k].key + ": another type of message on one channel");
    }
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
    requirePattern("source.channels", c.replay_channels, "lcm-logplayer");
    get(s, "fps", "source", c.play_fps);
    get(s, "duration_s", "source", c.play_duration_s);
    get(s, "format", "source", c.play_format);
  }
  if (j.contains("detector")) c.detector = worker(j["detector"], "detector", c.detector);
  if (j.contains("tracker")) c.tracker = worker(j["tracker"], "tracker", c.tracker);
  if (j.contains("qr_reader")) c.qr_reader = worker(j["qr_reader"], "qr_reader", c.qr_reader);
  if (j.contains("record")) {
    const Json& r = j["record"];
    checkKeys(r, "record", {"file", "channels", "split_mb", "keep"});
    get(r, "file", "record", c.record);
    get(r, "channels", "record", c.record_channels);
    requirePattern("record.channels", c.record_channels, "lcm-logger");
    get(r, "split_mb", "record", c.record_split_mb);
    get(r, "keep", "record", c.record_keep);
    if (!(c.record_split_mb == 0 || (c.record_split_mb >= 0.001 && c.record_split_mb <= 1e6)))
      throw std::runtime_error("record: split_mb must be 0 (one file) or 0.001 to 1000000 MB");
    if (c.record_keep < 2 || c.record_keep > 1000)
      throw std::runtime_error("record: keep must be 2 to 1000 files");
    if (r.contains("keep") && c.record_split_mb == 0)
      throw std::runtime_error("record: keep is the number of files split_mb makes: give split_mb too");
  }
  if (j.contains("restart")) {
    const Json& r = j["restart"];
    checkKeys(r, "restart", {"initial_s", "max_s", "stable_after_s", "hang_s"});
    get(r, "initial_s", "restart", c.restart.initial_s);
    get(r, "max_s", "restart", c.restart.max_s);
    get(r, "stable_after_s", "restart", c.restart.stable_after_s);
    get(r, "hang_s", "restart", c.restart.hang_s);
    if (!(c.restart.initial_s > 0) || c.restart.max_s < c.restart.initial_s)
      throw std::runtime_error("restart: need 0 < initial_s <= max_s");
    if (!(c.restart.hang_s == 0 || (c.restart.hang_s >= 1 && c.restart.hang_s <= 86400)))
      throw std::runtime_error("restart: hang_s must be 0 (never) or 1 to 86400 seconds");
  }
  if (!(c.speed >= 0.01 && c.speed <= 1000))
    throw std::runtime_error("source.speed: must be in [0.01, 1000] (lcm-logplayer's speed factor)");
  if (!(c.play_duration_s >= 0 && c.play_duration_s < 1e9))
    throw std::runtime_error("source.duration_s: must be >= 0 (0: the log once) and under 1e9");
  if (!(c.play_fps >= 0.001 && c.play_fps <= 1000))
    throw std::runtime_error("source.fps: must be in [0.001, 1000] (ld-play's range)");
  try {
    checkPlayFormat(c.play_format);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(std::string("source.format: ") + e.what());
  }
  return c;
}

void checkPlayFormat(const std::string& format) {
  if (format == "keep") return;
  try {
    (void)pixelFormatFromName(format);  // ld-play's own test of --format
  } catch (const ImageFormatError& e) {
    throw std::runtime_error(std::string(e.what()) + ", or keep");
  }
}

RunConfig RunConfig::load(const std::string& given) {
  // A path without an extension that names no file: the one of
  // given.yaml, given.yml, given.json that exists (ld-run@.service passes
  // /etc/landmark/<instance>).
  std::string path = given;
  const size_t slash = given.find_last_of('/');
  if (!std::filesystem::exists(given) && given.find('.', slash == std::string::npos ? 0 : slash + 1) == std::string::npos) {
    std::vector<std::string> found;
    for (const char* ext : {".yaml", ".yml", ".json"})
      if (std::filesystem::exists(given + ext)) found.push_back(given + ext);
    if (found.empty())
      throw std::runtime_error("cannot read config " + given + " (nor " + given + ".yaml, .yml or .json)");
    if (found.size() > 1)
      throw std::runtime_error("config " + given + ": both " + found[0] + " and " + found[1] + " exist; give one");
    path = found[0];
  }
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw std::runtime_error("config " + path + " is a folder");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read config " + path + ": " + std::strerror(errno));
  const std::optional<std::string> text = readAtMost(in, kMaxConfigBytes);
  if (!text) throw std::runtime_error("config " + path + " is larger than 16 MiB: not a configuration file");
  // (an image or a log given by mistake: the parser's words ended in the raw
  // byte it stopped at)
  if (text->compare(0, 2, "\xFF\xFE") == 0 || text->compare(0, 2, "\xFE\xFF") == 0)
    throw std::runtime_error("config " + path + " is UTF-16 text: save it as UTF-8");
  if (const size_t nul = text->find('\0'); nul != std::string::npos)
    throw std::runtime_error("config " + path + " contains a NUL byte at offset " + std::to_string(nul) +
                             " (not a text file)");
  std::istringstream f(*text);
  Json j;
  const bool yaml = endsWith(path, ".yaml") || endsWith(path, ".yml");
  if (yaml) {
    try {
      size_t count = 0;
      j = fromYaml(YAML::Load(f), count);
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(path + ": not valid YAML: line " + std::to_string(e.mark.line + 1) + ", column " +
                               std::to_string(e.mark.column + 1) + ": " + e.msg);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(path + ": " + e.what());
    }
    if (j.is_null()) j = Json::object();  // an empty file: every default
  } else {
    try {
      // (a key given twice: the parser keeps the last; said instead, as
      // the other configuration readers say it)
      std::vector<std::set<std::string>> keys;
      std::string twice;
      const Json::parser_callback_t check = [&](int, Json::parse_event_t event, Json& parsed) {
        if (event == Json::parse_event_t::object_start) keys.emplace_back();
        else if (event == Json::parse_event_t::object_end && !keys.empty()) keys.pop_back();
        else if (event == Json::parse_event_t::key && !keys.empty() && !keys.back().insert(parsed.get<std::string>()).second &&
                 twice.empty())
          twice = parsed.get<std::string>();
        return true;
      };
      j = Json::parse(f, check, true, /*ignore_comments=*/true);
      if (!twice.empty())
        throw std::runtime_error(path + ": key \"" + twice + "\" is given twice (only the last would count)");
    } catch (const Json::exception& e) {  // parse_error, and out_of_range for a number like 3e333
      // (the parser quotes the bytes it stopped at: a byte that is no
      // printable ASCII is written as \xNN, not put on the terminal)
      std::string words;
      for (const unsigned char c : std::string(e.what())) {
        char hex[8];
        std::snprintf(hex, sizeof hex, "\\x%02X", c);
        words += c >= 0x20 && c < 0x7F ? std::string(1, static_cast<char>(c)) : std::string(hex);
      }
      throw std::runtime_error(path + ": not valid JSON: " + words);
    }
  }
  try {
    RunConfig cfg = fromTree(j, yaml);
    cfg.file = path;
    return cfg;
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

std::vector<std::string> recordSplitFiles(const std::string& file, int keep) {
  std::vector<std::string> files;
  for (int i = 0; i < keep; ++i) files.push_back(file + "." + std::to_string(i));
  return files;
}

std::string recordSplitShift(const std::string& file, int keep) {
  const std::vector<std::string> files = recordSplitFiles(file, keep);
  std::error_code ec;
  std::filesystem::remove(files.back(), ec);
  if (ec) return "cannot remove " + files.back() + ": " + ec.message();
  for (size_t i = files.size() - 1; i-- > 0;) {
    if (!std::filesystem::exists(files[i], ec)) continue;
    std::filesystem::rename(files[i], files[i + 1], ec);
    if (ec) return "cannot rename " + files[i] + " to " + files[i + 1] + ": " + ec.message();
  }
  return "";
}

std::vector<ProcessSpec> buildProcessSpecs(const RunConfig& cfg, const std::string& url,
                                           const std::string& self_dir) {
  const BusChannels& ch = cfg.channels;
  std::vector<ProcessSpec> specs;
  const auto prog = [&](const std::string& name) { return resolveProgram(name, self_dir); };
  // An option ld-run passes itself, given again in the config's args: the
  // program refused it twice ("--in: At Most 1 required but received 2"),
  // which the user never typed twice, or (lcm-logplayer) took the last, and
  // replayed onto another bus. Options are compared by name ("--x=1" is --x),
  // a program's other name for one of them as that one (ld-qr-reader's
  // --codes is its --out).
  const auto checkArgs = [](const std::string& name, const std::vector<std::string>& argv,
                            const std::vector<std::string>& extra) {
    const auto optionName = [&name](const std::string& a) {
      const std::string option = a.substr(0, a.find('='));
      return name == "qr-reader" && option == "--codes" ? std::string("--out") : option;
    };
    for (const std::string& a : extra)
      for (size_t k = 1; k < argv.size(); ++k) {
        const std::string own = optionName(argv[k]);
        if (own.rfind("--", 0) != 0 || optionName(a) != own) continue;
        const std::string from = own == "--lcm-url"                          ? "lcm_url (or --lcm-url)"
                                 : own == "--speed"                          ? "source's speed (or --speed)"
                                 : own == "--regexp"                         ? "source's channels"
                                 : own == "--fps" || own == "--format" || own == "--duration"
                                     ? "source (fps, format, duration_s)"
                                     : "channels";
        const std::string given = a.substr(0, a.find('='));
        throw RepeatedOptionError(name + "'s args give " + given + (given == own ? "" : " (its " + own + ")") +
                                      ", which ld-run passes itself from the config's " + from + ": set it there",
                                  name, a);
      }
  };
  const auto add = [&](const std::string& name, ProcessRole role, std::vector<std::string> argv,
                       const std::vector<std::string>& extra) {
    checkArgs(name, argv, extra);
    argv.insert(argv.end(), extra.begin(), extra.end());
    specs.push_back({name, std::move(argv), role});
  };
  if (!cfg.record.empty()) {
    const std::string chans =
        cfg.record_channels.empty()
            ? quoteRegex(ch.landmarks) + "|" + quoteRegex(ch.tracked) + "|" + quoteRegex(ch.codes)
            : cfg.record_channels;
    // -a: a restarted recorder appends to what it wrote before (ld-run
    // removes the old file first). Split: FILE.0, FILE.1, ..., lcm-logger
    // shifting them as it splits; a restarted recorder appends to FILE.0,
    // and ld-run shifts the last run's along at its start.
    std::vector<std::string> argv{prog("lcm-logger"), "--lcm-url=" + url, "--channel=" + chans};
    if (cfg.record_split_mb > 0)
      argv.insert(argv.end(), {"--rotate=" + std::to_string(cfg.record_keep), "--split-mb=" + number(cfg.record_split_mb, 6)});
    else
      argv.emplace_back("-a");
    argv.insert(argv.end(), {"-q", asArgument(cfg.record)});
    add("recorder", ProcessRole::Recorder, std::move(argv), {});
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
                                  "--speed=" + number(cfg.speed),
                                  "--regexp=" + (cfg.replay_channels.empty()
                                                     ? "^" + quoteRegex(ch.image) + "$"
                                                     : cfg.replay_channels)};
    checkArgs("replay", argv, cfg.source_args);
    argv.insert(argv.end(), cfg.source_args.begin(), cfg.source_args.end());
    argv.push_back(asArgument(cfg.log));
    add("replay", ProcessRole::Source, argv, {});
  } else if (cfg.source == "play") {
    if (cfg.log.empty()) throw std::runtime_error("play: no log file given");
    std::vector<std::string> argv{prog("ld-play"), asArgument(cfg.log), "--lcm-url", url, "--channel", ch.image,
                                  "--fps", number(cfg.play_fps), "--format", cfg.play_format};
    if (cfg.play_duration_s > 0) {
      argv.push_back("--duration");
      argv.push_back(number(cfg.play_duration_s));
    }
    add("play", ProcessRole::Source, argv, cfg.source_args);
  } else if (cfg.source != "none") {
    throw std::runtime_error("unknown source \"" + cfg.source + "\"");
  }
  return specs;
}

}  // namespace ld
