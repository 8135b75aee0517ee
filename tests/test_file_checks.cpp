// ld::readImageFile, the image reader of ld-detect and ld-log-images: the
// image it gives is OpenCV's (cv::imdecode, as cv::imread reads the file),
// whether it decoded a JPEG once (plain JFIF, grey, progressive) or twice
// (an APP1 block, which OpenCV reads as Exif and turns the image by).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <csignal>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "ld/file_checks.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_json.hpp"

namespace {

// A 320x240 frame with colour, edges and noise (JPEG's every kind of block).
cv::Mat testFrame() {
  cv::Mat img(240, 320, CV_8UC3);
  cv::RNG rng(7);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(img, img, cv::Size(9, 9), 3);
  cv::rectangle(img, {40, 30, 80, 60}, {255, 0, 0}, cv::FILLED);
  cv::circle(img, {220, 150}, 50, {0, 0, 230}, cv::FILLED);
  cv::putText(img, "ld", {150, 220}, cv::FONT_HERSHEY_SIMPLEX, 1.5, {0, 0, 0}, 3);
  return img;
}

std::vector<uint8_t> encode(const cv::Mat& img, std::vector<int> params = {}) {
  std::vector<uint8_t> bytes;
  EXPECT_TRUE(cv::imencode(".jpg", img, bytes, params));
  return bytes;
}

// The bytes with an Exif block (APP1) after the JFIF one, whose one IFD
// entry is the orientation (6: turn 90 degrees clockwise to view); `name`
// is its header ("Exif").
std::vector<uint8_t> withExifOrientation(std::vector<uint8_t> jpeg, uint16_t orientation,
                                         const char (&name)[5] = "Exif") {
  const std::vector<uint8_t> exif = {
      static_cast<uint8_t>(name[0]), static_cast<uint8_t>(name[1]), static_cast<uint8_t>(name[2]),
      static_cast<uint8_t>(name[3]), 0, 0,               // Exif header
      'I', 'I', 0x2A, 0, 8, 0, 0, 0,                     // TIFF, little-endian, IFD at 8
      1, 0,                                              // one entry
      0x12, 0x01, 3, 0, 1, 0, 0, 0,                      // Orientation, SHORT, count 1
      static_cast<uint8_t>(orientation), static_cast<uint8_t>(orientation >> 8), 0, 0,
      0, 0, 0, 0};                                       // no next IFD
  EXPECT_TRUE(jpeg.size() > 6 && jpeg[2] == 0xFF && jpeg[3] == 0xE0);  // JFIF's APP0 first
  const size_t after_app0 = 4 + ((static_cast<size_t>(jpeg[4]) << 8) | jpeg[5]);
  const size_t len = exif.size() + 2;
  std::vector<uint8_t> app1 = {0xFF, 0xE1, static_cast<uint8_t>(len >> 8), static_cast<uint8_t>(len)};
  app1.insert(app1.end(), exif.begin(), exif.end());
  jpeg.insert(jpeg.begin() + static_cast<std::ptrdiff_t>(after_app0), app1.begin(), app1.end());
  return jpeg;
}

std::string writeFile(const std::string& name, const std::vector<uint8_t>& bytes) {
  const std::string path = testing::TempDir() + "/file_checks_" + name;
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                              static_cast<std::streamsize>(bytes.size()));
  return path;
}

// What readImageFile gives for these bytes, checked against cv::imdecode's.
void expectOpenCvImage(const std::string& name, const std::vector<uint8_t>& bytes, cv::Size size) {
  SCOPED_TRACE(name);
  cv::Mat read;
  ASSERT_EQ(ld::readImageFile(writeFile(name, bytes), read), "");
  const cv::Mat opencv = cv::imdecode(bytes, cv::IMREAD_COLOR);
  ASSERT_EQ(read.type(), CV_8UC3);
  ASSERT_EQ(read.size(), size);
  ASSERT_EQ(opencv.size(), size);
  EXPECT_EQ(cv::norm(read, opencv, cv::NORM_INF), 0);
}

TEST(ReadImageFile, JpegIsOpenCvsImageDecodedOnceOrTwice) {
  const cv::Mat frame = testFrame();
  const std::vector<uint8_t> plain = encode(frame, {cv::IMWRITE_JPEG_QUALITY, 85});
  cv::Mat grey;
  cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
  const std::vector<uint8_t> grey_jpeg = encode(grey);
  const std::vector<uint8_t> progressive = encode(frame, {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
  const std::vector<uint8_t> restarts = encode(frame, {cv::IMWRITE_JPEG_RST_INTERVAL, 4});
  // decoded once (4:2:0 colour, grey, progressive, restart markers): what
  // libjpeg gives is what OpenCV gives
  for (const auto* bytes : {&plain, &grey_jpeg, &progressive, &restarts})
    EXPECT_TRUE(ld::jpegReadsAsDecoded(bytes->data(), bytes->size()));
  expectOpenCvImage("plain.jpg", plain, frame.size());
  expectOpenCvImage("grey.jpg", grey_jpeg, frame.size());
  expectOpenCvImage("progressive.jpg", progressive, frame.size());
  expectOpenCvImage("restarts.jpg", restarts, frame.size());
  // an Exif orientation: OpenCV's image is turned (240x320), and so is this
  const std::vector<uint8_t> turned = withExifOrientation(plain, 6);
  EXPECT_FALSE(ld::jpegReadsAsDecoded(turned.data(), turned.size()));
  expectOpenCvImage("turned.jpg", turned, {frame.rows, frame.cols});
  // (an Exif block that keeps the image as it is reads as before too)
  const std::vector<uint8_t> upright = withExifOrientation(plain, 1);
  expectOpenCvImage("upright.jpg", upright, frame.size());
  // OpenCV takes the first APP1 block for Exif whatever its name says
  const std::vector<uint8_t> misnamed = withExifOrientation(plain, 6, "ZZZZ");
  EXPECT_FALSE(ld::jpegReadsAsDecoded(misnamed.data(), misnamed.size()));
  expectOpenCvImage("misnamed.jpg", misnamed, {frame.rows, frame.cols});
}

// How the Exif orientation turned the image, from the stored pixels: ld-detect
// turns a calibration of the photos as stored with it (a phone's portrait
// photo). Orientations 2-8: mirrored, 180, mirrored upside down, transposed,
// a quarter clockwise, transverse, a quarter anticlockwise.
TEST(ReadImageFile, SaysHowTheExifOrientationTurnedTheImage) {
  const cv::Mat frame = testFrame();
  const std::vector<uint8_t> plain = encode(frame, {cv::IMWRITE_JPEG_QUALITY, 85});
  const struct {
    int quarter_turns_cw;
    bool mirrored;
  } want[9] = {{}, {0, false}, {0, true}, {2, false}, {2, true}, {3, true}, {1, false}, {1, true}, {3, false}};
  for (uint16_t o = 1; o <= 8; ++o) {
    SCOPED_TRACE("orientation " + std::to_string(o));
    cv::Mat read;
    ld::ImageTurn turn;
    turn.quarter_turns_cw = 7;
    ASSERT_EQ(ld::readImageFile(writeFile("o" + std::to_string(o) + ".jpg", withExifOrientation(plain, o)), read, turn),
              "");
    EXPECT_EQ(turn.quarter_turns_cw, want[o].quarter_turns_cw);
    EXPECT_EQ(turn.mirrored, want[o].mirrored);
    EXPECT_EQ(turn.any(), o != 1);
    EXPECT_EQ(turn.stored, frame.size());
    EXPECT_EQ(read.size(), want[o].quarter_turns_cw % 2 ? cv::Size(frame.rows, frame.cols) : frame.size());
  }
  // A flat picture whose one mark lies between the grid's points: the grid
  // alone took a transposed one for one not turned (a review); the turn is
  // confirmed on every pixel.
  cv::Mat flat(480, 480, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::rectangle(flat, cv::Rect(32, 42, 6, 6), cv::Scalar(255, 0, 0), cv::FILLED);
  const std::vector<uint8_t> flat_jpeg = encode(flat, {cv::IMWRITE_JPEG_QUALITY, 95});
  for (uint16_t o : {5, 7}) {
    SCOPED_TRACE("flat, orientation " + std::to_string(o));
    cv::Mat read;
    ld::ImageTurn turn;
    ASSERT_EQ(ld::readImageFile(writeFile("flat" + std::to_string(o) + ".jpg", withExifOrientation(flat_jpeg, o)),
                                read, turn),
              "");
    EXPECT_EQ(turn.quarter_turns_cw, want[o].quarter_turns_cw);
    EXPECT_EQ(turn.mirrored, want[o].mirrored);
  }
  // not turned: a JPEG without Exif, a PNG
  cv::Mat read;
  ld::ImageTurn turn;
  ASSERT_EQ(ld::readImageFile(writeFile("plain.jpg", plain), read, turn), "");
  EXPECT_FALSE(turn.any());
  EXPECT_EQ(turn.stored, frame.size());
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", frame, png));
  ASSERT_EQ(ld::readImageFile(writeFile("plain.png", png), read, turn), "");
  EXPECT_FALSE(turn.any());
  EXPECT_EQ(turn.stored, frame.size());
}

// A folder's images, in name order, by their names' extensions in any case;
// files of image kinds OpenCV does not read (a phone's HEIC) named apart, so
// that they are said; other files and folders passed over; a folder that
// cannot be listed says why (ld-log-images said "no image files in" it).
TEST(ListImageFolder, ImagesInOrderAndUnreadKindsApart) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(testing::TempDir()) / "list_image_folder";
  fs::remove_all(dir);
  fs::create_directories(dir / "sub.png");
  for (const char* name : {"b.PNG", "a.jpg", "c.JFIF", "d.pnm", "IMG_0001.HEIC", "e.gif", "truth.jsonl", "f.dng"})
    std::ofstream(dir / name) << "x";
  std::vector<std::string> files, unread;
  ASSERT_EQ(ld::listImageFolder(dir.string(), files, unread), "");
  EXPECT_EQ(files, (std::vector<std::string>{(dir / "a.jpg").string(), (dir / "b.PNG").string(),
                                             (dir / "c.JFIF").string(), (dir / "d.pnm").string()}));
  EXPECT_EQ(unread, (std::vector<std::string>{"IMG_0001.HEIC", "e.gif", "f.dng"}));
  EXPECT_EQ(ld::describeUnreadImages(unread),
            "3 files of image kinds OpenCV does not read (HEIC/HEIF, AVIF, GIF, camera raw) left out (IMG_0001.HEIC, "
            "e.gif, f.dng): convert them to JPEG or PNG");
  EXPECT_EQ(ld::describeUnreadImages({}), "");
  EXPECT_NE(ld::listImageFolder((dir / "a.jpg").string(), files, unread), "");  // (not a folder)
  EXPECT_NE(ld::listImageFolder((dir / "none").string(), files, unread).find("No such file"), std::string::npos);
  EXPECT_TRUE(ld::isImageFileName("x/Y.TIFF"));
  EXPECT_FALSE(ld::isImageFileName("x/y.heic"));
  EXPECT_EQ(ld::imageFileExtensions().rfind(".png, .jpg, .jpeg", 0), 0u);
  fs::remove_all(dir);
}

TEST(ReadImageFile, JpegHeadersThatAreNotOneGoToOpenCv) {
  // no scan, or bytes that are no JPEG: not taken as read
  const std::vector<uint8_t> plain = encode(testFrame());
  const std::vector<uint8_t> headers_only(plain.begin(), plain.begin() + 20);
  EXPECT_FALSE(ld::jpegReadsAsDecoded(headers_only.data(), headers_only.size()));
  const std::vector<uint8_t> png_head = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  EXPECT_FALSE(ld::jpegReadsAsDecoded(png_head.data(), png_head.size()));
}

}  // namespace

namespace {

TEST(ReadImageFile, DecodersOwnWordsAreInTheOneLine) {
  // libpng printed "libpng error: ..." on stderr itself, a line that named
  // no file, before the caller's "cannot read as an image"
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", testFrame(), png));
  std::vector<uint8_t> cut(png.begin(), png.begin() + static_cast<std::ptrdiff_t>(png.size() / 2));
  std::vector<uint8_t> damaged = png;
  const auto idat = std::search(damaged.begin(), damaged.end(), std::begin("IDAT"), std::end("IDAT") - 1);
  ASSERT_NE(idat, damaged.end());
  for (int i = 8; i < 400; i += 7) idat[i] ^= 0x5A;  // (within the compressed data)
  cv::Mat read;
  testing::internal::CaptureStderr();
  const std::string cut_why = ld::readImageFile(writeFile("cut.png", cut), read);
  const std::string damaged_why = ld::readImageFile(writeFile("damaged.png", damaged), read);
  const std::string good_why = ld::readImageFile(writeFile("good.png", png), read);
  const std::string printed = testing::internal::GetCapturedStderr();
  EXPECT_EQ(cut_why, "cannot read as an image (libpng error: PNG input buffer is incomplete)");
  EXPECT_EQ(damaged_why.rfind("cannot read as an image (libpng error: ", 0), 0u) << damaged_why;
  EXPECT_EQ(good_why, "");
  EXPECT_EQ(read.size(), cv::Size(320, 240));
  EXPECT_EQ(printed, "");
  // the error libpng ends with after many warnings of its own (400 text
  // chunks with a wrong checksum, past the 4 KiB that were read back)
  std::vector<uint8_t> noisy(png.begin(), png.begin() + 33);  // signature, IHDR
  for (int i = 0; i < 400; ++i) {
    const uint8_t chunk[] = {0, 0, 0, 4, 't', 'E', 'X', 't', 'a', 0, 'b', 'c', 0, 0, 0, 0};
    noisy.insert(noisy.end(), std::begin(chunk), std::end(chunk));
  }
  noisy.insert(noisy.end(), png.begin() + 33, png.begin() + static_cast<std::ptrdiff_t>(png.size() / 2));
  testing::internal::CaptureStderr();
  const std::string noisy_why = ld::readImageFile(writeFile("noisy.png", noisy), read);
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(noisy_why, "cannot read as an image (libpng error: PNG input buffer is incomplete)");
  // standard error is as it was after each
  testing::internal::CaptureStderr();
  std::fprintf(stderr, "still here\n");
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "still here\n");
  // bytes no decoder takes: said as before
  EXPECT_EQ(ld::readImageFile(writeFile("text.png", {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'a', 'g', 'e'}), read),
            "cannot read as an image");
}

}  // namespace

namespace {

// RIFF chunks by hand: ID, little-endian size, data (padded to even).
void chunk(std::vector<uint8_t>& out, const char* id, const std::vector<uint8_t>& data) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(id[i]));
  const auto n = static_cast<uint32_t>(data.size());
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(n >> (8 * i)));
  out.insert(out.end(), data.begin(), data.end());
  if (data.size() % 2) out.push_back(0);
}
std::vector<uint8_t> list(const char* type, const std::vector<uint8_t>& chunks) {
  std::vector<uint8_t> data;
  for (int i = 0; i < 4; ++i) data.push_back(static_cast<uint8_t>(type[i]));
  for (const uint8_t b : chunks) data.push_back(b);
  return data;
}

// ld-view reads its video back with it: OpenCV's own reader counted the
// frames of a video's first GiB alone (FFmpeg's writer goes on in 'AVIX'
// sections), so a whole 2 GB video was said to be cut short.
// A floating-point image read black (OpenCV turned its 0-1 values into 8
// bits without scaling) and found nothing, without a word: it is refused,
// named. A 16-bit one reads as OpenCV reads it, scaled to 8 bits.
// An output named longer than a file name may be is refused before a run
// (ld-run ran the whole set, then could not write its summary).
TEST(PrepareOutputFile, NameTooLongIsRefused) {
  const std::string dir = testing::TempDir();
  EXPECT_EQ(ld::prepareOutputFile(dir + "/" + std::string(255, 'b')), "");
  EXPECT_EQ(ld::prepareOutputFile(dir + "/" + std::string(256, 'b')),
            "has a name of 256 bytes, more than the 255 a file name may have here");
}

// A file that could not be written whole is not left cut, as if whole (ld-eval
// left a table of 0 bytes on a full disk): here the file size limit cuts it.
TEST(WriteWholeFile, CutFileIsRemoved) {
  const std::string path = testing::TempDir() + "/cut_table.md";
  ASSERT_EQ(ld::writeWholeFile(path, "| a | b |\n"), "");
  auto* const old_handler = std::signal(SIGXFSZ, SIG_IGN);  // (the write fails instead of killing the test)
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  rlimit small = old;
  small.rlim_cur = 100;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  const std::string why = ld::writeWholeFile(path, std::string(100000, 'x'));
  ::setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_EQ(why, "File too large");
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(ReadImageFile, FloatingPointImagesAreRefusedNamed) {
  cv::Mat bgr(48, 64, CV_8UC3, cv::Scalar(40, 160, 250)), f;
  bgr.convertTo(f, CV_32FC3, 1 / 255.0);
  for (const auto& [ext, says] : std::vector<std::pair<std::string, std::string>>{
           {".pfm", "a PFM image"}, {".tiff", "a TIFF of floating-point samples"}}) {
    SCOPED_TRACE(ext);
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(cv::imencode(ext, f, bytes));
    cv::Mat read;
    EXPECT_EQ(ld::readImageFile(writeFile("float" + ext, bytes), read),
              "cannot read as an image: it is " + says +
                  " (OpenCV would read its values into 8 bits without scaling, black or wrong): convert it to an 8- "
                  "or 16-bit image first");
    EXPECT_TRUE(read.empty());
  }
  // (Radiance HDR: OpenCV scales it to 8 bits itself, and it reads)
  std::vector<uint8_t> hdr;
  ASSERT_TRUE(cv::imencode(".hdr", f, hdr));
  cv::Mat from_hdr;
  ASSERT_EQ(ld::readImageFile(writeFile("float.hdr", hdr), from_hdr), "");
  EXPECT_LE(cv::norm(from_hdr, bgr, cv::NORM_INF), 2);
  cv::Mat wide;
  bgr.convertTo(wide, CV_16UC3, 257);
  for (const std::string ext : {".png", ".tiff"}) {
    std::vector<uint8_t> bytes;
    ASSERT_TRUE(cv::imencode(ext, wide, bytes));
    cv::Mat read;
    ASSERT_EQ(ld::readImageFile(writeFile("wide" + ext, bytes), read), "") << ext;
    ASSERT_EQ(read.type(), CV_8UC3) << ext;
    EXPECT_EQ(cv::norm(read, bgr, cv::NORM_INF), 0) << ext;
  }
}

TEST(AviVideoFrames, CountsEverySectionAndStopsAtACut) {
  const std::string path = testing::TempDir() + "/file_checks_5.avi";
  {
    // (frames of noise: large beside the headers, so a cut lands among them)
    cv::VideoWriter w(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10, cv::Size(320, 240));
    ASSERT_TRUE(w.isOpened());
    cv::RNG rng(3);
    for (int i = 0; i < 5; ++i) {
      cv::Mat noise(240, 320, CV_8UC3);
      rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
      w.write(noise);
    }
  }
  EXPECT_EQ(ld::aviVideoFrames(path), 5);
  std::ifstream in(path, std::ios::binary);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  bytes.resize(bytes.size() * 6 / 10);  // (a full disk: the index and the last frames gone)
  const int64_t cut = ld::aviVideoFrames(writeFile("cut.avi", bytes));
  EXPECT_GE(cut, 1);
  EXPECT_LT(cut, 5);
  // two sections, as FFmpeg writes past 1 GiB: 2 frames, then 3 (and an
  // OpenDML index chunk and a 'rec ' list, which are no frames / hold one)
  const std::vector<uint8_t> jpeg = {0xFF, 0xD8, 0xFF, 0xD9, 0};
  std::vector<uint8_t> movi1, movi2, first, second, file;
  chunk(movi1, "00dc", jpeg);
  chunk(movi1, "00dc", jpeg);
  chunk(movi2, "00dc", jpeg);
  chunk(movi2, "ix00", {1, 2, 3, 4});
  std::vector<uint8_t> rec;
  chunk(rec, "00dc", jpeg);
  chunk(movi2, "LIST", list("rec ", rec));
  chunk(movi2, "00db", jpeg);
  chunk(first, "LIST", list("hdrl", {}));
  chunk(first, "LIST", list("movi", movi1));
  chunk(first, "idx1", {0, 0, 0, 0});
  chunk(second, "LIST", list("movi", movi2));
  chunk(file, "RIFF", list("AVI ", first));
  chunk(file, "RIFF", list("AVIX", second));
  EXPECT_EQ(ld::aviVideoFrames(writeFile("two.avi", file)), 5);
  // not an AVI, or no file
  EXPECT_EQ(ld::aviVideoFrames(writeFile("text.avi", {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', '!'})), -1);
  EXPECT_EQ(ld::aviVideoFrames(testing::TempDir() + "/file_checks_none.avi"), -1);
}

}  // namespace

// A label by a corner near an edge of the frame is kept inside it, its dark
// outline and the letters below the line too (ld-view's "#3 room-103 1.84 m"
// ran off the right edge, and one by a low corner off the bottom).
TEST(DrawLabel, StaysInsideTheFrame) {
  for (const int width : {640, 1280, 1920}) {
    const int height = width * 3 / 4, thick = std::max(1, width / 640);
    for (const cv::Point2f at : {cv::Point2f(width - 5.0f, height - 1.0f), cv::Point2f(-40.0f, -3.0f),
                                 cv::Point2f(width * 2.0f, 10.0f), cv::Point2f(5.0f, height + 50.0f)}) {
      cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
      ld::drawLabel(img, "#3 room-103 (coasting) yg", at, cv::Scalar(0, 255, 0), thick);
      cv::Mat ink;
      cv::inRange(img, cv::Scalar(0, 0, 0), cv::Scalar(254, 254, 254), ink);
      const cv::Rect drawn = cv::boundingRect(ink);
      ASSERT_GT(drawn.area(), 0) << width << " at " << at;
      // nothing on the frame's outermost rows and columns: the label was not cut
      EXPECT_GT(drawn.x, 0) << width << " at " << at;
      EXPECT_GT(drawn.y, 0) << width << " at " << at;
      EXPECT_LT(drawn.x + drawn.width, width) << width << " at " << at;
      EXPECT_LT(drawn.y + drawn.height, height) << width << " at " << at;
    }
  }
}
