#include "ld/lcm_url.hpp"

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>

#include <glib.h>
#include <lcm/lcm-cpp.hpp>

namespace ld {

std::string defaultLcmUrl() {
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) return env;
  return "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
}

int lcmOpenFailureStatus(const std::string& url) {
  const size_t end = url.find("://");
  if (end == std::string::npos) return 2;
  for (const char* known : {"udpm", "mpudpm", "file", "memq", "tcpq"})
    if (url.compare(0, end, known) == 0) return 1;
  return 2;
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

bool channelPatternTakes(const std::string& pattern, const std::string& channel) {
  if (pattern == channel) return true;
  // as LCM matches a subscription: GLib's (PCRE) expression of the whole name
  GRegex* re = g_regex_new(("^" + pattern + "$").c_str(), static_cast<GRegexCompileFlags>(0),
                           static_cast<GRegexMatchFlags>(0), nullptr);
  if (!re) return false;
  const bool takes = g_regex_match(re, channel.c_str(), static_cast<GRegexMatchFlags>(0), nullptr);
  g_regex_unref(re);
  return takes;
}

std::string channelProblem(const std::vector<ChannelOption>& inputs, const ChannelOption& output,
                           const std::string& whose) {
  for (const auto& [option, name] : inputs)
    if (name.empty()) return option + " needs a channel name";
  if (output.second.empty()) return output.first + " needs a channel name";
  for (const auto& [option, name] : inputs)
    if (channelPatternTakes(name, output.second))
      return option + " " + name + " takes " + whose + " own output " + output.second + ": it would feed itself";
  return "";
}

}  // namespace ld
