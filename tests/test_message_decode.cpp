// decodeMessage (ld/message_decode.hpp): well-formed messages decode exactly
// as LCM's own decoder does; the encodings that made the generated decoders
// allocate gigabytes, throw or load invalid booleans (found by
// tests/fuzz/fuzz_messages) are refused with a reason, quickly.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <sstream>

#include "image_error.hpp"
#include "lcm_bytes.hpp"
#include "ld/image_convert.hpp"
#include "ld/latest_message.hpp"
#include "ld/message_decode.hpp"
#include "ld_v1/qr_code_list_t.hpp"  // (tests/data/old_lcmtypes)

namespace {

using ld::test::Bytes;
using ld::test::lcmEncode;
using ld::test::putI32;

ld::landmark_list_t sampleList() {
  ld::landmark_list_t list{};
  list.utime = 123;
  list.seq = 4;
  list.width = 640;
  list.height = 480;
  list.backend = "cpu";
  list.stage_names = {"saturation", "contours"};
  list.stage_ms = {0.5f, 0.25f};
  list.nstages = 2;
  ld::landmark_t lm{};
  lm.track_id = -1;
  lm.has_payload = true;
  lm.payload = "dock";
  list.landmarks = {lm, lm};
  list.nlandmarks = 2;
  return list;
}

// byte offsets in sampleList()'s encoding
constexpr size_t kBackendLen = 8 + 8 + 8 + 4 + 4;        // after hash, utime, seq, width, height
constexpr size_t kNstages = kBackendLen + 4 + 4 + 8;      // after "cpu\0" and frames_skipped
constexpr size_t kFirstLandmark = kNstages + 4 + 4 + 11 + 4 + 9 + 2 * 4 + 4;
constexpr size_t kHasPayload = kFirstLandmark + 16 * 4 + 4;

TEST(DecodeMessage, WellFormedMessagesDecodeAsLcmDoes) {
  const ld::landmark_list_t list = sampleList();
  const Bytes b = lcmEncode(list);
  ld::landmark_list_t out;
  std::string why;
  ASSERT_TRUE(ld::decodeMessage(b.data(), b.size(), out, &why)) << why;
  EXPECT_EQ(lcmEncode(out), b);
  EXPECT_EQ(out.landmarks[1].payload, "dock");

  const ld::image_t img = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)),
                                         ld::image_t::PIXEL_FORMAT_BGR, 5, 9);
  ld::image_t img_out;
  const Bytes bi = lcmEncode(img);
  ASSERT_TRUE(ld::decodeMessage(bi.data(), bi.size(), img_out, &why)) << why;
  EXPECT_EQ(lcmEncode(img_out), bi);
  EXPECT_EQ(ld::imageSeq(img_out), 9);

  ld::qr_code_list_t codes{};
  codes.codes.resize(1);
  codes.codes[0].payload = "x";
  codes.ncodes = 1;
  codes.withheld_track_ids = {4, 9};
  codes.nwithheld = 2;
  ld::qr_code_list_t codes_out;
  const Bytes bq = lcmEncode(codes);
  ASSERT_TRUE(ld::decodeMessage(bq.data(), bq.size(), codes_out, &why)) << why;
  EXPECT_EQ(lcmEncode(codes_out), bq);
  EXPECT_EQ(codes_out.withheld_track_ids, (std::vector<int64_t>{4, 9}));
  // none withheld in the next message: none kept from the last
  codes.withheld_track_ids.clear();
  codes.nwithheld = 0;
  const Bytes none = lcmEncode(codes);
  ASSERT_TRUE(ld::decodeMessage(none.data(), none.size(), codes_out, &why)) << why;
  EXPECT_TRUE(codes_out.withheld_track_ids.empty());
  // a count of withheld ids the message has no bytes for
  Bytes cut = bq;
  cut.resize(cut.size() - 8);
  EXPECT_FALSE(ld::decodeMessage(cut.data(), cut.size(), codes_out, &why));
  EXPECT_NE(why.find("nwithheld 2 does not fit"), std::string::npos) << why;
}

// Payloads kept by track id between codes messages (ld-view's labels): a
// withheld track's is dropped, where ld-view drew the old payload on, and so
// is one the message leaves out (forgotten, or its track dropped: an
// integrator's audit found them kept for ever).
TEST(DecodeMessage, TakeCodesDropsWithheldPayloads) {
  std::map<int64_t, std::string> payloads{{3, "room-101"}, {4, "dock"}};
  ld::qr_code_list_t empty{};
  ld::takeCodes(empty, payloads);
  EXPECT_TRUE(payloads.empty());
  payloads = {{3, "room-101"}, {4, "dock"}};
  ld::qr_code_list_t codes{};
  codes.codes.resize(1);
  codes.codes[0].track_id = 5;
  codes.codes[0].payload = "room-102";
  codes.ncodes = 1;
  codes.withheld_track_ids = {3};
  codes.nwithheld = 1;
  codes.codes.resize(2);
  codes.codes[1].track_id = 4;
  codes.codes[1].payload = "dock";
  codes.ncodes = 2;
  ld::takeCodes(codes, payloads);
  EXPECT_EQ(payloads, (std::map<int64_t, std::string>{{4, "dock"}, {5, "room-102"}}));
  // the next message without track 4 (its payload forgotten at a jump)
  codes.codes.resize(1);
  codes.ncodes = 1;
  codes.withheld_track_ids.clear();
  codes.nwithheld = 0;
  ld::takeCodes(codes, payloads);
  EXPECT_EQ(payloads, (std::map<int64_t, std::string>{{5, "room-102"}}));
}

// A message reused across decodes (the processes' hot path) holds what the
// last one said: an empty image's data and a list without stages' times
// are empty, not the previous message's (lcm-gen's decoder leaves an array
// of bytes or numbers alone when its length is 0).
TEST(DecodeMessage, EmptyArraysDoNotKeepTheLastMessagesValues) {
  std::string why;
  ld::image_t img = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)), ld::image_t::PIXEL_FORMAT_BGR, 5, 9);
  ld::image_t reused;
  const Bytes full = lcmEncode(img);
  ASSERT_TRUE(ld::decodeMessage(full.data(), full.size(), reused, &why)) << why;
  ASSERT_EQ(reused.data.size(), 144u);
  img.size = 0;
  img.data.clear();
  const Bytes empty = lcmEncode(img);
  ASSERT_TRUE(ld::decodeMessage(empty.data(), empty.size(), reused, &why)) << why;
  EXPECT_TRUE(reused.data.empty());
  EXPECT_EQ(lcmEncode(reused), empty);

  ld::landmark_list_t list = sampleList(), reused_list;
  const Bytes with_stages = lcmEncode(list);
  ASSERT_TRUE(ld::decodeMessage(with_stages.data(), with_stages.size(), reused_list, &why)) << why;
  list.nstages = 0;
  list.stage_names.clear();
  list.stage_ms.clear();
  const Bytes without = lcmEncode(list);
  ASSERT_TRUE(ld::decodeMessage(without.data(), without.size(), reused_list, &why)) << why;
  EXPECT_TRUE(reused_list.stage_ms.empty());
  EXPECT_TRUE(reused_list.stage_names.empty());
  EXPECT_EQ(lcmEncode(reused_list), without);
}

TEST(DecodeMessage, LayoutOfTheSampleIsAsAssumed) {
  const Bytes b = lcmEncode(sampleList());
  EXPECT_EQ(b[kBackendLen + 3], 4);  // "cpu" + NUL
  EXPECT_EQ(b[kNstages + 3], 2);
  EXPECT_EQ(b[kHasPayload], 1);
}

TEST(DecodeMessage, HugeCountIsRefusedWithoutAllocating) {
  Bytes b = lcmEncode(sampleList());
  putI32(b, kNstages, 0x7fffffff);  // the generated decoder resizes to 2^31 strings first
  ld::landmark_list_t out;
  std::string why;
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), out, &why));
  EXPECT_NE(why.find("nstages 2147483647 does not fit"), std::string::npos) << why;

  ld::image_t img = ld::matToImage(cv::Mat(6, 8, CV_8UC1, cv::Scalar(1)),
                                   ld::image_t::PIXEL_FORMAT_GRAY, 5);
  Bytes bi = lcmEncode(img);
  putI32(bi, 8 + 8 + 4 * 4, 0x7ffffff0);  // image size: 2 GB of zeros in the generated decoder
  ld::image_t img_out;
  EXPECT_FALSE(ld::decodeMessage(bi.data(), bi.size(), img_out, &why));
  EXPECT_NE(why.find("image size"), std::string::npos) << why;
  putI32(bi, 8 + 8 + 4 * 4, -5);
  EXPECT_FALSE(ld::decodeMessage(bi.data(), bi.size(), img_out, &why));
  EXPECT_NE(why.find("negative"), std::string::npos) << why;
}

TEST(DecodeMessage, StringLengthZeroIsRefusedNotThrown) {
  Bytes b = lcmEncode(sampleList());
  putI32(b, kBackendLen, 0);  // the generated decoder throws std::length_error
  ld::landmark_list_t out;
  std::string why;
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), out, &why));
  EXPECT_NE(why.find("string backend has length 0"), std::string::npos) << why;
  putI32(b, kBackendLen, -1000);
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), out, &why));
}

TEST(DecodeMessage, StringsMustBeCStrings) {
  Bytes b = lcmEncode(sampleList());
  b[kBackendLen + 4 + 3] = 'x';  // no terminating NUL
  ld::landmark_list_t out;
  std::string why;
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), out, &why));
  EXPECT_NE(why.find("not a C string"), std::string::npos) << why;
  b = lcmEncode(sampleList());
  b[kBackendLen + 4 + 1] = 0;  // "c\0u\0": would re-encode shorter
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), out, &why));
}

TEST(DecodeMessage, BooleanOtherThanZeroOrOneIsRefused) {
  Bytes b = lcmEncode(sampleList());
  b[kHasPayload] = 2;  // would be loaded into a C++ bool
  ld::landmark_list_t out;
  std::string why;
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), out, &why));
  EXPECT_NE(why.find("boolean has_payload is 2"), std::string::npos) << why;
}

TEST(DecodeMessage, TruncatedTrailingAndForeignMessagesAreRefused) {
  const Bytes b = lcmEncode(sampleList());
  ld::landmark_list_t out;
  std::string why;
  for (size_t n = 0; n < b.size(); ++n) {
    EXPECT_FALSE(ld::decodeMessage(b.data(), n, out, &why)) << n;
    EXPECT_FALSE(why.empty());
  }
  Bytes longer = b;
  longer.push_back(0);
  EXPECT_FALSE(ld::decodeMessage(longer.data(), longer.size(), out, &why));
  EXPECT_NE(why.find("1 bytes after the message"), std::string::npos) << why;

  ld::image_t img;
  EXPECT_FALSE(ld::decodeMessage(b.data(), b.size(), img, &why));
  EXPECT_NE(why.find("fingerprint is not ld.image_t's"), std::string::npos) << why;
}

// LANDMARK_CODES recorded before withheld_track_ids: its fingerprint (the one
// lcm-gen gave qr_code_list_t.lcm as it was) is said to be the earlier
// version's, by the decoder (ld-view, the processes) and on its own (ld-dump).
TEST(DecodeMessage, EarlierVersionOfATypeIsNamed) {
  // an empty codes message of then, encoded by lcm-gen's code of then
  ld_v1::qr_code_list_t then{};
  then.utime = 1000;
  then.seq = 7;
  const Bytes old = lcmEncode(then);
  ASSERT_EQ(old.size(), 8u + 8 + 8 + 4);
  ld::qr_code_list_t codes;
  std::string why;
  EXPECT_FALSE(ld::decodeMessage(old.data(), old.size(), codes, &why));
  EXPECT_EQ(why,
            "not a valid ld.qr_code_list_t (28 bytes): fingerprint is not ld.qr_code_list_t's but that of ld.qr_code_list_t before withheld_track_ids "
            "(2026-12-07), an earlier version no longer decoded (a recording by an older build?)");
  EXPECT_EQ(ld::earlierTypeVersion(old.data(), old.size()), "ld.qr_code_list_t before withheld_track_ids (2026-12-07)");
  // today's message, another type's, and too few bytes: no earlier version
  ld::qr_code_list_t now{};  // (lcm-gen's members start uninitialised)
  const Bytes current = lcmEncode(now);
  EXPECT_EQ(ld::earlierTypeVersion(current.data(), current.size()), "");
  const Bytes list = lcmEncode(sampleList());
  EXPECT_EQ(ld::earlierTypeVersion(list.data(), list.size()), "");
  EXPECT_EQ(ld::earlierTypeVersion(old.data(), 7), "");
  ld::image_t img;  // (on another type's channel: not that type's, and which it is)
  EXPECT_FALSE(ld::decodeMessage(old.data(), old.size(), img, &why));
  EXPECT_NE(why.find("fingerprint is not ld.image_t's but that of ld.qr_code_list_t before"), std::string::npos) << why;
}

}  // namespace

namespace {

// A valid small JPEG whose frame header is rewritten to say `w` x `h`.
ld::image_t mjpegClaiming(int w, int h, bool message_says_it_too) {
  ld::image_t msg = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(10, 20, 30)),
                                   ld::image_t::PIXEL_FORMAT_MJPEG, 1);
  for (size_t i = 2; i + 9 < msg.data.size(); ++i)
    if (msg.data[i] == 0xFF && msg.data[i + 1] == 0xC0) {
      msg.data[i + 5] = static_cast<uint8_t>(h >> 8);
      msg.data[i + 6] = static_cast<uint8_t>(h);
      msg.data[i + 7] = static_cast<uint8_t>(w >> 8);
      msg.data[i + 8] = static_cast<uint8_t>(w);
      break;
    }
  msg.width = message_says_it_too ? w : 0;
  msg.height = message_says_it_too ? h : 0;
  return msg;
}

}  // namespace

// Found by tests/fuzz/fuzz_image (corpus entry regress-mjpeg-30000x30000): a
// 650-byte MJPEG message whose frame header claims 30000x30000 made
// cv::imdecode allocate 2.7 GB before it found the data missing.
TEST(ImageLimits, MjpegFrameSizeIsCheckedBeforeDecoding) {
  EXPECT_NE(ld::test::imageError(mjpegClaiming(30000, 30000, false)).find("larger than"), std::string::npos);
  EXPECT_NE(ld::test::imageError(mjpegClaiming(30000, 30000, true)).find("larger than"), std::string::npos);
  // within the limit, decoded: data for 8x6 in a frame of 640x480 is a frame
  // that lost most of its data, refused as damaged (libjpeg filled the rest
  // with grey, and the frame went on as good)
  EXPECT_NE(ld::test::imageError(mjpegClaiming(640, 480, false))
                .find("MJPEG data is damaged (libjpeg: Corrupt JPEG data: premature end of data segment)"),
            std::string::npos)
      << ld::test::imageError(mjpegClaiming(640, 480, false));
  ld::image_t says_other = mjpegClaiming(8, 6, false);
  says_other.width = 640;
  says_other.height = 480;
  EXPECT_NE(ld::test::imageError(says_other).find("MJPEG data is 8x6 but the message says 640x480"),
            std::string::npos);
  // a size given by half, or negative, is not the JPEG's either (only 0x0
  // says the sender does not know it)
  ld::image_t half = mjpegClaiming(8, 6, false);
  half.width = 8;
  EXPECT_NE(ld::test::imageError(half).find("MJPEG data is 8x6 but the message says 8x0"), std::string::npos)
      << ld::test::imageError(half);
  ld::image_t negative = mjpegClaiming(8, 6, false);
  negative.width = -8;
  negative.height = -6;
  EXPECT_NE(ld::test::imageError(negative).find("but the message says -8x-6"), std::string::npos)
      << ld::test::imageError(negative);
  ld::image_t not_jpeg = mjpegClaiming(8, 6, false);
  not_jpeg.data[0] = 0x89;
  EXPECT_NE(ld::test::imageError(not_jpeg).find("not a JPEG stream"), std::string::npos);
  EXPECT_EQ(ld::test::imageError(mjpegClaiming(8, 6, true)), "");
  EXPECT_EQ(ld::imageToBgr(mjpegClaiming(8, 6, false)).size(), cv::Size(8, 6));
}

// A JPEG frame cut short (a copy or a message that lost its end) is refused
// by name: libjpeg would decode it into grey rows with a warning of its own
// that names nothing. Padding after the end marker (some cameras send it)
// is allowed. An empty MJPEG message says it has no data.
TEST(ImageLimits, MjpegCutShortIsRefused) {
  ld::image_t whole = ld::matToImage(cv::Mat(48, 64, CV_8UC3, cv::Scalar(10, 20, 200)),
                                     ld::image_t::PIXEL_FORMAT_MJPEG, 1);
  EXPECT_EQ(ld::test::imageError(whole), "");
  EXPECT_TRUE(ld::jpegComplete(whole.data.data(), whole.data.size()));
  ld::image_t cut = whole;
  cut.data.resize(cut.data.size() * 2 / 3);
  cut.size = static_cast<int32_t>(cut.data.size());
  EXPECT_FALSE(ld::jpegComplete(cut.data.data(), cut.data.size()));
  EXPECT_NE(ld::test::imageError(cut).find("MJPEG data ends before its image does (no end-of-image marker"),
            std::string::npos)
      << ld::test::imageError(cut);
  ld::image_t padded = whole;
  padded.data.insert(padded.data.end(), 64, 0);
  padded.size = static_cast<int32_t>(padded.data.size());
  EXPECT_EQ(ld::test::imageError(padded), "");
  ld::image_t empty = whole;
  empty.data.clear();
  empty.size = 0;
  EXPECT_NE(ld::test::imageError(empty).find("MJPEG message has no data"), std::string::npos);
}

// A raw image's data must fit its header both ways: more bytes than whole
// rows hold is a width or height that is not the data's (half the height
// drew the top half as a frame of its own).
TEST(ImageLimits, RawDataLargerThanItsRowsIsRefused) {
  ld::image_t img = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)), ld::image_t::PIXEL_FORMAT_BGR, 1);
  EXPECT_EQ(ld::test::imageError(img), "");
  img.height = 3;
  EXPECT_NE(ld::test::imageError(img).find("holds at most 72 bytes, message has 144 (a wrong width or height?)"),
            std::string::npos)
      << ld::test::imageError(img);
  // a padded stride's last row without its padding (as ld-camera sends it) still fits
  ld::image_t strided = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)), ld::image_t::PIXEL_FORMAT_BGR, 1);
  std::vector<uint8_t> rows;
  for (int y = 0; y < 6; ++y) {
    rows.insert(rows.end(), strided.data.begin() + y * 24, strided.data.begin() + (y + 1) * 24);
    if (y < 5) rows.insert(rows.end(), 8, 0);
  }
  strided.data = rows;
  strided.size = static_cast<int32_t>(rows.size());
  strided.row_stride = 32;
  EXPECT_EQ(ld::test::imageError(strided), "");
}

// matToImage makes no message its readers refuse (ld-log-images logged a
// 70000x2 frame that ld-play and the detector then refused).
TEST(ImageLimits, MatToImageMakesNothingItsReadersRefuse) {
  const cv::Mat wide(1, (1 << 15) + 1, CV_8UC1, cv::Scalar(128));
  for (int32_t format : std::vector<int32_t>{ld::image_t::PIXEL_FORMAT_GRAY, ld::image_t::PIXEL_FORMAT_BGR,
                                             ld::image_t::PIXEL_FORMAT_MJPEG})
    EXPECT_THROW(ld::matToImage(wide, format, 0, 0), ld::ImageFormatError) << format;
  const cv::Mat widest_taken(1, 1 << 15, CV_8UC1, cv::Scalar(128));
  const ld::image_t taken = ld::matToImage(widest_taken, ld::image_t::PIXEL_FORMAT_GRAY, 0, 0);
  EXPECT_NO_THROW(ld::checkImage(taken));
  // MJPEG: 2^25 pixels at most (6000x6000 is 36 million)
  const cv::Mat big(6000, 6000, CV_8UC1, cv::Scalar(128));
  try {
    ld::matToImage(big, ld::image_t::PIXEL_FORMAT_MJPEG, 0, 0);
    ADD_FAILURE() << "a 6000x6000 MJPEG image_t was made";
  } catch (const ld::ImageFormatError& e) {
    EXPECT_STREQ(e.what(), "matToImage: a 6000x6000 image is more than the 33554432 pixels an MJPEG image_t takes");
  }
  EXPECT_NO_THROW(ld::checkImage(ld::matToImage(big, ld::image_t::PIXEL_FORMAT_GRAY, 0, 0)));
  // Raw: image_t's size is an int32. 32768x16385 RGBA is 2147614720 bytes;
  // the message said a size of -2147352576. (The grey frame is never read:
  // refused before any conversion, its pages are never touched.)
  const cv::Mat huge(16385, 1 << 15, CV_8UC1);
  try {
    ld::matToImage(huge, ld::image_t::PIXEL_FORMAT_RGBA, 0, 0);
    ADD_FAILURE() << "a 2 GiB RGBA image_t was made";
  } catch (const ld::ImageFormatError& e) {
    EXPECT_STREQ(e.what(), "matToImage: a 32768x16385 RGBA image is 2147614720 bytes, more than the 2147483647 an "
                           "image_t holds");
  }
}

TEST(ImageLimits, CheckImageRefusesWhatDecodingWouldWithoutDecoding) {
  const ld::image_t good = ld::matToImage(cv::Mat(6, 8, CV_8UC3, cv::Scalar(1, 2, 3)),
                                          ld::image_t::PIXEL_FORMAT_YUYV, 1);
  EXPECT_NO_THROW(ld::checkImage(good));
  EXPECT_NO_THROW(ld::checkImage(mjpegClaiming(8, 6, true)));
  ld::image_t bad = good;
  bad.height = 7;
  EXPECT_THROW(ld::checkImage(bad), ld::ImageFormatError);
  bad = good;
  bad.pixelformat = ld::fourcc('H', '2', '6', '4');
  EXPECT_THROW(ld::checkImage(bad), ld::ImageFormatError);
  EXPECT_THROW(ld::checkImage(mjpegClaiming(30000, 30000, true)), ld::ImageFormatError);
}

// ld::LatestMessage, the input of ld-detector and ld-tracker: the newest
// good message waits to be processed; a good one it replaced is counted as
// skipped; a bad one (not decoded, or refused by the process's check) is
// said in one line and counted, and loses nothing.
namespace {

struct Delivered {
  ld::test::Bytes bytes;
  void to(ld::LatestMessage<ld::landmark_list_t>& latest) {
    lcm::ReceiveBuffer rbuf{bytes.data(), static_cast<uint32_t>(bytes.size()), 0};
    latest.onMessage(&rbuf, "LANDMARKS");
  }
};

Delivered listOf(int64_t seq, int n) {
  ld::landmark_list_t m{};
  m.seq = seq;
  m.utime = 1000 * seq;
  m.nlandmarks = n;
  m.landmarks.resize(static_cast<size_t>(n));
  return {ld::test::lcmEncode(m)};
}

}  // namespace

TEST(LatestMessage, NewestGoodMessageWaitsAndReplacedOnesAreSkipped) {
  ld::LatestMessage<ld::landmark_list_t> latest("ld-test", "LANDMARKS", "message");
  EXPECT_EQ(latest.take(), nullptr);
  listOf(1, 1).to(latest);
  listOf(2, 2).to(latest);
  listOf(3, 0).to(latest);
  const ld::landmark_list_t* got = latest.take();
  ASSERT_NE(got, nullptr);
  EXPECT_EQ(got->seq, 3);
  EXPECT_EQ(got->nlandmarks, 0);
  EXPECT_EQ(latest.take(), nullptr);  // taken once
  EXPECT_EQ(latest.skipped(), 2);
  EXPECT_EQ(latest.bad(), 0);
  listOf(4, 3).to(latest);
  got = latest.take();
  ASSERT_NE(got, nullptr);
  EXPECT_EQ(got->seq, 4);
  EXPECT_EQ(got->landmarks.size(), 3u);
  EXPECT_EQ(latest.skipped(), 2);  // (taken before the next came: none skipped)
}

// Frames that never reached the process (the kernel's receive buffer full,
// a lossy network, a camera that dropped them) are counted by the gaps in
// their seqs, apart from those skipped to stay current and the bad ones; a
// seq that goes back (a log replayed again) starts anew.
TEST(LatestMessage, CountsTheSeqsThatNeverCame) {
  const auto seqOf = [](const ld::landmark_list_t& m) { return std::optional<int64_t>(m.seq); };
  ld::LatestMessage<ld::landmark_list_t> latest(
      "ld-test", "LANDMARKS", "message",
      [](const ld::landmark_list_t& m) { return m.nlandmarks > 2 ? std::string("too many") : std::string(); }, seqOf);
  listOf(5, 1).to(latest);  // (the first: nothing before it is missing)
  listOf(6, 1).to(latest);
  listOf(9, 1).to(latest);  // 7 and 8 lost
  EXPECT_EQ(latest.missing(), 2);
  EXPECT_EQ(latest.skipped(), 2);  // (5 and 6, replaced before taken: skipped, not missing)
  testing::internal::CaptureStderr();
  listOf(10, 5).to(latest);  // refused: its seq is not trusted
  Delivered cut = listOf(11, 1);
  cut.bytes.resize(cut.bytes.size() - 5);
  cut.to(latest);  // not decoded
  listOf(7, 9).to(latest);  // refused: a bad message's seq moves nothing
  (void)testing::internal::GetCapturedStderr();
  listOf(12, 1).to(latest);
  EXPECT_EQ(latest.bad(), 3);
  EXPECT_EQ(latest.missing(), 4);  // 7, 8 and the two bad ones
  listOf(14, 1).to(latest);  // (13 missing)
  EXPECT_EQ(latest.missing(), 5);
  listOf(13, 1).to(latest);  // reordered on the way: not missing after all
  EXPECT_EQ(latest.missing(), 4);
  listOf(15, 1).to(latest);  // (the run goes on from 14)
  EXPECT_EQ(latest.missing(), 4);
  listOf(0, 1).to(latest);  // replayed from the start: no gap, none missing
  listOf(1, 1).to(latest);
  listOf(-1, 1).to(latest);  // (no seq: passed over)
  listOf(3, 1).to(latest);
  EXPECT_EQ(latest.missing(), 5);
  listOf(INT64_MAX, 1).to(latest);  // (a huge jump does not overflow)
  EXPECT_EQ(latest.missing(), INT64_MAX);
  ld::LatestMessage<ld::landmark_list_t> without("ld-test", "LANDMARKS", "message");
  listOf(1, 1).to(without);
  listOf(9, 1).to(without);
  EXPECT_EQ(without.missing(), 0);  // (no seqs given: none counted)
}

// The frame waiting, come again (a recording with the set's outputs played
// onto the running tracker): a repeat, not a newer list that skipped it (2
// of 40 such were counted skipped, and the count went into every list).
TEST(LatestMessage, RepeatOfTheWaitingFrameIsNotASkip) {
  ld::LatestMessage<ld::landmark_list_t> latest(
      "ld-test", "LANDMARKS", "message", {}, {},
      [](const ld::landmark_list_t& a, const ld::landmark_list_t& b) { return a.seq == b.seq && a.utime == b.utime; });
  listOf(1, 1).to(latest);
  listOf(1, 2).to(latest);  // the same frame again
  EXPECT_EQ(latest.skipped(), 0);
  EXPECT_EQ(latest.repeated(), 1);
  const ld::landmark_list_t* got = latest.take();
  ASSERT_NE(got, nullptr);
  EXPECT_EQ(got->nlandmarks, 1);  // (the first kept)
  listOf(2, 1).to(latest);
  listOf(3, 1).to(latest);  // a newer one: the waiting one skipped
  EXPECT_EQ(latest.skipped(), 1);
  EXPECT_EQ(latest.repeated(), 1);
}

// A subscription's queue held to a byte budget (ld::QueueFit) rather than
// LCM's 30 messages, beyond which LCM's receiving thread dropped the newer
// ones without a word (Stack.StalledDetectorTakesTheNewestFrame is the
// test over multicast: memq:// queues without that limit): the count is
// 256 MiB over the largest message seen, 30 to 10000.
TEST(QueueFit, HoldsASubscriptionsQueueToAByteBudget) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  ld::LatestMessage<ld::landmark_list_t> latest("ld-test", "LANDMARKS", "message");
  ld::QueueFit none;  // (without a subscription: nothing to set)
  none.fit(1000);
  EXPECT_EQ(none.capacity(), 30);
  ld::QueueFit sized(lcm.subscribe("LANDMARKS", &ld::LatestMessage<ld::landmark_list_t>::onMessage, &latest));
  EXPECT_EQ(sized.capacity(), 30);  // (LCM's own, until a message is seen)
  sized.fit(1000);                   // a landmark list
  EXPECT_EQ(sized.capacity(), 10000);  // (the most)
  sized.fit(640 * 480 * 2);           // a 640x480 YUYV frame
  EXPECT_EQ(sized.capacity(), 436);
  sized.fit(size_t{6} << 20);         // a raw 1080p BGR frame
  EXPECT_EQ(sized.capacity(), 42);
  sized.fit(1000);                    // (the largest seen holds)
  EXPECT_EQ(sized.capacity(), 42);
  sized.fit(size_t{64} << 20);
  EXPECT_EQ(sized.capacity(), 30);  // (the least: LCM's own)
}

TEST(LatestMessage, BadMessagesAreSaidCountedAndLoseNothing) {
  ld::LatestMessage<ld::landmark_list_t> latest(
      "ld-test", "LANDMARKS", "message",
      [](const ld::landmark_list_t& m) { return m.nlandmarks > 2 ? std::string("too many") : std::string(); });
  listOf(1, 1).to(latest);
  Delivered cut = listOf(2, 1);
  cut.bytes.resize(cut.bytes.size() - 5);
  testing::internal::CaptureStderr();
  cut.to(latest);           // not decoded
  listOf(3, 5).to(latest);  // refused by the check
  const std::string said = testing::internal::GetCapturedStderr();
  const ld::landmark_list_t* got = latest.take();
  ASSERT_NE(got, nullptr);
  EXPECT_EQ(got->seq, 1);  // the good one waiting, not replaced
  EXPECT_EQ(latest.skipped(), 0);
  EXPECT_EQ(latest.bad(), 2);
  std::istringstream lines(said);
  std::string first, second, more;
  std::getline(lines, first);
  std::getline(lines, second);
  EXPECT_EQ(first.rfind("ld-test: dropped message: message on LANDMARKS is ", 0), 0u) << said;
  EXPECT_NE(first.find(" (1 bad so far)"), std::string::npos) << said;
  EXPECT_EQ(second, "ld-test: dropped message: too many (2 bad so far)") << said;
  EXPECT_FALSE(std::getline(lines, more)) << said;
  // a flood: the first ten said in full, then every hundredth; all counted
  testing::internal::CaptureStderr();
  for (int i = 0; i < 198; ++i) listOf(10 + i, 9).to(latest);
  const std::string flood = testing::internal::GetCapturedStderr();
  EXPECT_EQ(latest.bad(), 200);
  EXPECT_EQ(std::count(flood.begin(), flood.end(), '\n'), 8 + 2) << flood;  // 3..10, 100, 200
  EXPECT_EQ(latest.take(), nullptr);
}
