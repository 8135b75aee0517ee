// Every program's command line: CLI11, with the project's errors. A bad
// command line gives one line on stderr, "<program>: <what> (--help lists
// the options)", and exit status 2, as the programs' own errors do; --help
// prints the help and exits 0.
//
//   CLI::App app{"ld-x: ..."};
//   app.add_option("--fps", fps, "frames per second")->check(ld::cli::Positive);
//   LD_CLI_PARSE(app, argc, argv);
#pragma once

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

namespace ld::cli {

/// The program's name: argv[0] without its folder.
inline std::string programName(const char* argv0) {
  const std::string s = argv0 ? argv0 : "";
  const size_t slash = s.rfind('/');
  return slash == std::string::npos ? s : s.substr(slash + 1);
}

namespace detail {
/// True for a word of the command line that is an option's name or starts
/// with one ("--out", "-o", "--out=x"), not a negative number ("-0.5").
inline bool looksLikeOption(const std::string& word) {
  return word.size() >= 2 && word[0] == '-' && !std::isdigit(static_cast<unsigned char>(word[1])) && word[1] != '.';
}

/// The first word of the command line that CLI11 matched to no option nor
/// took as a value, when it looks like an option ("" when none).
inline std::string unknownOption(const CLI::App& app) {
  for (const std::string& word : app.remaining(true))
    if (looksLikeOption(word)) return word.substr(0, word.find('='));
  return "";
}

/// The option of `app`, or of an app above it (whose options a subcommand
/// also takes), named `name` ("--out", "-o"); null when none.
inline const CLI::Option* findOption(const CLI::App* app, const std::string& name) {
  for (; app; app = app->get_parent())
    if (const CLI::Option* opt = app->get_option_no_throw(name)) return opt;
  return nullptr;
}

/// "" or what went wrong when an option that needs a value was followed by
/// another of the program's options, which CLI11 then took as its value:
/// `ld-detect --draw --decode frames/` wrote its overlays into a folder named
/// "--decode" and decoded nothing. Written with '=' ("--camera-arg=--fps=20")
/// such a value is meant, and taken.
inline std::string optionTakenAsValue(const CLI::App& app, int argc, char** argv) {
  const CLI::App* at = &app;  // the subcommand the words are in
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i] ? argv[i] : "";
    if (word == "--") break;
    bool entered = false;
    for (const CLI::App* sub : at->get_subcommands())
      if (sub->check_name(word)) {
        at = sub;
        entered = true;
        break;
      }
    if (entered || !looksLikeOption(word) || word.find('=') != std::string::npos) continue;
    const CLI::Option* opt = findOption(at, word);
    if (!opt || opt->get_items_expected_min() < 1 || i + 1 >= argc) continue;
    const std::string next = argv[i + 1] ? argv[i + 1] : "";
    if (looksLikeOption(next) && findOption(at, next.substr(0, next.find('=')))) {
      // (CLI11 takes "--long=value"; a short option's value joined with '='
      // would keep the '=')
      const std::string joined = word[1] == '-' || opt->get_lnames().empty() ? word : "--" + opt->get_lnames()[0];
      return word + " needs a value, and the word after it is the option " + next.substr(0, next.find('=')) +
             " (to give " + word + " that word, write " + joined + "=" + next + ")";
    }
    ++i;  // the value, whatever it is
  }
  return "";
}
}  // namespace detail

/// Reports a bad command line as parse() does: one line, "<program>: <what>
/// (--help lists the options)"; returns 2, the status to exit with.
inline int usage(const char* argv0, const std::string& what) {
  std::cerr << programName(argv0) << ": " << what << " (--help lists the options)\n";
  return 2;
}

/// Parses; -1 when the program goes on, else the status to exit with (0
/// after --help, 2 after a bad command line, reported on one line).
inline int parse(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
    if (const std::string taken = detail::optionTakenAsValue(app, argc, argv); !taken.empty())
      return usage(argc > 0 ? argv[0] : nullptr, taken);
    return -1;
  } catch (const CLI::Success& e) {  // --help, --help-all, --version
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // an option that took the next option as its value is what went wrong,
    // whatever CLI11 found wrong after it ("--seed --out x": "--out" is not
    // a number; "--read-at --stack 8": the required --read-at is missing)
    if (const std::string taken = detail::optionTakenAsValue(app, argc, argv); !taken.empty())
      return usage(argc > 0 ? argv[0] : nullptr, taken);
    std::string what = e.what();
    // CLI11's "Could not convert: --seed = abc" (a value its type cannot
    // hold: not a number, a fraction for a count, beyond the type's range)
    // said as the project's checks say it
    if (dynamic_cast<const CLI::ConversionError*>(&e)) {
      const std::string head = "Could not convert: ";
      const size_t eq = what.find(" = ");
      if (what.compare(0, head.size(), head) == 0 && eq != std::string::npos)
        what = what.substr(head.size(), eq - head.size()) + ": '" + what.substr(eq + 3) +
               "' is not a value it takes (a number of its kind, in its type's range)";
    }
    // CLI11 checks required options, and what options need or exclude,
    // before it looks for unknown ones: a misspelt option would be reported
    // as the required one it is not
    if (dynamic_cast<const CLI::RequiredError*>(&e) || dynamic_cast<const CLI::RequiresError*>(&e) ||
        dynamic_cast<const CLI::ExcludesError*>(&e))
      if (const std::string unknown = detail::unknownOption(app); !unknown.empty())
        what = "The following argument was not expected: " + unknown;
    // "A subcommand is required" for a misspelt one ("ld-eval yaww"): named,
    // with those there are
    // (the first word left over, options after it left over too)
    if (dynamic_cast<const CLI::RequiredError*>(&e) && !app.get_subcommands({}).empty() &&
        app.get_subcommands().empty())
      if (const std::vector<std::string> left = app.remaining(true); !left.empty() && left[0].rfind('-', 0) != 0) {
        std::string known;
        for (const CLI::App* sub : app.get_subcommands({})) known += (known.empty() ? "" : ", ") + sub->get_name();
        what = "'" + left[0] + "' is no subcommand (" + known + ")";
      }
    for (char& c : what)
      if (c == '\n') c = ' ';
    std::cerr << programName(argc > 0 ? argv[0] : nullptr) << ": " << what << " (--help lists the options)\n";
    return 2;
  }
}

/// A size "WIDTHxHEIGHT" ("640x480", x or X), all of it, or nothing; the
/// callers check its range.
inline std::optional<std::pair<long, long>> parseSize(const std::string& text) {
  long w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%ld%c%ld%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X')) return std::nullopt;
  return std::pair{w, h};
}

/// A command line that parses but does not hold together ("give --png
/// and/or --svg"), found by a program's own checks after parse(): thrown
/// where convenient, reported by usage() as parse() reports CLI11's errors.
struct UsageError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

/// The status a program whose output is its standard output ends with: 0
/// when all of it was written, else 1, said in one line ("cannot write its
/// output: No space left on device"). A table printed to a full disk or a
/// closed pipe ended with status 0, without a word.
inline int outputStatus(const char* argv0) {
  errno = 0;
  const bool cpp = static_cast<bool>(std::cout.flush());
  const bool c = std::fflush(stdout) == 0 && !std::ferror(stdout);
  if (cpp && c) return 0;
  std::cerr << programName(argv0) << ": cannot write its output" << (errno ? std::string(": ") + std::strerror(errno) : "")
            << "\n";
  return 1;
}

/// `text` as a finite number, all of it ("2", "0.5", "1e3"), or nothing.
inline std::optional<double> parseNumber(const std::string& text) {
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used != text.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

namespace detail {
template <class Ok>
CLI::Validator numberCheck(const std::string& name, Ok ok, const std::string& rule) {
  return CLI::Validator(
      [ok, rule](std::string& text) {
        const std::optional<double> v = parseNumber(text);
        if (!v) return "'" + text + "' is not a number";
        return ok(*v) ? std::string() : rule + ", not " + text;
      },
      name, name);
}
}  // namespace detail

/// A number above 0 ("must be > 0, not -1"; CLI11's own PositiveNumber
/// prints its range up to the largest double, digit by digit).
inline const CLI::Validator Positive =
    detail::numberCheck("POSITIVE", [](double v) { return v > 0; }, "must be > 0");
/// A number of 0 or more.
inline const CLI::Validator NonNegative =
    detail::numberCheck("NONNEGATIVE", [](double v) { return v >= 0; }, "must be >= 0");
/// A number in [lo, hi] ("must be in [0.01, 2], not 5"; "'abc' is not a number").
inline CLI::Validator Between(double lo, double hi) {
  // (15 digits: a bound of 1e12 reads 1000000000000, as a whole number is written)
  std::ostringstream rule;
  rule << std::setprecision(15) << "must be in [" << lo << ", " << hi << "]";
  std::ostringstream name;
  name << std::setprecision(15) << "[" << lo << " - " << hi << "]";
  return detail::numberCheck(name.str(), [lo, hi](double v) { return v >= lo && v <= hi; }, rule.str());
}

/// A number in (0, hi] ("must be in (0, 1000], not 0").
inline CLI::Validator PositiveUpTo(double hi) {
  std::ostringstream rule;
  rule << "must be in (0, " << hi << "]";
  std::ostringstream name;
  name << "(0 - " << hi << "]";
  return detail::numberCheck(name.str(), [hi](double v) { return v > 0 && v <= hi; }, rule.str());
}

/// A random seed: a whole number from 0 to 2^64-1, as written (CLI11 takes
/// "-1" into a uint64_t as 2^64-1 and 2^64 as the same, without a word).
inline const CLI::Validator Seed(
    [](std::string& text) -> std::string {
      if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos)
        return "must be a whole number 0 or more, not " + text;
      try {
        (void)std::stoull(text);
      } catch (const std::out_of_range&) {
        return "must be under 2^64, not " + text;
      }
      return std::string();
    },
    "SEED", "SEED");

/// A utime to start a log's frames at: whole microseconds from 0 to 2^62
/// (about 146,000 years after 1970: room for any run's frames after it, so
/// that no frame's utime overflows; 1e6 or 99999999999999999999 were taken
/// as other numbers without a word).
inline const CLI::Validator StartUtime(
    [](std::string& text) -> std::string {
      if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos)
        return "must be whole microseconds, 0 or more, not " + text;
      if (text.size() > 19 || std::stoull(text) > (uint64_t{1} << 62))
        return "must be at most 2^62 (4611686018427387904), not " + text;
      return std::string();
    },
    "UTIME", "UTIME");

/// A list option given a value twice ("--side 0.15 --side 0.15"): each value
/// once, in the order first given (measured once, one row).
template <class T>
void dropRepeats(std::vector<T>& values) {
  std::vector<T> once;
  for (const T& v : values)
    if (std::find(once.begin(), once.end(), v) == once.end()) once.push_back(v);
  values.swap(once);
}

/// A text that `parse` accepts (it throws std::exception with the reason
/// otherwise): `->check(ld::cli::Parses("LEVEL", ld::artwork::parseQrEcc))`.
template <class Parse>
CLI::Validator Parses(const std::string& name, Parse parse) {
  return CLI::Validator(
      [parse](std::string& text) {
        try {
          parse(text);
          return std::string();
        } catch (const std::exception& e) {
          return std::string(e.what());
        }
      },
      name, name);
}

}  // namespace ld::cli

/// In main(): parse the command line, returning from main on --help or an error.
#define LD_CLI_PARSE(app, argc, argv)                                               \
  do {                                                                              \
    if (const int ld_cli_status = ::ld::cli::parse(app, argc, argv); ld_cli_status >= 0) \
      return ld_cli_status;                                                         \
  } while (false)
