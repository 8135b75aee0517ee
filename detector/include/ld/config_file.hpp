// Checks every configuration file reader (parameters, calibration) makes
// before it hands a file to cv::FileStorage, whose parsers in OpenCV 4.6 fail
// badly on some input (found by tests/fuzz/fuzz_camera):
//  - a NUL byte inside an XML attribute dereferences a null pointer;
//  - so does an XML attribute whose "=" has no quoted value after it
//    ("<?xml version=" at the end of a file);
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
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '<') {  // XML: every tag closed, attribute values quoted
    bool in_tag = false;
    for (size_t i = first; i < text.size(); ++i) {
      const char c = text[i];
      if (!in_tag) {
        in_tag = c == '<';
        continue;
      }
      if (c == '>') {
        in_tag = false;
      } else if (c == '"' || c == '\'') {
        const size_t close = text.find(c, i + 1);
        if (close == std::string::npos)
          return "offset " + std::to_string(i) + ": unterminated attribute value";
        i = close;
      } else if (c == '=') {
        const size_t v = text.find_first_not_of(" \t\r\n", i + 1);
        if (v == std::string::npos || (text[v] != '"' && text[v] != '\''))
          return "offset " + std::to_string(i) + ": XML attribute without a quoted value";
      }
    }
    if (in_tag) return "unterminated XML tag at the end";
  }
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
