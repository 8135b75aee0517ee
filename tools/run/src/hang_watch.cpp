#include "ld/hang_watch.hpp"

#include <algorithm>
#include <cstdio>

namespace ld {

void HangWatch::add(const std::string& name, std::vector<std::string> inputs, const std::string& output) {
  Worker w;
  w.name = name;
  w.output = output;
  w.inputs = std::move(inputs);
  w.inputs_seen.assign(w.inputs.size(), 0);
  w.inputs_last.assign(w.inputs.size(), 0);
  w.inputs_grew_us.assign(w.inputs.size(), 0);
  workers_.push_back(std::move(w));
}

namespace {
std::string seconds(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f s", s);
  return buf;
}
}  // namespace

std::vector<HangWatch::Event> HangWatch::check(int64_t now_us,
                                               const std::function<int64_t(const std::string&)>& messages,
                                               const std::function<Process(const std::string&)>& process) {
  std::vector<Event> events;
  if (hang_us_ <= 0) return events;
  for (Worker& w : workers_) {
    const int64_t out = messages(w.output);
    const Process p = process(w.name);
    if (!p.stopped) w.stopped_since_us = 0;
    else if (w.stopped_since_us == 0) w.stopped_since_us = now_us;
    const bool stopped = w.stopped_since_us > 0 && now_us - w.stopped_since_us >= hang_us_;
    bool all_grew_recently = !w.inputs.empty();
    for (size_t i = 0; i < w.inputs.size(); ++i) {
      const int64_t n = messages(w.inputs[i]);
      if (n > w.inputs_last[i]) w.inputs_grew_us[i] = now_us;
      w.inputs_last[i] = n;
      all_grew_recently = all_grew_recently && w.inputs_grew_us[i] > 0 && now_us - w.inputs_grew_us[i] <= kFlowingUs;
    }
    // its watch begins again here: (re)started, published, or an input
    // that paused (a worker idle while its input paused, a camera
    // unplugged, is not slow to answer)
    const auto mark = [&] {
      w.since_us = now_us;
      w.inputs_from_us = 0;
      w.output_seen = out;
      w.inputs_seen = w.inputs_last;
    };
    if (p.starts < 0) {  // (not running: the supervisor's)
      w.starts = -1;
      w.said = false;
      continue;
    }
    if (p.starts != w.starts) {
      w.starts = p.starts;
      w.said = false;  // (a restart ends the hang: the supervisor says it)
      w.answered = false;
      mark();
      continue;
    }
    if (out > w.output_seen) {
      if (w.said)
        events.push_back({w.name, false, static_cast<double>(now_us - w.since_us) * 1e-6,
                          "publishes on " + w.output + " again, after " +
                              seconds(static_cast<double>(now_us - w.since_us) * 1e-6) + " without"});
      w.said = false;
      w.answered = true;
      mark();
      continue;
    }
    if (!all_grew_recently) {
      mark();
      continue;
    }
    bool all_came = true;
    std::string came;
    for (size_t i = 0; i < w.inputs.size(); ++i) {
      const int64_t n = w.inputs_last[i] - w.inputs_seen[i];
      all_came = all_came && n >= kMinInputs;
      came += (i ? ", " : "") + std::to_string(n) + " on " + w.inputs[i];
    }
    if (w.inputs_from_us == 0) {  // (the silence counts from when they came)
      w.inputs_from_us = now_us;
      w.read_us = w.ran_us = now_us;
      w.backlog = p.backlog;
      w.runtime_ns = p.runtime_ns;
    }
    // reading: its socket's queue empty, or smaller than at the last look;
    // running: its main thread's CPU time grown since the last look
    if (p.backlog < 0 || p.backlog == 0 || (w.backlog >= 0 && p.backlog < w.backlog)) w.read_us = now_us;
    if (p.runtime_ns < 0 || w.runtime_ns < 0 || p.runtime_ns != w.runtime_ns) w.ran_us = now_us;
    w.backlog = p.backlog;
    w.runtime_ns = p.runtime_ns;
    if (w.said || !all_came) continue;
    const int64_t silent = now_us - w.inputs_from_us;
    // a stopped process at once; one that runs only once it has answered
    // since its start (a start may be slow: a GPU's driver) and read none of
    // its input all the silence
    const bool unread = w.answered && p.backlog > 0 && now_us - w.read_us >= hang_us_;
    const bool blocked = w.answered && now_us - w.ran_us >= hang_us_;
    if (silent < hang_us_ || !(stopped || unread || blocked)) continue;
    Event e{w.name, true, static_cast<double>(silent) * 1e-6, ""};
    e.text = "published nothing on " + w.output + " for " + seconds(e.silent_s) + " while its input came (" +
             came + ")" + (p.backlog > 0 ? ", " + std::to_string(p.backlog) + " bytes of it unread" : "") +
             (blocked ? ", its main thread not run since" : "");
    events.push_back(std::move(e));
    w.said = true;
  }
  return events;
}

}  // namespace ld
