#pragma once
// The newest good message of a channel, for a process that cannot always
// keep up with its input: it works on the newest message and counts those it
// skipped (the design's rule), and says each bad one without losing a good one.

#include <cstdint>
#include <functional>
#include <iostream>
#include <optional>
#include <string>
#include <utility>

#include <lcm/lcm-cpp.hpp>

#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"

namespace ld {

/// Keeps the newest good message of one channel. Each message is decoded
/// (ld::decodeMessage) and checked as it arrives, so a bad one is said at
/// once, in one line on stderr ("PROGRAM: dropped WHAT: WHY (N bad so far)",
/// thinned out as printBadLine says), and never takes the place of a good
/// one waiting to be processed; a good one that does counts as skipped.
/// Given the messages' sequence numbers, it also counts those that never
/// came: the gaps between one good message's seq and the next (lost before
/// the process, in the kernel's receive buffer, on the network or at the
/// source; a bad message's seq is not trusted, so a bad frame in the run
/// counts as bad and as missing). A seq up to kReorderedSeqs back is a
/// frame reordered on the way, no longer missing; one further back (a
/// source restarted, a log replayed again) starts anew. One publisher a
/// channel: two interleaved would read as gaps. The two
/// messages it holds keep their buffers: nothing is allocated once warm.
template <class Msg>
class LatestMessage {
 public:
  /// Why a decoded message is no good all the same, as said after
  /// "dropped WHAT: "; "" when it is good.
  using Check = std::function<std::string(const Msg&)>;
  /// A message's sequence number, if it has one.
  using SeqOf = std::function<std::optional<int64_t>(const Msg&)>;
  /// Whether two messages are of the same frame: one that comes while the
  /// other waits is a repeat (repeated()), not a newer one replacing it.
  using SameFrame = std::function<bool(const Msg&, const Msg&)>;

  /// `program` and `what` ("frame", "message") name the dropped line.
  LatestMessage(std::string program, std::string channel, std::string what, Check check = {}, SeqOf seq_of = {},
                SameFrame same_frame = {})
      : program_(std::move(program)), channel_(std::move(channel)), what_(std::move(what)),
        check_(std::move(check)), seq_of_(std::move(seq_of)), same_frame_(std::move(same_frame)) {}

  /// The LCM handler: latest.queueOn(lcm.subscribe(channel, &LatestMessage<Msg>::onMessage, &latest)).
  void onMessage(const lcm::ReceiveBuffer* rbuf, const std::string& = {}) {
    queue_.fit(rbuf->data_size);
    std::string why;
    if (!decodeMessage(rbuf->data, rbuf->data_size, incoming_, &why))
      why = "message on " + channel_ + " is " + why;
    else if (check_)
      why = check_(incoming_);
    if (!why.empty()) return reportBad(why);
    if (pending_ && same_frame_ && same_frame_(incoming_, newest_)) {
      ++repeated_;  // (the frame waiting, again: not a newer frame that skipped it)
      return;
    }
    countGap();
    if (pending_) ++skipped_;
    std::swap(incoming_, newest_);
    pending_ = true;
  }

  /// The newest good message not taken yet, or nullptr. It stays as it is
  /// until the next onMessage (LCM's handlers run within handle() alone).
  const Msg* take() {
    if (!pending_) return nullptr;
    pending_ = false;
    return &newest_;
  }

  /// Says a bad input and counts it, as onMessage does (for a message found
  /// bad only when it is processed, as an MJPEG frame's JPEG data is).
  void reportBad(const std::string& why) {
    if (printBadLine(++bad_))
      std::cerr << program_ << ": dropped " << what_ << ": " << why << " " << badSoFar(bad_) << "\n";
  }

  /// The subscription, for its queue's byte budget (ld::QueueFit).
  void queueOn(lcm::Subscription* subscription) { queue_ = QueueFit(subscription); }

  int64_t skipped() const { return skipped_; }  ///< good messages that a newer one replaced
  int64_t bad() const { return bad_; }          ///< messages said bad
  /// Messages that never came, by the gaps in their seqs (0 without SeqOf).
  int64_t missing() const { return missing_; }
  /// Messages of the frame waiting, come again (with SameFrame).
  int64_t repeated() const { return repeated_; }
  /// How far back a seq may be and be a reordered frame, not a new run.
  static constexpr int64_t kReorderedSeqs = 3;

 private:
  void countGap() {
    if (!seq_of_) return;
    const std::optional<int64_t> seq = seq_of_(incoming_);
    if (!seq || *seq < 0) return;  // (a negative seq is none)
    if (last_seq_ && *seq > *last_seq_) {
      const int64_t gap = *seq - 1 - *last_seq_;  // (both 0 or more: no overflow)
      missing_ = gap > INT64_MAX - missing_ ? INT64_MAX : missing_ + gap;
    } else if (last_seq_ && *seq < *last_seq_ && *last_seq_ - *seq <= kReorderedSeqs) {
      // (a frame that came after its successor: counted missing when the
      // successor came, it is here after all; the run goes on from there)
      if (missing_ > 0) --missing_;
      return;
    }
    last_seq_ = seq;
  }

  std::string program_, channel_, what_;
  Check check_;
  SeqOf seq_of_;
  SameFrame same_frame_;
  std::optional<int64_t> last_seq_;
  QueueFit queue_;
  Msg incoming_, newest_;
  bool pending_ = false;
  int64_t skipped_ = 0, bad_ = 0, missing_ = 0, repeated_ = 0;
};

}  // namespace ld
