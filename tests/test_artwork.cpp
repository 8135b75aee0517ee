// The generated artwork matches the layout of docs/landmark.md to the pixel,
// and its QR decodes with zbar.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <zbar.h>
#include <zlib.h>

#include "ld/artwork.hpp"

namespace {

using ld::artwork::Colours;

// binary: the bytes as encoded (as ld-qr-reader reads them); otherwise text,
// as zbar converts it for a reader that shows it (from the code's ECI, or a
// guess)
std::vector<std::string> zbarDecode(const cv::Mat& bgr, bool binary = true) {
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  zbar::ImageScanner scanner;
  scanner.set_config(zbar::ZBAR_NONE, zbar::ZBAR_CFG_ENABLE, 0);
  scanner.set_config(zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_ENABLE, 1);
  scanner.set_config(zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_BINARY, binary ? 1 : 0);
  zbar::Image image(static_cast<unsigned>(gray.cols), static_cast<unsigned>(gray.rows), "Y800",
                    gray.data, static_cast<unsigned long>(gray.total()));
  scanner.scan(image);
  std::vector<std::string> out;
  for (auto s = image.symbol_begin(); s != image.symbol_end(); ++s) out.push_back(s->get_data());
  image.set_data(nullptr, 0);
  return out;
}

// Counts pixels of `img` inside [x0,x1)x[y0,y1) that are not `colour`.
int wrongPixels(const cv::Mat& img, int x0, int y0, int x1, int y1, cv::Vec3b colour) {
  int bad = 0;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) bad += img.at<cv::Vec3b>(y, x) != colour;
  return bad;
}

}  // namespace

// At 900 px, u = 100 px: every square, gap and border lands on whole pixels,
// so the expected picture is written out here independently of the layout code.
TEST(Artwork, MatchesLayoutToThePixel) {
  const Colours c;
  const cv::Mat img = ld::artwork::renderLandmark("room-214/door", 900);
  ASSERT_EQ(img.size(), cv::Size(900, 900));
  ASSERT_EQ(img.type(), CV_8UC3);
  // Blue FIPs TL, TR, BL and the red AP, each [0.5u, 2.5u] from its corner.
  EXPECT_EQ(wrongPixels(img, 50, 50, 250, 250, c.blue), 0);
  EXPECT_EQ(wrongPixels(img, 650, 50, 850, 250, c.blue), 0);
  EXPECT_EQ(wrongPixels(img, 50, 650, 250, 850, c.blue), 0);
  EXPECT_EQ(wrongPixels(img, 650, 650, 850, 850, c.red), 0);
  // White margins of 0.5u around the pattern square.
  EXPECT_EQ(wrongPixels(img, 0, 0, 900, 50, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 0, 850, 900, 900, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 0, 0, 50, 900, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 850, 0, 900, 900, c.white), 0);
  // White between the squares, outside the QR square [2.5u, 6.5u]^2.
  EXPECT_EQ(wrongPixels(img, 250, 50, 650, 250, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 250, 650, 650, 850, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 50, 250, 250, 650, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 650, 250, 850, 650, c.white), 0);
  // Only black and white inside the QR square, with at least one module of
  // white quiet zone.
  const auto qr = ld::artwork::encodeQr("room-214/door");
  const double module_px = 400.0 / (qr.size + 2);
  const int q = static_cast<int>(std::floor(module_px));
  EXPECT_EQ(wrongPixels(img, 250, 250, 650, 250 + q, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 250, 650 - q, 650, 650, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 250, 250, 250 + q, 650, c.white), 0);
  EXPECT_EQ(wrongPixels(img, 650 - q, 250, 650, 650, c.white), 0);
  // Each module's centre pixel has the module's colour.
  for (int my = 0; my < qr.size; ++my)
    for (int mx = 0; mx < qr.size; ++mx) {
      const int px = static_cast<int>(250 + (mx + 1.5) * module_px);
      const int py = static_cast<int>(250 + (my + 1.5) * module_px);
      ASSERT_EQ(img.at<cv::Vec3b>(py, px), qr.dark(mx, my) ? c.black : c.white)
          << "module " << mx << "," << my;
    }
  int dark = 0;
  for (int y = 250; y < 650; ++y)
    for (int x = 250; x < 650; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      ASSERT_TRUE(p == c.black || p == c.white);
      dark += p == c.black;
    }
  EXPECT_GT(dark, 400 * 400 / 5);
}

TEST(Artwork, SquaresScaleWithAnySide) {
  for (int side : {18, 90, 101, 355, 1771}) {
    const cv::Mat img = ld::artwork::renderLandmark("x", side);
    const double u = side / 9.0;
    // Pixel centres strictly inside each square are coloured, just outside white.
    auto at = [&](double ux, double uy) {
      return img.at<cv::Vec3b>(static_cast<int>(uy * u), static_cast<int>(ux * u));
    };
    EXPECT_EQ(at(1.5, 1.5), Colours().blue) << side;
    EXPECT_EQ(at(7.5, 1.5), Colours().blue) << side;
    EXPECT_EQ(at(1.5, 7.5), Colours().blue) << side;
    EXPECT_EQ(at(7.5, 7.5), Colours().red) << side;
    EXPECT_EQ(at(0.2, 0.2), Colours().white) << side;
    EXPECT_EQ(at(4.5, 1.5), Colours().white) << side;
  }
}

TEST(Artwork, QrDecodesWithZbar) {
  const std::vector<std::string> payloads{
      "room-214/door", "L1", "UTF-8: \xc3\xa9t\xc3\xa9 \xe2\x86\x92 \xe6\x9d\xb1\xe4\xba\xac", "\xc3\xa9t\xc3\xa9 \xe6\x9d\xb1",
      std::string(100, 'A') };
  for (const auto& p : payloads) {
    const cv::Mat img = ld::artwork::renderLandmark(p, 540);
    const auto found = zbarDecode(img);
    ASSERT_EQ(found.size(), 1u) << p;
    EXPECT_EQ(found[0], p);
  }
}

// UTF-8 text beyond ASCII says so in its code (ECI 26): a reader that shows
// text reads it as written. Without it, zbar took short UTF-8 for
// Shift-JIS ("caf\xc3\xa9" read "caf\xe7\x9f\x87"). Bytes that are not UTF-8
// are encoded as they are.
TEST(Artwork, Utf8PayloadsReadAsTextByAnyReader) {
  const std::vector<std::string> texts{"caf\xc3\xa9", "\xc3\xa9", "\xe5\xae\x9f\xe9\xa8\x93\xe5\xae\xa4",
                                       "T\xc3\xbcr-214/\xe2\x9c\x93", "room-214/door"};
  for (const auto& p : texts) {
    const cv::Mat img = ld::artwork::renderLandmark(p, 540);
    for (bool binary : {false, true}) {
      const auto found = zbarDecode(img, binary);
      ASSERT_EQ(found.size(), 1u) << p;
      EXPECT_EQ(found[0], p) << (binary ? "bytes" : "text");
    }
  }
  // (the mark costs 12 bits: at the largest symbol's capacity, said)
  std::string full = "\xc3\xa9";
  while (full.size() < 2953) full += 'x';
  try {
    ld::artwork::encodeQr(full);
    ADD_FAILURE() << "2953 bytes of UTF-8 encoded";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "QR payload of 2953 bytes cannot be encoded (UTF-8 text, with its ECI mark: 12 bits more): a QR code "
              "holds at most 2953 bytes at level L");
  }
  EXPECT_NO_THROW(ld::artwork::encodeQr(std::string(2953, 'x')));
  full += std::string(1000, 'x');  // (too long either way: nothing said of the mark)
  try {
    ld::artwork::encodeQr(full);
    ADD_FAILURE() << "3953 bytes encoded";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "QR payload of 3953 bytes cannot be encoded: a QR code holds at most 2953 bytes at level L");
  }
  const std::string bytes = "\xff\xfe\x80 raw";
  const auto found = zbarDecode(ld::artwork::renderLandmark(bytes, 540));
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0], bytes);
}

// Auto error correction: level L's symbol (the largest modules the QR square
// can have), at the highest level that still fits it; an explicit level is
// used as given. Every level reads back with zbar.
TEST(Artwork, ErrorCorrectionAsHighAsTheSmallestSymbolAllows) {
  using ld::artwork::QrEcc;
  using ld::artwork::encodeQr;
  const QrEcc levels[] = {QrEcc::L, QrEcc::M, QrEcc::Q, QrEcc::H};
  const char names[] = {'L', 'M', 'Q', 'H'};
  for (size_t n : {1u, 13u, 20u, 23u, 60u, 100u, 300u}) {
    const std::string p(n, 'a');
    const auto autoqr = encodeQr(p);
    const auto l = encodeQr(p, QrEcc::L);
    EXPECT_EQ(autoqr.version, l.version) << n << " bytes";
    int chosen = -1;
    for (int k = 0; k < 4; ++k)
      if (names[k] == autoqr.ecc) chosen = k;
    ASSERT_GE(chosen, 0) << autoqr.ecc;
    // the symbol is the one of that level, and every higher level needs a larger one
    EXPECT_EQ(autoqr.modules, encodeQr(p, levels[chosen]).modules) << n << " bytes";
    for (int k = chosen + 1; k < 4; ++k) EXPECT_GT(encodeQr(p, levels[k]).version, l.version) << n << " bytes";
  }
  EXPECT_EQ(encodeQr(std::string(100, 'a')).ecc, 'L');  // version 5 holds 106 bytes at L, 84 at M
  EXPECT_EQ(encodeQr(std::string(100, 'a')).size, 37);
  EXPECT_EQ(encodeQr(std::string(100, 'a'), QrEcc::M).size, 41);
  EXPECT_EQ(encodeQr("room-214/door").ecc, 'M');  // version 1: 14 bytes at M, 11 at Q
  EXPECT_EQ(encodeQr("dock").ecc, 'H');
  for (int k = 0; k < 4; ++k) {
    const std::string p = "level-" + std::string(1, names[k]) + " room-214/door";
    const auto qr = encodeQr(p, levels[k]);
    EXPECT_EQ(qr.ecc, names[k]);
    const auto found = zbarDecode(ld::artwork::renderLandmark(qr, 540));
    ASSERT_EQ(found.size(), 1u) << p;
    EXPECT_EQ(found[0], p);
  }
  // 2000 bytes fit version 40 at L, not at H
  EXPECT_NO_THROW(encodeQr(std::string(2000, 'x')));
  EXPECT_THROW(encodeQr(std::string(2000, 'x'), QrEcc::H), std::invalid_argument);
  EXPECT_EQ(ld::artwork::parseQrEcc("auto"), QrEcc::Auto);
  EXPECT_EQ(ld::artwork::parseQrEcc("q"), QrEcc::Q);
  EXPECT_THROW(ld::artwork::parseQrEcc("X"), std::invalid_argument);
}

TEST(Artwork, CustomColoursAreUsed) {
  Colours ink;
  ink.blue = {120, 50, 45};
  ink.red = {50, 70, 215};
  ink.white = {228, 235, 235};
  ink.black = {40, 35, 35};
  const cv::Mat img = ld::artwork::renderLandmark("x", 180, ink);
  EXPECT_EQ(img.at<cv::Vec3b>(30, 30), ink.blue);
  EXPECT_EQ(img.at<cv::Vec3b>(150, 150), ink.red);
  EXPECT_EQ(img.at<cv::Vec3b>(2, 2), ink.white);
}

TEST(Artwork, TooLongPayloadIsRefused) {
  EXPECT_THROW(ld::artwork::encodeQr(std::string(4000, 'x')), std::invalid_argument);
}

TEST(Artwork, SvgHasExactPhysicalSize) {
  const std::string svg = ld::artwork::landmarkSvg("a&b<c>", 90.0);
  EXPECT_NE(svg.find("width=\"90mm\" height=\"90mm\" viewBox=\"0 0 90 90\""), std::string::npos);
  // u = 10 mm: FIPs at 5, 65 mm, AP at (65, 65), each 20 mm.
  EXPECT_NE(svg.find("<rect x=\"5\" y=\"5\" width=\"20\" height=\"20\" fill=\"#0000ff\"/>"),
            std::string::npos);
  EXPECT_NE(svg.find("<rect x=\"65\" y=\"5\" width=\"20\" height=\"20\" fill=\"#0000ff\"/>"),
            std::string::npos);
  EXPECT_NE(svg.find("<rect x=\"5\" y=\"65\" width=\"20\" height=\"20\" fill=\"#0000ff\"/>"),
            std::string::npos);
  EXPECT_NE(svg.find("<rect x=\"65\" y=\"65\" width=\"20\" height=\"20\" fill=\"#ff0000\"/>"),
            std::string::npos);
  EXPECT_NE(svg.find("a&amp;b&lt;c&gt;"), std::string::npos);
  // Every QR module run lies inside the QR square [25, 65] mm, quiet zone excluded.
  const auto qr = ld::artwork::encodeQr("a&b<c>");
  const double m = 40.0 / (qr.size + 2);
  const std::regex move("M([0-9.]+) ([0-9.]+)h");
  int runs = 0;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), move); it != std::sregex_iterator();
       ++it, ++runs) {
    const double x = std::stod((*it)[1]), y = std::stod((*it)[2]);
    EXPECT_GE(x, 25 + m - 1e-3);
    EXPECT_GE(y, 25 + m - 1e-3);
    EXPECT_LE(x, 65 - 2 * m + 1e-3);
    EXPECT_LE(y, 65 - 2 * m + 1e-3);
  }
  EXPECT_GT(runs, qr.size);
}

TEST(Artwork, SheetHoldsEveryLandmarkAndDecodes) {
  const std::vector<std::string> payloads{"dock", "room-101", "room-102", "lift"};
  const cv::Mat page = ld::artwork::sheetImage(payloads, 60.0, 150.0);
  EXPECT_EQ(page.cols, static_cast<int>(std::lround(210 / 25.4 * 150)));
  const auto found = zbarDecode(page);
  EXPECT_EQ(std::set<std::string>(found.begin(), found.end()),
            std::set<std::string>(payloads.begin(), payloads.end()));
  const std::string svg = ld::artwork::sheetSvg(payloads, 60.0);
  EXPECT_NE(svg.find("width=\"210mm\" height=\"297mm\""), std::string::npos);
  for (const auto& p : payloads) EXPECT_NE(svg.find(">" + p + " (60 mm)<"), std::string::npos);
  EXPECT_THROW(ld::artwork::sheetSvg(payloads, 300.0), std::invalid_argument);
  EXPECT_THROW(ld::artwork::sheetSvg(std::vector<std::string>(40, "x"), 60.0),
               std::invalid_argument);
}

// A label is cut to its landmark's width (about 1.8 mm a character of 3 mm
// text, wide scripts twice that), so neighbours' labels do not overlap: a
// payload too long loses its middle (ids differ at their ends), and the side
// stays where the payload keeps 6 characters beside it (at 20 mm every label
// read "... (20 mm)"); a label that may still be wider than its landmark is
// squeezed to its width; what is not text shows as U+FFFD.
TEST(Artwork, SheetLabelsFitTheirLandmark) {
  const std::string long_ascii(100, 'a'), long_cjk = "\xe6\x97\xa5\xe6\x9c\xac\xe8\xaa\x9e";  // 3 wide characters
  std::string cjk24;
  for (int i = 0; i < 8; ++i) cjk24 += long_cjk;
  const std::string svg = ld::artwork::sheetSvg({long_ascii, cjk24, "room-101", "a\x01\xff"}, 90.0);
  // 50 wide, 8 for the size, 3 dots: 20 from the start, 19 from the end
  EXPECT_NE(svg.find(" textLength=\"90\" lengthAdjust=\"spacingAndGlyphs\">" + std::string(20, 'a') + "..." +
                     std::string(19, 'a') + " (90 mm)<"),
            std::string::npos)
      << svg;
  EXPECT_NE(svg.find(">" + long_cjk + long_cjk + long_cjk + "\xe6\x97\xa5..." + long_cjk + long_cjk + long_cjk +
                     " (90 mm)<"),
            std::string::npos);
  EXPECT_NE(svg.find("fill=\"#404040\">room-101 (90 mm)<"), std::string::npos);  // (short: not squeezed)
  EXPECT_NE(svg.find(">a\xef\xbf\xbd\xef\xbf\xbd (90 mm)<"), std::string::npos);
  // small landmarks: the payload, not the side; a long one keeps both ends
  const std::string small = ld::artwork::sheetSvg({"room-101", "room-101-east-wing"}, 20.0);
  EXPECT_NE(small.find(">room-101<"), std::string::npos) << small;
  EXPECT_NE(small.find(">room...wing<"), std::string::npos) << small;
  // (a wide script at the least size keeps a character: it read "...")
  const std::string tiny = ld::artwork::sheetSvg({cjk24}, 10.0);
  EXPECT_NE(tiny.find(">\xe6\x97\xa5...<"), std::string::npos) << tiny;
}

// The cutting outline is drawn just outside each sheet, where the sheet
// does not cover it (the PNG's was drawn under the landmark, and none of it
// showed; the SVG's lay half under the sheet's white).
TEST(Artwork, SheetCuttingOutlineShows) {
  const double dpi = 300, px_mm = dpi / 25.4;
  const cv::Mat page = ld::artwork::sheetImage({"room-101"}, 60.0, dpi);
  const int x0 = static_cast<int>(std::lround(10 * px_mm)), side = static_cast<int>(std::lround(60 * px_mm));
  cv::Mat gray;
  cv::cvtColor(page, gray, cv::COLOR_BGR2GRAY);
  for (const cv::Rect edge : {cv::Rect(x0, x0 - 3, side, 3), cv::Rect(x0 - 3, x0, 3, side),
                              cv::Rect(x0, x0 + side, side, 3), cv::Rect(x0 + side, x0, 3, side)}) {
    cv::Mat grey_line = (gray(edge) > 100) & (gray(edge) < 200);
    EXPECT_GT(cv::countNonZero(grey_line), side) << edge;
  }
  const std::string svg = ld::artwork::sheetSvg({"room-101"}, 60.0);
  EXPECT_NE(svg.find("<rect x=\"9.9\" y=\"9.9\" width=\"60.2\" height=\"60.2\" fill=\"none\" stroke=\"#a0a0a0\" "
                     "stroke-width=\"0.2\"/>"),
            std::string::npos)
      << svg.substr(0, 600);
}

// The PNG's labels are the SVG's: the payload in UTF-8, drawn (DejaVu Sans),
// and the size. Two payloads that differ in a non-ASCII letter alone label
// differently (OpenCV's own font would draw both "B?ro").
TEST(Artwork, SheetImageLabelsInUtf8) {
  ASSERT_FALSE(ld::artwork::labelFontPath().empty()) << "fonts-dejavu-core is not installed";
  const double dpi = 150, px_mm = dpi / 25.4;
  const auto labelStrip = [&](const std::string& payload) {
    const cv::Mat page = ld::artwork::sheetImage({payload}, 60.0, dpi);
    // under the sheet (10 mm margin + 60 mm), down to 6 mm further
    return page(cv::Rect(0, static_cast<int>(70 * px_mm), static_cast<int>(80 * px_mm),
                         static_cast<int>(6 * px_mm)))
        .clone();
  };
  const cv::Mat a = labelStrip("Büro"), b = labelStrip("Bäro"), c = labelStrip("Büro");
  cv::Mat gray;
  cv::cvtColor(a, gray, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(gray < 128), 50);  // a label is there
  EXPECT_GT(cv::norm(a, b, cv::NORM_L1), 0);   // ü and ä drawn apart
  EXPECT_EQ(cv::norm(a, c, cv::NORM_L1), 0);
  // and the size follows, as in the SVG: a longer label than the payload alone
  int right = 0, top = gray.rows, bottom = -1;
  for (int x = 0; x < gray.cols; ++x)
    if (cv::countNonZero(gray.col(x) < 128) > 0) right = x;
  for (int y = 0; y < gray.rows; ++y)
    if (cv::countNonZero(gray.row(y) < 128) > 0) top = std::min(top, y), bottom = y;
  EXPECT_GT(right, static_cast<int>(25 * px_mm));  // "Büro (60 mm)" at 3 mm text is over 15 mm long
  // where the SVG puts it: 3 mm text on a baseline 3.5 mm under the sheet
  // (70 mm down the page), the parentheses' tails a little below it
  EXPECT_LT(top / px_mm + 70, 72.0) << "the label's top";
  EXPECT_GT(top / px_mm + 70, 70.0) << "the label's top";
  EXPECT_LT(bottom / px_mm + 70, 74.5) << "the label's bottom";
}

// Without DejaVu Sans (a .deb installed without its recommended font, or a
// file that is not a font), the labels are drawn in OpenCV's own font at the
// same place: ASCII as written, one '?' for each other character.
TEST(Artwork, SheetImageLabelsWithoutTheFont) {
  const double dpi = 150, px_mm = dpi / 25.4;
  const std::string not_a_font = testing::TempDir() + "not_a_font.ttf";
  std::ofstream(not_a_font) << "not a font";
  for (const std::string& font : {std::string(), not_a_font}) {
    SCOPED_TRACE("font '" + font + "'");
    const auto labelStrip = [&](const std::string& payload) {
      const cv::Mat page = ld::artwork::sheetImage({payload}, 60.0, dpi, {}, ld::artwork::QrEcc::Auto, font);
      cv::Mat gray;
      cv::cvtColor(page(cv::Rect(0, static_cast<int>(70 * px_mm), static_cast<int>(80 * px_mm),
                                 static_cast<int>(6 * px_mm))),
                   gray, cv::COLOR_BGR2GRAY);
      return gray;
    };
    const cv::Mat a = labelStrip("Büro"), b = labelStrip("Bäro"), c = labelStrip("Buro");
    EXPECT_GT(cv::countNonZero(a < 128), 50);    // a label is there
    EXPECT_EQ(cv::norm(a, b, cv::NORM_L1), 0);   // both "B?ro (60 mm)"
    EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0);   // and not "Buro"
    int right = 0, top = a.rows, bottom = -1;
    for (int x = 0; x < a.cols; ++x)
      if (cv::countNonZero(a.col(x) < 128) > 0) right = x;
    for (int y = 0; y < a.rows; ++y)
      if (cv::countNonZero(a.row(y) < 128) > 0) top = std::min(top, y), bottom = y;
    EXPECT_GT(right, static_cast<int>(20 * px_mm));  // the size follows the payload
    EXPECT_GT(top / px_mm + 70, 70.0) << "the label's top";
    EXPECT_LT(bottom / px_mm + 70, 74.5) << "the label's bottom";
  }
}

// The PNG's bytes carry the resolution: a pHYs chunk after IHDR, pixels
// per metre, with a valid CRC; OpenCV reads the image back unchanged.
TEST(Artwork, PngCarriesItsDpi) {
  const cv::Mat img = ld::artwork::renderLandmark("dock", 90);
  const std::vector<uint8_t> png = ld::artwork::pngWithDpi(img, 300);
  ASSERT_GT(png.size(), 54u);
  EXPECT_EQ(std::string(png.begin() + 37, png.begin() + 41), "pHYs");
  const auto be32 = [&](size_t at) {
    return uint32_t{png[at]} << 24 | uint32_t{png[at + 1]} << 16 | uint32_t{png[at + 2]} << 8 | png[at + 3];
  };
  EXPECT_EQ(be32(33), 9u);
  EXPECT_EQ(be32(41), 11811u);  // 300 dpi
  EXPECT_EQ(be32(45), 11811u);
  EXPECT_EQ(png[49], 1);  // the metre
  EXPECT_EQ(be32(50), crc32(crc32(0L, Z_NULL, 0), png.data() + 37, 13));
  const cv::Mat back = cv::imdecode(png, cv::IMREAD_COLOR);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(cv::norm(back, img, cv::NORM_L1), 0);
}

TEST(Artwork, LandmarksPerPage) {
  // A4 less 10 mm margins, 8 mm gaps, a label under each (6 % of the side, at least 4 mm)
  EXPECT_EQ(ld::artwork::landmarksPerPage(150.0), 1);
  EXPECT_EQ(ld::artwork::landmarksPerPage(60.0), 6);                  // 2 across, 3 down
  EXPECT_EQ(ld::artwork::landmarksPerPage(90.0, {297.0, 420.0}), 6);  // A3: 2 across, 3 down
  EXPECT_EQ(ld::artwork::landmarksPerPage(40.0), 20);                 // 4 across, 5 down
  EXPECT_THROW(ld::artwork::landmarksPerPage(300.0), std::invalid_argument);
  // As many as the count says fit one page; one more does not.
  const int n = ld::artwork::landmarksPerPage(60.0);
  EXPECT_NO_THROW(ld::artwork::sheetSvg(std::vector<std::string>(static_cast<size_t>(n), "x"), 60.0));
  EXPECT_THROW(ld::artwork::sheetSvg(std::vector<std::string>(static_cast<size_t>(n) + 1, "x"), 60.0),
               std::invalid_argument);
}

TEST(Artwork, PixelsForDpi) {
  EXPECT_EQ(ld::artwork::sidePixels(0.0254, 300), 300);
  EXPECT_EQ(ld::artwork::sidePixels(0.15, 300), 1772);
}
