// The fuzz input as a file, for the readers that take a path.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace ld::fuzz {

/// Writes `size` bytes to this process's scratch file (one per process, so
/// that parallel fuzzing jobs do not share it) with the given extension and
/// returns its path. The file is removed at exit.
inline std::string writeInput(const uint8_t* data, size_t size, const char* ext) {
  static const std::string base = [] {
    const char* tmp = std::getenv("TMPDIR");
    return std::string(tmp && *tmp ? tmp : "/tmp") + "/ld-fuzz-" + std::to_string(getpid());
  }();
  static std::string last;
  if (!last.empty()) std::remove(last.c_str());
  last = base + ext;
  static const bool registered = [] {
    std::atexit([] { if (!last.empty()) std::remove(last.c_str()); });
    return true;
  }();
  (void)registered;
  FILE* f = std::fopen(last.c_str(), "wb");
  if (!f) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
  return last;
}

}  // namespace ld::fuzz
