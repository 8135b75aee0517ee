#include "ld/hang_watch.hpp"

#include <cstdio>

namespace ld {

void HangWatch::add(const std::string& name, std::vector<std::string> inputs, const std::string& output) {
  Worker w;
  w.name = name;
  w.output = output;
  w.inputs = std::move(inputs);
  w.inputs_seen.assign(w.inputs.size(), 0);
  workers_.push_back(std::move(w));
}

std::vector<HangWatch::Event> HangWatch::check(int64_t now_us, const std::function<Heard(const std::string&)>& heard,
                                               const std::function<int(const std::string&)>& starts) {
  std::vector<Event> events;
  if (hang_us_ <= 0) return events;
  for (Worker& w : workers_) {
    const Heard out = heard(w.output);
    const int started = starts(w.name);
    // (re)started, or published: its watch begins again here
    const auto restart = [&] {
      w.since_us = now_us;
      w.inputs_from_us = 0;
      w.output_seen = out.messages;
      for (size_t i = 0; i < w.inputs.size(); ++i) w.inputs_seen[i] = heard(w.inputs[i]).messages;
    };
    if (started < 0) {  // (not running: the supervisor's)
      w.starts = -1;
      w.said = false;
      continue;
    }
    if (started != w.starts) {
      w.starts = started;
      w.said = false;  // (a restart ends the hang: the supervisor says it)
      restart();
      continue;
    }
    if (out.messages > w.output_seen) {
      if (w.said) {
        Event e{w.name, false, static_cast<double>(now_us - w.since_us) * 1e-6, ""};
        char buf[64];
        std::snprintf(buf, sizeof buf, "%.1f s", e.silent_s);
        e.text = "publishes on " + w.output + " again, after " + buf + " without";
        events.push_back(std::move(e));
        w.said = false;
      }
      restart();
      continue;
    }
    if (w.said) continue;
    // the inputs: each must have come since the mark and still come; the
    // silence is counted from when they all came (a worker idle while its
    // input paused, a camera unplugged, is not slow to answer)
    bool flowing = !w.inputs.empty(), all_came = true;
    std::string came;
    for (size_t i = 0; i < w.inputs.size(); ++i) {
      const Heard in = heard(w.inputs[i]);
      const int64_t n = in.messages - w.inputs_seen[i];
      all_came = all_came && n > 0;
      flowing = flowing && n >= kMinInputs && now_us - in.last_us <= kFlowingUs;
      came += (i ? ", " : "") + std::to_string(n) + " on " + w.inputs[i];
    }
    if (w.inputs_from_us == 0 && all_came) w.inputs_from_us = now_us;
    if (w.inputs_from_us > 0 && !all_came) w.inputs_from_us = 0;
    bool stopped = false;  // (an input that stopped: marked again, as at a restart)
    for (size_t i = 0; i < w.inputs.size(); ++i)
      stopped = stopped || (heard(w.inputs[i]).last_us > 0 && now_us - heard(w.inputs[i]).last_us > kFlowingUs);
    if (stopped) {
      restart();
      continue;
    }
    if (!flowing || w.inputs_from_us == 0 || now_us - w.inputs_from_us < hang_us_) continue;
    Event e{w.name, true, static_cast<double>(now_us - w.inputs_from_us) * 1e-6, ""};
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.1f s", e.silent_s);
    e.text = "published nothing on " + w.output + " for " + buf + " while its input came (" + came + ")";
    events.push_back(std::move(e));
    w.said = true;
  }
  return events;
}

}  // namespace ld
