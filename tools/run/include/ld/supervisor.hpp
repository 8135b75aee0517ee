// A small process supervisor: starts a set of programs, restarts the ones
// that die (with exponential backoff), collects their output line by line,
// and stops them in order. Used by ld-run; no LCM in here.
#pragma once

#include <chrono>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include <poll.h>
#include <sys/types.h>

namespace ld {

using SteadyClock = std::chrono::steady_clock;

/// What happens when a process ends by itself.
enum class ProcessRole {
  Worker,    ///< always restarted (ld-detector, ld-tracker, ld-qr-reader, ld-camera)
  Source,    ///< a replay: exit status 0 means "done", anything else is restarted
  Recorder,  ///< restarted like a worker; started first and stopped last (lcm-logger)
};

struct ProcessSpec {
  std::string name;               ///< short name in status lines and the summary ("detector")
  std::vector<std::string> argv;  ///< argv[0]: a path, or a name looked up on PATH
  ProcessRole role = ProcessRole::Worker;
};

/// Restart delays: initial_s, then doubled on each consecutive failure up to
/// max_s. A process that ran stable_after_s before dying starts over at
/// initial_s, so a one-off crash costs initial_s and a crash loop does not
/// spin.
struct RestartPolicy {
  double initial_s = 0.2;
  double max_s = 5.0;
  double stable_after_s = 10.0;
  /// A worker that publishes nothing for this long while its inputs keep
  /// coming is hung, and killed to be restarted (ld-run; 0: never).
  double hang_s = 10.0;
  /// A process that exits with status 2 (a usage error: a file or option it
  /// refuses) is not restarted, as it would fail the same way again; ld-run
  /// sets it (and ends the run).
  bool usage_error_is_final = false;
  /// A crash loop is told in full for its first `loop_shown` quick failures
  /// (deaths within stable_after_s of the start, or starts that failed);
  /// after that only every `loop_every`-th restart, with the output of that
  /// run, until a run lasts stable_after_s (its held lines then follow). A
  /// camera unplugged for a day printed about 17,000 restarts' lines.
  int loop_shown = 10;
  int loop_every = 100;
};

/// Delay before a restart after `consecutive_failures` (>= 1) quick deaths.
double restartDelay(const RestartPolicy& policy, int consecutive_failures);

/// "exit 0", "exit 3", "signal 9 (Killed)".
std::string describeWaitStatus(int status);

/// The program to run for `name`: a name with a '/' is used as is; a bare
/// name is found next to `self_dir` first (the installed or built ld-*
/// siblings), then on $PATH. Returns `name` unchanged when nothing matches.
std::string resolveProgram(const std::string& name, const std::string& self_dir);

/// The directory of the running executable (/proc/self/exe).
std::string selfDirectory();

struct ProcessState {
  ProcessSpec spec;
  pid_t pid = -1;                   ///< -1 when not running
  int starts = 0;                   ///< times started (restarts = starts - 1)
  int runs = 0;                     ///< of them, the starts that ran (not failed to start)
  int consecutive_failures = 0;
  bool done = false;                ///< a Source that finished (exit 0)
  bool failed_to_start = false;     ///< the last start failed (exec, pipe, fork)
  std::string last_exit;            ///< describeWaitStatus of the last end, "" if none
  bool failed = false;              ///< a Source that ended with a usage error (RestartPolicy)
  int hangs = 0;                    ///< times killed as hung (killHung)
  SteadyClock::time_point started{};
  SteadyClock::time_point restart_at{};  ///< when pid == -1 and not done: next start
  int out_fd = -1;                  ///< read end of the child's stdout+stderr
  std::string partial;              ///< output not yet ended by a newline
  // A crash loop's telling (RestartPolicy::loop_shown): quick failures in a
  // row that ended alike (the same exit, or the same reason a start failed).
  int alike_failures = 0;
  std::string failure_kind;         ///< how the last of them ended
  bool quiet = false;               ///< this run is one of a crash loop's not shown
  int not_shown = 0;                ///< quiet starts since the last one shown
  std::vector<std::string> held;    ///< a quiet run's first lines, shown if it lasts
  std::deque<std::string> held_tail;  ///< and its last ones
  long long held_dropped = 0;       ///< lines between the two not kept
};

class Supervisor {
 public:
  /// Receives each line a child writes (stdout and stderr merged), and the
  /// supervisor's own notes about it (start, exit, restart).
  using LineSink = std::function<void(const std::string& name, const std::string& line)>;

  /// `events`, when given, receives the supervisor's own notes instead of
  /// `sink` (ld-run shows them on its console even where the children's
  /// lines go to files: which process died was said only in its file).
  Supervisor(RestartPolicy policy, LineSink sink, LineSink events = nullptr);
  ~Supervisor();  ///< kills (SIGKILL) whatever still runs
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  /// Adds a process (not started yet); returns its index.
  size_t add(ProcessSpec spec);
  /// Starts process i now. False (and a note to the sink) when fork or exec
  /// fails; it is then retried like a process that died.
  bool start(size_t i);

  /// Reaps children that ended, restarts the ones due, reads their output.
  /// Call it every few tens of milliseconds.
  void poll(SteadyClock::time_point now);
  /// The output pipes, for the caller's poll(2).
  void appendPollFds(std::vector<pollfd>& fds) const;

  /// Sends SIGTERM in order (sources, then workers, then recorders), each
  /// group given up to `grace_s` before SIGKILL. True when every process
  /// ended by that signal or with exit status 0.
  bool stopAll(double grace_s);
  bool stopping() const { return stopping_; }

  const std::vector<ProcessState>& processes() const { return procs_; }
  /// SIGKILLs the running process `name`, found hung (ld::HangWatch), so
  /// that it is restarted as one that died; counted in its `hangs`. False
  /// when none of that name runs.
  bool killHung(const std::string& name);
  /// A Source exists and all sources are done.
  bool sourcesDone() const;
  /// A process that ended with a usage error and is not restarted, or nullptr.
  const ProcessState* failedProcess() const;
  /// Number of restarts so far, all processes.
  int restarts() const;

 private:
  void onExit(ProcessState& p, int status, SteadyClock::time_point now);
  void drainOutput(ProcessState& p, bool eof);
  bool stopGroup(ProcessRole role, double grace_s);

  void event(const ProcessState& p, const std::string& line) { (events_ ? events_ : sink_)(p.spec.name, line); }
  /// A child's line: to the sink, or held while its run is quiet.
  void childLine(ProcessState& p, const std::string& line);
  /// Shows a quiet run's held lines, after `why` where there are any (or
  /// always with `tell`), and ends its quiet (it lasted, or ended the loop
  /// otherwise).
  void endQuiet(ProcessState& p, const std::string& why, bool tell = false);
  /// At a start: decides whether the run is quiet; for a run shown after
  /// quiet ones, the number of them (and the count starts again), else 0.
  int beginRun(ProcessState& p);
  /// Counts a failure that ended as `kind`, quick or not; true where it
  /// ended otherwise than the loop of quick failures before it.
  bool countFailure(ProcessState& p, const std::string& kind, bool quick);
  /// " (N quick failures in a row; ...)": the restarts not shown before this
  /// one (`hidden`), and which the next one shown is; "" where nothing is.
  std::string loopNote(const ProcessState& p, int hidden) const;
  static constexpr size_t kHeldLines = 100;  ///< a quiet run's first lines kept to show, and as many last ones

  RestartPolicy policy_;
  LineSink sink_, events_;
  std::vector<ProcessState> procs_;
  bool stopping_ = false;
};

}  // namespace ld
