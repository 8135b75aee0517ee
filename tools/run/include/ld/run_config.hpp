// ld-run's configuration: which processes to start, with which arguments.
// A JSON or YAML file (tools/run/ld-run.example.json, .yaml: the same keys)
// gives the defaults; the command line overrides them.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "ld/bus_monitor.hpp"
#include "ld/supervisor.hpp"

namespace ld {

struct WorkerConfig {
  bool enabled = true;
  std::string program;            ///< "ld-detector", ...; a bare name is looked up next to ld-run
  std::vector<std::string> args;  ///< extra arguments after the ones ld-run adds
};

struct RunConfig {
  std::string lcm_url;  ///< empty: the project default (ld::defaultLcmUrl)
  BusChannels channels;

  /// "camera" (ld-camera), "replay" (lcm-logplayer), "play" (ld-play: a
  /// log's images looped at a fixed rate with fresh utime and seq), "none".
  std::string source = "camera";
  std::vector<std::string> camera_args;  ///< for ld-camera
  std::string log;                       ///< for replay and play
  double speed = 1.0;                    ///< replay speed
  std::string replay_channels;           ///< replay only these (regex); default: the image channel
  double play_fps = 30;                  ///< play: frames per second
  double play_duration_s = 0;            ///< play: seconds (0: once through the log)
  std::string play_format = "keep";      ///< play: publish as logged or converted (bgr, yuyv, ...)
  std::vector<std::string> source_args;  ///< extra arguments of the replay / play program

  WorkerConfig detector{true, "ld-detector", {}};
  WorkerConfig tracker{true, "ld-tracker", {}};
  WorkerConfig qr_reader{true, "ld-qr-reader", {}};

  std::string record;  ///< lcm-logger output file ("" none)
  std::string file;    ///< the file load() read ("" for a tree given otherwise)
  std::string record_channels;  ///< default: LANDMARKS, LANDMARKS_TRACKED and LANDMARK_CODES
  /// > 0: the recording is split into files of about this many MB, FILE.0
  /// the newest, FILE.1 the one before, ..., at most record_keep of them
  /// (lcm-logger's --split-mb and --rotate): a robot's recording of days
  /// in bounded disk, and a run's start keeps the last run's (ld-run shifts
  /// them to FILE.1, ...: recordSplitShift) where one file is written anew.
  double record_split_mb = 0;
  int record_keep = 10;

  RestartPolicy restart;

  /// Reads a JSON config; unknown keys and wrong types are errors
  /// (std::runtime_error naming the key).
  static RunConfig fromJson(const nlohmann::json& j);
  /// A file: YAML when it ends in .yaml or .yml, else JSON (// comments
  /// allowed). A path with no extension that names no file is the one of
  /// PATH.yaml, PATH.yml, PATH.json that exists. YAML's plain true/false
  /// are booleans, null and ~ nothing, every other scalar text: numbers are
  /// read from decimal text where a number is expected, and args keep what
  /// was written (--fps, 30). Errors name the file and the key, or the line.
  static RunConfig load(const std::string& path);

 private:
  static RunConfig fromTree(const nlohmann::json& j, bool yaml);

 public:
};

/// The files of a split recording, FILE.0 to FILE.(keep - 1).
std::vector<std::string> recordSplitFiles(const std::string& file, int keep);
/// Shifts a split recording's files along, FILE.(keep - 2) to FILE.(keep - 1)
/// (the last one removed), ..., FILE.0 to FILE.1, so that a new run starts
/// FILE.0 afresh: lcm-logger 1.3.1 with --rotate appends to FILE.0 at its
/// start and shifts only when it splits, so short runs grew FILE.0 without
/// end. "" when done, else what failed.
std::string recordSplitShift(const std::string& file, int keep);

/// Throws std::runtime_error unless `format` is one ld-play's --format
/// takes: keep, or a pixel format it converts to (ld::pixelFormatFromName's).
void checkPlayFormat(const std::string& format);

/// A process's args giving an option that ld-run passes it itself.
struct RepeatedOptionError : std::runtime_error {
  RepeatedOptionError(const std::string& what, std::string process_, std::string given_)
      : std::runtime_error(what), process(std::move(process_)), given(std::move(given_)) {}
  std::string process;  ///< "detector", "camera", ...
  std::string given;    ///< the argument as given ("--out=X", "--out")
};

/// The processes to start, in order: recorder, workers, then the source.
/// `url` is the LCM URL every process gets; `self_dir` is where ld-run's
/// sibling programs are looked for. Throws RepeatedOptionError for a
/// process's args that give an option ld-run passes it.
std::vector<ProcessSpec> buildProcessSpecs(const RunConfig& cfg, const std::string& url,
                                           const std::string& self_dir);

}  // namespace ld
