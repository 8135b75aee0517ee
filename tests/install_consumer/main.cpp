// Detects the landmarks of one image with the installed library, reads their
// QR codes, tracks them over two frames of it, and publishes the tracked list
// over LCM (memq://, in this process) with ld::MessagePublisher and reads it
// back, as a robot program linking the libraries would. Prints one line per
// landmark:
//   <payload> <TL corner x> <TL corner y> <track id>
#include <cstdio>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include <lcm/lcm-cpp.hpp>

#include "ld/detector.hpp"
#include "ld/landmark_msg.hpp"
#include "ld/message_publisher.hpp"
#include "ld/qr_reader.hpp"
#include "ld/tracker.hpp"
#include "ld/tracker_msg.hpp"

namespace {
struct Receiver {
  ld::landmark_list_t list;
  int got = 0;
  void on(const lcm::ReceiveBuffer*, const std::string&, const ld::landmark_list_t* m) {
    list = *m;
    ++got;
  }
};
}  // namespace

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

  ld::landmark_list_t detected, msg;
  ld::toListMessage(det, 1'033'000, 2, image.cols, image.rows, "cpu", 0, detected);
  ld::Tracker tracker;
  tracker.update(det.landmarks, 1'000'000, image.size());
  const std::vector<ld::Track>& tracks = tracker.update(det.landmarks, 1'033'000, image.size());
  ld::toTrackedListMessage(tracks, detected, 0.0, 0, msg);
  // (through LCM in this process, as a robot node publishes it)
  lcm::LCM lcm("memq://");
  if (!lcm.good()) return 1;
  Receiver back;
  lcm.subscribe("LANDMARKS", &Receiver::on, &back);
  ld::MessagePublisher publisher(lcm);
  if (publisher.publish("LANDMARKS", msg) != 0 || lcm.handleTimeout(1000) <= 0 || back.got != 1) return 1;
  for (const ld::landmark_t& m : back.list.landmarks) {
    const ld::Landmark lm = ld::fromMessage(m);
    std::printf("%s %.1f %.1f %lld\n", lm.payload ? lm.payload->c_str() : "-", lm.corners[0].x, lm.corners[0].y,
                static_cast<long long>(m.track_id));
  }
  return 0;
}
