// ld-generate: printable landmarks (PNG at a DPI, SVG at exact physical size)
// and sheets of several landmarks.
#include <fstream>
#include <iostream>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>

#include "ld/artwork.hpp"

namespace {

bool writeText(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  return static_cast<bool>(f);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Make printable landmarks (docs/landmark.md): PNG at a DPI, SVG at exact size."};
  std::vector<std::string> payloads;
  double side_m = 0.15, dpi = 300.0;
  std::string png, svg;
  bool sheet = false;
  ld::artwork::SheetLayout page;
  app.add_option("-p,--payload", payloads, "QR text; repeat with --sheet for several")->required();
  app.add_option("-s,--size", side_m, "printed sheet side S in metres")->check(CLI::Range(0.01, 2.0))
      ->capture_default_str();
  app.add_option("--dpi", dpi, "resolution of the PNG")->check(CLI::Range(10.0, 2400.0))
      ->capture_default_str();
  app.add_option("--png", png, "write a PNG here");
  app.add_option("--svg", svg, "write an SVG here (vector, exact physical size)");
  app.add_flag("--sheet", sheet, "lay the landmarks out on a page with their payloads as labels");
  app.add_option("--page-width", page.page_w_mm, "page width in mm (sheet)")->capture_default_str();
  app.add_option("--page-height", page.page_h_mm, "page height in mm (sheet)")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (png.empty() && svg.empty()) {
    std::cerr << "ld-generate: give --png and/or --svg\n";
    return 2;
  }
  if (payloads.size() > 1 && !sheet) {
    std::cerr << "ld-generate: several payloads need --sheet\n";
    return 2;
  }
  try {
    const double side_mm = side_m * 1000.0;
    if (!svg.empty()) {
      const std::string text = sheet ? ld::artwork::sheetSvg(payloads, side_mm, page)
                                     : ld::artwork::landmarkSvg(payloads.front(), side_mm);
      if (!writeText(svg, text)) {
        std::cerr << "ld-generate: cannot write " << svg << "\n";
        return 2;
      }
      std::cout << "wrote " << svg << "\n";
    }
    if (!png.empty()) {
      const cv::Mat img =
          sheet ? ld::artwork::sheetImage(payloads, side_mm, dpi, page)
                : ld::artwork::renderLandmark(payloads.front(), ld::artwork::sidePixels(side_m, dpi));
      if (!cv::imwrite(png, img)) {
        std::cerr << "ld-generate: cannot write " << png << "\n";
        return 2;
      }
      std::cout << "wrote " << png << " (" << img.cols << "x" << img.rows << " px at " << dpi
                << " dpi)\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "ld-generate: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
