// ld-tracker-testlog: writes an LCM log of LANDMARKS messages with known
// tracks, for the ld-tracker process test: landmark A static, B moving right
// 6 px per frame, C hidden for frames 10-14 (0.25 s at 20 frames/s) and seen
// again where it was. Frames are 50 ms apart in utime and in log time.
#include <cmath>
#include <cstdio>
#include <iostream>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/landmark_msg.hpp"

namespace {

ld::Landmark square(float cx, float cy, float side) {
  const float h = side / 2, q = side * 3 / 8;
  ld::Landmark lm;
  lm.corners = {cv::Point2f(cx - h, cy - h), cv::Point2f(cx + h, cy - h),
                cv::Point2f(cx + h, cy + h), cv::Point2f(cx - h, cy + h)};
  lm.fip_tl = {cx - q, cy - q};
  lm.fip_tr = {cx + q, cy - q};
  lm.fip_bl = {cx - q, cy + q};
  lm.ap = {cx + q, cy + q};
  lm.score = 1;
  return lm;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-tracker-testlog: a LANDMARKS log with three known tracks (tests)."};
  std::string out, channel = "LANDMARKS";
  int frames = 40;
  app.add_option("--out", out, "log file to write")->required();
  app.add_option("--channel", channel, "channel")->capture_default_str();
  app.add_option("--frames", frames, "frames")->check(ld::cli::Positive)->capture_default_str();
  int non_finite_at = -1;
  app.add_option("--non-finite-at", non_finite_at,
                 "frame whose list also holds a landmark with NaN corners (a fourth, never tracked)");
  LD_CLI_PARSE(app, argc, argv);

  lcm::LogFile log(out, "w");
  if (!log.good()) {
    std::cerr << "ld-tracker-testlog: cannot write " << out << "\n";
    return 2;
  }
  const int64_t t0 = 1'700'000'000'000'000;
  for (int k = 0; k < frames; ++k) {
    ld::landmark_list_t msg{};
    msg.utime = t0 + k * 50'000;
    msg.seq = 1000 + k;
    msg.width = 640;
    msg.height = 480;
    msg.backend = "cpu";
    msg.nstages = 1;
    msg.stage_names = {"saturation"};
    msg.stage_ms = {0.5f};
    ld::Landmark a = square(100, 100, 40);
    a.payload = "A";
    msg.landmarks.push_back(ld::toMessage(a));
    msg.landmarks.push_back(ld::toMessage(square(100.0f + 6.0f * k, 300, 30)));
    if (k < 10 || k >= 15) msg.landmarks.push_back(ld::toMessage(square(500, 150, 50)));
    if (k == non_finite_at) msg.landmarks.push_back(ld::toMessage(square(std::nanf(""), 200, 40)));
    msg.nlandmarks = static_cast<int32_t>(msg.landmarks.size());

    std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm::LogEvent ev{};
    ev.eventnum = k;
    ev.timestamp = msg.utime;
    ev.channel = channel;
    ev.datalen = static_cast<int32_t>(buf.size());
    ev.data = buf.data();
    if (log.writeEvent(&ev) != 0) {
      std::cerr << "ld-tracker-testlog: cannot write " << out << "\n";
      return 1;
    }
  }
  return 0;
}
