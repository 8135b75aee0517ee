// ld-generate: printable landmarks (PNG at a DPI, SVG at exact physical size)
// and sheets of several landmarks.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <vector>

#include <CLI/CLI.hpp>

#include "ld/cli.hpp"
#include "ld/file_checks.hpp"
#include "ld/artwork.hpp"

namespace {

// Pixels a QR module should have in the PNG for readers to find it.
constexpr double kMinModulePx = 3.0;
// A PNG's largest side: 20000 px is 1.2 GB of pixels to draw, a 2 m sheet
// at 254 dpi or an A3 page at 1700.
constexpr double kMaxPngSide = 20000;

// Page k (from 1) of a sheet that takes several: "sheet.svg" -> "sheet-2.svg".
std::string pagePath(const std::string& path, int k, int pages) {
  if (pages <= 1) return path;
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  const size_t at = dot != std::string::npos && (slash == std::string::npos || dot > slash) ? dot : path.size();
  return path.substr(0, at) + "-" + std::to_string(k) + path.substr(at);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Make printable landmarks (docs/landmark.md): PNG at a DPI, SVG at exact size."};
  std::vector<std::string> payloads;
  double side_m = 0.15, dpi = 300.0;
  std::string png, svg, ecc_text = "auto";
  bool sheet = false;
  ld::artwork::SheetLayout page;
  app.add_option("-p,--payload", payloads, "QR text; repeat with --sheet for several")->required();
  app.add_option("-s,--size", side_m, "printed sheet side S in metres")->check(ld::cli::Between(0.01, 2.0))
      ->capture_default_str();
  auto* dpi_opt = app.add_option("--dpi", dpi, "resolution of the PNG")->check(ld::cli::Between(10.0, 2400.0))
      ->capture_default_str();
  app.add_option("--png", png, "write a PNG here");
  app.add_option("--svg", svg, "write an SVG here (vector, exact physical size)");
  app.add_option("--ecc", ecc_text,
                 "QR error correction: L, M, Q, H, or auto (the smallest symbol that holds the payload, at the "
                 "highest level that keeps it: the largest modules)")
      ->capture_default_str()
      ->check(ld::cli::Parses("LEVEL", ld::artwork::parseQrEcc));
  app.add_flag("--sheet", sheet,
               "lay the landmarks out on pages with their payloads as labels (more than a page holds: "
               "FILE-1.svg, FILE-2.svg, ...)");
  auto* page_w = app.add_option("--page-width", page.page_w_mm, "page width in mm (sheet)")
      ->check(ld::cli::Between(10.0, 5000.0))
      ->capture_default_str();
  auto* page_h = app.add_option("--page-height", page.page_h_mm, "page height in mm (sheet)")
      ->check(ld::cli::Between(10.0, 5000.0))
      ->capture_default_str();
  LD_CLI_PARSE(app, argc, argv);

  if (png.empty() && svg.empty()) {
    return ld::cli::usage(argv[0], "give --png and/or --svg");
  }
  // (a PNG is written whatever the name: one that says so)
  if (!png.empty() && !ld::hasExtension(png, ".png"))
    return ld::cli::usage(argv[0], "--png " + png + ": the file name must end in .png");
  if (!svg.empty() && !ld::hasExtension(svg, ".svg"))
    return ld::cli::usage(argv[0], "--svg " + svg + ": the file name must end in .svg");
  if (payloads.size() > 1 && !sheet) return ld::cli::usage(argv[0], "several payloads need --sheet");
  // (the SVG has no pixels: the resolution was dropped without a word)
  if (dpi_opt->count() > 0 && png.empty())
    return ld::cli::usage(argv[0], "--dpi is the PNG's resolution, and no --png is written (the SVG is exact at any size)");
  // (a single landmark is its own page: the page's size was dropped without a word)
  for (const auto* o : {page_w, page_h})
    if (!sheet && o->count() > 0)
      return ld::cli::usage(argv[0], o->get_name() + " is for --sheet (a landmark alone is a page of its own "
                                                     "size, --size)");
  // (the PNG's size before anything is written: OpenCV cannot allocate a
  // 2 m sheet at 2400 dpi, 188976 px a side, and says so in its own words)
  if (!png.empty()) {
    const double mm_w = sheet ? page.page_w_mm : side_m * 1000, mm_h = sheet ? page.page_h_mm : side_m * 1000;
    const double px_w = mm_w / 25.4 * dpi, px_h = mm_h / 25.4 * dpi, side_px = side_m / 0.0254 * dpi;
    std::ostringstream m;
    if (std::max(px_w, px_h) > kMaxPngSide)
      m << "--png at --dpi " << dpi << " is " << std::lround(px_w) << "x" << std::lround(px_h) << " px, over the "
        << kMaxPngSide << " px a side it may have: --dpi "
        << static_cast<int>(std::floor(dpi * kMaxPngSide / std::max(px_w, px_h))) << " or less, or --svg alone "
        << "(exact at any size)";
    else if (std::lround(side_px) < 9)
      m << "a " << side_m * 1000 << " mm landmark at --dpi " << dpi << " is " << std::lround(side_px)
        << " px a side, under the 9 px of its layout: --dpi " << static_cast<int>(std::ceil(dpi * 9 / side_px))
        << " or more";
    if (!m.str().empty()) return ld::cli::usage(argv[0], m.str());
  }
  for (const std::string& path : {svg, png}) {
    if (path.empty()) continue;
    if (const std::string problem = ld::prepareOutputFile(path); !problem.empty()) {
      std::cerr << "ld-generate: cannot write " << path << ": " << problem << "\n";
      return 2;
    }
  }
  const ld::artwork::QrEcc ecc = ld::artwork::parseQrEcc(ecc_text);  // (checked on parsing)
  try {
    const double side_mm = side_m * 1000.0;
    // (first: a landmark too large for the page is refused before anything is printed)
    const size_t per_page = sheet ? static_cast<size_t>(ld::artwork::landmarksPerPage(side_mm, page)) : 1;
    // What each code became (the distance it reads from: ld-eval size).
    // (each line whole before it is printed: a payload that does not fit leaves no half line)
    std::vector<double> module_u;  // each payload's QR module, in units u (for the PNG's check below)
    for (const auto& p : payloads) {
      const ld::artwork::QrCode qr = ld::artwork::encodeQr(p, ecc);
      module_u.push_back(ld::artwork::qrPlacement(qr).module_u);
      const std::string shown = ld::artwork::shownPayload(p);
      std::cout << "QR \"" << shown << "\": " << ld::artwork::describeQr(qr, side_mm) << "\n";
      if (qr.size > 37) {
        // (the command that measures this very code: ld-eval size renders
        // ASCII payloads of up to 1000 bytes at the level asked; UTF-8 ones
        // carry a marker that can take them a version higher)
        const bool ascii = std::all_of(p.begin(), p.end(), [](char c) { return static_cast<unsigned char>(c) < 0x80; });
        const std::string how_close =
            ascii && p.size() <= 1000
                ? "ld-eval size --payload-bytes " + std::to_string(p.size()) +
                      (ecc_text == "auto" ? std::string() : " --ecc " + ecc_text) + " says how close"
                : "ld-eval size measures ASCII payloads of up to 1000 bytes, so none of its figures is this "
                  "code's";
        std::cerr << "ld-generate: note: \"" << shown << "\" needs QR version " << qr.version << " ("
                  << qr.size << " modules, more than the 37 of version 5, which holds 100 bytes at level L): "
                  << "its modules are small and read only from close by (" << how_close << ")\n";
      }
    }
    // The pages: one payload alone, or as many per page as fit.
    std::vector<std::vector<std::string>> pages;
    for (size_t i = 0; i < payloads.size(); i += per_page)
      pages.emplace_back(payloads.begin() + static_cast<std::ptrdiff_t>(i),
                         payloads.begin() + static_cast<std::ptrdiff_t>(std::min(payloads.size(), i + per_page)));
    const int n = static_cast<int>(pages.size());
    for (int k = 1; k <= n; ++k) {
      const auto& on_page = pages[static_cast<size_t>(k - 1)];
      if (!svg.empty()) {
        const std::string path = pagePath(svg, k, n);
        const std::string text = sheet ? ld::artwork::sheetSvg(on_page, side_mm, page, ecc)
                                       : ld::artwork::landmarkSvg(on_page.front(), side_mm, ecc);
        if (const std::string why = ld::writeWholeFile(path, text); !why.empty()) {
          std::cerr << "ld-generate: cannot write " << path << ": " << why << "\n";
          return 2;
        }
        std::cout << "wrote " << path << (sheet ? " (" + std::to_string(on_page.size()) + (on_page.size() == 1 ? " landmark)" : " landmarks)") : "")
                  << "\n";
      }
      if (!png.empty()) {
        const std::string path = pagePath(png, k, n);
        const cv::Mat img =
            sheet ? ld::artwork::sheetImage(on_page, side_mm, dpi, page, ecc)
                  : ld::artwork::renderLandmark(on_page.front(), ld::artwork::sidePixels(side_m, dpi), {}, ecc);
        const std::vector<uint8_t> bytes = ld::artwork::pngWithDpi(img, dpi);  // (the print size in the file)
        if (const std::string why = ld::writeWholeFile(path, std::string(bytes.begin(), bytes.end())); !why.empty()) {
          std::cerr << "ld-generate: cannot write " << path << ": " << why << "\n";
          return 2;
        }
        std::cout << "wrote " << path << " (" << img.cols << "x" << img.rows << " px at " << dpi << " dpi)\n";
        // (a QR whose modules are a pixel or two in the PNG is lost to the
        // pixel grid: no reader reads it off the PNG, nor off its print)
        const auto first = module_u.begin() + static_cast<std::ptrdiff_t>(static_cast<size_t>(k - 1) * per_page);
        const double smallest =
            *std::min_element(first, first + static_cast<std::ptrdiff_t>(on_page.size())) * side_mm / 25.4 * dpi / 9;
        if (smallest < kMinModulePx) {
          std::ostringstream w;
          w.precision(2);
          w << "ld-generate: warning: " << path << ": a QR module is " << smallest << " px at " << dpi
            << " dpi, too few to read (" << kMinModulePx << " or more): raise --dpi to "
            << static_cast<int>(std::ceil(dpi * kMinModulePx / smallest)) << " or more, or print the SVG\n";
          std::cerr << w.str();
        }
      }
    }
    // Files an earlier run left beside these (more numbered pages, or the
    // unnumbered file of a run of one page) are not this run's: say so
    // rather than delete what may be someone's file.
    for (const std::string& base : {svg, png}) {
      if (base.empty()) continue;
      std::string stale;
      std::error_code ec;
      if (n > 1 && std::filesystem::exists(base, ec)) stale = base;
      for (int k = n == 1 ? 1 : n + 1; std::filesystem::exists(pagePath(base, k, k + 1), ec); ++k)
        stale += (stale.empty() ? "" : ", ") + pagePath(base, k, k + 1);
      if (!stale.empty())
        std::cerr << "ld-generate: note: " << stale << " from an earlier run left in place (not written now)\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "ld-generate: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
