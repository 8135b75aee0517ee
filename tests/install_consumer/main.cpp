// Detects the landmarks of one image with the installed library, reads their
// QR codes, and sends the list through the LCM message's encode/decode, as a
// robot program linking the libraries would. Prints one line per landmark:
//   <payload> <TL corner x> <TL corner y>
#include <cstdio>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "ld/detector.hpp"
#include "ld/landmark_msg.hpp"
#include "ld/qr_reader.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: consumer IMAGE\n");
    return 2;
  }
  const cv::Mat image = cv::imread(argv[1], cv::IMREAD_COLOR);
  if (image.empty()) {
    std::fprintf(stderr, "consumer: cannot read %s\n", argv[1]);
    return 2;
  }
  ld::Detector detector;
  ld::QrReader reader;
  ld::Detection det = detector.detect(image);
  for (ld::Landmark& lm : det.landmarks)
    if (auto code = reader.decode(image, lm.corners)) lm.payload = code->payload;

  ld::landmark_list_t msg;
  ld::toListMessage(det, 1, 1, image.cols, image.rows, "cpu", 0, msg);
  std::vector<uint8_t> bytes(msg.getEncodedSize());
  if (msg.encode(bytes.data(), 0, static_cast<int>(bytes.size())) != static_cast<int>(bytes.size())) return 1;
  ld::landmark_list_t back;
  if (back.decode(bytes.data(), 0, static_cast<int>(bytes.size())) != static_cast<int>(bytes.size())) return 1;
  for (const ld::landmark_t& m : back.landmarks) {
    const ld::Landmark lm = ld::fromMessage(m);
    std::printf("%s %.1f %.1f\n", lm.payload ? lm.payload->c_str() : "-", lm.corners[0].x, lm.corners[0].y);
  }
  return 0;
}
