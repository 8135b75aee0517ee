// ld-run: starts the process set (a camera or a replayed log, ld-detector,
// ld-tracker, ld-qr-reader), restarts whatever dies, prints a live status
// line measured on the bus, stops everything in order on Ctrl-C / SIGTERM,
// and writes a JSON summary at exit.
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>
#include <tuple>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>
#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ld/cli.hpp"
#include "ld/bus_monitor.hpp"
#include "ld/hang_watch.hpp"
#include "ld/file_checks.hpp"
#include "ld/lcm_log_reader.hpp"
#include "ld/lcm_url.hpp"
#include "ld/netns.hpp"
#include "ld/rss_series.hpp"
#include "ld/run_config.hpp"
#include "ld/supervisor.hpp"

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;
using Json = nlohmann::ordered_json;

std::atomic<bool> g_stop{false};
std::atomic<int> g_signal{0};
void onSignal(int s) {
  g_signal = s;
  g_stop = true;
}
// SIGUSR1: the --log-dir files are opened again (logrotate's rename, then
// a signal: SIGHUP stops the set, as a terminal's hangup does)
std::atomic<bool> g_reopen_logs{false};
void onReopenSignal(int) { g_reopen_logs = true; }

// A pause in a replayed log, at the replay's speed, that is said (microseconds).
constexpr double kLongReplayGapUs = 10e6;

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

int64_t wallMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

int64_t rssKb(int pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (f >> key) {
    if (key == "VmRSS:") {
      int64_t kb = 0;
      f >> kb;
      return kb;
    }
    f.ignore(1 << 12, '\n');
  }
  return -1;
}

// Child output and ld-run's own notes, on stderr or in per-process files,
// kept apart from the status line when stderr is a terminal.
class Console {
 public:
  Console(bool tty, bool quiet, std::string log_dir)
      : tty_(tty), quiet_(quiet), log_dir_(std::move(log_dir)) {}
  void line(const std::string& name, const std::string& text) {
    if (name != "ld-run" && toFile(name, text)) return;
    if (quiet_ && name != "ld-run") return;
    print(name, text);
  }
  /// ld-run's own note about a process (started, died, restarting,
  /// stopped): on stderr always, and in the process's file too with
  /// --log-dir (it went to the file alone: the console never said which
  /// process died, an operator's audit).
  void event(const std::string& name, const std::string& text) {
    toFile(name, "[ld-run] " + text);
    print(name, text);
  }
  void status(const std::string& text) {
    if (tty_) {
      std::fprintf(stderr, "\r\033[K%s", text.c_str());
      status_shown_ = true;
    } else {
      std::fprintf(stderr, "[status] %s\n", text.c_str());
    }
    std::fflush(stderr);
  }
  /// Closes the --log-dir files; each is opened again (created when it was
  /// moved away) at its next line, and one that could not be written is
  /// tried again.
  void reopenLogs() {
    files_.clear();
    unwritable_.clear();
  }
  /// Where a process's own lines went, for a message that points to them.
  std::string whereLinesOf(const std::string& name) const {
    if (!log_dir_.empty() && !unwritable_.count(name)) return "its error is in " + log_dir_ + "/" + name + ".log";
    if (quiet_) return "-q kept its error out: run without it";
    return "its error is above";
  }
  void clearStatus() {
    if (status_shown_) std::fprintf(stderr, "\r\033[K");
    status_shown_ = false;
  }

 private:
  void print(const std::string& name, const std::string& text) {
    clearStatus();
    std::fprintf(stderr, "[%s] %s\n", name.c_str(), text.c_str());
  }
  /// With --log-dir, the line into the process's file; false when not
  /// written there (no --log-dir, or the file cannot be written: a full
  /// disk, said once, and the lines from then on go where they would
  /// without --log-dir; they were lost without a word).
  bool toFile(const std::string& name, const std::string& text) {
    if (log_dir_.empty() || unwritable_.count(name)) return false;
    auto& f = files_[name];
    const std::string path = log_dir_ + "/" + name + ".log";
    errno = 0;
    if (!f.is_open()) f.open(path, std::ios::app);
    f << text << std::endl;
    if (f) return true;
    clearStatus();
    std::fprintf(stderr, "[ld-run] cannot write %s: %s; %s's lines from here go where they would without --log-dir\n",
                 path.c_str(), std::strerror(errno ? errno : EIO), name.c_str());
    unwritable_.insert(name);
    failed_ever_ = true;
    return false;
  }

 private:
  bool tty_, quiet_;
  bool status_shown_ = false;
  std::string log_dir_;
  std::map<std::string, std::ofstream> files_;
  std::set<std::string> unwritable_;  // processes whose log file could not be written (since SIGUSR1)
  bool failed_ever_ = false;           // some log file could not be written, in the whole run

 public:
  /// Whether some process's log file could not be written.
  bool logsFailed() const { return failed_ever_; }
};

// Writes `text` to `path` through a temporary file renamed when whole: ""
// when it did, else why (a full disk left a state or summary file empty or
// cut, without a word). The file as it was stays then.
std::string writeFileAtomically(const std::string& path, const std::string& text) {
  // (a short name of its own in the same folder: PATH.tmp was 4 bytes
  // longer than a name the length check had let through, and wrote over
  // a user's file of that name)
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  std::string tmp = (folder.empty() ? std::string(".") : folder.string()) + "/.ld-run-XXXXXX";
  const int fd = ::mkstemp(tmp.data());
  if (fd < 0) return std::strerror(errno);
  ::close(fd);
  errno = 0;
  std::ofstream f(tmp, std::ios::trunc);
  f << text;
  f.close();
  if (!f) {
    const std::string why = std::strerror(errno ? errno : EIO);
    std::remove(tmp.c_str());
    return why;
  }
  ::chmod(tmp.c_str(), 0644);  // (mkstemp makes it 0600: a summary others read)
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    return why;
  }
  return "";
}

// The CPU time process `pid`'s main thread has had (/proc's schedstat, ns);
// -1 when the kernel does not say.
int64_t mainThreadRuntimeNs(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/task/" + std::to_string(pid) + "/schedstat");
  int64_t ns = -1;
  if (!(f >> ns)) return -1;
  return ns;
}

// A process's state as /proc says it ("T (stopped)", "R (running)", ...);
// "" when it cannot be read.
std::string procState(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  std::getline(f, stat);
  const size_t paren = stat.rfind(')');
  if (paren == std::string::npos || paren + 2 >= stat.size()) return "";
  const char c = stat[paren + 2];
  const char* what = c == 'R' ? "running" : c == 'S' ? "sleeping" : c == 'D' ? "in uninterruptible wait"
                   : c == 'T' ? "stopped" : c == 't' ? "stopped by a debugger" : c == 'Z' ? "a zombie" : "?";
  return std::string(1, c) + " (" + what + ")";
}

Json processesJson(const ld::Supervisor& sup, const std::map<std::string, ld::RssSeries>* rss) {
  Json arr = Json::array();
  for (const auto& p : sup.processes()) {
    Json j{{"name", p.spec.name},
           {"argv", p.spec.argv},
           {"pid", p.pid},
           {"running", p.pid > 0},
           {"starts", p.starts},
           {"restarts", std::max(0, p.starts - 1)},
           {"hangs", p.hangs},
           {"done", p.done},
           {"last_exit", p.last_exit}};
    if (rss) {
      const auto it = rss->find(p.spec.name);
      if (it != rss->end()) {
        Json samples = Json::array();
        for (const auto& [t, kb] : it->second.samples)
          samples.push_back({std::round(t * 10) / 10, kb});
        j["rss_kb"] = {{"max", it->second.max_kb}, {"last", it->second.last_kb}, {"samples", samples}};
      }
    }
    arr.push_back(j);
  }
  return arr;
}

void printReport(const Json& s) {
  const Json& f = s["summary"]["frames"];
  const Json& lat = s["summary"]["latency_ms"];
  const Json& lpf = s["summary"]["landmarks_per_frame"];
  std::printf("run: %.1f s, %s\n", s["duration_s"].get<double>(), s["end"].get<std::string>().c_str());
  std::printf("frames: %lld images, %lld tracked (skipped: %lld by the detector, %lld by the tracker",
              f["images"].get<long long>(), f["tracked"].get<long long>(),
              f["detector_skipped"].get<long long>(), f["tracker_skipped"].get<long long>());
  if (!f["qr_reader_skipped"].is_null())
    std::printf(", %lld by the QR reader", f["qr_reader_skipped"].get<long long>());
  std::printf(")");
  // the images no tracked list came for, beyond those skipped (an operator's
  // audit: 292 of 921 images were accounted for nowhere in the report)
  const long long lost = f["unmatched_images"].get<long long>() - f["detector_skipped"].get<long long>() -
                         f["tracker_skipped"].get<long long>();
  if (lost > 0)
    std::printf("; %lld more never tracked (no tracked list came for them: a process stopped, restarting or "
                "left out, frames the detector could not decode, lost on the bus, or on their way at the end)",
                lost);
  std::printf("\n");
  if (lpf["histogram"].empty()) {  // (no tracked frame: a histogram of nothing read "frames by count:" and no more)
    std::printf("landmarks per frame: none (no frame was tracked)\n");
  } else {
    std::printf("landmarks per frame: mean %.2f, max %d; frames by count:", lpf["mean"].get<double>(),
                lpf["max"].get<int>());
    for (const auto& [n, c] : lpf["histogram"].items()) std::printf(" %s:%lld", n.c_str(), c.get<long long>());
    std::printf("\n");
  }
  if (lat["count"].get<long long>() > 0)
    std::printf("end-to-end latency IMAGE -> LANDMARKS_TRACKED (%lld frames): p50 %.2f ms, p90 %.2f ms, "
                "p99 %.2f ms, max %.2f ms\n",
                lat["count"].get<long long>(), lat["p50"].get<double>(), lat["p90"].get<double>(),
                lat["p99"].get<double>(), lat["max"].get<double>());
  else
    std::printf("end-to-end latency IMAGE -> LANDMARKS_TRACKED: none measured (no frame was tracked)\n");
  const long long tracks_left_out = s["summary"].value("tracks_left_out", 0LL);
  std::printf("tracks (%lld, %lld with a payload)%s:\n",
              static_cast<long long>(s["summary"]["tracks"].size()) + tracks_left_out,
              s["summary"]["payloads_decoded"].get<long long>(),
              tracks_left_out > 0 ? (", the " + std::to_string(s["summary"]["tracks"].size()) + " last seen").c_str() : "");
  // (a tracker that restarted numbered its tracks from 1 again: each run's apart)
  const long long tracker_restarts = s["summary"]["tracker_restarts"].get<long long>();
  if (tracker_restarts > 0)
    std::printf("  (the tracker started again %lld time%s: ids are per tracker run, \"id N/RUN\")\n",
                tracker_restarts, tracker_restarts == 1 ? "" : "s");
  for (const auto& t : s["summary"]["tracks"]) {
    std::printf("  id %-4s %-20s frames %lld-%lld, %lld visible, %lld coasting\n",
                (std::to_string(t["id"].get<long long>()) +
                 (tracker_restarts > 0 ? "/" + std::to_string(t["tracker_run"].get<int>()) : ""))
                    .c_str(),
                t["payload"].is_null() ? "(no payload)" : ("\"" + t["payload"].get<std::string>() + "\"").c_str(),
                t["first_seq"].get<long long>(), t["last_seq"].get<long long>(),
                t["frames_visible"].get<long long>(), t["frames_coasting"].get<long long>());
    // (an id that carried two landmarks' payloads: each, from its frame)
    if (t["payloads"].size() > 1) {
      std::printf("       payloads in turn:");
      for (const auto& p : t["payloads"])
        std::printf(" \"%s\" from frame %lld;", p["payload"].get<std::string>().c_str(),
                    p["from_seq"].get<long long>());
      std::printf(" one id for more than one landmark?\n");
    }
  }
  for (const auto& p : s["processes"]) {
    std::printf("process %-10s restarts %d, last exit: %s", p["name"].get<std::string>().c_str(),
                p["restarts"].get<int>(), p["last_exit"].get<std::string>().c_str());
    if (p.contains("rss_kb"))
      std::printf(", RSS max %.1f MiB", static_cast<double>(p["rss_kb"]["max"].get<int64_t>()) / 1024);
    std::printf("\n");
  }
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGUSR1, onReopenSignal);  // (from the start: its default ends the process)
  CLI::App app{
      "ld-run: starts the process set (source, ld-detector, ld-tracker, ld-qr-reader), restarts\n"
      "what dies, prints a live status line and writes a JSON summary (see README)."};
  std::string config_file, url, replay, play, source, summary_file, state_file, log_dir, record;
  std::vector<std::string> camera_args, detector_args, tracker_args, qr_reader_args, processes;
  double speed = 0, drain_s = 3, wait_ready_s = 10, status_interval = -1, grace_s = 3;
  double play_fps = 0, play_duration = 0;
  std::string play_format;
  bool exit_when_done = false, netns = false, report = false, quiet = false;
  app.add_option("-c,--config", config_file, "config file: JSON, or YAML when it ends in .yaml/.yml (see tools/run/ld-run.example.json, .yaml)");
  app.add_option("--lcm-url", url, "LCM URL of every process (default: the project's, ttl=0)");
  app.add_option("--source", source, "camera, replay, play or none (default: the config's, or camera)")
      ->check(CLI::IsMember({"camera", "replay", "play", "none"}));
  app.add_option("--replay", replay, "replay this LCM log with lcm-logplayer (implies --source replay)");
  app.add_option("--speed", speed, "replay speed factor (lcm-logplayer -s; 0.01 to 1000)")
      ->check(ld::cli::Between(0.01, 1000));
  app.add_option("--play", play,
                 "play this log's images back and forth with ld-play, fresh utime and seq (implies --source play)");
  app.add_option("--fps", play_fps, "--play: frames per second (0.001 to 1000)")->check(ld::cli::Between(0.001, 1000));
  app.add_option("--duration", play_duration, "--play: seconds to publish (default: the log once)")
      ->check(ld::cli::NonNegative);
  app.add_option("--play-format", play_format, "--play: keep, bgr, rgb, rgba, bgra, gray, yuyv, uyvy or mjpeg")
      ->check(ld::cli::Parses("FORMAT", ld::checkPlayFormat));
  app.add_option("--camera-arg", camera_args, "an argument for ld-camera (repeatable)")
      ->allow_extra_args(false);
  // (after the config's args of the process; an option given in both is
  // refused by the program, as any option given twice)
  app.add_option("--detector-arg", detector_args, "an argument for ld-detector (repeatable), after the config's")
      ->allow_extra_args(false);
  app.add_option("--tracker-arg", tracker_args, "an argument for ld-tracker (repeatable), after the config's")
      ->allow_extra_args(false);
  app.add_option("--qr-reader-arg", qr_reader_args, "an argument for ld-qr-reader (repeatable), after the config's")
      ->allow_extra_args(false);
  app.add_option("--processes", processes,
                 "which of detector, tracker, qr-reader to run (default: the config's, all); "
                 "'none' for only the source")
      ->delimiter(',');
  app.add_flag("--exit-when-replay-done", exit_when_done,
               "end the run when the replay (or play) has finished and the set has drained");
  app.add_option("--drain", drain_s, "seconds at most to wait for the last frames after the replay")
      ->capture_default_str()
      ->check(ld::cli::NonNegative);
  app.add_option("--record", record, "record the outputs with lcm-logger to this file");
  app.add_flag("--netns", netns,
               "run the whole set in a private network namespace (multicast on loopback only)");
  app.add_option("--summary", summary_file, "write a JSON summary here at exit");
  app.add_option("--state-file", state_file, "keep the process table (pids, restarts) in this JSON file");
  app.add_flag("--report", report, "print a readable summary on stdout at exit");
  app.add_option("--status-interval", status_interval,
                 "seconds between status lines (default 1 on a terminal, else 5; 0: none)")
      ->check(ld::cli::NonNegative);
  app.add_option("--log-dir", log_dir, "write each process's output to DIR/NAME.log instead of stderr");
  app.add_flag("-q,--quiet", quiet, "do not print the processes' output");
  app.add_option("--wait-ready", wait_ready_s,
                 "seconds at most to wait for the processes to subscribe before the source starts")
      ->capture_default_str()
      ->check(ld::cli::NonNegative);
  app.add_option("--stop-grace", grace_s, "seconds a process gets to stop before SIGKILL")
      ->capture_default_str()
      ->check(ld::cli::NonNegative);
  LD_CLI_PARSE(app, argc, argv);

  // Sources a child would refuse (and be restarted for, again and again).
  if (!replay.empty() && !play.empty()) {
    std::cerr << "ld-run: --replay and --play name two sources; give one\n";
    return 2;
  }
  if (!source.empty() && ((!replay.empty() && source != "replay") || (!play.empty() && source != "play"))) {
    std::cerr << "ld-run: --source " << source << " and " << (replay.empty() ? "--play" : "--replay")
              << " name two sources; give one\n";
    return 2;
  }
  ld::RunConfig cfg;
  try {
    if (!config_file.empty()) cfg = ld::RunConfig::load(config_file);
  } catch (const std::exception& e) {
    std::cerr << "ld-run: " << e.what() << "\n";
    return 2;
  }
  if (!url.empty()) cfg.lcm_url = url;
  if (!replay.empty()) {
    cfg.source = "replay";
    cfg.log = replay;
  }
  if (!play.empty()) {
    cfg.source = "play";
    cfg.log = play;
  }
  if (!source.empty()) cfg.source = source;
  if (app.count("--speed")) cfg.speed = speed;
  if (app.count("--fps")) cfg.play_fps = play_fps;
  if (app.count("--duration")) cfg.play_duration_s = play_duration;
  if (!play_format.empty()) cfg.play_format = play_format;
  // (the processes' args from the config alone: an error in them names the file)
  const std::map<std::string, std::vector<std::string>> config_args{{"camera", cfg.camera_args},
                                                                    {"detector", cfg.detector.args},
                                                                    {"tracker", cfg.tracker.args},
                                                                    {"qr-reader", cfg.qr_reader.args}};
  cfg.camera_args.insert(cfg.camera_args.end(), camera_args.begin(), camera_args.end());
  const std::tuple<const char*, const std::vector<std::string>*, ld::WorkerConfig*> worker_args[] = {
      {"--detector-arg", &detector_args, &cfg.detector},
      {"--tracker-arg", &tracker_args, &cfg.tracker},
      {"--qr-reader-arg", &qr_reader_args, &cfg.qr_reader}};
  for (const auto& [option, given, worker] : worker_args)
    worker->args.insert(worker->args.end(), given->begin(), given->end());
  if (!record.empty()) cfg.record = record;
  if (!processes.empty()) {
    cfg.detector.enabled = cfg.tracker.enabled = cfg.qr_reader.enabled = false;
    for (const auto& p : processes) {
      if (p == "detector") cfg.detector.enabled = true;
      else if (p == "tracker") cfg.tracker.enabled = true;
      else if (p == "qr-reader" || p == "qr_reader") cfg.qr_reader.enabled = true;
      else if (p != "none" && !p.empty()) {
        return ld::cli::usage(argv[0], "--processes: unknown process \"" + p +
                                           "\" (detector, tracker, qr-reader or none)");
      }
    }
  }
  // Options of another source than the run's: refused, not dropped without
  // a word (--fps with --replay: lcm-logplayer keeps the log's timing).
  {
    std::string stray;
    if (cfg.source != "play")
      for (const char* o : {"--fps", "--duration", "--play-format"})
        if (stray.empty() && app.count(o)) stray = std::string(o) + " is for --play (ld-play's source)";
    if (stray.empty() && cfg.source != "replay" && app.count("--speed"))
      stray = "--speed is for --replay (lcm-logplayer's source; --play takes --fps)";
    if (stray.empty() && cfg.source != "camera" && !camera_args.empty())
      stray = "--camera-arg is for the camera source";
    if (!stray.empty()) return ld::cli::usage(argv[0], stray + ", and this run's source is " + cfg.source);
  }
  for (const auto& [option, given, worker] : worker_args)
    if (!given->empty() && !worker->enabled)
      return ld::cli::usage(argv[0], std::string(option) + " is for " + worker->program +
                                         ", which this run does not start (--processes or the config)");
  if (exit_when_done && cfg.source != "replay" && cfg.source != "play")
    return ld::cli::usage(argv[0], "--exit-when-replay-done needs a replay or play source");

  // 1. The network namespace, before any thread exists: the caller's own
  // where it made one, else one of ld-run's.
  std::string netns_whose = ld::netnsVouchedFor() ? "the caller's" : "";  // (said in the running line)
  if (netns && netns_whose.empty() && ld::useThisPrivateNetns()) netns_whose = "the caller's";
  if (netns && netns_whose.empty()) {
    netns_whose = "ld-run's own";
    try {
      ld::enterPrivateNetns();
    } catch (const std::exception& e) {
      std::cerr << "ld-run: --netns: " << e.what() << "\n";
      return 2;
    }
  }
  if (cfg.lcm_url.empty()) cfg.lcm_url = ld::defaultLcmUrl();

  std::vector<ld::ProcessSpec> specs;
  try {
    specs = ld::buildProcessSpecs(cfg, cfg.lcm_url, ld::selfDirectory());
  } catch (const ld::RepeatedOptionError& e) {
    // (one of the config's args: the file named, as its other errors name
    // it; not one of --camera-arg's and the like)
    const auto it = config_args.find(e.process);
    const bool in_config = it != config_args.end() &&
                           std::find(it->second.begin(), it->second.end(), e.given) != it->second.end();
    std::cerr << "ld-run: " << (in_config && !cfg.file.empty() ? cfg.file + ": " : "") << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "ld-run: " << e.what() << "\n";
    return 2;
  }
  // What lcm-logplayer, ld-play or lcm-logger would fail on at once, and
  // be restarted for: refused here, in one line. A program that is not
  // there (a config's "program" mistyped) is the first such.
  for (const auto& spec : specs)
    if (spec.argv.empty() || spec.argv[0].empty() || ::access(spec.argv[0].c_str(), X_OK) != 0) {
      std::cerr << "ld-run: the " << spec.name << "'s program "
                << (spec.argv.empty() || spec.argv[0].empty() ? std::string("\"\"") : spec.argv[0])
                << " cannot be run (not in " << ld::selfDirectory() << " nor on PATH, or not executable)\n";
      return 2;
    }
  if (!cfg.log.empty() && (cfg.source == "replay" || cfg.source == "play")) {
    const ld::LcmLogCheck log = ld::checkLcmLogStart(cfg.log);
    if (log.start == ld::LcmLogStart::Unreadable) {
      std::cerr << "ld-run: cannot read log " << cfg.log << ": " << log.error << "\n";
      return 2;
    }
    if (log.start != ld::LcmLogStart::Events) {
      std::cerr << "ld-run: " << cfg.source << " log " << cfg.log << " " << log.problem << "\n";
      return 2;
    }
  }
  // A replayed log's images, counted (the summary says how many came), and
  // its damage said: lcm-logplayer stops at damaged bytes without a word
  // ld-run would see.
  // Its longest pause too: lcm-logplayer keeps the log's timing, so two
  // sessions in one log (lcm-logger -a appends) replay with the time between
  // them, silent.
  int64_t log_images = -1;
  ld::ChannelCounts log_channels;  // (the replay's)
  std::string log_damage, log_gap;
  if (cfg.source == "replay") {
    ld::LcmLogReader reader(cfg.log);
    log_images = 0;
    int64_t previous = 0, gap = 0, gap_after = 0;
    while (reader.next(false)) {  // (headers alone)
      log_images += reader.channel == cfg.channels.image;
      ++log_channels[reader.channel];
      if (reader.messages() > 1 && reader.timestamp - previous > gap) {
        gap = reader.timestamp - previous;
        gap_after = reader.messages() - 1;
      }
      previous = reader.timestamp;
    }
    log_damage = reader.problem();
    // Nothing the replay plays (by default the image channel alone): a log
    // without images, ld-run's own recording of the outputs, say, was
    // replayed for the whole of its length before the run said so. (The
    // config's source.channels plays other channels too, its lists to the
    // tracker alone, say: checked against that, as lcm-logplayer reads it.)
    int64_t played = log_images;
    if (!cfg.replay_channels.empty()) {
      played = 0;
      for (const auto& [name, n] : log_channels) played += ld::channelPatternTakes(cfg.replay_channels, name) ? n : 0;
    }
    if (played == 0) {
      const std::string channels = ld::describeChannels(log_channels);
      std::cerr << "ld-run: replay log " << cfg.log << " holds no message "
                << (cfg.replay_channels.empty() ? "on " + cfg.channels.image
                                                : "on a channel source.channels " + cfg.replay_channels + " plays")
                << (channels.empty() ? "" : " (its channels: " + channels + ")")
                << (log_damage.empty() ? "" : "; " + log_damage)
                << (cfg.replay_channels.empty()
                        ? ": nothing for the set to work on; replay the log the images are in (a recording of the "
                          "set's outputs holds none unless record.channels takes them), or name their channel "
                          "with the config's channels.image\n"
                        : ": nothing to replay\n");
      return 2;
    }
    if (gap / cfg.speed > kLongReplayGapUs) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "%.1f s without a message after its message %lld (two sessions in one log, as lcm-logger -a "
                    "appends?): lcm-logplayer waits %.1f s there at speed %g (--play plays the images without "
                    "the wait)",
                    static_cast<double>(gap) / 1e6, static_cast<long long>(gap_after),
                    static_cast<double>(gap) / 1e6 / cfg.speed, cfg.speed);
      log_gap = buf;
    }
  }
  using OutputFile = std::pair<const char*, std::string>;
  // (the recording's files: one, or a split recording's FILE.0 to
  // FILE.(keep - 1), which rotation renames and removes)
  const std::vector<std::string> recording_files =
      cfg.record.empty() ? std::vector<std::string>{}
      : cfg.record_split_mb > 0 ? ld::recordSplitFiles(cfg.record, cfg.record_keep)
                                : std::vector<std::string>{cfg.record};
  // No file ld-run writes is the log it plays or its config, nor another file
  // it writes (a recording over the log emptied it before it was played; a
  // summary over it, or over the recording, or over the config replaced it).
  {
    const bool plays = cfg.source == "replay" || cfg.source == "play";
    std::vector<OutputFile> files{{"log", plays ? cfg.log : ""}, {"config", cfg.file}};
    for (const std::string& f : recording_files) files.emplace_back("recording", f);
    files.emplace_back("summary", summary_file);
    files.emplace_back("state file", state_file);
    for (size_t i = 0; i < files.size(); ++i)
      for (size_t j = std::max<size_t>(i + 1, 2); j < files.size(); ++j)  // (the log and the config are read)
        if (!files[i].second.empty() && !files[j].second.empty() && ld::sameFile(files[i].second, files[j].second)) {
          std::cerr << "ld-run: the " << files[j].first << " " << files[j].second << " is the " << files[i].first
                    << ": it would be written over\n";
          return 2;
        }
  }
  // (missing folders created; a recording is written over an LCM log alone,
  // the summary and the state file over JSON alone: not over an image or a
  // config named by mistake)
  std::vector<OutputFile> outputs;
  for (const std::string& f : recording_files) outputs.emplace_back("recording", f);
  outputs.emplace_back("summary", summary_file);
  outputs.emplace_back("state file", state_file);
  for (const auto& [what, path] : outputs) {
    if (path.empty()) continue;
    const std::string problem =
        std::string(what) == "recording" ? ld::prepareLogOutputFile(path) : ld::prepareJsonOutputFile(path);
    if (!problem.empty()) {
      std::cerr << "ld-run: " << what << " " << path << ": " << problem << "\n";
      return 2;
    }
  }

  if (!log_dir.empty()) {  // the processes' NAME.log files go there
    const std::string problem = ld::prepareOutputFolder(log_dir);
    if (!problem.empty()) {
      std::cerr << "ld-run: --log-dir " << log_dir << ": " << problem << "\n";
      return 2;
    }
  }
  const bool tty = ::isatty(STDERR_FILENO);
  if (status_interval < 0) status_interval = tty ? 1 : 5;
  Console console(tty, quiet, log_dir);
  const auto note = [&](const std::string& text) { console.line("ld-run", text); };
  // (said first: the replay will sit through it)
  if (!log_gap.empty()) note("warning: replay log " + cfg.log + ": " + log_gap);

  // 2. The monitor subscribes before anything publishes.
  // (udpm:// alone: the set starts once each process has its socket on the
  // udpm port; memq:// is each process's own, so the set would never hear
  // each other, tcpq:// needs a server, file:// is a log)
  const size_t sep = cfg.lcm_url.find("://");
  if (std::string problem = ld::lcmUrlProblem(cfg.lcm_url);
      !problem.empty() || (sep != std::string::npos && cfg.lcm_url.compare(0, sep, "udpm") != 0)) {
    if (problem.empty())
      problem = cfg.lcm_url + ": ld-run runs its set over udpm:// multicast only (" +
                (cfg.lcm_url.compare(0, sep, "memq") == 0 ? "memq is within one process, the set is several"
                                                          : "it waits for each process's socket on the udpm port") +
                ")";
    std::cerr << "ld-run: LCM URL " << problem << "\n";
    return 2;
  }
  lcm::LCM lcm(cfg.lcm_url);
  if (const int status = ld::lcmOpenStatus(lcm, cfg.lcm_url, "ld-run")) return status;
  ld::BusMonitor monitor(cfg.channels);
  // (lcm-logplayer publishes the logged utimes: not capture times, however recent)
  monitor.setUtimesLogged(cfg.source == "replay");
  monitor.subscribe(lcm);

  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::signal(SIGHUP, onSignal);
  std::signal(SIGPIPE, SIG_IGN);

  cfg.restart.usage_error_is_final = true;  // (as the systemd units' RestartPreventExitStatus=2)
  ld::Supervisor sup(
      cfg.restart, [&](const std::string& n, const std::string& l) { console.line(n, l); },
      [&](const std::string& n, const std::string& l) { console.event(n, l); });
  // a worker that publishes nothing while its inputs come is hung: killed,
  // to be restarted (one that was never watched stayed so for ever)
  ld::HangWatch hangs(cfg.restart.hang_s);
  const ld::BusChannels& bch = cfg.channels;
  // (the project's own programs take their messages in the main thread,
  // which wakes every 200 ms at least: one that does not run is blocked;
  // another program may not)
  std::set<std::string> main_thread_judged;
  for (const auto& s : specs) {
    if (s.name == "detector") hangs.add(s.name, {bch.image}, bch.landmarks);
    if (s.name == "tracker") hangs.add(s.name, {bch.landmarks}, bch.tracked);
    if (s.name == "qr-reader") hangs.add(s.name, {bch.image, bch.tracked}, bch.codes);
    const std::string prog = fs::path(s.argv.at(0)).filename().string();
    if (prog == "ld-detector" || prog == "ld-tracker" || prog == "ld-qr-reader") main_thread_judged.insert(s.name);
  }
  const int lcm_port = ld::lcmUdpPort(cfg.lcm_url);
  auto next_hang_check = Clock::now();
  std::vector<size_t> early, late;  // late: the image source, started once the rest listens
  for (auto& s : specs) {
    const bool is_source = s.role == ld::ProcessRole::Source || s.name == "camera";
    (is_source ? late : early).push_back(sup.add(std::move(s)));
  }
  // (one file: written anew; split, the last run's files shifted to FILE.1,
  // ..., record.keep of them kept)
  if (!cfg.record.empty() && cfg.record_split_mb == 0) std::remove(cfg.record.c_str());
  if (!cfg.record.empty() && cfg.record_split_mb > 0) {
    if (const std::string why = ld::recordSplitShift(cfg.record, cfg.record_keep); !why.empty()) {
      std::cerr << "ld-run: recording " << cfg.record << ": " << why << "\n";
      return 2;
    }
  }
  const auto t0 = Clock::now();
  std::map<std::string, ld::RssSeries> rss;
  int64_t self_rss_max_kb = 0;  // ld-run's own (it receives every image too)
  bool ready = false;
  std::string end_reason = "stopped by signal";
  bool state_failed = false;  // (said once)
  const auto writeState = [&]() {
    if (state_file.empty()) return;
    Json j{{"pid", ::getpid()}, {"ready", ready}, {"restarts", sup.restarts()},
           {"processes", processesJson(sup, nullptr)}};
    if (const std::string why = writeFileAtomically(state_file, j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n");
        !why.empty() && !state_failed) {
      note("cannot write the state file " + state_file + ": " + why + " (it stays as it was)");
      state_failed = true;
    }
  };

  // 3. Start the recorder and the workers and wait until each listens: its
  //    socket is bound to the LCM port and its LCM self test is over (LCM
  //    drops everything else that arrives during the test, which it repeats
  //    every 100 ms until its own message comes back). Then start the
  //    source, so that no frame is lost.
  const int64_t self_tests_before = monitor.selfTests();
  for (size_t i : early) sup.start(i);
  const int port = ld::lcmUdpPort(cfg.lcm_url);
  const auto ready_deadline = Clock::now() + std::chrono::milliseconds(static_cast<int64_t>(wait_ready_s * 1000));
  while (!g_stop && port > 0 && !early.empty()) {
    lcm.handleTimeout(20);
    sup.poll(Clock::now());
    bool all = true;
    for (size_t i : early) {
      const auto& p = sup.processes()[i];
      if (p.pid <= 0 || !ld::hasUdpSocketOnPort(p.pid, port)) all = false;
    }
    if (all && monitor.selfTests() - self_tests_before >= static_cast<int64_t>(early.size()) &&
        wallMicros() - monitor.lastSelfTest() > 150'000)
      break;
    if (sup.failedProcess()) break;  // (said below: no use waiting for it)
    if (Clock::now() > ready_deadline) {
      // (naming those that do not: the self test is the set's, so those
      // without a socket on the port are named, or all when each has one)
      std::string silent;
      for (size_t i : early) {
        const auto& p = sup.processes()[i];
        if (p.pid <= 0 || !ld::hasUdpSocketOnPort(p.pid, port))
          silent += (silent.empty() ? "" : ", ") + p.spec.name +
                    (p.pid <= 0 ? " (not running" + (p.last_exit.empty() ? "" : ": " + p.last_exit) + ")" : "");
      }
      note("not every process listens after " + std::to_string(wait_ready_s).substr(0, 4) + " s (" +
           (silent.empty() ? "LCM's self test not over" : silent) + "); starting the source anyway");
      break;
    }
  }
  if (!g_stop && !sup.failedProcess()) {
    for (size_t i : late) sup.start(i);
    ready = true;
  }
  writeState();
  if (!log_damage.empty())
    note("warning: replay log " + cfg.log + ": " + log_damage +
         "; lcm-logplayer stops at the damage (--play reads past it)");
  {
    std::string names;
    for (const auto& p : sup.processes()) names += " " + p.spec.name;
    // (whose namespace: a program of the caller's hears the set only in the
    // caller's own)
    note("running" + names + " on " + cfg.lcm_url +
         (ld::inPrivateNetns() ? " (private network namespace" + (netns_whose.empty() ? "" : ", " + netns_whose) + ")"
                               : ""));
  }

  // 4. The loop: bus messages, child output and deaths, status, RSS.
  monitor.statusLine(wallMicros());  // starts the first status window
  auto next_status = Clock::now() + std::chrono::milliseconds(static_cast<int64_t>(status_interval * 1000));
  auto next_rss = Clock::now();
  Clock::time_point done_at{};
  int64_t tracked_at_done = -1, codes_at_done = -1;
  Clock::time_point last_tracked_change{};
  std::vector<std::pair<pid_t, int>> last_pids;
  int exit_code = 0;
  std::vector<pollfd> fds;
  while (!g_stop) {
    if (g_reopen_logs.exchange(false)) console.reopenLogs();
    fds.clear();
    fds.push_back({lcm.getFileno(), POLLIN, 0});
    sup.appendPollFds(fds);
    const int r = ::poll(fds.data(), fds.size(), 50);
    if (r < 0 && errno != EINTR) {
      note(std::string("poll failed: ") + std::strerror(errno));
      exit_code = 1;
      break;
    }
    if (r > 0 && (fds[0].revents & POLLIN)) {
      // (for kMaxDrainMs at most, as the processes drain theirs: under a
      // flood the supervisor and the children's output are served too)
      const auto until = Clock::now() + std::chrono::milliseconds(ld::kMaxDrainMs);
      while (Clock::now() < until && lcm.handleTimeout(0) > 0) {
      }
    }
    const auto now = Clock::now();
    sup.poll(now);
    if (now >= next_hang_check) {
      std::map<std::string, std::string> states;  // (each worker's /proc state at this look, said with a hang)
      const auto events = hangs.check(
          std::chrono::duration_cast<std::chrono::microseconds>(now.time_since_epoch()).count(),
          [&](const std::string& ch) { return monitor.messages(ch); },
          [&](const std::string& name) {
            ld::HangWatch::Process hp;
            for (const auto& p : sup.processes())
              if (p.spec.name == name && p.pid > 0) {
                hp.starts = p.starts;
                hp.backlog = lcm_port > 0 ? ld::udpBacklogOnPort(p.pid, lcm_port) : -1;
                if (main_thread_judged.count(name)) hp.runtime_ns = mainThreadRuntimeNs(p.pid);
                const std::string& state = states[name] = procState(p.pid);
                hp.stopped = !state.empty() && (state[0] == 'T' || state[0] == 't');
              }
            return hp;
          });
      for (const auto& e : events) {
        if (!e.hung) {
          console.event(e.name, e.text);
          continue;
        }
        const std::string& state = states[e.name];
        console.event(e.name, e.text + (state.empty() ? "" : "; it is " + state) + ": hung, killed to be restarted");
        sup.killHung(e.name);
      }
      next_hang_check = now + std::chrono::milliseconds(250);
    }

    std::vector<std::pair<pid_t, int>> pids;
    for (const auto& p : sup.processes()) pids.emplace_back(p.pid, p.starts);
    if (pids != last_pids) {
      writeState();
      last_pids = pids;
    }
    if (now >= next_rss) {
      for (const auto& p : sup.processes()) {
        if (p.pid <= 0) continue;
        const int64_t kb = rssKb(p.pid);
        if (kb < 0) continue;
        rss[p.spec.name].add(seconds(now - t0), kb);
      }
      self_rss_max_kb = std::max(self_rss_max_kb, rssKb(::getpid()));
      next_rss = now + std::chrono::seconds(1);
    }
    if (status_interval > 0 && now >= next_status) {
      console.status(monitor.statusLine(wallMicros()) + " | restarts " + std::to_string(sup.restarts()));
      next_status = now + std::chrono::milliseconds(static_cast<int64_t>(status_interval * 1000));
    }
    // A set that cannot run (a process exits 2: an argument or an input a
    // restart will not mend, such as a log without images for the source, or
    // an option a worker refuses) ends the run, live or replaying, instead of
    // restarting that process again and again; status 2, as for a
    // configuration ld-run refuses itself (ld-run@.service does not restart
    // it then).
    if (const ld::ProcessState* failed = sup.failedProcess()) {
      end_reason = std::string(failed->spec.role == ld::ProcessRole::Source ? "the source " : "") +
                   failed->spec.name + " failed (exit 2; " + console.whereLinesOf(failed->spec.name) + ")";
      exit_code = 2;
      break;
    }
    if (exit_when_done && sup.sourcesDone()) {
      // Drain: wait until no tracked frame and no codes came for 0.5 s (or
      // --drain passed). (The tracked lists alone: the QR reader, behind
      // on 1080p frames, was stopped with frames it neither read nor counted.)
      if (done_at == Clock::time_point{}) {
        done_at = last_tracked_change = now;
        tracked_at_done = monitor.trackedFrames();
        codes_at_done = monitor.codesMessages();
      }
      if (monitor.trackedFrames() != tracked_at_done || monitor.codesMessages() != codes_at_done) {
        tracked_at_done = monitor.trackedFrames();
        codes_at_done = monitor.codesMessages();
        last_tracked_change = now;
      }
      if (now - last_tracked_change > std::chrono::milliseconds(500) ||
          seconds(now - done_at) > drain_s) {
        end_reason = "replay done";
        // (a log whose images are on another channel replays "fine" and
        // feeds the set nothing)
        // (or came as no image at all: another project's type on the channel)
        if (monitor.imageFrames() == 0 && monitor.badImages() > 0) {
          end_reason += ", but none of the " + std::to_string(monitor.badImages()) + " messages on " +
                        cfg.channels.image + " is an image (another project's type, or malformed: the detector's "
                        "lines say why)";
          exit_code = 1;
        } else if (monitor.imageFrames() == 0) {
          // (a replayed log without images is refused at the start)
          end_reason += ", but no image came on " + cfg.channels.image +
                        " (are the source's images on another channel? the config's channels.image names it)";
          exit_code = 1;
        }
        break;
      }
    }
  }
  if (g_signal) end_reason = std::string("stopped by ") + (g_signal == SIGINT ? "SIGINT" : g_signal == SIGTERM ? "SIGTERM" : "SIGHUP");
  console.clearStatus();

  // 5. Stop in order: source, workers, recorder.
  note(end_reason + "; stopping");
  // A process that had died and waited to be started again was not running
  // at the end of a run that ended by itself (a replay done, --duration):
  // the run did not do its work (a replay's status was 0 with a detector
  // that never ran). Not when stopped by a signal: a live set stopped while
  // its camera waits to be plugged in again stopped as it should.
  for (const auto& p : sup.processes())
    if (p.spec.role == ld::ProcessRole::Recorder && p.runs > 1) {
      // (a recorder that died lost what came while it was down, though its
      // restarts append to the log: a full disk killed it again and again,
      // and the run ended with 0)
      note("warning: the recording " + cfg.record + (cfg.record_split_mb > 0 ? ".0, ..." : "") +
           " is incomplete: its recorder died and was restarted " +
           std::to_string(p.runs - 1) + " time" + (p.runs == 2 ? "" : "s") +
           (p.last_exit.empty() ? "" : " (its last end: " + p.last_exit + ")") + "; what came meanwhile is not in it");
      exit_code = std::max(exit_code, 1);
    }
  for (const auto& p : sup.processes())
    if (p.runs == 0 && p.starts > 0) {
      // (one that never ran at all, signal or not: out of descriptors, say;
      // the run waited for it and ended with 0 when stopped)
      note(p.spec.name + " never ran: its " + std::to_string(p.starts) + " start" + (p.starts == 1 ? "" : "s") +
           " failed (the last: " + p.last_exit + ")");
      exit_code = std::max(exit_code, 1);
    } else if (!g_signal && p.starts > 0 && p.pid <= 0 && !p.done && !p.failed) {
      note(p.spec.name + " was not running at the end: it was waiting to be started again (started " +
           std::to_string(p.starts) + " time" + (p.starts == 1 ? "" : "s") +
           (p.last_exit.empty() ? "" : "; its last end: " + p.last_exit) + ")");
      exit_code = std::max(exit_code, 1);
    }
  // Whatever is still on the bus for the monitor.
  while (lcm.handleTimeout(0) > 0) {
  }
  if (!sup.stopAll(grace_s)) {
    note("not every process stopped cleanly");
    exit_code = std::max(exit_code, 1);
  }
  writeState();

  Json s{{"duration_s", std::round(seconds(Clock::now() - t0) * 1000) / 1000},
         {"end", end_reason},
         {"lcm_url", cfg.lcm_url},
         {"netns", ld::inPrivateNetns()},
         {"rmem_max", ld::rmemMax()},
         {"source", cfg.source},
         {"log", cfg.log},
         {"log_images", log_images >= 0 ? Json(log_images) : Json(nullptr)},
         {"processes", processesJson(sup, &rss)},
         {"ld_run_rss_kb_max", self_rss_max_kb},
         {"summary", monitor.summary()}};
  if (!summary_file.empty()) {
    // (payloads are what the codes held: bytes that are not UTF-8, as
    // printed, are written as U+FFFD, as ld-detect writes them)
    // (through a temporary file: a full disk left a cut summary, and said no why)
    if (const std::string why =
            writeFileAtomically(summary_file, s.dump(2, ' ', false, Json::error_handler_t::replace) + "\n");
        !why.empty()) {
      std::cerr << "ld-run: cannot write " << summary_file << ": " << why << "\n";
      exit_code = std::max(exit_code, 1);
    }
  }
  if (report) printReport(s);
  const Json& f = s["summary"]["frames"];
  const Json& lat = s["summary"]["latency_ms"];
  // (images of a whole replay that never came: lost on the bus, as large
  // images are with a small receive buffer)
  // (messages that came and are no image_t are not lost: the processes said
  // what was wrong with each)
  // (the set's outputs twice: a recording holding them played onto the set)
  if (const int64_t repeated = f["repeated_messages"].get<int64_t>(); repeated > 0)
    note("warning: " + std::to_string(repeated) + " landmark list" + (repeated == 1 ? "" : "s") +
         " and codes messages came again for frames already seen (a recording holding the set's outputs "
         "played onto it, or a second tracker?): each frame is counted once");
  const int64_t bad_images = f["bad_images"].get<int64_t>();
  if (log_images > 0 && end_reason == "replay done" && bad_images > 0)
    note("warning: " + std::to_string(bad_images) + " of the log's " + std::to_string(log_images) +
         " messages on " + cfg.channels.image + " are not images (malformed: the detector's lines say why)");
  if (log_images > 0 && end_reason == "replay done" && f["images"].get<int64_t>() + bad_images < log_images)
    note("warning: " + std::to_string(log_images - f["images"].get<int64_t>() - bad_images) + " of the log's " +
         std::to_string(log_images) + " images on " + cfg.channels.image +
         (log_damage.empty() ? " never came (lost on the bus: README, \"LCM URL and large images\")"
                             : " never came (lcm-logplayer stopped at the log's damage: --play reads past it)"));
  // (a state file or a process's log that could not be written: said when
  // it happened, and the run's status says it too)
  if (state_failed || console.logsFailed()) exit_code = std::max(exit_code, 1);
  char e2e[64] = "e2e -";  // (nothing tracked, nothing timed: not 0.00 ms)
  if (lat["count"].get<long long>() > 0)
    std::snprintf(e2e, sizeof e2e, "e2e p50 %.2f ms p99 %.2f ms", lat["p50"].get<double>(), lat["p99"].get<double>());
  char buf[256];
  std::snprintf(buf, sizeof buf, "%lld images, %lld tracked, %s, %d restarts; exit %d",
                f["images"].get<long long>(), f["tracked"].get<long long>(), e2e, sup.restarts(), exit_code);
  note(buf);
  return exit_code;
}
