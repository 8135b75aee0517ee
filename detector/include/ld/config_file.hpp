// A check every configuration file reader (parameters, calibration) makes
// before it hands a file to cv::FileStorage: OpenCV 4.6's parsers crash on
// some binary input (a NUL byte inside an XML attribute dereferences a null
// pointer; found by tests/fuzz/fuzz_camera), and no configuration file has
// NUL bytes.
#pragma once

#include <algorithm>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>

namespace ld {

/// Why the file at `path` cannot be a text configuration file ("contains a
/// NUL byte at offset N"), or nullopt when it can (or cannot be read at
/// all: the reader reports that itself).
inline std::optional<std::string> notATextFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return std::nullopt;
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  const size_t nul = text.find('\0');
  if (nul == std::string::npos) return std::nullopt;
  return "contains a NUL byte at offset " + std::to_string(nul) + " (not a text file)";
}

}  // namespace ld
