#include "ld/artwork.hpp"

#include <array>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <vector>

#include <opencv2/freetype.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <qrencode.h>
#include <zlib.h>

#include "ld/landmark_layout.hpp"

namespace ld::artwork {
namespace {

// The element of the artwork under sheet point (x, y), in units u.
enum class Element { White, Blue, Red, Black };

Element elementAt(const QrCode& qr, const QrPlacement& place, double x, double y) {
  for (int i = 0; i < 4; ++i) {
    const auto& c = layout::kCentresU[static_cast<size_t>(i)];
    const double h = layout::kSquareSide / 2;
    if (x >= c[0] - h && x < c[0] + h && y >= c[1] - h && y < c[1] + h)
      return i == layout::kAp ? Element::Red : Element::Blue;
  }
  const int mx = static_cast<int>(std::floor((x - place.origin_u) / place.module_u));
  const int my = static_cast<int>(std::floor((y - place.origin_u) / place.module_u));
  if (mx >= 0 && my >= 0 && mx < qr.size && my < qr.size && qr.dark(mx, my)) return Element::Black;
  return Element::White;
}

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4f", v);
  std::string s = buf;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// The code points of UTF-8 text; a byte that does not start a valid
// sequence (or an overlong, surrogate or out-of-range one) is U+FFFD.
std::vector<char32_t> codePoints(const std::string& s) {
  std::vector<char32_t> out;
  for (size_t i = 0; i < s.size();) {
    const auto b = static_cast<unsigned char>(s[i]);
    const int n = b < 0x80 ? 0 : (b & 0xE0) == 0xC0 ? 1 : (b & 0xF0) == 0xE0 ? 2 : (b & 0xF8) == 0xF0 ? 3 : -1;
    char32_t cp = n == 0 ? b : n == 1 ? (b & 0x1Fu) : n == 2 ? (b & 0x0Fu) : (b & 0x07u);
    bool ok = n >= 0 && i + static_cast<size_t>(n) < s.size() + (n == 0 ? 1 : 0);
    for (int k = 1; ok && k <= n; ++k) {
      const auto c = static_cast<unsigned char>(s[i + static_cast<size_t>(k)]);
      ok = (c & 0xC0) == 0x80;
      cp = (cp << 6) | (c & 0x3Fu);
    }
    static constexpr char32_t kLeast[] = {0, 0x80, 0x800, 0x10000};
    ok = ok && cp >= kLeast[std::max(n, 0)] && cp <= 0x10FFFF && !(cp >= 0xD800 && cp <= 0xDFFF);
    out.push_back(ok ? cp : 0xFFFD);
    i += ok ? static_cast<size_t>(n) + 1 : 1;
  }
  return out;
}

void appendUtf8(std::string& out, char32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (cp >> 18));
    out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

// A payload as text to print or to put in XML: bytes that are not UTF-8 and
// control characters (XML 1.0 allows none but tab and line ends, and a label
// is one line) become U+FFFD. The QR itself holds the payload's bytes as given.
std::vector<char32_t> printable(const std::string& s) {
  std::vector<char32_t> cps = codePoints(s);
  for (char32_t& cp : cps)
    if (cp < 0x20 || (cp >= 0x7F && cp < 0xA0) || cp == 0xFFFE || cp == 0xFFFF) cp = 0xFFFD;
  return cps;
}

std::string xmlEscape(const std::string& s) {
  std::string out;
  for (const char32_t cp : printable(s)) {
    switch (cp) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: appendUtf8(out, cp);
    }
  }
  return out;
}

}  // namespace

std::string shownPayload(const std::string& payload) {
  const std::vector<char32_t> cps = printable(payload);
  std::string out;
  for (size_t i = 0; i < cps.size() && (cps.size() <= 40 || i < 32); ++i) appendUtf8(out, cps[i]);
  return cps.size() <= 40 ? out : out + "... (" + std::to_string(payload.size()) + " bytes)";
}

namespace {

// The label under a landmark of a sheet: its payload and its side, in 3 mm
// text, cut to the landmark's width (about 1.8 mm a character, twice that
// for the wide scripts) so that neighbours' labels do not run into each
// other. The payload comes first: the side (which tells prints of other
// sizes apart) only where the payload keeps 6 characters beside it, and a
// payload too long loses its middle, not its end ("room-...-101": at 20 mm
// every label read "... (20 mm)"). The SVG and the PNG squeeze what is
// still wider than the landmark (wide letters: W, M) to its width.
std::string sheetLabel(const std::string& payload, double side_mm) {
  const std::string size = " (" + fmt(side_mm) + " mm)";
  const auto width = [](char32_t cp) { return cp >= 0x1100 ? 2 : 1; };
  const int room = std::max(4, static_cast<int>(side_mm / 1.8));
  const std::vector<char32_t> cps = printable(payload);
  int total = 0;
  for (const char32_t cp : cps) total += width(cp);
  const bool with_size = room - static_cast<int>(size.size()) >= std::min(total, 6);
  const int payload_room = with_size ? room - static_cast<int>(size.size()) : room;
  std::string out;
  if (total <= payload_room) {
    for (const char32_t cp : cps) appendUtf8(out, cp);
  } else {
    // its start and its end, "..." between (ids differ at their ends)
    const int keep = payload_room - 3;
    int head_room = (keep + 1) / 2, head_used = 0;
    size_t head = 0, tail = cps.size();
    for (; head < cps.size() && head_used + width(cps[head]) <= head_room; ++head) head_used += width(cps[head]);
    if (head == 0) head_used = width(cps[head++]);  // (one character at least: a wide one at 10 mm left "...")
    const int tail_room = keep - head_used;
    for (int used = 0; tail > head && used + width(cps[tail - 1]) <= tail_room; --tail) used += width(cps[tail - 1]);
    for (size_t i = 0; i < head; ++i) appendUtf8(out, cps[i]);
    out += "...";
    for (size_t i = tail; i < cps.size(); ++i) appendUtf8(out, cps[i]);
  }
  return with_size ? out + size : out;
}

// The label's width in 3 mm text as sheetLabel reckons it (mm).
double labelWidthMm(const std::string& label) {
  double w = 0;
  for (const char32_t cp : printable(label)) w += cp >= 0x1100 ? 3.6 : 1.8;
  return w;
}

// SVG elements of one landmark of side `side` (user units) at (x0, y0).
void appendLandmark(std::ostringstream& os, const QrCode& qr, double x0, double y0, double side) {
  const double u = side / layout::kUnits;
  os << "<rect x=\"" << fmt(x0) << "\" y=\"" << fmt(y0) << "\" width=\"" << fmt(side)
     << "\" height=\"" << fmt(side) << "\" fill=\"#ffffff\"/>\n";
  for (int i = 0; i < 4; ++i) {
    const auto& c = layout::kCentresU[static_cast<size_t>(i)];
    const double h = layout::kSquareSide / 2;
    os << "<rect x=\"" << fmt(x0 + (c[0] - h) * u) << "\" y=\"" << fmt(y0 + (c[1] - h) * u)
       << "\" width=\"" << fmt(layout::kSquareSide * u) << "\" height=\""
       << fmt(layout::kSquareSide * u) << "\" fill=\"" << (i == layout::kAp ? "#ff0000" : "#0000ff")
       << "\"/>\n";
  }
  // QR modules as one path of horizontal runs.
  const QrPlacement p = qrPlacement(qr);
  const double m = p.module_u * u;
  os << "<path fill=\"#000000\" shape-rendering=\"crispEdges\" d=\"";
  for (int y = 0; y < qr.size; ++y) {
    for (int x = 0; x < qr.size;) {
      if (!qr.dark(x, y)) {
        ++x;
        continue;
      }
      int run = 1;
      while (x + run < qr.size && qr.dark(x + run, y)) ++run;
      os << "M" << fmt(x0 + p.origin_u * u + x * m) << " " << fmt(y0 + p.origin_u * u + y * m)
         << "h" << fmt(run * m) << "v" << fmt(m) << "h" << fmt(-run * m) << "z";
      x += run;
    }
  }
  os << "\"/>\n";
}

// Text beyond ASCII, all of it UTF-8.
bool isUtf8BeyondAscii(const std::string& s) {
  if (std::all_of(s.begin(), s.end(), [](char c) { return static_cast<unsigned char>(c) < 0x80; })) return false;
  std::string again;
  for (char32_t cp : codePoints(s)) appendUtf8(again, cp);
  return again == s;  // (a byte that is no UTF-8 came back as U+FFFD)
}

// libqrencode's smallest symbol for `payload` at `level`, or null when none
// holds it; `utf8_mark`: announced as UTF-8 text (ECI 26, 12 bits more: a
// payload at a symbol's capacity may need the next).
std::unique_ptr<QRcode, decltype(&QRcode_free)> encodeAt(const std::string& payload, QRecLevel level,
                                                         bool utf8_mark) {
  const auto* bytes = reinterpret_cast<const unsigned char*>(payload.data());
  const int size = static_cast<int>(payload.size());
  if (!utf8_mark) return {QRcode_encodeData(size, bytes, 0, level), &QRcode_free};
  std::unique_ptr<QRinput, decltype(&QRinput_free)> input(QRinput_new2(0, level), &QRinput_free);
  constexpr unsigned int kEciUtf8 = 26;
  if (!input || QRinput_appendECIheader(input.get(), kEciUtf8) < 0 ||
      QRinput_append(input.get(), QR_MODE_8, size, bytes) < 0)
    return {nullptr, &QRcode_free};
  return {QRcode_encodeInput(input.get()), &QRcode_free};
}

// The same, UTF-8 text beyond ASCII announced as such: a QR's bytes are ISO
// 8859-1 unless it says otherwise, and readers guess (zbar's text mode read
// "café" as "caf矇", Shift-JIS).
std::unique_ptr<QRcode, decltype(&QRcode_free)> encodeAt(const std::string& payload, QRecLevel level) {
  return encodeAt(payload, level, isUtf8BeyondAscii(payload));
}

struct Grid {
  int cols, rows;
  double cell_w, cell_h;
};

Grid sheetGrid(size_t count, double side_mm, const SheetLayout& page) {
  const double label = std::max(4.0, side_mm * 0.06);
  const double cell_w = side_mm + page.gap_mm, cell_h = side_mm + label + page.gap_mm;
  const int cols = static_cast<int>((page.page_w_mm - 2 * page.margin_mm + page.gap_mm) / cell_w);
  const int rows = static_cast<int>((page.page_h_mm - 2 * page.margin_mm + page.gap_mm) / cell_h);
  if (cols < 1 || rows < 1) {
    // the largest that fits: within the margins across, and with its label down
    const double across = page.page_w_mm - 2 * page.margin_mm, down = page.page_h_mm - 2 * page.margin_mm;
    const double largest = std::min(across, down / 1.06 >= 4 / 0.06 ? down / 1.06 : down - 4);  // label: max(4, 0.06 side)
    throw std::invalid_argument("a " + fmt(side_mm) + " mm landmark does not fit on a " + fmt(page.page_w_mm) +
                                "x" + fmt(page.page_h_mm) + " mm page (" +
                                // (a size under ld-generate's least, 10 mm, is none to suggest)
                                (largest >= 10 ? "at most " + fmt(std::floor(largest)) + " mm with its label and " + fmt(page.margin_mm) +
                                                   " mm margins: --size " + fmt(std::floor(largest) / 1000)
                                             : "room for none of 10 mm or more within its margins") +
                                "; --page-width and --page-height for larger paper, A3 is 297 x 420)");
  }
  if (count > static_cast<size_t>(cols * rows))
    throw std::invalid_argument(std::to_string(count) + " landmarks of " + fmt(side_mm) +
                                " mm do not fit on one page (at most " +
                                std::to_string(cols * rows) + ")");
  return {cols, rows, cell_w, cell_h};
}

}  // namespace

int landmarksPerPage(double side_mm, const SheetLayout& page) {
  const Grid g = sheetGrid(1, side_mm, page);
  return g.cols * g.rows;
}

QrEcc parseQrEcc(const std::string& text) {
  std::string t;
  for (char c : text) t += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (t == "AUTO") return QrEcc::Auto;
  if (t == "L") return QrEcc::L;
  if (t == "M") return QrEcc::M;
  if (t == "Q") return QrEcc::Q;
  if (t == "H") return QrEcc::H;
  throw std::invalid_argument("QR error correction must be auto, L, M, Q or H, not '" + text + "'");
}

QrCode encodeQr(const std::string& payload, QrEcc ecc) {
  // (qrencode refuses no data, and the message said the payload was too long)
  if (payload.empty()) throw std::invalid_argument("QR payload is empty: a code holds at least one byte");
  static constexpr QRecLevel kLevel[] = {QR_ECLEVEL_L, QR_ECLEVEL_L, QR_ECLEVEL_M, QR_ECLEVEL_Q, QR_ECLEVEL_H};
  static constexpr char kName[] = {'L', 'L', 'M', 'Q', 'H'};
  int chosen = static_cast<int>(ecc);
  auto code = encodeAt(payload, kLevel[chosen]);
  if (code && ecc == QrEcc::Auto) {
    // The highest level that keeps level L's symbol.
    for (int level = static_cast<int>(QrEcc::H); level > static_cast<int>(QrEcc::L); --level) {
      auto higher = encodeAt(payload, kLevel[level]);
      if (higher && higher->version == code->version) {
        code = std::move(higher);
        chosen = level;
        break;
      }
    }
  }
  if (!code)
    throw std::invalid_argument("QR payload of " + std::to_string(payload.size()) + " bytes cannot be encoded" +
                                (ecc == QrEcc::Auto ? "" : std::string(" at error correction ") + kName[chosen]) +
                                (isUtf8BeyondAscii(payload) && encodeAt(payload, kLevel[chosen], false)
                                     ? " (UTF-8 text, with its ECI mark: 12 bits more)"
                                     : "") +
                                // (version 40's bytes at each level)
                                ": a QR code holds at most " +
                                std::to_string(std::array<int, 5>{2953, 2953, 2331, 1663, 1273}[chosen]) +
                                " bytes at level " + kName[chosen]);
  QrCode qr;
  qr.size = code->width;
  qr.version = code->version;
  qr.ecc = kName[chosen];
  qr.modules.resize(static_cast<size_t>(qr.size) * qr.size);
  for (size_t i = 0; i < qr.modules.size(); ++i) qr.modules[i] = code->data[i] & 1;
  return qr;
}

QrPlacement qrPlacement(const QrCode& qr) {
  const double module = (layout::kQrMax - layout::kQrMin) / (qr.size + 2);
  return {layout::kQrMin + module, module};
}

std::string describeQr(const QrCode& qr, double side_mm) {
  char module_mm[32];
  std::snprintf(module_mm, sizeof module_mm, "%.2f", qrPlacement(qr).module_u * side_mm / layout::kUnits);
  return "version " + std::to_string(qr.version) + " (" + std::to_string(qr.size) + " modules), error correction " +
         qr.ecc + ", modules of " + module_mm + " mm";
}

cv::Mat renderLandmark(const QrCode& qr, int side_px, const Colours& colours) {
  if (side_px < 9) throw std::invalid_argument("landmark side must be at least 9 px");
  const QrPlacement place = qrPlacement(qr);
  cv::Mat img(side_px, side_px, CV_8UC3);
  const double scale = layout::kUnits / side_px;
  for (int y = 0; y < side_px; ++y) {
    auto* row = img.ptr<cv::Vec3b>(y);
    const double v = (y + 0.5) * scale;
    for (int x = 0; x < side_px; ++x) {
      switch (elementAt(qr, place, (x + 0.5) * scale, v)) {
        case Element::White: row[x] = colours.white; break;
        case Element::Blue: row[x] = colours.blue; break;
        case Element::Red: row[x] = colours.red; break;
        case Element::Black: row[x] = colours.black; break;
      }
    }
  }
  return img;
}

cv::Mat renderLandmark(const std::string& payload, int side_px, const Colours& colours, QrEcc ecc) {
  return renderLandmark(encodeQr(payload, ecc), side_px, colours);
}

int sidePixels(double side_m, double dpi) {
  return static_cast<int>(std::lround(side_m / 0.0254 * dpi));
}

std::string landmarkSvg(const std::string& payload, double side_mm, QrEcc ecc) {
  const QrCode qr = encodeQr(payload, ecc);
  std::ostringstream os;
  os << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
     << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fmt(side_mm) << "mm\" height=\""
     << fmt(side_mm) << "mm\" viewBox=\"0 0 " << fmt(side_mm) << " " << fmt(side_mm) << "\">\n"
     << "<title>landmark " << xmlEscape(payload) << "</title>\n";
  appendLandmark(os, qr, 0, 0, side_mm);
  os << "</svg>\n";
  return os.str();
}

std::string sheetSvg(const std::vector<std::string>& payloads, double side_mm,
                     const SheetLayout& page, QrEcc ecc) {
  const Grid g = sheetGrid(payloads.size(), side_mm, page);
  std::ostringstream os;
  os << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
     << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << fmt(page.page_w_mm)
     << "mm\" height=\"" << fmt(page.page_h_mm) << "mm\" viewBox=\"0 0 " << fmt(page.page_w_mm)
     << " " << fmt(page.page_h_mm) << "\">\n"
     << "<rect width=\"100%\" height=\"100%\" fill=\"#ffffff\"/>\n";
  for (size_t i = 0; i < payloads.size(); ++i) {
    const double x0 = page.margin_mm + static_cast<double>(i % g.cols) * g.cell_w;
    const double y0 = page.margin_mm + static_cast<double>(i / g.cols) * g.cell_h;
    // A thin grey cutting outline just outside the sheet, 0.2 mm wide, its
    // inner edge on the sheet's (drawn on the sheet's edge, the sheet's white
    // covered half of it: 0.05 mm, which no printer prints).
    os << "<rect x=\"" << fmt(x0 - 0.1) << "\" y=\"" << fmt(y0 - 0.1) << "\" width=\"" << fmt(side_mm + 0.2)
       << "\" height=\"" << fmt(side_mm + 0.2)
       << "\" fill=\"none\" stroke=\"#a0a0a0\" stroke-width=\"0.2\"/>\n";
    appendLandmark(os, encodeQr(payloads[i], ecc), x0, y0, side_mm);
    const std::string label = sheetLabel(payloads[i], side_mm);
    os << "<text x=\"" << fmt(x0) << "\" y=\"" << fmt(y0 + side_mm + 3.5)
       << "\" font-family=\"sans-serif\" font-size=\"3\" fill=\"#404040\"";
    // (squeezed to the landmark's width where it may be wider: wide letters)
    if (labelWidthMm(label) > 0.8 * side_mm)
      os << " textLength=\"" << fmt(side_mm) << "\" lengthAdjust=\"spacingAndGlyphs\"";
    os << ">" << xmlEscape(label) << "</text>\n";
  }
  os << "</svg>\n";
  return os.str();
}

cv::Mat sheetImage(const std::vector<std::string>& payloads, double side_mm, double dpi,
                   const SheetLayout& page, QrEcc ecc, const std::string& label_font) {
  const Grid g = sheetGrid(payloads.size(), side_mm, page);
  const double px_per_mm = dpi / 25.4;
  cv::Mat img(static_cast<int>(std::lround(page.page_h_mm * px_per_mm)),
              static_cast<int>(std::lround(page.page_w_mm * px_per_mm)), CV_8UC3,
              cv::Scalar(255, 255, 255));
  const int side_px = static_cast<int>(std::lround(side_mm * px_per_mm));
  cv::Ptr<cv::freetype::FreeType2> font;
  if (!label_font.empty()) {
    try {
      font = cv::freetype::createFreeType2();
      font->loadFontData(label_font, 0);
    } catch (const cv::Exception&) {
      font.release();  // (a damaged font file: OpenCV's own font)
    }
  }
  for (size_t i = 0; i < payloads.size(); ++i) {
    const int x0 = static_cast<int>(
        std::lround((page.margin_mm + static_cast<double>(i % g.cols) * g.cell_w) * px_per_mm));
    const int y0 = static_cast<int>(
        std::lround((page.margin_mm + static_cast<double>(i / g.cols) * g.cell_h) * px_per_mm));
    const cv::Rect roi(x0, y0, side_px, side_px);
    renderLandmark(payloads[i], side_px, {}, ecc).copyTo(img(roi));
    // the cutting outline, just outside the sheet (drawn under it before:
    // the landmark covered it whole), 0.2 mm and at least a pixel wide
    const int line = std::max(1, static_cast<int>(std::lround(0.2 * px_per_mm)));
    cv::rectangle(img, cv::Rect(x0 - line, y0 - line, side_px + 2 * line, side_px + 2 * line),
                  cv::Scalar(160, 160, 160), line);
    // the SVG's label: 3 mm text, its baseline 3.5 mm under the sheet
    const std::string label = sheetLabel(payloads[i], side_mm);
    const cv::Point baseline(x0, y0 + side_px + static_cast<int>(3.5 * px_per_mm));
    int height = std::max(4, static_cast<int>(std::lround(3.0 * px_per_mm)));
    if (font) {
      // (a label wider than the landmark, as measured, drawn smaller to fit,
      // down to half its height: it ran into its neighbour's)
      int baseline_px = 0;
      const int w = font->getTextSize(label, height, -1, &baseline_px).width;
      if (w > side_px) height = std::max(std::max(4, height / 2), height * side_px / w);
      // (bottomLeftOrigin true: the point is the text's baseline, as the SVG's y)
      font->putText(img, label, baseline, height, cv::Scalar(64, 64, 64), -1, cv::LINE_AA, true);
    } else {
      std::string ascii;  // OpenCV's Hershey font has ASCII alone: one '?' per other character
      for (size_t k = 0; k < label.size(); ++k) {
        const auto c = static_cast<unsigned char>(label[k]);
        if (c < 0x80) ascii += label[k];
        else if ((c & 0xC0) != 0x80) ascii += '?';
      }
      double scale = 0.1 * px_per_mm;
      int baseline_px = 0;
      const int w = cv::getTextSize(ascii, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline_px).width;
      if (w > side_px) scale = std::max(scale / 2, scale * side_px / w);
      cv::putText(img, ascii, baseline, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(64, 64, 64),
                  std::max(1, static_cast<int>(scale)), cv::LINE_AA);
    }
  }
  return img;
}

std::string labelFontPath() {
  for (const char* path : {"/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
                           "/usr/share/fonts/TTF/DejaVuSans.ttf", "/usr/share/fonts/dejavu/DejaVuSans.ttf"})
    if (std::ifstream(path).good()) return path;
  return "";
}

std::vector<uint8_t> pngWithDpi(const cv::Mat& img, double dpi) {
  std::vector<uint8_t> png;
  if (!cv::imencode(".png", img, png) || png.size() < 33)
    throw std::runtime_error("OpenCV could not encode the image as PNG");
  // After the signature (8 bytes) and IHDR (always first, 25 bytes), a pHYs
  // chunk: pixels per metre across and down, unit 1 (the metre), and the
  // CRC of its type and data.
  const auto ppm = static_cast<uint32_t>(std::lround(dpi / 0.0254));
  std::vector<uint8_t> chunk{0, 0, 0, 9, 'p', 'H', 'Y', 's'};
  for (int k = 0; k < 2; ++k)
    for (int shift = 24; shift >= 0; shift -= 8) chunk.push_back(static_cast<uint8_t>(ppm >> shift));
  chunk.push_back(1);
  const uLong crc = crc32(crc32(0L, Z_NULL, 0), chunk.data() + 4, 13);
  for (int shift = 24; shift >= 0; shift -= 8) chunk.push_back(static_cast<uint8_t>(crc >> shift));
  png.insert(png.begin() + 33, chunk.begin(), chunk.end());
  return png;
}

}  // namespace ld::artwork
