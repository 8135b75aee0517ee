#include "ld/lcm_url.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include <arpa/inet.h>
#include <netinet/in.h>

#include <glib.h>
#include <lcm/lcm-cpp.hpp>

namespace ld {

std::string defaultLcmUrl() {
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) return env;
  return "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
}

std::string lcmUrlProblem(const std::string& url) {
  // (LCM takes "" for its own default, without the receive buffer large
  // images need: an unset variable in `--lcm-url "$URL"` brought image loss
  // back without a word)
  if (url.empty())
    return "is empty (leave the option out for " + defaultLcmUrl() + ", or give one, e.g. " + kLcmUrlExample + ")";
  const size_t end = url.find("://");
  if (end == std::string::npos) return url + " is not an LCM URL (PROVIDER://..., e.g. " + kLcmUrlExample + ")";
  const std::string provider = url.substr(0, end);
  if (provider == "udpm" || provider == "mpudpm") {
    // udpm://GROUP:PORT?options: LCM takes a missing port as 0, where it
    // never receives (and its wait then aborts the process)
    const size_t q = url.find('?');
    const std::string target = url.substr(end + 3, q == std::string::npos ? std::string::npos : q - end - 3);
    const size_t colon = target.find(':');
    const std::string group = target.substr(0, colon);
    in_addr a{};
    if (group.empty() && !target.empty())
      return url + ": no multicast group before the port (udpm://GROUP:PORT, e.g. " + kLcmUrlExample + ")";
    if (!group.empty() && (inet_pton(AF_INET, group.c_str(), &a) != 1 || !IN_MULTICAST(ntohl(a.s_addr))))
      return url + ": " + group + " is not a multicast group (224.0.0.0 to 239.255.255.255, e.g. " +
             kLcmUrlExample + ")";
    if (!target.empty()) {
      const std::string port = colon == std::string::npos ? "" : target.substr(colon + 1);
      char* stop = nullptr;
      const long p = std::strtol(port.c_str(), &stop, 0);  // (as LCM reads it: 0x1df3 too)
      if (port.empty() || *stop != '\0' || p < 1 || p > 65535)
        return url + ": " + (port.empty() ? std::string("no port") : "port " + port + " is not one") +
               " (udpm://GROUP:PORT, e.g. " + kLcmUrlExample + ")";
    }
    // The options LCM reads a number from: one that is none it takes as 0
    // with a line of its own ("Invalid value for ttl") and goes on.
    for (size_t at = q; at != std::string::npos && at + 1 < url.size();) {
      const size_t next = url.find('&', at + 1);
      const std::string option = url.substr(at + 1, next == std::string::npos ? std::string::npos : next - at - 1);
      at = next;
      const size_t eq = option.find('=');
      const std::string key = option.substr(0, eq), value = eq == std::string::npos ? "" : option.substr(eq + 1);
      const long lo = 0, hi = key == "ttl" ? 255 : INT32_MAX;  // (recv_buf_size 0: LCM's default)
      // (LCM says "unknown provider argument" on a line of its own and runs
      // on: a misspelt ttl=1 kept a robot's traffic on one machine unnoticed)
      if (provider == "udpm" && !key.empty() && key != "ttl" && key != "recv_buf_size" && key != "transmit_only")
        return url + ": udpm has no option " + key + " (ttl, recv_buf_size; e.g. " + kLcmUrlExample + ")";
      if (key != "ttl" && key != "recv_buf_size") continue;
      char* stop = nullptr;
      errno = 0;
      const long v = std::strtol(value.c_str(), &stop, 0);  // (as LCM reads it)
      if (value.empty() || *stop != '\0' || errno != 0 || v < lo || v > hi)
        return url + ": " + key + " " + (value.empty() ? std::string("has no value") : value + " is not one") + " (" +
               std::to_string(lo) + " to " + std::to_string(hi) + (key == "ttl" ? ": 0 keeps packets on this machine, 1 on its LAN" : " bytes, 0 LCM's default") + ")";
    }
    return "";
  }
  for (const char* known : {"file", "memq", "tcpq"})
    if (provider == known) return "";
  return url + ": LCM has no provider " + provider + " (udpm, mpudpm, file, memq, tcpq)";
}

bool lcmUrlUsable(const std::string& url, const std::string& program) {
  const std::string problem = lcmUrlProblem(url);
  if (!problem.empty()) std::cerr << program << ": LCM URL " << problem << "\n";
  return problem.empty();
}

int lcmOpenFailureStatus(const std::string& url) { return lcmUrlProblem(url).empty() ? 1 : 2; }

int lcmOpenStatus(lcm::LCM& lcm, const std::string& url, const std::string& program) {
  if (lcm.good() && lcm.getFileno() >= 0) return 0;
  // (the tcpq hint only for tcpq: out of descriptors or memory, a udpm URL
  // got it too; LCM says its own reason on the line above)
  std::cerr << program << ": cannot open LCM at " << url
            << (lcm.good() ? url.rfind("tcpq://", 0) == 0 ? " (no connection: is its tcpq server running?)"
                                                          : " (LCM's own line above says why)"
                           : "")
            << "\n";
  return lcmOpenFailureStatus(url);
}

bool pumpLcm(lcm::LCM& lcm, int timeout_ms, const std::atomic<bool>& stop, const char* program) {
  if (lcm.handleTimeout(timeout_ms) < 0) {
    if (stop || errno == EINTR) return true;  // a signal, not a failure
    std::cerr << program << ": LCM receive failed: " << std::strerror(errno) << "\n";
    return false;
  }
  // (at most kMaxDrainMs of it: under a flood, or starved of CPU, the queue
  // may never be empty when looked at, and the caller would never get to
  // process the newest it has)
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(kMaxDrainMs);
  while (!stop && std::chrono::steady_clock::now() < until && lcm.handleTimeout(0) > 0) {
  }
  return true;
}

std::chrono::steady_clock::time_point catchUpAfterStall(lcm::LCM& lcm, std::chrono::steady_clock::time_point last_pump,
                                                        const std::atomic<bool>& stop) {
  const auto now = std::chrono::steady_clock::now();
  if (now - last_pump < std::chrono::milliseconds(kStallMs)) return now;
  const auto until = now + std::chrono::milliseconds(kMaxCatchUpMs);
  while (!stop && std::chrono::steady_clock::now() < until && lcm.handleTimeout(kCatchUpGapMs) > 0) {
  }
  return std::chrono::steady_clock::now();
}

void QueueFit::fit(size_t message_bytes) {
  if (!subscription_ || message_bytes <= largest_) return;
  largest_ = message_bytes;
  const int capacity = static_cast<int>(std::clamp<size_t>(kQueueBytes / largest_, 30, 10000));
  if (capacity == capacity_) return;
  subscription_->setQueueCapacity(capacity);
  capacity_ = capacity;
}

namespace {

// A subscription's channel as LCM reads it: GLib's (PCRE) expression of the
// whole name, "^pattern$"; null, with GLib's reason in `why`, when it is
// none, or when the pattern alone is none (a trailing backslash escapes the
// $ LCM adds, and lcm-logger or lcm-logplayer, which take it as it is,
// refuse it).
GRegex* wholeName(const std::string& pattern, std::string* why = nullptr) {
  GError* error = nullptr;
  GRegex* alone = g_regex_new(pattern.c_str(), static_cast<GRegexCompileFlags>(0),
                              static_cast<GRegexMatchFlags>(0), &error);
  GRegex* re = alone ? g_regex_new(("^" + pattern + "$").c_str(), static_cast<GRegexCompileFlags>(0),
                                   static_cast<GRegexMatchFlags>(0), &error)
                     : nullptr;
  if (alone) g_regex_unref(alone);
  if (!re && why) {
    *why = error && error->message ? error->message : "not a regular expression";
    // (GLib names the expression and an offset in it: its reason comes last)
    if (const size_t at = why->rfind(": "); at != std::string::npos) *why = why->substr(at + 2);
  }
  if (error) g_error_free(error);
  return re;
}

bool matches(GRegex* re, const std::string& text) {
  if (!re) return false;
  const bool takes = g_regex_match(re, text.c_str(), static_cast<GRegexMatchFlags>(0), nullptr);
  g_regex_unref(re);
  return takes;
}

}  // namespace

bool channelPatternTakes(const std::string& pattern, const std::string& channel) {
  return pattern == channel || matches(wholeName(pattern), channel);
}

std::string channelPatternError(const std::string& pattern) {
  std::string why;
  GRegex* re = wholeName(pattern, &why);
  if (!re) return why;
  g_regex_unref(re);
  return "";
}

bool channelNameTakesItself(const std::string& name) { return matches(wholeName(name), name); }

std::string inputChannelProblem(const ChannelOption& input) {
  const auto& [option, name] = input;
  if (name.empty()) return option + " needs a channel name";
  if (const std::string why = channelPatternError(name); !why.empty())
    return option + " " + name + ": LCM reads a subscription's channel as a regular expression, and this is none (" +
           why + ")";
  return "";
}

std::string channelProblem(const std::vector<ChannelOption>& inputs, const ChannelOption& output,
                           const std::string& whose) {
  for (const auto& [option, name] : inputs)
    if (name.empty()) return option + " needs a channel name";
  if (output.second.empty()) return output.first + " needs a channel name";
  for (const auto& input : inputs)
    if (const std::string problem = inputChannelProblem(input); !problem.empty()) return problem;
  for (const auto& [option, name] : inputs)
    if (channelPatternTakes(name, output.second))
      return option + " " + name + " takes " + whose + " own output " + output.second + ": it would feed itself";
  // (two inputs of different types on one channel: every message of one is
  // dropped as no message of the other's type, without end)
  for (size_t i = 0; i < inputs.size(); ++i)
    for (size_t j = i + 1; j < inputs.size(); ++j)
      if (channelPatternTakes(inputs[i].second, inputs[j].second) ||
          channelPatternTakes(inputs[j].second, inputs[i].second))
        return inputs[i].first + " " + inputs[i].second + " and " + inputs[j].first + " " + inputs[j].second +
               " take the same channel: each needs its own";
  return "";
}

}  // namespace ld
