// ld-fuzz-seeds: writes the seed corpora of the fuzz targets
// (tests/fuzz/corpus/<target>/): a few small valid inputs of each kind, from
// which libFuzzer's mutations start. Run once after a change of the formats:
//   build-fuzz/bin/ld-fuzz-seeds tests/fuzz/corpus
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>
#include <tuple>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "../lcm_bytes.hpp"
#include "ld/adaptive.hpp"
#include "ld/camera.hpp"
#include "ld/detector.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_msg.hpp"
#include "ld/qr_code_list_t.hpp"
#include "ld/synth.hpp"
#include "ld/tracker.hpp"
#include "ld/tracker_msg.hpp"

namespace fs = std::filesystem;

namespace {

using ld::test::Bytes;
using ld::test::lcmEncode;

void write(const fs::path& dir, const std::string& name, const Bytes& bytes) {
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}


Bytes fileBytes(const fs::path& path, uint8_t prefix, bool with_prefix) {
  std::ifstream f(path, std::ios::binary);
  Bytes text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (with_prefix) text.insert(text.begin(), prefix);
  return text;
}

Bytes textBytes(uint8_t prefix, const std::string& text) {
  Bytes b{prefix};
  b.insert(b.end(), text.begin(), text.end());
  return b;
}

cv::Mat frame(cv::Size size, double distance) {
  ld::synth::SceneSpec spec;
  spec.camera = ld::CameraModel::pinhole(size, size.width * 0.95);
  spec.background = ld::synth::Background::Plain;
  spec.distractors = 0;
  spec.landmarks.push_back(ld::synth::placeLandmark(spec.camera, distance, 15, 0, 10));
  return ld::synth::render(spec).bgr;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: ld-fuzz-seeds CORPUS_DIR\n";
    return 2;
  }
  const fs::path root = argv[1];
  const cv::Mat small = frame({8, 6}, 1.0);

  // fuzz_image: messages as on the bus (byte 0 even) and header + pixels (odd)
  const struct { int32_t format; const char* name; } formats[] = {
      {ld::image_t::PIXEL_FORMAT_GRAY, "gray"}, {ld::image_t::PIXEL_FORMAT_RGB, "rgb"},
      {ld::image_t::PIXEL_FORMAT_BGR, "bgr"},   {ld::image_t::PIXEL_FORMAT_RGBA, "rgba"},
      {ld::image_t::PIXEL_FORMAT_BGRA, "bgra"}, {ld::image_t::PIXEL_FORMAT_YUYV, "yuyv"},
      {ld::image_t::PIXEL_FORMAT_UYVY, "uyvy"}, {ld::image_t::PIXEL_FORMAT_MJPEG, "mjpeg"}};
  for (size_t i = 0; i < std::size(formats); ++i) {
    const ld::image_t msg = ld::matToImage(small, formats[i].format, 1000, 7, 80);
    write(root / "fuzz_image", std::string("msg-") + formats[i].name, lcmEncode(msg, 0));
    Bytes h{1, static_cast<uint8_t>(i),
            static_cast<uint8_t>(msg.width), static_cast<uint8_t>(msg.width >> 8),
            static_cast<uint8_t>(msg.height), static_cast<uint8_t>(msg.height >> 8),
            static_cast<uint8_t>(msg.row_stride), static_cast<uint8_t>(msg.row_stride >> 8), 0};
    h.insert(h.end(), msg.data.begin(), msg.data.end());
    write(root / "fuzz_image", std::string("raw-") + formats[i].name, h);
  }

  // fuzz_messages: one of each type, with content
  ld::image_t img = ld::matToImage(small, ld::image_t::PIXEL_FORMAT_GRAY, 1000, 7);
  write(root / "fuzz_messages", "image_t", lcmEncode(img, 0));
  const cv::Mat f = frame({160, 120}, 0.5);
  ld::Detector detector;
  ld::landmark_list_t list;
  ld::toListMessage(detector.detect(f), 2000, 8, f.cols, f.rows, "cpu", 3, list);
  if (list.landmarks.empty()) {
    std::cerr << "ld-fuzz-seeds: no landmark detected in the seed frame\n";
    return 1;
  }
  list.landmarks.push_back(list.landmarks[0]);
  for (auto& c : list.landmarks[1].corners) c[0] += 30;
  list.landmarks[1].has_payload = true;
  list.landmarks[1].payload = "room 7";
  list.nlandmarks = static_cast<int32_t>(list.landmarks.size());
  write(root / "fuzz_messages", "landmark_list_t", lcmEncode(list, 1));
  ld::Tracker tracker;
  std::vector<ld::Landmark> dets;
  ld::landmarksFromList(list, dets);
  ld::landmark_list_t tracked;
  ld::toTrackedListMessage(tracker.update(dets, list.utime), list, 0.2, 0, tracked);
  write(root / "fuzz_messages", "landmark_list_t-tracked", lcmEncode(tracked, 1));
  ld::qr_code_list_t codes;
  codes.utime = 2000;
  codes.seq = 8;
  for (int i = 0; i < 2; ++i) {
    ld::qr_code_t c{};
    c.track_id = i;
    c.payload = i ? "dock" : "room 7";
    c.utime = 1000;
    c.seq = 7;
    for (int k = 0; k < 4; ++k) c.corners[k][0] = c.corners[k][1] = static_cast<float>(10 * k);
    c.decode_ms = 1.5f;
    codes.codes.push_back(c);
  }
  codes.ncodes = 2;
  codes.withheld_track_ids = {5};
  codes.nwithheld = 1;
  write(root / "fuzz_messages", "qr_code_list_t", lcmEncode(codes, 2));

  // fuzz_detector: header + pixels; a frame with a landmark in 3, 1 and 4 channels
  const cv::Mat d = frame({120, 90}, 0.45);
  auto detectorSeed = [&](const cv::Mat& m, uint8_t flags) {
    Bytes b{flags, static_cast<uint8_t>(m.cols), static_cast<uint8_t>(m.cols >> 8),
            static_cast<uint8_t>(m.rows), static_cast<uint8_t>(m.rows >> 8)};
    for (int y = 0; y < m.rows; ++y)
      b.insert(b.end(), m.ptr<uint8_t>(y), m.ptr<uint8_t>(y) + m.cols * m.elemSize());
    return b;
  };
  cv::Mat gray, bgra;
  cv::cvtColor(d, gray, cv::COLOR_BGR2GRAY);
  cv::cvtColor(d, bgra, cv::COLOR_BGR2BGRA);
  write(root / "fuzz_detector", "bgr-landmark", detectorSeed(d, 2));
  write(root / "fuzz_detector", "bgr-landmark-paper", detectorSeed(d, 2 | 4));
  write(root / "fuzz_detector", "gray-landmark", detectorSeed(gray, 0));
  write(root / "fuzz_detector", "bgra-small", detectorSeed(bgra(cv::Rect(30, 20, 40, 30)).clone(), 3));
  {
    // a landmark under a warm hot spot (glare 0.75, 4200 K), the frame as
    // the lighting adapter corrects it, flagged glare-corrected (64): the
    // detector finds the landmark only with the flag (the adapter itself
    // would not flag it: its stretch, 2.6, is under the 3 of a strong veil)
    ld::synth::SceneSpec spec;
    spec.camera = ld::CameraModel::pinhole({160, 120}, 160 * 0.95);
    spec.background = ld::synth::Background::Plain;
    spec.distractors = 0;
    spec.landmarks.push_back(ld::synth::placeLandmark(spec.camera, 0.5, 15, 0, 10));
    const auto t = ld::synth::truthFor(spec.camera, spec.landmarks[0]);
    const cv::Point2d c = (t.fip_tl + t.ap) / 2;
    spec.lighting.colour_temp_k = 4200;
    spec.lighting.glare = 0.75;
    spec.lighting.glare_radius = 0.15;
    spec.lighting.glare_centre = {c.x / 160, c.y / 120};
    ld::LightingAdapter adapter;
    write(root / "fuzz_detector", "bgr-glare-corrected",
          detectorSeed(adapter.correct(ld::synth::render(spec).bgr).clone(), 2 | 64));
  }
  write(root / "fuzz_detector", "1x1", Bytes{2, 1, 0, 1, 0, 0, 0, 255});
  write(root / "fuzz_detector", "0x0", Bytes{2, 0, 0, 0, 0});

  // fuzz_qr: header (version - 1, width - 8, height - 8, four corners in
  // eighths of a pixel) + gray pixels; a far landmark's QR (a 100-byte
  // payload, version 5, about 1.1 px a module; a 23-byte one, version 2) in
  // a 135 x 135 crop, at its true corners
  for (const auto& [name, payload, version] :
       {std::tuple{"far-v5", std::string(100, 'Q'), 5}, std::tuple{"far-v2", std::string("salle-107 caf\xc3\xa9"), 2}}) {
    ld::synth::SceneSpec spec;
    spec.camera = ld::CameraModel::defaultVga();
    spec.background = ld::synth::Background::Plain;
    spec.distractors = 0;
    spec.landmarks.push_back(ld::synth::placeLandmark(spec.camera, 1.0, 15, 0, 10, 0, 0, 0.15, payload));
    const auto t = ld::synth::truthFor(spec.camera, spec.landmarks[0]);
    cv::Mat g;
    cv::cvtColor(ld::synth::render(spec).bgr, g, cv::COLOR_BGR2GRAY);
    const cv::Point2d mid = (t.corners[0] + t.corners[2]) / 2;
    const cv::Rect crop(static_cast<int>(mid.x) - 67, static_cast<int>(mid.y) - 67, 135, 135);
    Bytes b{static_cast<uint8_t>(version - 1), 127, 127};
    for (const auto& c : t.corners)
      for (double v : {c.x - crop.x, c.y - crop.y}) {
        const auto e = static_cast<int16_t>(std::lround(v * 8));
        b.push_back(static_cast<uint8_t>(e & 0xff));
        b.push_back(static_cast<uint8_t>((e >> 8) & 0xff));
      }
    for (int y = crop.y; y < crop.y + crop.height; ++y) b.insert(b.end(), g.ptr<uint8_t>(y) + crop.x, g.ptr<uint8_t>(y) + crop.x + crop.width);
    write(root / "fuzz_qr", name, b);
  }

  // fuzz_params: byte 0 even = detector, odd = tracker
  const fs::path tmp = fs::temp_directory_path() / "ld-fuzz-seeds.yml";
  ld::DetectorParams().save(tmp.string());
  write(root / "fuzz_params", "detector-default", fileBytes(tmp, 0, true));
  ld::DetectorParams::paper().save(tmp.string());
  write(root / "fuzz_params", "detector-paper", fileBytes(tmp, 0, true));
  write(root / "fuzz_params", "detector-plain",
        textBytes(0, "%YAML:1.0\nfront_end: paper\nblur_kernel: 5\ncomplete_missing: 0\n"));
  write(root / "fuzz_params", "tracker-default", textBytes(1, ld::TrackerParams().toYaml()));
  write(root / "fuzz_params", "tracker-plain",
        textBytes(1, "max_distance: 3\npredict: false  # the paper's tracker\nmin_hits: 2\n"));
  write(root / "fuzz_params", "tracker-json", textBytes(1, "{\"max_lifetime_s\": 0.5}\n"));

  // fuzz_camera: OpenCV calibration files, YAML and XML, with and without distortion
  ld::CameraModel::defaultVga().save(tmp.string());
  write(root / "fuzz_camera", "vga.yml", fileBytes(tmp, 0, false));
  ld::CameraModel wide = ld::CameraModel::pinhole({1280, 720}, 700);
  wide.dist = (cv::Mat_<double>(1, 5) << -0.3, 0.1, 0.001, -0.002, -0.02);
  wide.save(tmp.string());
  write(root / "fuzz_camera", "wide5.yml", fileBytes(tmp, 0, false));
  const fs::path xml = fs::temp_directory_path() / "ld-fuzz-seeds.xml";
  wide.dist = (cv::Mat_<double>(1, 8) << -0.3, 0.1, 0.001, -0.002, -0.02, 0.01, 0, 0);
  wide.save(xml.string());
  write(root / "fuzz_camera", "wide8.xml", fileBytes(xml, 0, false));
  fs::remove(tmp);
  fs::remove(xml);

  // fuzz_run_config: byte 0 even = YAML, odd = JSON
  write(root / "fuzz_run_config", "replay.yaml",
        textBytes(0, "source: {type: replay, log: run.lcmlog, speed: 2}\n"
                     "tracker: {enabled: false}\nrecord: {file: out.lcmlog}\n"));
  write(root / "fuzz_run_config", "camera.yaml",
        textBytes(0, "source:\n  type: camera\n  args: [--device, /dev/video0, --fps, 30]\n"
                     "restart: {initial_s: 0.2, max_s: 5}\n"));
  write(root / "fuzz_run_config", "play.json",
        textBytes(1, "{\"source\": {\"type\": \"play\", \"log\": \"a.lcmlog\", \"fps\": 15}, // comment\n"
                     "\"qr_reader\": {\"args\": [\"-v\"]}}\n"));
  std::cout << "seeds written under " << root << "\n";
  return 0;
}
