// ld-publish-garbage: publishes malformed messages on a channel, for fault
// tests: random bytes, a truncated image_t, an image_t whose size does not
// match its format, and one with an unknown pixel format.
#include <iostream>
#include <random>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/image_convert.hpp"
#include "ld/lcm_url.hpp"

int main(int argc, char** argv) {
  CLI::App app{"Publish malformed messages (test helper)."};
  std::string url = ld::defaultLcmUrl(), channel = "IMAGE";
  app.add_option("--lcm-url", url);
  app.add_option("--channel", channel);
  CLI11_PARSE(app, argc, argv);
  lcm::LCM lcm(url);
  if (!lcm.good()) return 2;

  std::mt19937 rng(1);
  std::vector<uint8_t> junk(1000);
  for (auto& b : junk) b = static_cast<uint8_t>(rng());
  lcm.publish(channel, junk.data(), static_cast<unsigned>(junk.size()));

  ld::image_t img = ld::matToImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3)),
                                   ld::image_t::PIXEL_FORMAT_BGR, 1, 0);
  std::vector<uint8_t> buf(static_cast<size_t>(img.getEncodedSize()));
  img.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm.publish(channel, buf.data(), static_cast<unsigned>(buf.size() / 2));  // truncated

  ld::image_t bad = img;
  bad.width = 640;
  bad.height = 480;  // 9216 bytes cannot hold 640x480 BGR
  lcm.publish(channel, &bad);

  bad = img;
  bad.pixelformat = ld::fourcc('H', '2', '6', '4');
  lcm.publish(channel, &bad);
  std::cout << "published 4 malformed messages on " << channel << "\n";
  return 0;
}
