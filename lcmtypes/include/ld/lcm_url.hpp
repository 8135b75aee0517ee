// The LCM URL the project's processes use unless told otherwise.
#pragma once

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace ld {

/// $LCM_DEFAULT_URL when set; otherwise LCM's default multicast group with
/// ttl=0 (nothing leaves this host) and an 8 MiB receive buffer, so that
/// large images are not dropped by the kernel (raise net.core.rmem_max to
/// let it take effect; see README).
std::string defaultLcmUrl();

/// An LCM URL of the project's default kind, for messages.
constexpr const char* kLcmUrlExample = "udpm://239.255.76.67:7667?ttl=0";

/// Why `url` cannot be an LCM URL, or "": a provider LCM does not have, a
/// udpm group that is not a multicast address, a udpm URL without a port or
/// with one that is not (LCM takes a missing port as 0: it never receives,
/// and its wait aborts the process after a while), an empty one (LCM's own
/// default, without the receive buffer large images need). The processes check it
/// before they open LCM and refuse such a URL with status 2.
std::string lcmUrlProblem(const std::string& url);
/// In a process's main, before it opens LCM: false, with the one line
/// "PROGRAM: LCM URL <problem>" on stderr, when `url` has an lcmUrlProblem.
bool lcmUrlUsable(const std::string& url, const std::string& program);

/// The exit status of a process whose LCM would not open at `url`: 1 (may
/// pass: a network not up yet at boot; a supervisor restarts it) for a URL
/// without an lcmUrlProblem, 2 (a restart will not mend it: the URL is
/// wrong) for one with a problem.
int lcmOpenFailureStatus(const std::string& url);

}  // namespace ld

namespace lcm {
class LCM;
class Subscription;
}

namespace ld {

/// After `lcm::LCM lcm(url)` in a process's main: 0 when LCM opened, else
/// its exit status (lcmOpenFailureStatus), with the one line "PROGRAM: cannot
/// open LCM at URL" on stderr. Opened means good() and a file descriptor to
/// wait on: a tcpq:// URL whose server does not answer gives good() and no
/// descriptor, and LCM's wait then aborted the process ("bit out of range 0
/// - FD_SETSIZE on fd_set").
int lcmOpenStatus(lcm::LCM& lcm, const std::string& url, const std::string& program);

/// Watches the utimes of the frames a process handles: a publisher that does
/// not stamp its frames (utime 0, or one value for ever) stops everything
/// that counts time from them (a track's lifetime, a QR retry) without a
/// word. note(utime) returns true once, at the 10th frame in a row with the
/// same utime, for the caller's one line.
class StillTimeWatch {
 public:
  bool note(int64_t utime) {
    same_ = utime == last_ ? same_ + 1 : 0;
    last_ = utime;
    if (same_ < 9 || said_) return false;
    said_ = true;
    return true;
  }

 private:
  int64_t last_ = INT64_MIN;
  int same_ = 0;
  bool said_ = false;
};

/// One turn of a process's receive loop: waits up to timeout_ms for messages
/// on `lcm`, then handles every message already queued (for kMaxDrainMs at
/// most), so that the caller sees only the newest. A signal interrupting
/// the wait (and setting `stop`) is not an error. Returns false only when
/// LCM itself failed, which is reported in one line prefixed with `program`.
constexpr int kMaxDrainMs = 50;
bool pumpLcm(lcm::LCM& lcm, int timeout_ms, const std::atomic<bool>& stop, const char* program);

/// After a stall (the process stopped or starved for kStallMs or more between
/// two pumps), LCM's receiving thread is still reading the kernel's backlog
/// when pumpLcm returns, and the newest message then is one from the middle
/// of it: handles messages for as long as they keep coming (kCatchUpGapMs
/// apart at most), for up to kMaxCatchUpMs, so that the newest is the
/// source's latest. (A detector stopped for 3 s worked on a third frame of
/// the stall's backlog now and then.) Call it after pumpLcm with the time
/// the previous pumpLcm returned, plus the processor time the caller spent
/// on its frame since (a caller slow on its own is not stalled: the time it
/// was stopped or starved counts, its own work does not); it returns the
/// time to pass next.
constexpr int kStallMs = 1000, kCatchUpGapMs = 20, kMaxCatchUpMs = 500;
std::chrono::steady_clock::time_point catchUpAfterStall(lcm::LCM& lcm, std::chrono::steady_clock::time_point last_pump,
                                                        const std::atomic<bool>& stop);

/// A subscription's queue, held to about kQueueBytes of messages rather than
/// LCM's 30. LCM keeps at most that many messages waiting for a
/// subscription's handler and its receiving thread drops what comes beyond
/// them without a word: after a stall (a process stopped, starved or slow for
/// a second) it kept the oldest 30 and lost the newer ones, so a process
/// took a stale frame for the newest and never counted those it lost. Held
/// to a byte budget instead (kQueueBytes over the largest message seen, 30
/// to 10000 messages: a 640x480 YUYV frame about 440, an MJPEG one thousands,
/// a raw 1080p one 43), every message that reaches the process in a stall
/// of a few seconds is handled (pumpLcm drains them) and counted:
/// processed, or skipped for a newer one. What the kernel's receive buffer
/// drops (a process stopped long enough to fill it) never reaches it.
/// `fit` goes in the handler, with each message's size.
constexpr size_t kQueueBytes = size_t{256} << 20;
class QueueFit {
 public:
  QueueFit() = default;
  /// Starts at 30 (LCM's own) until the first message's size is known.
  explicit QueueFit(lcm::Subscription* subscription) : subscription_(subscription) {}
  void fit(size_t message_bytes);
  int capacity() const { return capacity_; }

 private:
  lcm::Subscription* subscription_ = nullptr;
  size_t largest_ = 0;
  int capacity_ = 30;
};

/// Whether a subscription to `pattern` (LCM reads it as a regular
/// expression of the whole channel name) takes messages on `channel`: a
/// process whose input takes its own output feeds itself without end. A
/// pattern that is no valid expression is taken as a name.
bool channelPatternTakes(const std::string& pattern, const std::string& channel);

/// What is wrong with `pattern` as LCM reads a subscription's channel (GLib's
/// regular expression of the whole name): "" when nothing, else GLib's words
/// ("missing terminating ] for character class"). LCM said so on a line of
/// its own and the process went on subscribed to nothing.
std::string channelPatternError(const std::string& pattern);

/// Whether `name`, published on, is taken by a subscription to the same
/// text: false for a name LCM's regular expression reads as another
/// ("CAM(1)" takes "CAM1", not itself), or that is no expression at all.
bool channelNameTakesItself(const std::string& name);

/// What is wrong with a process's channels, for its one-line refusal ("" when
/// nothing): an empty name ("--in needs a channel name"), an input that is no
/// regular expression LCM can read, an input that
/// takes the process's own output, which would feed it itself ("--in X takes
/// the tracker's own output Y: ..."; `whose`: "the tracker's"), or two
/// inputs that take the same channel. Channels are (option, name) pairs.
using ChannelOption = std::pair<std::string, std::string>;
/// What is wrong with one input channel alone ("" when nothing): empty, or
/// no regular expression LCM can read (for a reader with no output: ld-view).
std::string inputChannelProblem(const ChannelOption& input);
std::string channelProblem(const std::vector<ChannelOption>& inputs, const ChannelOption& output,
                           const std::string& whose);

/// Whether a process prints the line of its `bad`'th bad input (1, 2, ...):
/// the first kBadLinesInFull, then every kBadLinesEvery'th, so that a flood
/// of garbage does not flood the log; all are counted.
constexpr int64_t kBadLinesInFull = 10, kBadLinesEvery = 100;
inline bool printBadLine(int64_t bad) { return bad <= kBadLinesInFull || bad % kBadLinesEvery == 0; }
/// The end of that line: "(N bad so far)" (or another word than "bad"), and on the last line printed in
/// full, that only every kBadLinesEvery'th is printed from there on.
inline std::string badSoFar(int64_t bad, const char* what = "bad") {
  return "(" + std::to_string(bad) + " " + what + " so far" +
         (bad == kBadLinesInFull ? "; from here on every " + std::to_string(kBadLinesEvery) +
                                       "th is printed, all are counted)"
                                 : ")");
}

}  // namespace ld
