#include "ld/lcm_url.hpp"

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <regex>

#include <lcm/lcm-cpp.hpp>

namespace ld {

std::string defaultLcmUrl() {
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) return env;
  return "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
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
  try {
    return std::regex_match(channel, std::regex(pattern, std::regex::extended));
  } catch (const std::regex_error&) {
    return false;
  }
}

}  // namespace ld
