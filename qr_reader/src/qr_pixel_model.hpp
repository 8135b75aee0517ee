// A QR code's modules estimated from the camera's pixels through a model of
// the camera, for the QR reader's module-by-module path (qr_reader.cpp). Not
// a public interface; tests include it by its path.
//
// Where a module is about a pixel, sampling each module's centre (as the
// equaliser does) mixes it with its neighbours in proportions that change
// across the code, as the module grid drifts against the pixel grid. The
// homography says exactly which part of which modules each pixel sees, so
// the model predicts each pixel as
//
//   pixel = a + b * (K * C x)
//
// where x is the modules' darkness (0 light, 1 dark), C the share of each
// module in each pixel's square (from the homography), K the optics' blur
// (a small kernel over pixels) and a, b the light (planes across the code:
// uneven light and glare). The blur and the light are fitted where the
// pixels see only modules every code has (finders, timing and alignment
// patterns, the quiet zone): each blur of a small set (round Gaussians) is
// tried and the one that predicts those pixels best is kept; then the grid
// is moved onto those pixels by a small affine step or two (Lucas-Kanade:
// the corners are a tenth of a pixel or two off, a module about one; a
// shift alone where the affine step would move the grid more than half a
// pixel), kept while they fit better. The data modules are then first the
// least-squares fit to the pixels (conjugate gradients), then moved one or
// two at a time (a module, or a module and its right or lower neighbour, flipped) while
// that lowers the squared difference between the pixels and their
// prediction (iterated conditional modes: pairs get out of the many
// minima that single flips stop in, where two neighbours share pixels).
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace ld::detail {

/// An n-module code's module coordinates (x right, y down, 0 at the
/// symbol's top-left edge, one module a unit) in the sheet frame (units u):
/// the QR square holds the symbol and one module of quiet zone
/// (docs/landmark.md). Times ld::layout::sheetToImage, `module_to_image`.
cv::Matx33d moduleToSheet(int n);

/// The model's stages that can be left out: the reader uses them all;
/// tests leave one out to see what it does.
struct QrPixelModelStages {
  int align_steps = 2;                ///< steps moving the grid onto the pixels (0: the grid as given)
  int least_squares_iterations = 20;  ///< of the start (0: every data module light)
  bool pair_flips = true;             ///< flip neighbour pairs too, not only single modules
};

class QrPixelModel {
 public:
  explicit QrPixelModel(QrPixelModelStages stages = {}) : stages_(stages) {}
  /// The modules of an n-module code (n x n, row-major, 1 dark, 0 light;
  /// function patterns as every code has them) from the 8-bit gray image.
  /// `module_to_image` maps module coordinates (x right, y down, 0 at the
  /// symbol's top-left edge, one module a unit)
  /// to image pixels. False when the code is not in the image, too few pixels
  /// see known modules, or dark modules do not read darker than light ones.
  /// Nothing is allocated once warm for codes of the sizes seen before.
  bool estimate(const cv::Mat& gray, const cv::Matx33d& module_to_image, int n, std::vector<uint8_t>& modules);
  /// The grid the last estimate that returned true fitted the modules on:
  /// its `module_to_image` moved onto the pixels.
  const cv::Matx33d& grid() const { return grid_; }

 private:
  bool cover(const cv::Mat& gray, const cv::Matx33d& module_to_image, int n);
  double fitLight(const cv::Mat& kernel, double coeff[6]);
  bool chooseBlur(double& best, double (&light)[6]);
  bool alignStep(const double (&light)[6], const cv::Matx33d& grid, cv::Matx33d& moved);
  void render(const std::vector<float>& x, bool known, cv::Mat& out);
  void coverTransposed(const cv::Mat& img, std::vector<float>& out) const;
  void solveLeastSquares(int iterations);
  void buildFootprints();
  double flipChange(size_t m) const;
  void flip(size_t m);
  void descend();

  QrPixelModelStages stages_;
  cv::Matx33d grid_ = cv::Matx33d::eye();
  int g_ = 0;                                  // modules across the model's grid: the code and two light rings
  std::vector<uint8_t> known_;                 // g x g: 1 for a module every code has (or the rings)
  std::vector<float> x_;                       // g x g: darkness (known: as known)
  // the ROI's images (headers over store_ and valid_store_, which only grow)
  static constexpr size_t kImages = 12;
  std::vector<float> store_[kImages];
  std::vector<uint8_t> valid_store_;
  cv::Mat value_, valid_, a_, b_, target_, weight_;
  int roi_x_ = 0, roi_y_ = 0;                        // the ROI's top-left pixel in the image
  cv::Mat kernel_, between_, tmp1_, tmp2_, scratch_, known_cover_, known_dark_cover_, known_share_, known_dark_;
  std::vector<int> cover_start_, cover_module_;      // per ROI pixel: the modules in its square
  std::vector<float> cover_weight_;
  std::vector<int> foot_start_, foot_pixel_;         // per module: the pixels it reaches through the blur
  std::vector<float> foot_weight_;
  std::vector<int> by_module_start_, by_module_pixel_, slot_;
  std::vector<float> by_module_weight_;
  std::vector<float> residual_;                      // per ROI pixel: value - prediction (valid pixels)
  std::vector<float> cg_x_, cg_r_, cg_p_, cg_q_, ones_;
};

}  // namespace ld::detail
