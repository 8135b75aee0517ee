// An LCM log read event by event (lcm_eventlog's format, ld/file_checks.hpp),
// saying what LCM's own reader does not: where a log was cut off, and what
// it skipped. Where no whole event starts (an event cut off by a recorder
// killed mid-write, then more appended: lcm-logger -a; damaged bytes) it
// skips to the next event magic and goes on, as LCM's reader does.
#pragma once

#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace ld {

class LcmLogReader {
 public:
  explicit LcmLogReader(const std::string& path);
  bool good() const { return static_cast<bool>(f_); }
  /// The next event (timestamp, channel, data), or false at the end of the
  /// file or at a problem that ends it. Without `read_data`, `data` is left
  /// empty (counting a log's events: its headers alone are read).
  bool next(bool read_data = true);
  /// What went wrong, or "" for a whole log: the bytes skipped and how the
  /// file ended ("the log ends mid-event after 2 messages (...)").
  std::string problem() const;
  int64_t messages() const { return messages_; }

  int64_t timestamp = 0;
  std::string channel;
  std::vector<uint8_t> data;

 private:
  size_t readAt(int64_t at, uint8_t* to, size_t n);
  bool magicAt(int64_t at);
  bool skipToNextEvent(int64_t before = -1);
  bool fail(const std::string& what, const std::string& detail);
  std::ifstream f_;
  int64_t size_ = 0, offset_ = 0, messages_ = 0, skipped_bytes_ = 0, skips_ = 0, first_skip_ = 0;
  std::string end_problem_;
};

/// A span of a log in seconds from its first message, as ld-dump's and
/// ld-view's --from and --to give it (the frames about second 12 of a run).
struct LogSpan {
  double from_s = 0, to_s = std::numeric_limits<double>::infinity();
  bool limited() const { return from_s > 0 || std::isfinite(to_s); }
  /// Whether a message logged at `timestamp` (us) lies in the span of a log
  /// whose first message was logged at `first`: any, where no span is given
  /// (one logged before the first, a clock set back or two logs appended,
  /// was dropped); with a span, one logged before the first is outside it.
  bool holds(int64_t first, int64_t timestamp) const {
    if (!limited()) return true;
    const double s = static_cast<double>(timestamp - first) / 1e6;
    return s >= from_s && s <= to_s;
  }
  /// "--to 0.1 is before --from 0.3" for a span that ends before it starts;
  /// "" otherwise.
  std::string problem() const;
  /// "from 12 to 12.5 s", or "from 3 s on" without an end: for a note.
  std::string text() const;
};

/// Messages a channel, as a log's readers count them to name its channels.
using ChannelCounts = std::map<std::string, int64_t>;
/// "IMAGE (450), LANDMARKS (450)": a log's channels as a message names
/// them (where a channel asked for has nothing).
std::string describeChannels(const ChannelCounts& counts);

}  // namespace ld
