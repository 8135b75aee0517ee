#include "ld/lcm_url.hpp"

#include <cstdlib>

namespace ld {

std::string defaultLcmUrl() {
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) return env;
  return "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
}

}  // namespace ld
