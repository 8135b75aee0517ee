// Telling a worker that hangs (stopped, deadlocked, spinning) from the bus:
// ld-run's processes each publish one message for each they take in (the
// detector a list per image, the tracker a list per list, the QR reader a
// codes message per image and tracked list of one frame), so one that
// publishes nothing for a while as its inputs keep coming is not working.
// A process that dies is the supervisor's; one that hangs was seen by no
// one (an operator's audit: a detector stopped for minutes left the robot
// blind, the state file saying it ran).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace ld {

class HangWatch {
 public:
  /// A channel's messages so far and when the last came (wall-clock
  /// microseconds; 0: none yet).
  struct Heard {
    int64_t messages = 0;
    int64_t last_us = 0;
  };
  /// What check() found about one worker.
  struct Event {
    std::string name;
    bool hung = true;       ///< false: it publishes again after a hang said
    double silent_s = 0;    ///< how long its output was silent
    std::string text;       ///< said as ld-run says it
  };
  /// Inputs that came this recently count as still coming.
  static constexpr int64_t kFlowingUs = 2'000'000;
  /// At least this many messages on each input during the silence.
  static constexpr int64_t kMinInputs = 3;

  /// hang_s: the output's silence, while every input comes, that is a hang
  /// (0: never one).
  explicit HangWatch(double hang_s) : hang_us_(static_cast<int64_t>(hang_s * 1e6)) {}

  /// A worker `name` that publishes on `output` for what comes on `inputs`.
  void add(const std::string& name, std::vector<std::string> inputs, const std::string& output);

  /// Looks at every worker at now_us: `heard` gives a channel's counts,
  /// `starts` how often the process has been started (a restart begins its
  /// watch again; < 0: it does not run now). A hang is said once, and its
  /// end once.
  std::vector<Event> check(int64_t now_us, const std::function<Heard(const std::string&)>& heard,
                           const std::function<int(const std::string&)>& starts);

 private:
  struct Worker {
    std::string name, output;
    std::vector<std::string> inputs;
    int starts = -1;
    int64_t since_us = 0;                 ///< its start or its last output
    int64_t inputs_from_us = 0;           ///< when every input had come since (0: not yet)
    int64_t output_seen = 0;              ///< the output's count then
    std::vector<int64_t> inputs_seen;     ///< the inputs' counts then
    bool said = false;                    ///< a hang said, not its end yet
  };
  int64_t hang_us_;
  std::vector<Worker> workers_;
};

}  // namespace ld
