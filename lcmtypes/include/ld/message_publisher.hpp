#pragma once
// Publishing without an allocation per message.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

namespace ld {

/// `text` as an LCM string can carry it. LCM's encoders end a string at its
/// first NUL byte while its size counts them all, so a message holding one
/// encodes short and is never sent. Each NUL (a QR code's byte-mode payload
/// may hold one) becomes U+FFFD, the replacement character.
inline std::string lcmString(std::string text) {
  for (size_t at = text.find('\0'); at != std::string::npos; at = text.find('\0', at + 3))
    text.replace(at, 1, "\xEF\xBF\xBD");
  return text;
}

/// Publishes messages on an LCM instance through one encoding buffer kept
/// between calls. lcm::LCM::publish(channel, &msg) allocates a buffer of the
/// encoded size for every message, a whole frame for an image; this buffer
/// only grows (to the largest message so far), so nothing is allocated once
/// warm (the design's rule for hot paths).
class MessagePublisher {
 public:
  explicit MessagePublisher(lcm::LCM& lcm) : lcm_(lcm) {}

  /// As lcm::LCM::publish: 0 when sent, -1 when the message cannot be
  /// encoded or LCM refuses it.
  template <class Msg>
  int publish(const std::string& channel, const Msg& msg) {
    const int n = msg.getEncodedSize();
    if (n < 0) return -1;
    if (buffer_.size() < static_cast<size_t>(n)) buffer_.resize(static_cast<size_t>(n));
    if (msg.encode(buffer_.data(), 0, n) != n) return -1;
    return lcm_.publish(channel, buffer_.data(), static_cast<unsigned>(n));
  }

  /// The buffer's start and size (for tests: it moves only when it grows).
  const uint8_t* buffer() const { return buffer_.data(); }
  size_t bufferSize() const { return buffer_.size(); }

 private:
  lcm::LCM& lcm_;
  std::vector<uint8_t> buffer_;
};

}  // namespace ld
