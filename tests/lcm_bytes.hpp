// LCM messages as bytes, for the tests and test tools that build malformed
// encodings by hand (test_message_decode, ld-publish-garbage, ld-fuzz-seeds).
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace ld::test {

using Bytes = std::vector<uint8_t>;

/// `msg` encoded as LCM sends it (fingerprint first), after one `prefix`
/// byte when given (the fuzz targets' message-type selector).
template <class T>
Bytes lcmEncode(const T& msg, int prefix = -1) {
  const size_t at = prefix >= 0 ? 1 : 0;
  Bytes b(at + static_cast<size_t>(msg.getEncodedSize()));
  if (prefix >= 0) b[0] = static_cast<uint8_t>(prefix);
  if (msg.encode(b.data() + at, 0, static_cast<int>(b.size() - at)) != static_cast<int>(b.size() - at))
    throw std::logic_error("lcmEncode: the message did not encode");
  return b;
}

/// Overwrites the 32-bit integer at byte `at` (big-endian, as LCM encodes
/// integers): a count, a length or a size made to lie.
inline void putI32(Bytes& b, size_t at, int64_t v) {
  const auto u = static_cast<uint32_t>(v);
  for (int i = 0; i < 4; ++i) b.at(at + static_cast<size_t>(i)) = static_cast<uint8_t>(u >> (24 - 8 * i));
}

}  // namespace ld::test
