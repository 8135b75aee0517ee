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
// Other malformed YAML makes the parser loop forever too (tests/fuzz/
// opencv-hangs), with no pattern to refuse, so every file is parsed first in
// a child process that is given up after a time limit (parserFailure).
#pragma once

#include <algorithm>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <regex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_set>

#include <opencv2/core.hpp>  // (cv::Exception)
#include <opencv2/core/persistence.hpp>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

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

/// The first integer of `text` (outside comments) that OpenCV's parsers
/// would wrap around: they read integers into 32 bits, so 4294967299 became
/// 3 without a word. Only under the keys `checked` takes (the key of a
/// `key:` line, or of an XML line's first tag, and of the lines after it
/// until the next: a camera file's other keys, a camera's 10-digit serial
/// say, are not read as numbers). As "line N: the integer X is out of
/// range (...)", or nullopt. An integer written with a leading 0 (040) is
/// refused too: OpenCV reads it as octal (32), without a word.
inline std::optional<std::string> integerOutOfRange(
    const std::string& text, const std::function<bool(const std::string&)>& checked = nullptr) {
  static const std::regex yaml_key(R"(^\s*(?:-\s+)?["']?([A-Za-z_][A-Za-z0-9_]*)["']?\s*:)");
  static const std::regex xml_tag(R"(<([A-Za-z_][A-Za-z0-9_]*)[\s>/])");
  constexpr std::string_view kBefore = " \t\r:[,{>", kAfter = " \t\r,]}<";  // (what a number token stands between)
  size_t line = 1, start = 0;
  std::string key;
  bool in_xml_comment = false;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    std::string s = text.substr(start, end - start);
    s = s.substr(0, s.find('#'));
    // (XML comments, over several lines too)
    for (size_t at = 0; at < s.size();) {
      if (in_xml_comment) {
        const size_t close = s.find("-->", at);
        s.erase(at, close == std::string::npos ? std::string::npos : close + 3 - at);
        if (close == std::string::npos) break;
        in_xml_comment = false;
      } else {
        at = s.find("<!--", at);
        if (at == std::string::npos) break;
        in_xml_comment = true;
      }
    }
    std::smatch m;
    if (std::regex_search(s, m, yaml_key) || std::regex_search(s, m, xml_tag)) key = m[1].str();
    const bool look = !checked || checked(key);
    char quote = 0;  // (a quoted string's text is no number: "v 01 x")
    for (size_t i = 0; look && i < s.size();) {
      // a whole token of digits (an optional sign first), between separators
      const bool boundary = i == 0 || kBefore.find(s[i - 1]) != std::string_view::npos;
      if (quote || ((s[i] == '"' || s[i] == '\'') && boundary)) {
        quote = !quote ? s[i] : s[i] == quote ? 0 : quote;
        ++i;
        continue;
      }
      size_t j = i + (s[i] == '-' || s[i] == '+');
      const size_t digits = j;
      while (j < s.size() && s[j] >= '0' && s[j] <= '9') ++j;
      const bool whole = j > digits && (j == s.size() || kAfter.find(s[j]) != std::string_view::npos);
      if (boundary && whole) {
        const std::string token = s.substr(i, j - i);
        const std::string mag = token.substr(digits - i);
        const std::string limit = token[0] == '-' ? "2147483648" : "2147483647";
        const size_t lead = std::min(mag.find_first_not_of('0'), mag.size());
        const std::string m2 = mag.substr(lead);
        // (not 00, which is 0 either way, nor the minutes of a time, 10:05)
        const bool time = i >= 2 && s[i - 1] == ':' && s[i - 2] >= '0' && s[i - 2] <= '9';
        if (mag.size() > 1 && mag[0] == '0' && !m2.empty() && !time) {
          std::string read = "no octal number in it";
          if (m2.find_first_of("89") == std::string::npos) {
            const unsigned long long v = m2.size() <= 11 ? std::stoull(m2, nullptr, 8) : ~0ull;
            read = v <= (token[0] == '-' ? 2147483648ull : 2147483647ull)
                       ? "it as octal (" + std::string(token[0] == '-' ? "-" : "") + std::to_string(v) + ")"
                       : "it as octal, out of range (-2147483648 to 2147483647)";
          }
          return "line " + std::to_string(line) + ": the integer " + token + " has a leading 0, and OpenCV reads " +
                 read + ": write it without";
        }
        if (m2.size() > limit.size() || (m2.size() == limit.size() && m2 > limit))
          return "line " + std::to_string(line) + ": the integer " + token +
                 " is out of range (-2147483648 to 2147483647)";
      }
      i = std::max(j, i + 1);
    }
    start = end + 1;
    ++line;
  }
  return std::nullopt;
}

/// A name-like string value of a configuration file as written: OpenCV's
/// YAML parser keeps a trailing comment (`front_end: paper   # or fast`) and
/// the spaces before it in a plain string; they are cut here. For names
/// only: a quoted value with " #" in it (a path, say) would be cut too.
inline std::string configString(const cv::FileNode& n) {
  std::string s = static_cast<std::string>(n);
  for (size_t hash = s.find('#'); hash != std::string::npos; hash = s.find('#', hash + 1))
    if (hash > 0 && (s[hash - 1] == ' ' || s[hash - 1] == '\t')) {
      s.erase(hash);
      break;
    }
  const size_t end = s.find_last_not_of(" \t\r");
  return end == std::string::npos ? std::string() : s.substr(0, end + 1);
}

/// The first key that a map of `node` (the node itself or one inside it,
/// at any depth) holds twice, as "outer.inner" for nested maps, or nullopt.
/// cv::FileStorage keeps both and reads the first, so a setting added again
/// further down a file would be silently ignored.
inline std::optional<std::string> duplicateKey(const cv::FileNode& node, const std::string& prefix = "",
                                               int depth = 0) {
  if ((!node.isMap() && !node.isSeq()) || depth > 64) return std::nullopt;  // (no configuration nests deeper)
  std::unordered_set<std::string> names;
  int index = 0;
  for (auto it = node.begin(); it != node.end(); ++it, ++index) {
    const cv::FileNode child = *it;
    const std::string name = node.isMap() ? child.name() : "";
    if (node.isMap() && !names.insert(name).second) return prefix + name;
    const std::string inner_prefix = node.isMap() ? prefix + name + "." : prefix + "[" + std::to_string(index) + "].";
    if (const auto inner = duplicateKey(child, inner_prefix, depth + 1)) return inner;
  }
  return std::nullopt;
}

/// Why OpenCV's parser must not be run on `text` in this process, found by
/// running it in a child process first: it did not return within `limit`
/// (OpenCV 4.6's YAML parser loops forever on some malformed files) or the
/// child died (a crash inside the parser). nullopt when the child parsed it,
/// successfully or with an exception, or when the child could not be made or
/// waited for (the caller then parses as it would without the check). The
/// child says nothing, leaves no core file and dies with its parent.
inline std::optional<std::string> parserFailure(const std::string& text,
                                                std::chrono::seconds limit = std::chrono::seconds(5)) {
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) return std::nullopt;
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(0);  // (the parent died before that took)
    // Ctrl-C or a SIGTERM to the process group is the parent's to handle (it
    // ends the child, by PR_SET_PDEATHSIG, if it ends); a crash in the parser
    // dies of its signal (the parent's handlers, a fuzzer's or a sanitizer's,
    // put back to the default); the alarm ends it should the parent stop.
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, SIG_IGN);
    for (int sig : {SIGALRM, SIGSEGV, SIGBUS, SIGABRT, SIGFPE, SIGILL}) std::signal(sig, SIG_DFL);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    const rlimit no_core{0, 0};
    ::setrlimit(RLIMIT_CORE, &no_core);
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) {
      ::dup2(null, 1);
      ::dup2(null, 2);
    }
    ::alarm(static_cast<unsigned>(limit.count() + 2));  // (should the parent be stopped)
    try {
      cv::FileStorage fs;
      fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
    } catch (...) {
    }
    ::_exit(0);
  }
  const auto start = std::chrono::steady_clock::now();
  long nap_ns = 20'000;
  for (;;) {
    int status = 0;
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) {
      const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
      if (sig == SIGSEGV || sig == SIGBUS || sig == SIGABRT || sig == SIGFPE || sig == SIGILL)
        return "OpenCV's parser crashes on it (signal " + std::to_string(sig) + ")";
      // (another signal, SIGKILL from the kernel short of memory say, says
      // nothing of the file: the caller parses it as it would without this)
      if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
        return "OpenCV's parser fails on it (exit " + std::to_string(WEXITSTATUS(status)) + ")";
      return std::nullopt;
    }
    if (r < 0 && errno != EINTR) return std::nullopt;  // (reaped by someone else: SIGCHLD ignored)
    if (std::chrono::steady_clock::now() - start > limit) {
      ::kill(pid, SIGKILL);
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      return "OpenCV's parser does not finish on it (given up after " + std::to_string(limit.count()) +
             " s: malformed YAML?)";
    }
    const timespec nap{0, nap_ns};
    ::nanosleep(&nap, nullptr);
    nap_ns = std::min(nap_ns * 2, 5'000'000L);
  }
}

/// The whole of `in`, or nullopt when it holds more than `max_bytes`: a
/// configuration file is read by every reader with kMaxConfigBytes, so that
/// /dev/zero, or a pipe that never ends, is refused (it was read for ever).
constexpr size_t kMaxConfigBytes = 16u << 20;
inline std::optional<std::string> readAtMost(std::istream& in, size_t max_bytes) {
  std::string text;
  char chunk[1 << 16];
  while (in.read(chunk, sizeof chunk) || in.gcount() > 0) {
    text.append(chunk, static_cast<size_t>(in.gcount()));
    if (text.size() > max_bytes) return std::nullopt;
  }
  return text;
}

/// A configuration file (YAML, XML or JSON) opened for reading, the way every
/// reader of the project opens one: the file read once, its text checked by
/// unsafeForOpenCv, plain YAML given the "%YAML:1.0" header OpenCV wants, and
/// parsed from memory. Throws std::runtime_error("<what> <path>: <why>") when
/// the path is a directory or cannot be read, the file is empty (a file cut
/// short or never written; `{}` is an empty map), is unsafe, makes OpenCV's
/// parser loop or crash (parserFailure), or does not parse
/// (OpenCV's cv::Exception and the std::length_error and others its parser
/// lets out included), or holds an integer beyond 32 bits under a key
/// `int_keys` takes (every key when null).
inline cv::FileStorage openConfigFile(const std::string& path, const std::string& what,
                                      const std::function<bool(const std::string&)>& int_keys = nullptr) {
  const auto fail = [&](const std::string& why) { throw std::runtime_error(what + " " + path + ": " + why); };
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) fail("is a directory");
  std::ifstream f(path, std::ios::binary);
  if (!f) fail(std::string("cannot open: ") + std::strerror(errno));  // (no such file, no permission)
  std::optional<std::string> read = readAtMost(f, kMaxConfigBytes);
  if (!read) fail("is larger than 16 MiB: not a configuration file");
  std::string text = std::move(*read);
  // (an editor's UTF-8 byte order mark: OpenCV takes it as part of the first key)
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) text.erase(0, 3);
  if (const auto why = unsafeForOpenCv(text)) fail(*why);
  if (const auto why = integerOutOfRange(text, int_keys)) fail(*why);
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) fail("is empty");
  int added_lines = 0;  // (before the file's own: its line numbers are said as the file has them)
  if (text[first] != '<' && text[first] != '{' && text.compare(first, 5, "%YAML") != 0) {
    text = "%YAML:1.0\n---\n" + text;
    added_lines = 2;
  }
  // OpenCV's YAML parser fails on a tab anywhere ("skipSpaces"), where YAML
  // allows one between a value and its comment: spaces do as well.
  if (text[text.find_first_not_of(" \t\r\n")] == '%') std::replace(text.begin(), text.end(), '\t', ' ');
  if (const auto why = parserFailure(text)) fail(*why);
  cv::FileStorage fs;
  bool opened = false;
  std::string error;
  try {
    opened = fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  } catch (const cv::Exception& e) {
    error = e.err;
    // (OpenCV 4.6's parsers put the line and the reason where the function's
    // name goes, "(3): Incorrect indentation", and the function's name
    // where the reason goes)
    for (const std::string& where : {e.func, e.msg}) {
      const size_t open = where.find('('), close = where.find("): ");
      if (open == std::string::npos || close == std::string::npos || close <= open + 1) continue;
      const std::string digits = where.substr(open + 1, close - open - 1);
      if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) continue;
      std::string reason = where.substr(close + 3);
      while (!reason.empty() && (reason.back() == '\'' || reason.back() == '\n')) reason.pop_back();
      error = "line " + std::to_string(std::max(1, std::stoi(digits) - added_lines)) + ": " + reason;
      break;
    }
  } catch (const std::exception& e) {
    error = e.what();
  }
  if (!error.empty()) fail("cannot parse as YAML, XML or JSON (OpenCV: " + error + ")");
  if (!opened) fail("cannot parse as YAML, XML or JSON");
  if (const auto key = duplicateKey(fs.root())) fail("key '" + *key + "' is given twice (only the first would count)");
  return fs;
}

}  // namespace ld
