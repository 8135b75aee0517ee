// Telling a worker that hangs (stopped, deadlocked) from the bus: ld-run's
// detector, tracker and QR reader each answer what they take in, their main
// thread taking each message from LCM, whose own thread reads the socket.
// One that publishes nothing while its inputs keep coming, and all that
// time is stopped (SIGSTOP, a debugger), or has not read its socket (the
// kernel's receive queue never emptied nor shrank: every thread stuck), or
// whose main thread has not run at all (blocked: a deadlock), is not
// working. (One spinning in a loop is not told from one working.) Silence alone is no hang: a
// detector dropping damaged JPEG frames, a tracker dropping repeated lists,
// a QR reader whose images and lists never join all read on and publish
// nothing. A process that dies is the supervisor's; one that hung was seen
// by no one (an operator's audit: a detector stopped for minutes left the
// robot blind, the state file saying it ran).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ld {

class HangWatch {
 public:
  /// A worker's process as it is now.
  struct Process {
    int starts = -1;        ///< times started (a restart begins its watch again); < 0: not running
    int64_t backlog = -1;   ///< bytes waiting in its socket's receive queue; < 0: not known
    bool stopped = false;   ///< stopped by a signal or a debugger (/proc state T or t); a hang
                            ///< only when seen so at every look for hang_s (strace stops a
                            ///< process at each call, for a moment)
    int64_t runtime_ns = -1;  ///< CPU time its main thread has had, ns; < 0: not known
  };
  /// What check() found about one worker.
  struct Event {
    std::string name;
    bool hung = true;       ///< false: it publishes again after a hang said
    double silent_s = 0;    ///< how long its output was silent
    std::string text;       ///< said as ld-run says it
  };
  /// Inputs whose count grew this recently count as still coming.
  static constexpr int64_t kFlowingUs = 2'000'000;
  /// At least this many messages on each input during the silence.
  static constexpr int64_t kMinInputs = 3;

  /// hang_s: the output's silence, while every input comes and the worker
  /// reads none of it (or is stopped), that is a hang (0: never one).
  explicit HangWatch(double hang_s) : hang_us_(static_cast<int64_t>(hang_s * 1e6)) {}

  /// A worker `name` that publishes on `output` for what comes on `inputs`.
  void add(const std::string& name, std::vector<std::string> inputs, const std::string& output);

  /// Looks at every worker at now_us (a steady clock, microseconds):
  /// `messages` gives a channel's count so far, `process` the worker's
  /// process. A hang is said once, and its end once.
  std::vector<Event> check(int64_t now_us, const std::function<int64_t(const std::string&)>& messages,
                           const std::function<Process(const std::string&)>& process);

 private:
  struct Worker {
    std::string name, output;
    std::vector<std::string> inputs;
    int starts = -1;
    bool answered = false;                ///< it published since its start
    int64_t since_us = 0;                 ///< its start or its last output
    int64_t inputs_from_us = 0;           ///< when every input had come since (0: not yet)
    int64_t read_us = 0;                  ///< when its backlog was last seen empty or shrinking
    int64_t backlog = -1;                 ///< at the last check
    int64_t ran_us = 0;                   ///< when its main thread was last seen to have run
    int64_t stopped_since_us = 0;         ///< stopped at every look since (0: not stopped)
    int64_t runtime_ns = -1;              ///< at the last check
    int64_t output_seen = 0;              ///< the output's count at since_us
    std::vector<int64_t> inputs_seen;     ///< the inputs' counts at since_us
    std::vector<int64_t> inputs_last;     ///< the inputs' counts at the last check
    std::vector<int64_t> inputs_grew_us;  ///< when each last grew
    bool said = false;                    ///< a hang said, not its end yet
  };
  int64_t hang_us_;
  std::vector<Worker> workers_;
};

}  // namespace ld
