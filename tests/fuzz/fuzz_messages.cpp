// Fuzz target: every message type as it comes off the bus
// (ld/message_decode.hpp), and what the processes do with a list that
// decodes: the tracker (ld-tracker) and the QR reader's rectification
// (ld-qr-reader) on its landmarks.
//
// Byte 0 picks the type (image_t, landmark_list_t, qr_code_list_t); the rest
// is the encoded message. A message that decodes must encode back to exactly
// the same bytes; the tracker's output for it must decode again.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "ld/image_convert.hpp"
#include "ld/message_decode.hpp"
#include "ld/qr_reader.hpp"
#include "ld/tracker.hpp"
#include "ld/tracker_msg.hpp"

namespace {

template <class T>
void checkRoundTrip(const uint8_t* data, size_t size, const T& msg) {
  std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
  const int n = msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  if (n != static_cast<int>(size) || buf.size() != size || std::memcmp(buf.data(), data, size) != 0)
    std::abort();
}

void trackAndRead(const ld::landmark_list_t& list) {
  std::vector<ld::Landmark> detections;
  ld::landmarksFromList(list, detections);
  ld::Tracker tracker;
  ld::landmark_list_t out;
  // two frames at the message's utime and at its seq: any pair of times, as
  // a process may receive them
  for (const int64_t utime : {list.utime, list.seq}) {
    const auto& tracks = tracker.update(detections, utime);
    ld::toTrackedListMessage(tracks, list, 0.5, 0, out);
    std::vector<uint8_t> buf(static_cast<size_t>(out.getEncodedSize()));
    if (out.encode(buf.data(), 0, static_cast<int>(buf.size())) != static_cast<int>(buf.size()))
      std::abort();
    ld::landmark_list_t again;
    if (!ld::decodeMessage(buf.data(), buf.size(), again)) std::abort();
  }
  static ld::QrReader reader;
  static const cv::Mat image(48, 64, CV_8UC3, cv::Scalar(200, 200, 200));
  for (size_t i = 0; i < list.landmarks.size() && i < 2; ++i) {
    std::array<cv::Point2f, 4> corners;
    for (size_t k = 0; k < 4; ++k)
      corners[k] = {list.landmarks[i].corners[k][0], list.landmarks[i].corners[k][1]};
    (void)reader.decode(image, corners);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t* msg = data + 1;
  const size_t n = size - 1;
  switch (data[0] % 3) {
    case 0: {
      ld::image_t image;
      if (!ld::decodeMessage(msg, n, image)) return 0;
      checkRoundTrip(msg, n, image);
      (void)ld::imageSeq(image);
      break;
    }
    case 1: {
      ld::landmark_list_t list;
      if (!ld::decodeMessage(msg, n, list)) return 0;
      checkRoundTrip(msg, n, list);
      trackAndRead(list);
      break;
    }
    default: {
      ld::qr_code_list_t codes;
      if (!ld::decodeMessage(msg, n, codes)) return 0;
      checkRoundTrip(msg, n, codes);
      break;
    }
  }
  return 0;
}
