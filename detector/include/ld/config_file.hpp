// Checks every configuration file reader (parameters, calibration) makes
// before it hands a file to cv::FileStorage, whose parsers in OpenCV 4.6 fail
// badly on some input (found by tests/fuzz/fuzz_camera):
//  - a NUL byte inside an XML attribute dereferences a null pointer;
//  - a YAML "---" document marker with text after it on its line, followed
//    by another "---" later, makes the YAML parser loop forever.
// No configuration file needs either: OpenCV writes "---" on a line of its
// own, and comments (after '#') are not looked at.
#pragma once

#include <fstream>
#include <iterator>
#include <optional>
#include <string>

namespace ld {

/// Why cv::FileStorage must not be given `text`, or nullopt when it may.
inline std::optional<std::string> unsafeForOpenCv(const std::string& text) {
  const size_t nul = text.find('\0');
  if (nul != std::string::npos)
    return "contains a NUL byte at offset " + std::to_string(nul) + " (not a text file)";
  size_t line = 1, start = 0;
  while (start <= text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string s = text.substr(start, end - start);
    s = s.substr(0, s.find('#'));  // comments may hold anything
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.pop_back();
    if (s.find("---") != std::string::npos && s != "---")
      return "line " + std::to_string(line) + ": \"---\" must stand on a line of its own";
    start = end + 1;
    ++line;
  }
  return std::nullopt;
}

/// The same for the file at `path` (nullopt when it cannot be read at all:
/// the reader reports that itself).
inline std::optional<std::string> unsafeFileForOpenCv(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return std::nullopt;
  return unsafeForOpenCv(std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>()));
}

}  // namespace ld
