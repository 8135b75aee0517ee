// Message types round-trip through LCM encoding; image conversions round-trip
// every pixel format and refuse inconsistent messages.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include <atomic>
#include <chrono>
#include <thread>

#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "image_error.hpp"
#include "ld/image_convert.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_publisher.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/qr_code_list_t.hpp"

namespace {

template <typename T>
T roundTrip(const T& in) {
  std::vector<uint8_t> buf(static_cast<size_t>(in.getEncodedSize()));
  EXPECT_EQ(in.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  T out;
  EXPECT_EQ(out.decode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return out;
}

ld::landmark_t sampleLandmark(int k) {
  ld::landmark_t l{};
  for (int i = 0; i < 2; ++i) {
    l.fip_tl[i] = 10.5f + k + i;
    l.fip_tr[i] = 20.25f + k + i;
    l.fip_bl[i] = 30.125f + k + i;
    l.ap[i] = 40.0f + k + i;
  }
  for (int c = 0; c < 4; ++c)
    for (int i = 0; i < 2; ++i) l.corners[c][i] = static_cast<float>(100 * c + i + k);
  l.score = 0.75f;
  l.has_payload = k % 2 == 0;
  l.payload = l.has_payload ? "room-214/door \xc3\xa9" : "";
  l.pose_valid = true;
  l.t[0] = 0.1; l.t[1] = -0.2; l.t[2] = 1.5 + k;
  l.rvec[0] = 0.01; l.rvec[1] = 0.5; l.rvec[2] = -3.0;
  l.distance = 1.52;
  l.track_id = 1000 + k;
  l.age = 17;
  l.frames_since_seen = 2;
  l.time_since_seen_us = 66666;
  l.visible = false;
  return l;
}

void expectSame(const ld::landmark_t& a, const ld::landmark_t& b) {
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(a.fip_tl[i], b.fip_tl[i]);
    EXPECT_EQ(a.fip_tr[i], b.fip_tr[i]);
    EXPECT_EQ(a.fip_bl[i], b.fip_bl[i]);
    EXPECT_EQ(a.ap[i], b.ap[i]);
  }
  for (int c = 0; c < 4; ++c)
    for (int i = 0; i < 2; ++i) EXPECT_EQ(a.corners[c][i], b.corners[c][i]);
  EXPECT_EQ(a.score, b.score);
  EXPECT_EQ(a.has_payload, b.has_payload);
  EXPECT_EQ(a.payload, b.payload);
  EXPECT_EQ(a.pose_valid, b.pose_valid);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(a.t[i], b.t[i]);
    EXPECT_EQ(a.rvec[i], b.rvec[i]);
  }
  EXPECT_EQ(a.distance, b.distance);
  EXPECT_EQ(a.track_id, b.track_id);
  EXPECT_EQ(a.age, b.age);
  EXPECT_EQ(a.frames_since_seen, b.frames_since_seen);
  EXPECT_EQ(a.time_since_seen_us, b.time_since_seen_us);
  EXPECT_EQ(a.visible, b.visible);
}

ld::landmark_list_t sampleList() {
  ld::landmark_list_t m;
  m.utime = 1700000000123456;
  m.seq = 42;
  m.width = 640;
  m.height = 480;
  m.backend = "cpu";
  m.frames_skipped = 3;
  m.stage_names = {"blur", "saturation", "edges"};
  m.stage_ms = {0.1f, 0.2f, 0.3f};
  m.nstages = 3;
  m.landmarks = {sampleLandmark(0), sampleLandmark(1)};
  m.nlandmarks = 2;
  return m;
}

// A smooth colourful test image (chroma subsampling and JPEG keep it close).
cv::Mat testImage(int w, int h) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(255 * x / w),
                                          static_cast<uint8_t>(255 * y / h),
                                          static_cast<uint8_t>(128 + 100 * std::sin(x * 0.05)));
  return img;
}

double maxAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  double m = 0;
  cv::minMaxLoc(cv::abs(a.reshape(1) - b.reshape(1)), nullptr, &m);
  cv::Mat d;
  cv::absdiff(a, b, d);
  cv::minMaxLoc(d.reshape(1), nullptr, &m);
  return m;
}

double meanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  return cv::mean(d.reshape(1))[0];
}

}  // namespace

TEST(Messages, LandmarkListRoundTrips) {
  const auto in = sampleList();
  const auto out = roundTrip(in);
  EXPECT_EQ(out.utime, in.utime);
  EXPECT_EQ(out.seq, in.seq);
  EXPECT_EQ(out.width, in.width);
  EXPECT_EQ(out.height, in.height);
  EXPECT_EQ(out.backend, in.backend);
  EXPECT_EQ(out.frames_skipped, in.frames_skipped);
  EXPECT_EQ(out.stage_names, in.stage_names);
  EXPECT_EQ(out.stage_ms, in.stage_ms);
  ASSERT_EQ(out.nlandmarks, 2);
  for (int i = 0; i < 2; ++i) expectSame(out.landmarks[static_cast<size_t>(i)], in.landmarks[static_cast<size_t>(i)]);
}

TEST(Messages, QrCodeListRoundTrips) {
  ld::qr_code_list_t in;
  in.utime = 5;
  in.seq = 6;
  ld::qr_code_t c{};
  c.track_id = 7;
  c.payload = std::string(100, 'x') + "\xe2\x9c\x93";
  c.utime = 8;
  c.seq = 9;
  for (int k = 0; k < 4; ++k) c.corners[k][0] = c.corners[k][1] = static_cast<float>(k);
  c.decode_ms = 1.5f;
  in.codes = {c, c};
  in.ncodes = 2;
  in.withheld_track_ids = {3};
  in.nwithheld = 1;
  const auto out = roundTrip(in);
  ASSERT_EQ(out.ncodes, 2);
  EXPECT_EQ(out.withheld_track_ids, std::vector<int64_t>{3});
  EXPECT_EQ(out.codes[1].payload, c.payload);
  EXPECT_EQ(out.codes[1].track_id, 7);
  EXPECT_EQ(out.codes[1].corners[3][1], 3.0f);
  EXPECT_EQ(out.codes[0].decode_ms, 1.5f);
}

TEST(Messages, ImageRoundTripsWithMetadata) {
  const ld::image_t in = ld::matToImage(testImage(64, 48), ld::image_t::PIXEL_FORMAT_BGR, 99, 1234);
  const auto out = roundTrip(in);
  EXPECT_EQ(out.utime, 99);
  EXPECT_EQ(out.data, in.data);
  ASSERT_TRUE(ld::imageSeq(out).has_value());
  EXPECT_EQ(*ld::imageSeq(out), 1234);
  // a seq that is no frame number (negative, not a whole number): none
  ld::image_t odd = in;
  for (const char* text : {"-5", "12a", ""}) {
    ld::setImageSeq(odd, 0);
    auto& m = *std::find_if(odd.metadata.begin(), odd.metadata.end(), [](const auto& e) { return e.key == "seq"; });
    m.value.assign(text, text + std::strlen(text));
    m.n = static_cast<int32_t>(m.value.size());
    EXPECT_FALSE(ld::imageSeq(odd).has_value()) << text;
  }
}

TEST(Messages, TruncatedBufferIsRejectedByDecode) {
  const auto in = sampleList();
  std::vector<uint8_t> buf(static_cast<size_t>(in.getEncodedSize()));
  in.encode(buf.data(), 0, static_cast<int>(buf.size()));
  ld::landmark_list_t out;
  EXPECT_LT(out.decode(buf.data(), 0, static_cast<int>(buf.size()) - 5), 0);
  buf[0] ^= 0xff;  // wrong fingerprint
  EXPECT_LT(out.decode(buf.data(), 0, static_cast<int>(buf.size())), 0);
}

// Real LCM publish/subscribe in one process over memq://.
class Receiver {
 public:
  void onList(const lcm::ReceiveBuffer*, const std::string& channel, const ld::landmark_list_t* m) {
    channel_ = channel;
    list_ = *m;
    ++count_;
  }
  std::string channel_;
  ld::landmark_list_t list_;
  int count_ = 0;
};

TEST(Messages, PublishSubscribeOverMemq) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Receiver r;
  lcm.subscribe("LANDMARKS", &Receiver::onList, &r);
  const auto in = sampleList();
  ASSERT_EQ(lcm.publish("LANDMARKS", &in), 0);
  ASSERT_GE(lcm.handleTimeout(1000), 1);
  EXPECT_EQ(r.count_, 1);
  EXPECT_EQ(r.channel_, "LANDMARKS");
  EXPECT_EQ(r.list_.seq, 42);
  expectSame(r.list_.landmarks[1], in.landmarks[1]);
}

// ld::MessagePublisher: what it sends is the message, and its buffer grows
// to the largest message and is kept (no allocation per message once warm).
TEST(Messages, PublisherKeepsItsBuffer) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Receiver r;
  lcm.subscribe("LANDMARKS", &Receiver::onList, &r);
  ld::MessagePublisher publisher(lcm);
  auto big = sampleList();
  big.landmarks.push_back(big.landmarks[0]);
  big.nlandmarks = static_cast<int32_t>(big.landmarks.size());
  auto small = sampleList();
  small.landmarks.resize(1);
  small.nlandmarks = 1;
  ASSERT_EQ(publisher.publish("LANDMARKS", big), 0);
  ASSERT_GE(lcm.handleTimeout(1000), 1);
  EXPECT_EQ(r.list_.landmarks.size(), big.landmarks.size());
  const uint8_t* buffer = publisher.buffer();
  EXPECT_EQ(publisher.bufferSize(), static_cast<size_t>(big.getEncodedSize()));
  for (int k = 0; k < 3; ++k) {
    small.seq = k;
    ASSERT_EQ(publisher.publish("LANDMARKS", small), 0);
    ASSERT_GE(lcm.handleTimeout(1000), 1);
    EXPECT_EQ(r.list_.seq, k);
    ASSERT_EQ(r.list_.landmarks.size(), 1u);
    expectSame(r.list_.landmarks[0], small.landmarks[0]);
    ASSERT_EQ(publisher.publish("LANDMARKS", big), 0);
    ASSERT_GE(lcm.handleTimeout(1000), 1);
    expectSame(r.list_.landmarks[2], big.landmarks[2]);
  }
  EXPECT_EQ(r.count_, 7);
  EXPECT_EQ(publisher.buffer(), buffer);
  EXPECT_EQ(publisher.bufferSize(), static_cast<size_t>(big.getEncodedSize()));
}

// ld::pumpLcm under a flood: every message handled brings another (here
// the handler publishes it, taking 1 ms each, as a process starved of CPU
// finds the next image always queued). The drain stops after
// ld::kMaxDrainMs so that the caller gets to process the newest it has;
// unbounded, it handled all 300 (and a process read nothing at ld-run
// --speed 6: ld-qr-reader, 1 frame of 142).
namespace {
struct Flood {
  lcm::LCM* lcm = nullptr;
  int handled = 0;
  void on(const lcm::ReceiveBuffer*, const std::string&, const ld::landmark_list_t* msg) {
    ++handled;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (handled < 300) lcm->publish("FLOOD", msg);
  }
};
}  // namespace

TEST(Pump, DrainIsBoundedUnderAFlood) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Flood f;
  f.lcm = &lcm;
  lcm.subscribe("FLOOD", &Flood::on, &f);
  const auto msg = sampleList();
  ASSERT_EQ(lcm.publish("FLOOD", &msg), 0);
  std::atomic<bool> stop{false};
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(ld::pumpLcm(lcm, 100, stop, "test"));
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("one pump under a flood: %d messages handled in %.1f ms\n", f.handled, ms);
  EXPECT_GE(f.handled, 2);
  EXPECT_LT(f.handled, 200);
  // the next pump goes on with the flood
  const int before = f.handled;
  ASSERT_TRUE(ld::pumpLcm(lcm, 100, stop, "test"));
  EXPECT_GT(f.handled, before);
}

// After a stall the rest of the backlog is read before the newest is taken
// (a stalled detector worked on frames from the middle of it): messages
// that keep coming are handled; without a stall, nothing is waited for.
namespace {
struct Backlog {
  int handled = 0;
  void on(const lcm::ReceiveBuffer*, const std::string&, const ld::landmark_list_t*) { ++handled; }
};
}  // namespace

TEST(Pump, CatchUpAfterAStallReadsTheBacklog) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Backlog b;
  lcm.subscribe("BACKLOG", &Backlog::on, &b);
  const auto msg = sampleList();
  std::atomic<bool> stop{false};
  for (int i = 0; i < 40; ++i) ASSERT_EQ(lcm.publish("BACKLOG", &msg), 0);
  // no stall (the last pump a moment ago): returns at once, handles nothing
  auto t0 = std::chrono::steady_clock::now();
  (void)ld::catchUpAfterStall(lcm, t0, stop);
  EXPECT_EQ(b.handled, 0);
  // a stall of 2 s: the whole backlog, then one gap of kCatchUpGapMs
  const auto returned = ld::catchUpAfterStall(lcm, t0 - std::chrono::seconds(2), stop);
  EXPECT_EQ(b.handled, 40);
  EXPECT_LT(returned - t0, std::chrono::milliseconds(ld::kMaxCatchUpMs));
}

struct FormatCase {
  int32_t format;
  double max_err;   // largest allowed per-channel difference
  double mean_err;  // largest allowed mean difference
};

class ImageFormats : public ::testing::TestWithParam<FormatCase> {};

TEST_P(ImageFormats, RoundTrip) {
  const FormatCase c = GetParam();
  const cv::Mat src = testImage(160, 120);
  const ld::image_t msg = ld::matToImage(src, c.format, 1, 2);
  EXPECT_EQ(msg.pixelformat, c.format);
  EXPECT_EQ(msg.width, 160);
  EXPECT_EQ(msg.height, 120);
  EXPECT_EQ(static_cast<size_t>(msg.size), msg.data.size());
  const cv::Mat back = ld::imageToBgr(roundTrip(msg));
  ASSERT_EQ(back.size(), src.size());
  ASSERT_EQ(back.type(), CV_8UC3);
  EXPECT_LE(maxAbsDiff(back, src), c.max_err) << ld::pixelFormatName(c.format);
  EXPECT_LE(meanAbsDiff(back, src), c.mean_err) << ld::pixelFormatName(c.format);
}

INSTANTIATE_TEST_SUITE_P(
    AllFormats, ImageFormats,
    ::testing::Values(FormatCase{ld::image_t::PIXEL_FORMAT_BGR, 0, 0},
                      FormatCase{ld::image_t::PIXEL_FORMAT_RGB, 0, 0},
                      FormatCase{ld::image_t::PIXEL_FORMAT_BGRA, 0, 0},
                      FormatCase{ld::image_t::PIXEL_FORMAT_RGBA, 0, 0},
                      FormatCase{ld::image_t::PIXEL_FORMAT_YUYV, 12, 2.0},
                      FormatCase{ld::image_t::PIXEL_FORMAT_UYVY, 12, 2.0},
                      FormatCase{ld::image_t::PIXEL_FORMAT_MJPEG, 40, 2.5}));

TEST(ImageConvert, GrayRoundTripsExactly) {
  cv::Mat gray;
  cv::cvtColor(testImage(100, 80), gray, cv::COLOR_BGR2GRAY);
  const ld::image_t msg = ld::matToImage(gray, ld::image_t::PIXEL_FORMAT_GRAY, 0);
  EXPECT_EQ(msg.size, 100 * 80);
  cv::Mat back;
  ld::imageToMat(msg, back);
  ASSERT_EQ(back.type(), CV_8UC1);
  EXPECT_EQ(maxAbsDiff(back, gray), 0);
  const cv::Mat bgr = ld::imageToBgr(msg);
  cv::Mat b2g;
  cv::cvtColor(bgr, b2g, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(maxAbsDiff(b2g, gray), 0);
}

TEST(ImageConvert, HonoursRowStridePadding) {
  const cv::Mat src = testImage(30, 20);
  ld::image_t msg = ld::matToImage(src, ld::image_t::PIXEL_FORMAT_BGR, 0);
  const int stride = 30 * 3 + 6;
  std::vector<uint8_t> padded(static_cast<size_t>(stride) * 20, 0xAB);
  for (int y = 0; y < 20; ++y)
    std::copy_n(msg.data.begin() + y * 90, 90, padded.begin() + y * stride);
  msg.data = padded;
  msg.size = static_cast<int32_t>(padded.size());
  msg.row_stride = stride;
  EXPECT_EQ(maxAbsDiff(ld::imageToBgr(msg), src), 0);
}

TEST(ImageConvert, ReusesOutputBuffer) {
  const ld::image_t msg = ld::matToImage(testImage(64, 48), ld::image_t::PIXEL_FORMAT_YUYV, 0);
  cv::Mat out;
  ld::imageToBgr(msg, out);
  const uint8_t* data = out.data;
  ld::imageToBgr(msg, out);
  EXPECT_EQ(out.data, data);
}

TEST(ImageConvert, RefusesInconsistentMessages) {
  const ld::image_t good = ld::matToImage(testImage(40, 30), ld::image_t::PIXEL_FORMAT_BGR, 0);
  ASSERT_EQ(ld::test::imageError(good), "");

  ld::image_t m = good;
  m.data.resize(m.data.size() - 1);
  EXPECT_NE(ld::test::imageError(m).find("does not match"), std::string::npos) << ld::test::imageError(m);

  m = good;
  m.data.resize(m.data.size() - 100);
  m.size = static_cast<int32_t>(m.data.size());
  EXPECT_NE(ld::test::imageError(m).find("needs 3600 bytes"), std::string::npos) << ld::test::imageError(m);

  m = good;
  m.height = 31;
  EXPECT_NE(ld::test::imageError(m).find("needs"), std::string::npos) << ld::test::imageError(m);

  m = good;
  m.row_stride = 10;
  EXPECT_NE(ld::test::imageError(m).find("row_stride"), std::string::npos) << ld::test::imageError(m);

  m = good;
  m.width = -5;
  EXPECT_NE(ld::test::imageError(m).find("invalid size"), std::string::npos) << ld::test::imageError(m);

  m = good;
  m.pixelformat = ld::fourcc('N', 'V', '1', '2');
  EXPECT_NE(ld::test::imageError(m).find("unsupported pixel format 'NV12'"), std::string::npos) << ld::test::imageError(m);

  m = ld::matToImage(testImage(40, 30), ld::image_t::PIXEL_FORMAT_YUYV, 0);
  m.width = 39;
  EXPECT_NE(ld::test::imageError(m).find("even width"), std::string::npos) << ld::test::imageError(m);

  m = ld::matToImage(testImage(40, 30), ld::image_t::PIXEL_FORMAT_MJPEG, 0);
  for (size_t i = 2; i < m.data.size(); ++i) m.data[i] = static_cast<uint8_t>(i * 7);
  EXPECT_NE(ld::test::imageError(m).find("MJPEG"), std::string::npos) << ld::test::imageError(m);

  m = ld::matToImage(testImage(40, 30), ld::image_t::PIXEL_FORMAT_MJPEG, 0);
  m.width = 80;
  EXPECT_NE(ld::test::imageError(m).find("but the message says 80x30"), std::string::npos) << ld::test::imageError(m);

  m = ld::matToImage(testImage(40, 30), ld::image_t::PIXEL_FORMAT_MJPEG, 0);
  m.data.clear();
  m.size = 0;
  EXPECT_NE(ld::test::imageError(m).find("MJPEG"), std::string::npos) << ld::test::imageError(m);
}

// An MJPEG frame whose data is damaged but still ends in an end-of-image
// marker (a USB transfer that lost packets): libjpeg filled the lost part
// with grey, said so on stderr in its own words and the frame went on as
// good. Now it is refused, named, and libjpeg prints nothing; the padding
// many cameras put before the end marker is no damage.
TEST(ImageConvert, DamagedMjpegIsRefusedPaddedIsWhole) {
  const cv::Mat original = testImage(320, 240);
  const ld::image_t good = ld::matToImage(original, ld::image_t::PIXEL_FORMAT_MJPEG, 0, -1, 90);
  size_t scan = 0;  // the start of the entropy-coded data: after the SOS segment
  for (size_t i = 2; i + 3 < good.data.size(); ++i)
    if (good.data[i] == 0xFF && good.data[i + 1] == 0xDA) {
      scan = i + 2 + (size_t{good.data[i + 2]} << 8 | good.data[i + 3]);
      break;
    }
  ASSERT_GT(scan, 0u);
  const size_t end = good.data.size() - 2;  // FF D9
  ASSERT_EQ(good.data[end], 0xFF);
  ASSERT_EQ(good.data[end + 1], 0xD9);

  cv::Mat bgr;
  testing::internal::CaptureStderr();
  ld::imageToBgr(good, bgr);
  cv::Mat reference = cv::imdecode(good.data, cv::IMREAD_COLOR);
  EXPECT_LE(maxAbsDiff(bgr, reference), 1.0);  // as OpenCV decodes it

  ld::image_t cut = good;  // half the data, then the end marker
  cut.data.erase(cut.data.begin() + static_cast<long>(scan + (end - scan) / 2), cut.data.end() - 2);
  cut.size = static_cast<int32_t>(cut.data.size());
  const std::string why = ld::test::imageError(cut);
  EXPECT_NE(why.find("MJPEG data is damaged (libjpeg: Corrupt JPEG data: premature end of data segment)"),
            std::string::npos)
      << why;

  ld::image_t padded = good;  // two bytes of padding before the end marker
  padded.data.insert(padded.data.end() - 2, {0x00, 0x00});
  padded.size = static_cast<int32_t>(padded.data.size());
  EXPECT_EQ(ld::test::imageError(padded), "");
  ld::imageToBgr(padded, bgr);
  EXPECT_EQ(maxAbsDiff(bgr, reference), 0.0);
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");  // libjpeg's own lines kept off stderr

  // Warnings that say nothing of the pixels are no damage: zeros where a
  // sequential frame's scan parameters go (some cameras write them).
  ld::image_t zero_sos = good;
  const size_t sos = [&] {
    for (size_t i = 2; i + 1 < good.data.size(); ++i)
      if (good.data[i] == 0xFF && good.data[i + 1] == 0xDA) return i;
    return size_t{0};
  }();
  const size_t ss = sos + 5 + 2 * size_t{good.data[sos + 4]};  // Ss, Se, Ah/Al after the components
  zero_sos.data[ss] = zero_sos.data[ss + 1] = zero_sos.data[ss + 2] = 0;
  EXPECT_EQ(ld::test::imageError(zero_sos), "");
  ld::imageToBgr(zero_sos, bgr);
  EXPECT_EQ(maxAbsDiff(bgr, reference), 0.0);

  // Bytes that belong to no block before a restart marker (a USB packet
  // sent twice) are damage, though libjpeg calls them "extraneous" as it
  // calls a camera's padding before the end marker.
  std::vector<uint8_t> rst;
  cv::imencode(".jpg", original, rst, {cv::IMWRITE_JPEG_QUALITY, 90, cv::IMWRITE_JPEG_RST_INTERVAL, 4});
  size_t marker = 0;  // the third restart marker
  for (size_t i = 2, found = 0; i + 1 < rst.size() && !marker; ++i)
    if (rst[i] == 0xFF && rst[i + 1] >= 0xD0 && rst[i + 1] <= 0xD7 && ++found == 3) marker = i;
  ASSERT_GT(marker, 16u);
  rst.insert(rst.begin() + static_cast<long>(marker), rst.begin() + static_cast<long>(marker - 12),
             rst.begin() + static_cast<long>(marker - 4));  // 8 bytes again
  cv::Mat out;
  EXPECT_NE(ld::decodeJpeg(rst.data(), rst.size(), out).find("is damaged (libjpeg: Corrupt JPEG data:"),
            std::string::npos)
      << ld::decodeJpeg(rst.data(), rst.size(), out);

  // A header may say anything: a size over the limit is refused before
  // libjpeg allocates for it.
  ld::image_t huge = good;
  for (size_t i = 2; i + 9 < huge.data.size(); ++i)
    if (huge.data[i] == 0xFF && huge.data[i + 1] == 0xC0) {
      huge.data[i + 5] = huge.data[i + 7] = 0xFF;  // 65500 x 65500
      huge.data[i + 6] = huge.data[i + 8] = 0xDC;
      break;
    }
  EXPECT_EQ(ld::decodeJpeg(huge.data.data(), huge.data.size(), out),
            "could not be decoded (libjpeg: its frame 65500x65500 is larger than 1073741824 pixels)");
  EXPECT_TRUE(out.empty());
}

TEST(ImageConvert, PixelFormatNames) {
  EXPECT_EQ(ld::pixelFormatFromName("gray"), ld::image_t::PIXEL_FORMAT_GRAY);
  EXPECT_EQ(ld::pixelFormatFromName("GREY"), ld::image_t::PIXEL_FORMAT_GRAY);
  EXPECT_EQ(ld::pixelFormatFromName("mjpg"), ld::image_t::PIXEL_FORMAT_MJPEG);
  EXPECT_EQ(ld::pixelFormatFromName("yuyv"), ld::image_t::PIXEL_FORMAT_YUYV);
  EXPECT_THROW(ld::pixelFormatFromName("h264"), ld::ImageFormatError);
  EXPECT_EQ(ld::pixelFormatName(ld::image_t::PIXEL_FORMAT_RGB), "RGB");
  EXPECT_EQ(ld::fourcc('G', 'R', 'E', 'Y'), ld::image_t::PIXEL_FORMAT_GRAY);
  EXPECT_EQ(ld::fourcc('M', 'J', 'P', 'G'), ld::image_t::PIXEL_FORMAT_MJPEG);
  EXPECT_EQ(ld::fourcc('Y', 'U', 'Y', 'V'), ld::image_t::PIXEL_FORMAT_YUYV);
}

TEST(ImageConvert, SeqMetadata) {
  ld::image_t m = ld::matToImage(testImage(8, 8), ld::image_t::PIXEL_FORMAT_GRAY, 0);
  EXPECT_FALSE(ld::imageSeq(m).has_value());
  ld::setImageSeq(m, 7);
  ld::setImageSeq(m, 123456789012LL);
  EXPECT_EQ(m.nmetadata, 1);
  EXPECT_EQ(*ld::imageSeq(m), 123456789012LL);
  // rewritten in place: a message kept from frame to frame allocates nothing
  const uint8_t* value = m.metadata[0].value.data();
  // (INT64_MIN, the longest text, is written so too; read back it is no
  // frame number: a negative seq is none)
  for (const int64_t seq : {int64_t{0}, INT64_MAX, INT64_MIN, int64_t{42}}) {
    ld::setImageSeq(m, seq);
    if (seq >= 0)
      EXPECT_EQ(ld::imageSeq(m), std::optional<int64_t>(seq));
    else
      EXPECT_FALSE(ld::imageSeq(m).has_value());
    EXPECT_EQ(m.metadata[0].value.data(), value);
  }
  m.metadata[0].value = {'1', 'x'};
  m.metadata[0].n = 2;
  EXPECT_FALSE(ld::imageSeq(m).has_value());
  m.metadata[0].n = 5;  // n disagrees with the bytes present
  EXPECT_FALSE(ld::imageSeq(m).has_value());
}

// An LCM that will not open: 1 where a restart may mend it (a provider LCM
// has, the network not up yet), 2 where the URL itself is wrong.
// Frames whose utime stands still (a publisher that does not stamp them) are
// said once, at the 10th in a row; time moving on in between starts the
// count again.
TEST(StillTimeWatch, SaysOnceAtTheTenthFrameInARow) {
  ld::StillTimeWatch w;
  for (int k = 0; k < 9; ++k) EXPECT_FALSE(w.note(5)) << k;  // 9 alike
  EXPECT_FALSE(w.note(6));
  for (int k = 0; k < 9; ++k) EXPECT_FALSE(w.note(0)) << k;
  EXPECT_TRUE(w.note(0));  // the 10th 0 in a row
  for (int k = 0; k < 30; ++k) EXPECT_FALSE(w.note(0));  // once
  ld::StillTimeWatch moving;
  for (int64_t t = 0; t < 100; ++t) EXPECT_FALSE(moving.note(t * 33333));
}

TEST(LcmUrl, OpenFailureStatusTellsAWrongUrl) {
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://?ttl=1"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://239.255.76.67:0x1df3"), 1);  // (LCM reads the port as C does)
  EXPECT_EQ(ld::lcmOpenFailureStatus("mpudpm://239.255.76.67:7667?ttl=0"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus("tcpq://localhost:7700"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus(""), 2);  // (empty: LCM took its own default, without the receive buffer)
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://239.255.76.67"), 2);  // no port: LCM took 0 and never received
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://:7667"), 2);
  EXPECT_EQ(ld::lcmOpenFailureStatus("file:///tmp/x.lcmlog?mode=r"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus("memq://"), 1);
  EXPECT_EQ(ld::lcmOpenFailureStatus("bogus://x"), 2);
  EXPECT_EQ(ld::lcmOpenFailureStatus("239.255.76.67:7667"), 2);
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://999.1.1.1:7667"), 2);   // no address
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://10.0.0.1:7667"), 2);    // not multicast
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://239.255.76.67:70000"), 2);
  EXPECT_EQ(ld::lcmOpenFailureStatus("udpm://239.255.76.67:port"), 2);
}
