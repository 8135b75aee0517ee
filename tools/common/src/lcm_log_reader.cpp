#include "ld/lcm_log_reader.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "ld/file_checks.hpp"

namespace ld {

namespace {
constexpr uint8_t kMagic[4] = {kLcmLogMagic >> 24, (kLcmLogMagic >> 16) & 0xff, (kLcmLogMagic >> 8) & 0xff,
                               kLcmLogMagic & 0xff};
}  // namespace

LcmLogReader::LcmLogReader(const std::string& path) : f_(path, std::ios::binary) {
  f_.seekg(0, std::ios::end);
  size_ = static_cast<int64_t>(f_.tellg());
  f_.seekg(0);
}

bool LcmLogReader::next(bool read_data) {
  for (;;) {
    const int64_t left = size_ - offset_;
    if (left <= 0) return false;
    uint8_t h[kLcmLogHeaderBytes];
    const size_t got = readAt(offset_, h, static_cast<size_t>(std::min<int64_t>(left, sizeof h)));
    const auto be = [&h](size_t at, int bytes) {
      uint64_t v = 0;
      for (int i = 0; i < bytes; ++i) v = (v << 8) | h[at + i];
      return v;
    };
    if (std::memcmp(h, kMagic, std::min<size_t>(got, 4)) != 0) {  // (a cut magic is the start of one)
      if (skipToNextEvent()) continue;
      return fail("unreadable data", "at byte " + std::to_string(offset_) + " no LCM event starts");
    }
    if (got < sizeof h) return fail("the log ends mid-event", std::to_string(left) + " bytes of an event header");
    // (the header's lengths are unsigned: 0xFFFFFFF0 is 4294967280 bytes, not -16)
    const int64_t channel_len = be(20, 4), data_len = be(24, 4);
    if (channel_len <= 0 || channel_len > 1024 || data_len > INT32_MAX) {
      if (skipToNextEvent()) continue;
      return fail("unreadable data", "at byte " + std::to_string(offset_) + " an event header with a channel of " +
                                         std::to_string(channel_len) + " bytes and " + std::to_string(data_len) +
                                         " bytes of data");
    }
    const int64_t need = static_cast<int64_t>(sizeof h) + channel_len + data_len;
    // A whole event ends at the end of the file or where the next one
    // starts; one that does not was cut off, when another starts inside it.
    const bool whole = need == left || (need < left && magicAt(offset_ + need));
    if (!whole && skipToNextEvent(offset_ + need)) continue;
    if (need > left)
      return fail("the log ends mid-event", std::to_string(left) + " of the event's " + std::to_string(need) + " bytes");
    timestamp = static_cast<int64_t>(be(12, 8));
    channel.resize(static_cast<size_t>(channel_len));
    data.resize(read_data ? static_cast<size_t>(data_len) : 0);
    if (readAt(offset_ + static_cast<int64_t>(sizeof h), reinterpret_cast<uint8_t*>(channel.data()), channel.size()) !=
            channel.size() ||
        readAt(offset_ + static_cast<int64_t>(sizeof h) + channel_len, data.data(), data.size()) != data.size())
      return fail("cannot read the log", std::strerror(errno));
    offset_ += need;
    ++messages_;
    return true;
  }
}

std::string LcmLogReader::problem() const {
  std::string p;
  if (skipped_bytes_ > 0)
    p = "skipped " + std::to_string(skipped_bytes_) + " bytes that are no whole LCM event (" +
        (skips_ == 1 ? "at byte " : std::to_string(skips_) + " places, the first at byte ") +
        std::to_string(first_skip_) + "), read " + std::to_string(messages_) +
        (messages_ == 1 ? " message" : " messages");
  if (!end_problem_.empty()) p += (p.empty() ? "" : "; ") + end_problem_;
  return p;
}

size_t LcmLogReader::readAt(int64_t at, uint8_t* to, size_t n) {
  f_.clear();
  f_.seekg(at);
  f_.read(reinterpret_cast<char*>(to), static_cast<std::streamsize>(n));
  return static_cast<size_t>(f_.gcount());
}

bool LcmLogReader::magicAt(int64_t at) {
  uint8_t m[4];
  return readAt(at, m, 4) == 4 && std::memcmp(m, kMagic, 4) == 0;
}

bool LcmLogReader::skipToNextEvent(int64_t before) {
  const int64_t end = before < 0 ? size_ : std::min(before, size_);
  std::vector<uint8_t> buf(1 << 16);
  for (int64_t at = offset_ + 1; at < end;) {
    const size_t got = readAt(at, buf.data(), static_cast<size_t>(std::min<int64_t>(end - at + 3, buf.size())));
    if (got < 4) break;
    const auto* hit = std::search(buf.data(), buf.data() + got, kMagic, kMagic + 4);
    if (hit != buf.data() + got && at + (hit - buf.data()) < end) {
      const int64_t pos = at + (hit - buf.data());
      if (skips_++ == 0) first_skip_ = offset_;
      skipped_bytes_ += pos - offset_;
      offset_ = pos;
      return true;
    }
    at += static_cast<int64_t>(got) - 3;  // a magic may straddle two reads
  }
  return false;
}

bool LcmLogReader::fail(const std::string& what, const std::string& detail) {
  end_problem_ = what + " after " + std::to_string(messages_) + (messages_ == 1 ? " message" : " messages") + " (" +
                 detail + ")";
  return false;
}

namespace {
std::string shortNumber(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}
}  // namespace

std::string LogSpan::problem() const {
  return to_s < from_s ? "--to " + shortNumber(to_s) + " is before --from " + shortNumber(from_s) : "";
}

std::string LogSpan::text() const {
  return "from " + shortNumber(from_s) + (std::isfinite(to_s) ? " to " + shortNumber(to_s) + " s" : " s on");
}

std::string describeChannels(const ChannelCounts& counts) {
  std::string out;
  for (const auto& [name, n] : counts) out += (out.empty() ? "" : ", ") + name + " (" + std::to_string(n) + ")";
  return out;
}

}  // namespace ld
