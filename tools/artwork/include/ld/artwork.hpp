// Printable landmark artwork exactly as docs/landmark.md defines it: raster
// (for PNG files and for rendering synthetic scenes) and vector (SVG at exact
// physical size), single landmarks and sheets of several.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace ld::artwork {

/// Colours of the artwork, BGR. The defaults are the nominal sRGB values of
/// the layout; ld-synth passes printed-ink colours instead.
struct Colours {
  cv::Vec3b blue{255, 0, 0};
  cv::Vec3b red{0, 0, 255};
  cv::Vec3b white{255, 255, 255};
  cv::Vec3b black{0, 0, 0};
};

/// QR error correction: L, M, Q, H recover about 7, 15, 25, 30 % of the
/// symbol's codewords. Auto takes the smallest symbol that holds the payload
/// (level L's) and then the highest level that still fits that symbol: the
/// largest modules for the QR square, so the longest reading distance, and
/// all the error correction that costs no module size.
enum class QrEcc { Auto, L, M, Q, H };
/// "auto", "L", "M", "Q", "H" (either case); throws std::invalid_argument
/// naming the text otherwise.
QrEcc parseQrEcc(const std::string& text);

/// A QR symbol as a square grid of modules (true = dark), no quiet zone.
struct QrCode {
  int size = 0;                 // modules per side (17 + 4 version)
  int version = 0;              // 1..40
  char ecc = 'M';               // the level used: 'L', 'M', 'Q' or 'H'
  std::vector<uint8_t> modules; // row-major, size*size
  bool dark(int x, int y) const { return modules[static_cast<size_t>(y) * size + x] != 0; }
};

/// Encodes `payload` (bytes, UTF-8 text as is) with libqrencode at the level
/// `ecc` (Auto: see QrEcc). Throws std::invalid_argument when it does not fit.
QrCode encodeQr(const std::string& payload, QrEcc ecc = QrEcc::Auto);

/// Geometry of the QR inside the sheet, in units u: the symbol plus one
/// module of quiet zone fills the QR square [2.5u, 6.5u].
struct QrPlacement {
  double origin_u;  // sheet coordinate of the symbol's first module edge
  double module_u;  // module side
};
QrPlacement qrPlacement(const QrCode& qr);

/// What a code is on a landmark of side_mm, for people: "version 5 (37
/// modules), error correction L, modules of 1.71 mm" (the module's size is
/// what decides the distance the code reads from).
std::string describeQr(const QrCode& qr, double side_mm);

/// The landmark rendered to a side_px x side_px BGR image. Each pixel takes
/// the colour of the element under its centre, so the artwork is exact to the
/// pixel at any size (and a pixel-perfect copy of the layout when side_px is
/// a multiple of 18).
cv::Mat renderLandmark(const QrCode& qr, int side_px, const Colours& colours = {});
cv::Mat renderLandmark(const std::string& payload, int side_px, const Colours& colours = {},
                       QrEcc ecc = QrEcc::Auto);

/// A payload as a terminal line or a label may show it: bytes that are not
/// UTF-8 and control characters as U+FFFD, and over 40 characters, its
/// first 32 and "... (N bytes)".
std::string shownPayload(const std::string& payload);

/// Pixel side of a sheet of `side_m` metres printed at `dpi`.
int sidePixels(double side_m, double dpi);

/// A standalone SVG of one landmark with width and height `side_mm`
/// millimetres, so printing at 100% gives a sheet of exactly that side.
std::string landmarkSvg(const std::string& payload, double side_mm, QrEcc ecc = QrEcc::Auto);

/// A page of several landmarks (side_mm each) laid out in a grid with the
/// payload printed under each (with the side, cut to the landmark's width;
/// bytes that are not UTF-8 and control characters shown as U+FFFD); page
/// size in millimetres (A4 by default).
/// Throws std::invalid_argument when not even one landmark fits the page.
struct SheetLayout {
  double page_w_mm = 210.0;
  double page_h_mm = 297.0;
  double margin_mm = 10.0;
  double gap_mm = 8.0;
};
std::string sheetSvg(const std::vector<std::string>& payloads, double side_mm,
                     const SheetLayout& page = {}, QrEcc ecc = QrEcc::Auto);
/// How many landmarks of side_mm one page holds (throws std::invalid_argument
/// when not even one fits): more payloads than that take several pages.
int landmarksPerPage(double side_mm, const SheetLayout& page = {});
/// The font sheetImage labels with ("" when not installed).
std::string labelFontPath();
/// The same page as a raster image at `dpi`. Labels as the SVG's (the
/// payload and the side in mm), drawn with DejaVu Sans (fonts-dejavu-core)
/// through OpenCV's FreeType module, so UTF-8 payloads read as printed;
/// without the font (`label_font` empty or not a font), OpenCV's own font,
/// which has ASCII alone ('?' for the rest).
cv::Mat sheetImage(const std::vector<std::string>& payloads, double side_mm, double dpi,
                   const SheetLayout& page = {}, QrEcc ecc = QrEcc::Auto,
                   const std::string& label_font = labelFontPath());

/// A PNG file's bytes for `img`, with its resolution (`dpi`) in a pHYs
/// chunk, so a viewer or a print dialog at 100 % gives the printed size.
/// Throws std::runtime_error when OpenCV cannot encode the image.
std::vector<uint8_t> pngWithDpi(const cv::Mat& img, double dpi);

}  // namespace ld::artwork
