#include "ld/message_decode.hpp"

#include <cstdint>
#include <cstring>
#include <limits>

namespace ld {
namespace {

// The fingerprints of the types' earlier versions (lcm-gen's getHash() of
// the .lcm files as they were), with what changed since.
struct EarlierVersion {
  uint64_t hash;
  const char* what;
};
constexpr EarlierVersion kEarlierVersions[] = {
    {0x553eb387ecca27c4ULL, "ld.qr_code_list_t before withheld_track_ids (2026-12-07)"},
};

std::string earlierVersionOf(int64_t hash) {
  for (const EarlierVersion& v : kEarlierVersions)
    if (static_cast<int64_t>(v.hash) == hash) return v.what;
  return "";
}

// Walks an LCM encoding (big-endian, counts as int32, strings as an int32
// length that includes the terminating zero) and records the first problem.
class Walker {
 public:
  Walker(const void* data, size_t size) : p_(static_cast<const uint8_t*>(data)), n_(size) {}

  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  size_t pos() const { return pos_; }

  void skip(size_t bytes, const char* what) {
    if (!ok()) return;
    if (bytes > n_ - pos_) return fail(std::string("truncated in ") + what);
    pos_ += bytes;
  }
  int64_t i64(const char* what) {
    uint64_t v = 0;
    if (take(8, what))
      for (int i = 0; i < 8; ++i) v = (v << 8) | p_[pos_ - 8 + i];
    return static_cast<int64_t>(v);
  }
  int32_t i32(const char* what) {
    uint32_t v = 0;
    if (take(4, what))
      for (int i = 0; i < 4; ++i) v = (v << 8) | p_[pos_ - 4 + i];
    return static_cast<int32_t>(v);
  }
  void boolean(const char* what) {
    if (take(1, what) && p_[pos_ - 1] > 1)
      fail(std::string("boolean ") + what + " is " + std::to_string(p_[pos_ - 1]));
  }
  void string(const char* what) {
    const int32_t len = i32(what);
    if (!ok()) return;
    if (len < 1) return fail(std::string("string ") + what + " has length " + std::to_string(len));
    const size_t start = pos_;
    skip(static_cast<size_t>(len), what);
    if (!ok()) return;
    // LCM strings are C strings: one terminating zero, none before it (the
    // generated encoder measures them with strlen)
    const size_t chars = static_cast<size_t>(len) - 1;
    if (p_[start + chars] != 0 || std::memchr(p_ + start, 0, chars) != nullptr) {
      pos_ = start;
      fail(std::string("string ") + what + " is not a C string");
    }
  }
  // A count of elements that take at least `min_bytes` each: it must be >= 0
  // and the elements must fit in what is left.
  int32_t count(const char* what, size_t min_bytes) {
    const int32_t c = i32(what);
    if (!ok()) return 0;
    if (c < 0) {
      fail(std::string(what) + " is negative (" + std::to_string(c) + ")");
      return 0;
    }
    if (static_cast<size_t>(c) > (n_ - pos_) / min_bytes) {
      fail(std::string(what) + " " + std::to_string(c) + " does not fit in the " +
           std::to_string(n_ - pos_) + " bytes left");
      return 0;
    }
    return c;
  }
  void hash(int64_t expected, const char* type) {
    const int64_t h = i64("fingerprint");
    if (!ok() || h == expected) return;
    const std::string earlier = earlierVersionOf(h);
    if (earlier.empty()) return fail(std::string("fingerprint is not ") + type + "'s");
    error_ = std::string("fingerprint is not ") + type + "'s but that of " + earlier +
             ", an earlier version no longer decoded (a recording by an older build?)";
  }
  void end() {
    if (ok() && pos_ != n_) fail(std::to_string(n_ - pos_) + " bytes after the message");
  }

 private:
  bool take(size_t bytes, const char* what) {
    if (!ok()) return false;
    if (bytes > n_ - pos_) {
      fail(std::string("truncated in ") + what);
      return false;
    }
    pos_ += bytes;
    return true;
  }
  void fail(const std::string& what) {
    if (ok()) error_ = what + " at byte " + std::to_string(pos_);
  }

  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  std::string error_;
};

void walkMetadata(Walker& w) {
  w.string("metadata key");
  const int32_t n = w.count("metadata value size", 1);
  w.skip(static_cast<size_t>(n), "metadata value");
}

void walkImage(Walker& w) {
  w.skip(8 + 4 * 4, "image header");  // utime, width, height, row_stride, pixelformat
  const int32_t size = w.count("image size", 1);
  w.skip(static_cast<size_t>(size), "image data");
  const int32_t nmetadata = w.count("nmetadata", 4 + 1 + 4);  // the smallest entry: "" and 0 bytes
  for (int32_t i = 0; i < nmetadata && w.ok(); ++i) walkMetadata(w);
}

constexpr size_t kLandmarkMinBytes = 16 * 4 + 4 + 1 + 5 + 1 + 7 * 8 + 8 + 4 + 4 + 8 + 1;

void walkLandmark(Walker& w) {
  w.skip(16 * 4 + 4, "landmark points");  // fip_tl, fip_tr, fip_bl, ap, corners, score
  w.boolean("has_payload");
  w.string("payload");
  w.boolean("pose_valid");
  w.skip(7 * 8 + 8 + 4 + 4 + 8, "landmark pose and track");  // t, rvec, distance, track_id, ...
  w.boolean("visible");
}

void walkLandmarkList(Walker& w) {
  w.skip(8 + 8 + 4 + 4, "list header");  // utime, seq, width, height
  w.string("backend");
  w.skip(8, "frames_skipped");
  const int32_t nstages = w.count("nstages", 5 + 4);  // "" and a float
  for (int32_t i = 0; i < nstages && w.ok(); ++i) w.string("stage name");
  w.skip(static_cast<size_t>(nstages) * 4, "stage_ms");
  const int32_t nlandmarks = w.count("nlandmarks", kLandmarkMinBytes);
  for (int32_t i = 0; i < nlandmarks && w.ok(); ++i) walkLandmark(w);
}

constexpr size_t kQrCodeMinBytes = 8 + 5 + 8 + 8 + 8 * 4 + 4;

void walkQrCodeList(Walker& w) {
  w.skip(8 + 8, "list header");  // utime, seq
  const int32_t ncodes = w.count("ncodes", kQrCodeMinBytes);
  for (int32_t i = 0; i < ncodes && w.ok(); ++i) {
    w.skip(8, "track_id");
    w.string("payload");
    w.skip(8 + 8 + 8 * 4 + 4, "code fields");  // utime, seq, corners, decode_ms
  }
  const int32_t nwithheld = w.count("nwithheld", 8);
  w.skip(static_cast<size_t>(nwithheld) * 8, "withheld_track_ids");
}

template <class T, class Walk>
bool decodeChecked(const void* data, size_t size, T& out, std::string* error, const char* type,
                   Walk walk) {
  Walker w(data, size);
  if (size > static_cast<size_t>(std::numeric_limits<int>::max())) {
    if (error) *error = std::string(type) + ": message of " + std::to_string(size) + " bytes";
    return false;
  }
  w.hash(static_cast<int64_t>(T::getHash()), type);
  walk(w);
  w.end();
  const int n = static_cast<int>(size);
  if (w.ok() && out.decode(data, 0, n) == n) return true;
  if (error)
    *error = std::string("not a valid ") + type + " (" + std::to_string(size) + " bytes): " +
             (w.ok() ? std::string("rejected by its decoder") : w.error());
  return false;
}

}  // namespace

// (lcm-gen's decoder resizes an array of bytes or numbers only when its
// length is not 0: an empty one would keep a reused message's old values)
bool decodeMessage(const void* data, size_t size, image_t& out, std::string* error) {
  if (!decodeChecked(data, size, out, error, "ld.image_t", walkImage)) return false;
  if (out.size == 0) out.data.clear();
  for (auto& m : out.metadata)
    if (m.n == 0) m.value.clear();
  return true;
}

bool decodeMessage(const void* data, size_t size, landmark_list_t& out, std::string* error) {
  if (!decodeChecked(data, size, out, error, "ld.landmark_list_t", walkLandmarkList)) return false;
  if (out.nstages == 0) out.stage_ms.clear();
  return true;
}

int64_t fingerprintOf(const void* data, size_t size) {
  if (size < 8) return 0;
  const auto* p = static_cast<const uint8_t*>(data);
  uint64_t h = 0;
  for (int i = 0; i < 8; ++i) h = (h << 8) | p[i];
  return static_cast<int64_t>(h);
}

std::string earlierTypeVersion(const void* data, size_t size) {
  return size < 8 ? "" : earlierVersionOf(fingerprintOf(data, size));
}

void takeCodes(const qr_code_list_t& codes, std::map<int64_t, std::string>& payloads) {
  // (each message is the whole of what is known for its frame's tracks: a
  // payload it leaves out is forgotten, withheld, or of a track dropped;
  // merged into the last, they stayed for ever)
  payloads.clear();
  for (const auto& c : codes.codes) payloads[c.track_id] = c.payload;
}

bool decodeMessage(const void* data, size_t size, qr_code_list_t& out, std::string* error) {
  if (!decodeChecked(data, size, out, error, "ld.qr_code_list_t", walkQrCodeList)) return false;
  if (out.nwithheld == 0) out.withheld_track_ids.clear();
  return true;
}

}  // namespace ld
