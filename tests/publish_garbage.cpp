// ld-publish-garbage: publishes malformed messages on a channel, for fault
// tests: random bytes, a truncated image_t, an image_t whose size does not
// match its format, one with an unknown pixel format, and the encodings that
// LCM's generated decoders cannot take (see ld/message_decode.hpp): counts of
// 2^31-1 in each message type, a string of length 0, an image claiming 2 GB
// of data, and an MJPEG frame whose header claims 30000x30000. Every one of
// them is malformed for every message type, whatever the channel carries.
#include <chrono>
#include <iostream>
#include <random>
#include <thread>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "lcm_bytes.hpp"
#include "ld/cli.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/lcm_url.hpp"
#include "ld/qr_code_list_t.hpp"

using ld::test::lcmEncode;
using ld::test::putI32;

int main(int argc, char** argv) {
  CLI::App app{"Publish malformed messages (test helper)."};
  std::string url = ld::defaultLcmUrl(), channel = "IMAGE";
  int interval_ms = 0;
  app.add_option("--lcm-url", url);
  app.add_option("--channel", channel);
  app.add_option("--interval-ms", interval_ms, "pause between messages (receivers that keep only "
                                               "the newest message then see each one)");
  int big_list = 0;
  app.add_option("--big-list", big_list, "instead, one well-formed landmark_list_t of this many landmarks "
                                         "(more than a tracker takes)");
  std::string interleave;
  app.add_option("--interleave", interleave,
                 "instead, publish this log's messages on --channel, each followed at once by one of the "
                 "malformed ones (in turn), the pairs --interval-ms apart: a bad message that comes before a "
                 "good one was processed");
  LD_CLI_PARSE(app, argc, argv);
  lcm::LCM lcm(url);
  if (!lcm.good()) return 2;
  if (big_list > 0) {
    ld::landmark_list_t list{};
    list.backend = "cpu";
    list.nlandmarks = big_list;
    list.landmarks.resize(static_cast<size_t>(big_list));
    for (int k = 0; k < big_list; ++k) {  // 30 px squares, overlapping, as a clump
      ld::landmark_t& lm = list.landmarks[static_cast<size_t>(k)];
      const float x = static_cast<float>(20 + (k * 7) % 600), y = static_cast<float>(20 + (k * 13) % 440);
      const float c[4][2] = {{x, y}, {x + 30, y}, {x + 30, y + 30}, {x, y + 30}};
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 2; ++j) lm.corners[i][j] = c[i][j];
      lm.track_id = -1;
    }
    lcm.publish(channel, &list);
    std::cout << "published a list of " << big_list << " landmarks on " << channel << "\n";
    return 0;
  }

  std::vector<std::vector<uint8_t>> messages;
  std::mt19937 rng(1);
  std::vector<uint8_t> junk(1000);
  for (auto& b : junk) b = static_cast<uint8_t>(rng());
  messages.push_back(junk);

  const ld::image_t img = ld::matToImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3)),
                                         ld::image_t::PIXEL_FORMAT_BGR, 1, 0);
  std::vector<uint8_t> buf = lcmEncode(img);
  messages.emplace_back(buf.begin(), buf.begin() + static_cast<long>(buf.size() / 2));  // truncated

  ld::image_t bad = img;
  bad.width = 640;
  bad.height = 480;  // 9216 bytes cannot hold 640x480 BGR
  messages.push_back(lcmEncode(bad));

  bad = img;
  bad.pixelformat = ld::fourcc('H', '2', '6', '4');
  messages.push_back(lcmEncode(bad));

  buf = lcmEncode(img);
  putI32(buf, 8 + 8 + 4 * 4, 0x7ffffff0);  // size: 2 GB that are not there
  messages.push_back(buf);

  ld::image_t jpeg = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)),
                                    ld::image_t::PIXEL_FORMAT_MJPEG, 1, 0);
  for (size_t i = 2; i + 9 < jpeg.data.size(); ++i)
    if (jpeg.data[i] == 0xFF && jpeg.data[i + 1] == 0xC0) {  // SOF0: height, width = 30000
      jpeg.data[i + 5] = jpeg.data[i + 7] = 30000 >> 8;
      jpeg.data[i + 6] = jpeg.data[i + 8] = 30000 & 0xff;
      break;
    }
  jpeg.width = jpeg.height = 0;
  messages.push_back(lcmEncode(jpeg));

  ld::landmark_list_t list{};
  list.backend = "cpu";
  buf = lcmEncode(list);
  const size_t backend_len = 8 + 8 + 8 + 4 + 4, nstages = backend_len + 4 + 4 + 8;
  putI32(buf, nstages, 0x7fffffff);  // 2^31-1 stage names
  messages.push_back(buf);
  buf = lcmEncode(list);
  putI32(buf, backend_len, 0);  // a string of length 0
  messages.push_back(buf);

  ld::qr_code_list_t codes{};
  buf = lcmEncode(codes);
  putI32(buf, 8 + 8 + 8, 0x7fffffff);  // 2^31-1 codes
  messages.push_back(buf);

  if (!interleave.empty()) {
    lcm::LogFile log(interleave, "r");
    if (!log.good()) {
      std::cerr << "ld-publish-garbage: cannot read " << interleave << "\n";
      return 2;
    }
    size_t good = 0;
    while (const lcm::LogEvent* e = log.readNextEvent()) {
      if (e->channel != channel) continue;
      const auto& m = messages[good % messages.size()];
      lcm.publish(channel, e->data, static_cast<unsigned>(e->datalen));
      lcm.publish(channel, m.data(), static_cast<unsigned>(m.size()));
      ++good;
      if (interval_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(interval_ms));
    }
    std::cout << "published " << good << " messages of the log on " << channel << ", each followed by a malformed one\n";
    return 0;
  }
  for (const auto& m : messages) {
    lcm.publish(channel, m.data(), static_cast<unsigned>(m.size()));
    if (interval_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(interval_ms));
  }
  std::cout << "published " << messages.size() << " malformed messages on " << channel << "\n";
  return 0;
}
