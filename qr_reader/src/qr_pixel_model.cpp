#include "qr_pixel_model.hpp"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"
#include "qr_function_patterns.hpp"

namespace ld::detail {
namespace {

// The blur kernels tried, over 7 x 7 pixels: a round Gaussian of sigma px
// sampled at the pixels' centres (a sensor's pixels sample the optics' blur;
// each pixel's own square is the cover's). Motion blur (a line) is not
// modelled: stretched kernels and lines were tried and read 1 code more in
// 80 at 0.75 m (1.4 px per module), where frames with motion are the misses.
constexpr int kKernelReach = 3;
void blurKernel(double sigma, cv::Mat& k) {
  k.create(2 * kKernelReach + 1, 2 * kKernelReach + 1, CV_32F);
  double total = 0;
  for (int y = -kKernelReach; y <= kKernelReach; ++y)
    for (int x = -kKernelReach; x <= kKernelReach; ++x) {
      const double v = std::exp(-0.5 * (x * x + y * y) / (sigma * sigma));
      k.at<float>(y + kKernelReach, x + kKernelReach) = static_cast<float>(v);
      total += v;
    }
  k /= total;
}

// The blurs tried, and then one between the best and its neighbours.
constexpr double kSigmas[] = {0.15, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.15, 1.3};
const std::vector<cv::Mat>& kernels() {
  static const std::vector<cv::Mat> k = [] {
    std::vector<cv::Mat> v;
    for (double s : kSigmas) blurKernel(s, v.emplace_back());
    return v;
  }();
  return k;
}

// `out` = the kernel `k` applied to `in` (a correlation, as cv::filter2D's;
// the kernels are symmetric, so it is their convolution too), outside the
// image its edge (`replicate`) or 0, through `scratch`. The kernels are round
// Gaussians, a row times a column, so it goes in two passes of 7 taps. By
// hand: filter2D takes buffers at each call, and the fit makes about a
// hundred.
void convolve(const cv::Mat& in, cv::Mat& out, const cv::Mat& k, bool replicate, cv::Mat& scratch) {
  const int w = in.cols, h = in.rows, r = k.rows / 2;
  float g[2 * kKernelReach + 1];
  float sum = 0;
  for (int i = 0; i <= 2 * r; ++i) sum += g[i] = k.at<float>(r, i);
  for (int i = 0; i <= 2 * r; ++i) g[i] /= sum;
  auto tap = [&](int i, int n, bool& skip) {  // the index to read, or skip it
    skip = false;
    if (i >= 0 && i < n) return i;
    if (!replicate) skip = true;
    return std::clamp(i, 0, n - 1);
  };
  bool skip;
  for (int y = 0; y < h; ++y) {  // along rows
    const float* row = in.ptr<float>(y);
    float* o = scratch.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      float acc = 0;
      for (int t = -r; t <= r; ++t) {
        const int xx = tap(x + t, w, skip);
        if (!skip) acc += g[t + r] * row[xx];
      }
      o[x] = acc;
    }
  }
  for (int y = 0; y < h; ++y) {  // along columns
    float* o = out.ptr<float>(y);
    for (int x = 0; x < w; ++x) o[x] = 0;
    for (int t = -r; t <= r; ++t) {
      const int yy = tap(y + t, h, skip);
      if (skip) continue;
      const float* row = scratch.ptr<float>(yy);
      for (int x = 0; x < w; ++x) o[x] += g[t + r] * row[x];
    }
  }
}

// Least squares in 6 unknowns (the light's two planes, an affine move), by
// their normal equations, a row at a time.
struct LeastSquares6 {
  cv::Matx<double, 6, 6> ata = cv::Matx<double, 6, 6>::zeros();
  cv::Matx<double, 6, 1> atb = cv::Matx<double, 6, 1>::zeros();
  double btb = 0;
  int rows = 0;
  void add(const double (&f)[6], double target) {
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) ata(i, j) += f[i] * f[j];
      atb(i) += f[i] * target;
    }
    btb += target * target;
    ++rows;
  }
  // x, by Cholesky (a small ridge keeps it solvable); false when it is not.
  bool solve(cv::Matx<double, 6, 1>& x) const {
    cv::Matx<double, 6, 6> a = ata;
    const double ridge = 1e-9 * (cv::trace(a) + 1);
    for (int i = 0; i < 6; ++i) a(i, i) += ridge;
    x = atb;
    if (!cv::Cholesky(a.val, 6 * sizeof(double), 6, x.val, sizeof(double), 1)) return false;
    for (int i = 0; i < 6; ++i)
      if (!std::isfinite(x(i))) return false;
    return true;
  }
  // the rms of the rows' differences from x: |A x - b|^2 = x'A'A x - 2 x'A'b + b'b
  double rms(const cv::Matx<double, 6, 1>& x) const {
    const double res = (x.t() * ata * x)(0) - 2 * (x.t() * atb)(0) + btb;
    return std::sqrt(std::max(0.0, res / rows));
  }
};

// A pixel of the ROI in the coordinates of the light's planes and of the
// affine move: from its middle, in units of its longer side.
struct RoiPlane {
  double cx, cy, scale;
  explicit RoiPlane(const cv::Mat& roi)
      : cx(roi.cols / 2.0), cy(roi.rows / 2.0), scale(1.0 / std::max(roi.cols, roi.rows)) {}
  double u(int x) const { return (x - cx) * scale; }
  double v(int y) const { return (y - cy) * scale; }
  // the light's a and b at (x, y), of coefficients a0, au, av, b0, bu, bv
  double a(const double (&light)[6], int x, int y) const { return light[0] + light[1] * u(x) + light[2] * v(y); }
  double b(const double (&light)[6], int x, int y) const { return light[3] + light[4] * u(x) + light[5] * v(y); }
};

// Sub-samples per pixel side for the modules' shares of a pixel's square.
constexpr int kCoverSub = 6;
// A pixel is fitted for the light when this share of it sees known modules.
constexpr double kKnownShare = 0.98;
// The least squares' pull towards 0.5 (keeps modules no pixel sees at
// undecided). 0.05 pulled the seen ones too: at 0.005 the sweep at 0.7-1.1
// m read 10-14 more of 500 100-byte codes (seeds 1, 3, 7); 0.02 to 0.002
// read about as many.
constexpr double kPull = 0.005;
constexpr int kMaxSweeps = 10;
// Each step moving the grid onto the pixels makes this part of the move the
// least squares give: the central differences of a blurred prediction
// understate its slope, and the full move overshoots (a grid 0.1 / 0.2 px
// off was moved back by 0.16 / 0.33 px, a review measured). (The number of
// steps, the least squares' iterations and the pair flips: QrPixelModelStages.)
constexpr double kAlignDamping = 0.6;

}  // namespace

cv::Matx33d moduleToSheet(int n) {
  const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
  return {module, 0, layout::kQrMin + module, 0, module, layout::kQrMin + module, 0, 0, 1};
}

bool QrPixelModel::cover(const cv::Mat& gray, const cv::Matx33d& module_to_image, int n) {
  const cv::Matx33d to_module = module_to_image.inv();
  double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
  for (const auto& [mx, my] : {std::pair{-1.0, -1.0}, {n + 1.0, -1.0}, {n + 1.0, n + 1.0}, {-1.0, n + 1.0}}) {
    const cv::Vec3d p = module_to_image * cv::Vec3d(mx, my, 1);
    if (!(p[2] > 0)) return false;
    x0 = std::min(x0, p[0] / p[2]), x1 = std::max(x1, p[0] / p[2]);
    y0 = std::min(y0, p[1] / p[2]), y1 = std::max(y1, p[1] / p[2]);
  }
  // the QR square and its quiet zone, and room for the blur around them
  constexpr int kPad = kKernelReach + 1;
  if (!(x1 > 0 && y1 > 0 && x0 < gray.cols && y0 < gray.rows)) return false;  // (NaN too)
  // (clamped to the image before the casts: a grid may reach far outside it)
  const int u0 = static_cast<int>(std::max(0.0, std::floor(x0) - kPad));
  const int u1 = static_cast<int>(std::min(gray.cols - 1.0, std::ceil(x1) + kPad));
  const int v0 = static_cast<int>(std::max(0.0, std::floor(y0) - kPad));
  const int v1 = static_cast<int>(std::min(gray.rows - 1.0, std::ceil(y1) + kPad));
  if (u1 - u0 < 8 || v1 - v0 < 8) return false;
  // the ROI's images, over buffers that only grow (a header over a buffer
  // of the right size is not reallocated by OpenCV)
  const int rows = v1 - v0 + 1, cols = u1 - u0 + 1;
  cv::Mat* images[] = {&value_, &a_, &b_, &target_, &weight_, &tmp1_, &tmp2_,
                       &known_cover_, &known_dark_cover_, &known_share_, &known_dark_, &scratch_};
  static_assert(sizeof(images) / sizeof(images[0]) == kImages);
  for (size_t i = 0; i < kImages; ++i) {
    store_[i].resize(static_cast<size_t>(rows) * cols);
    *images[i] = cv::Mat(rows, cols, CV_32F, store_[i].data());
  }
  valid_store_.resize(static_cast<size_t>(rows) * cols);
  valid_ = cv::Mat(rows, cols, CV_8U, valid_store_.data());
  gray(cv::Rect(u0, v0, cols, rows)).convertTo(value_, CV_32F);
  roi_x_ = u0, roi_y_ = v0;
  cover_start_.clear();
  cover_module_.clear();
  cover_weight_.clear();
  int mods[kCoverSub * kCoverSub], counts[kCoverSub * kCoverSub];
  for (int v = v0; v <= v1; ++v)
    for (int u = u0; u <= u1; ++u) {
      const cv::Vec3d c = to_module * cv::Vec3d(u, v, 1);
      const double mx = c[0] / c[2], my = c[1] / c[2];
      // pixels in the QR square (code and quiet zone) are fitted
      valid_.at<uint8_t>(v - v0, u - u0) = mx >= -1 && my >= -1 && mx <= n + 1 && my <= n + 1;
      // the square's sub-samples, through the homography's local linear map
      const cv::Vec3d cx = to_module * cv::Vec3d(u + 1, v, 1), cy = to_module * cv::Vec3d(u, v + 1, 1);
      const double jxx = cx[0] / cx[2] - mx, jyx = cx[1] / cx[2] - my;
      const double jxy = cy[0] / cy[2] - mx, jyy = cy[1] / cy[2] - my;
      int count = 0;
      for (int ky = 0; ky < kCoverSub; ++ky)
        for (int kx = 0; kx < kCoverSub; ++kx) {
          const double dx = (kx + 0.5) / kCoverSub - 0.5, dy = (ky + 0.5) / kCoverSub - 0.5;
          const double px = mx + jxx * dx + jxy * dy, py = my + jyx * dx + jyy * dy;
          // (outside the grid: the outer light ring, which the sheet is,
          // but for the QR square's corners, where the coloured squares
          // touch it diagonally: a small misfit; a point beyond the
          // sheet's horizon, not finite, too)
          const double fx = std::isfinite(px) ? std::clamp(std::floor(px) + 2, 0.0, g_ - 1.0) : 0.0;
          const double fy = std::isfinite(py) ? std::clamp(std::floor(py) + 2, 0.0, g_ - 1.0) : 0.0;
          const int col = static_cast<int>(fx), row = static_cast<int>(fy);
          const int m = row * g_ + col;
          int t = 0;
          while (t < count && mods[t] != m) ++t;
          if (t == count) mods[count] = m, counts[count] = 0, ++count;
          ++counts[t];
        }
      cover_start_.push_back(static_cast<int>(cover_module_.size()));
      for (int t = 0; t < count; ++t) {
        cover_module_.push_back(mods[t]);
        cover_weight_.push_back(static_cast<float>(counts[t]) / (kCoverSub * kCoverSub));
      }
    }
  cover_start_.push_back(static_cast<int>(cover_module_.size()));
  // (what the known modules cover, and how dark: the same for every blur tried)
  render(ones_, true, known_cover_);
  render(x_, true, known_dark_cover_);
  return true;
}

// C x over the known modules (`known`) or the unknown ones.
void QrPixelModel::render(const std::vector<float>& x, bool known, cv::Mat& out) {
  float* o = out.ptr<float>();
  const int pixels = value_.rows * value_.cols;
  for (int j = 0; j < pixels; ++j) {
    float s = 0;
    for (int t = cover_start_[static_cast<size_t>(j)]; t < cover_start_[static_cast<size_t>(j) + 1]; ++t) {
      const auto m = static_cast<size_t>(cover_module_[static_cast<size_t>(t)]);
      if ((known_[m] != 0) == known) s += cover_weight_[static_cast<size_t>(t)] * x[m];
    }
    o[j] = s;
  }
}

// C' img over the unknown modules, added to `out` (g x g).
void QrPixelModel::coverTransposed(const cv::Mat& img, std::vector<float>& out) const {
  const float* v = img.ptr<float>();
  const int pixels = value_.rows * value_.cols;
  for (int j = 0; j < pixels; ++j)
    for (int t = cover_start_[static_cast<size_t>(j)]; t < cover_start_[static_cast<size_t>(j) + 1]; ++t) {
      const auto m = static_cast<size_t>(cover_module_[static_cast<size_t>(t)]);
      if (!known_[m]) out[m] += cover_weight_[static_cast<size_t>(t)] * v[j];
    }
}

// The light a + b k (each a plane across the code: 1, u, v) fitted on the
// pixels that see known modules only, through `kernel`; the fit's rms
// difference (gray levels), or -1 when too few pixels see known modules.
double QrPixelModel::fitLight(const cv::Mat& kernel, double coeff[6]) {
  convolve(known_cover_, known_share_, kernel, true, scratch_);
  convolve(known_dark_cover_, known_dark_, kernel, true, scratch_);
  LeastSquares6 ls;
  const RoiPlane plane(value_);
  for (int y = 0; y < value_.rows; ++y)
    for (int x = 0; x < value_.cols; ++x) {
      if (!valid_.at<uint8_t>(y, x) || known_share_.at<float>(y, x) < kKnownShare) continue;
      const double k = known_dark_.at<float>(y, x), u = plane.u(x), v = plane.v(y);
      ls.add({1, u, v, k, u * k, v * k}, value_.at<float>(y, x));
    }
  cv::Matx<double, 6, 1> w;
  if (ls.rows < 40 || !ls.solve(w)) return -1;
  for (int i = 0; i < 6; ++i) coeff[i] = w(i);
  return ls.rms(w);
}

// The unknown modules' least-squares darkness: (W'W + kPull I) x = W'y +
// kPull / 2 over them, W = K C, by conjugate gradients.
void QrPixelModel::solveLeastSquares(int iterations) {
  const size_t gg = x_.size();
  auto apply = [&](const std::vector<float>& x, std::vector<float>& out) {
    render(x, false, tmp1_);
    convolve(tmp1_, tmp2_, kernel_, false, scratch_);
    float* t = tmp2_.ptr<float>();
    const float* wt = weight_.ptr<float>();
    for (int j = 0; j < value_.rows * value_.cols; ++j) t[j] *= wt[j];
    convolve(tmp2_, tmp1_, kernel_, false, scratch_);
    out.assign(gg, 0.0f);
    coverTransposed(tmp1_, out);
    for (size_t m = 0; m < gg; ++m)
      if (!known_[m]) out[m] += static_cast<float>(kPull) * x[m];
  };
  // right-hand side W'y + kPull / 2 (target_ is y, zero where not fitted), in cg_r_
  convolve(target_, tmp1_, kernel_, false, scratch_);
  cg_r_.assign(gg, 0.0f);
  coverTransposed(tmp1_, cg_r_);
  // from x = 0.5: r = rhs - A x, p = r
  cg_x_.assign(gg, 0.0f);
  for (size_t m = 0; m < gg; ++m)
    if (!known_[m]) cg_r_[m] += static_cast<float>(kPull * 0.5), cg_x_[m] = 0.5f;
  apply(cg_x_, cg_q_);
  for (size_t m = 0; m < gg; ++m) cg_r_[m] = known_[m] ? 0.0f : cg_r_[m] - cg_q_[m];
  cg_p_ = cg_r_;
  double rr = 0;
  for (float r : cg_r_) rr += static_cast<double>(r) * r;
  for (int it = 0; it < iterations && rr > 1e-9; ++it) {
    apply(cg_p_, cg_q_);
    double pq = 0;
    for (size_t m = 0; m < gg; ++m) pq += static_cast<double>(cg_p_[m]) * cg_q_[m];
    if (!(pq > 0)) break;
    const double alpha = rr / pq;
    double rr_next = 0;
    for (size_t m = 0; m < gg; ++m) {
      cg_x_[m] += static_cast<float>(alpha * cg_p_[m]);
      cg_r_[m] -= static_cast<float>(alpha * cg_q_[m]);
      rr_next += static_cast<double>(cg_r_[m]) * cg_r_[m];
    }
    const double beta = rr_next / rr;
    rr = rr_next;
    for (size_t m = 0; m < gg; ++m) cg_p_[m] = cg_r_[m] + static_cast<float>(beta * cg_p_[m]);
  }
  for (size_t m = 0; m < gg; ++m)
    if (!known_[m]) x_[m] = cg_x_[m] > 0.5f ? 1.0f : 0.0f;
}

// Each unknown module's footprint: the fitted pixels it reaches through the
// blur, and by how much (its share of each pixel's square, blurred).
void QrPixelModel::buildFootprints() {
  const size_t gg = x_.size();
  const int w = value_.cols, h = value_.rows, pixels = w * h;
  // the cover by module (unknown modules only)
  by_module_start_.assign(gg + 1, 0);
  for (int j = 0; j < pixels; ++j)
    for (int t = cover_start_[static_cast<size_t>(j)]; t < cover_start_[static_cast<size_t>(j) + 1]; ++t)
      ++by_module_start_[static_cast<size_t>(cover_module_[static_cast<size_t>(t)]) + 1];
  for (size_t m = 0; m < gg; ++m) by_module_start_[m + 1] += by_module_start_[m];
  by_module_pixel_.resize(static_cast<size_t>(by_module_start_[gg]));
  by_module_weight_.resize(by_module_pixel_.size());
  slot_.assign(gg, 0);  // (fill positions per module, reused below per pixel)
  for (int j = 0; j < pixels; ++j)
    for (int t = cover_start_[static_cast<size_t>(j)]; t < cover_start_[static_cast<size_t>(j) + 1]; ++t) {
      const auto m = static_cast<size_t>(cover_module_[static_cast<size_t>(t)]);
      const auto at = static_cast<size_t>(by_module_start_[m] + slot_[m]++);
      by_module_pixel_[at] = j;
      by_module_weight_[at] = cover_weight_[static_cast<size_t>(t)];
    }
  // through the kernel (convolve's correlation: pixel j feeds j - offset)
  slot_.assign(static_cast<size_t>(pixels), -1);
  foot_start_.assign(gg + 1, 0);
  foot_pixel_.clear();
  foot_weight_.clear();
  const float* wt = weight_.ptr<float>();
  for (size_t m = 0; m < gg; ++m) {
    foot_start_[m] = static_cast<int>(foot_pixel_.size());
    if (known_[m]) continue;
    const size_t first = foot_pixel_.size();
    for (int t = by_module_start_[m]; t < by_module_start_[m + 1]; ++t) {
      const int j = by_module_pixel_[static_cast<size_t>(t)], y = j / w, x = j % w;
      for (int ky = 0; ky < kernel_.rows; ++ky)
        for (int kx = 0; kx < kernel_.cols; ++kx) {
          const int y2 = y - (ky - kKernelReach), x2 = x - (kx - kKernelReach);
          if (y2 < 0 || x2 < 0 || y2 >= h || x2 >= w) continue;
          const int j2 = y2 * w + x2;
          if (wt[j2] == 0) continue;
          const float add = by_module_weight_[static_cast<size_t>(t)] * kernel_.at<float>(ky, kx);
          int& s = slot_[static_cast<size_t>(j2)];
          if (s < 0) {
            s = static_cast<int>(foot_pixel_.size());
            foot_pixel_.push_back(j2);
            foot_weight_.push_back(add);
          } else {
            foot_weight_[static_cast<size_t>(s)] += add;
          }
        }
    }
    for (size_t i = first; i < foot_pixel_.size(); ++i) slot_[static_cast<size_t>(foot_pixel_[i])] = -1;
  }
  foot_start_[gg] = static_cast<int>(foot_pixel_.size());
}

// How much the squared difference between the pixels and their prediction
// changes when module m is flipped.
double QrPixelModel::flipChange(size_t m) const {
  const float delta = x_[m] > 0.5f ? -1.0f : 1.0f;
  const float* b = b_.ptr<float>();
  double change = 0;
  for (int t = foot_start_[m]; t < foot_start_[m + 1]; ++t) {
    const auto j = static_cast<size_t>(foot_pixel_[static_cast<size_t>(t)]);
    const double d = b[j] * delta * foot_weight_[static_cast<size_t>(t)];
    const double r = residual_[j];
    change += (r - d) * (r - d) - r * r;
  }
  return change;
}

void QrPixelModel::flip(size_t m) {
  const float delta = x_[m] > 0.5f ? -1.0f : 1.0f;
  const float* b = b_.ptr<float>();
  for (int t = foot_start_[m]; t < foot_start_[m + 1]; ++t) {
    const auto j = static_cast<size_t>(foot_pixel_[static_cast<size_t>(t)]);
    residual_[j] -= b[j] * delta * foot_weight_[static_cast<size_t>(t)];
  }
  x_[m] = 1.0f - x_[m];
}

// Flips modules, one at a time and then a module with its right or lower
// neighbour, while a flip lowers the squared difference.
void QrPixelModel::descend() {
  const size_t gg = x_.size();
  auto movable = [&](size_t m) { return m < gg && !known_[m] && foot_start_[m] < foot_start_[m + 1]; };
  for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
    int flips = 0;
    for (size_t m = 0; m < gg; ++m)
      if (movable(m) && flipChange(m) < 0) flip(m), ++flips;
    for (size_t m = 0; m < gg && stages_.pair_flips; ++m) {
      if (!movable(m)) continue;
      for (size_t m2 : {m + 1, m + static_cast<size_t>(g_)}) {
        if (!movable(m2)) continue;
        const double first = flipChange(m);
        flip(m);
        if (first + flipChange(m2) < -1e-6) {
          flip(m2);
          ++flips;
        } else {
          flip(m);  // (back)
        }
      }
    }
    if (flips == 0) break;
  }
}

// One step of moving the grid onto the pixels (Lucas-Kanade): where the
// light fit predicts the known pixels (light, through known_dark_), the
// image's difference from the prediction against the prediction's gradient
// gives, by least squares, an affine move of the image points (or a shift
// alone, where the affine move is more than half a pixel somewhere in the
// code); `moved` is the grid after it. False when the affine move cannot be
// solved, or neither it nor the shift is within half a pixel.
bool QrPixelModel::alignStep(const double (&light)[6], const cv::Matx33d& grid, cv::Matx33d& moved) {
  const int w = value_.cols, h = value_.rows;
  const RoiPlane plane(value_);
  auto predict = [&](int x, int y) {
    return plane.a(light, x, y) + plane.b(light, x, y) * known_dark_.at<float>(y, x);
  };
  LeastSquares6 ls;
  for (int y = 1; y < h - 1; ++y)
    for (int x = 1; x < w - 1; ++x) {
      if (!valid_.at<uint8_t>(y, x) || known_share_.at<float>(y, x) < kKnownShare) continue;
      const double gx = (predict(x + 1, y) - predict(x - 1, y)) / 2, gy = (predict(x, y + 1) - predict(x, y - 1)) / 2;
      if (gx == 0 && gy == 0) continue;
      const double u = plane.u(x), v = plane.v(y);
      // the difference from the prediction is -(gx dx + gy dy)
      ls.add({gx, gx * u, gx * v, gy, gy * u, gy * v}, predict(x, y) - value_.at<float>(y, x));
    }
  cv::Matx<double, 6, 1> d;
  if (ls.rows < 40 || !ls.solve(d)) return false;
  d *= kAlignDamping;
  // the move at the ROI's corners: at most half a pixel
  auto too_far = [&] {
    for (double u : {-0.5, 0.5})
      for (double v : {-0.5, 0.5})
        if (std::hypot(d(0) + d(1) * u + d(2) * v, d(3) + d(4) * u + d(5) * v) > 0.5) return true;
    return false;
  };
  if (too_far()) {
    // A shift alone (its two unknowns' normal equations): where the grid is
    // a third of a pixel off, the affine terms come out wrong, as large as
    // the shift, while the shift is right.
    const double a = ls.ata(0, 0), b = ls.ata(0, 3), c = ls.ata(3, 3), det = a * c - b * b;
    if (!(det > 1e-12 * (a * c + 1))) return false;
    d = cv::Matx<double, 6, 1>::zeros();
    d(0) = kAlignDamping * (c * ls.atb(0) - b * ls.atb(3)) / det;
    d(3) = kAlignDamping * (a * ls.atb(3) - b * ls.atb(0)) / det;
    if (too_far()) return false;
  }
  // image point X -> X + d(X), with u = (X - roi_x0 - cx) * scale
  const double xc = roi_x_ + plane.cx, yc = roi_y_ + plane.cy, scale = plane.scale;
  const cv::Matx33d move(1 + d(1) * scale, d(2) * scale, d(0) - d(1) * scale * xc - d(2) * scale * yc,  //
                         d(4) * scale, 1 + d(5) * scale, d(3) - d(4) * scale * xc - d(5) * scale * yc,  //
                         0, 0, 1);
  moved = move * grid;
  return true;
}

// The blur (kernel_) and the light (`light`) that predict the known pixels
// best (`best`, their rms): each kernel tried, then one between the best and
// its neighbours (the parabola through their fits). False when none fits.
bool QrPixelModel::chooseBlur(double& best, double (&light)[6]) {
  double coeff[6];
  best = -1;
  size_t best_k = 0;
  const auto& tried = kernels();
  for (size_t i = 0; i < tried.size(); ++i) {
    const double res = fitLight(tried[i], coeff);
    if (res >= 0 && (best < 0 || res < best)) best = res, best_k = i, kernel_ = tried[i], std::copy(coeff, coeff + 6, light);
  }
  if (best < 0) return false;
  if (best_k > 0 && best_k + 1 < tried.size()) {
    double r[3], sg[3];
    for (int i = 0; i < 3; ++i) {
      sg[i] = kSigmas[best_k + static_cast<size_t>(i) - 1];
      r[i] = fitLight(tried[best_k + static_cast<size_t>(i) - 1], coeff);
    }
    const double denom = (sg[0] - sg[1]) * (sg[0] - sg[2]) * (sg[1] - sg[2]);
    const double pa = (sg[2] * (r[1] - r[0]) + sg[1] * (r[0] - r[2]) + sg[0] * (r[2] - r[1])) / denom;
    const double pb = (sg[2] * sg[2] * (r[0] - r[1]) + sg[1] * sg[1] * (r[2] - r[0]) + sg[0] * sg[0] * (r[1] - r[2])) / denom;
    if (pa > 0 && r[0] >= 0 && r[2] >= 0) {
      const double at = std::clamp(-pb / (2 * pa), sg[0], sg[2]);
      blurKernel(at, between_);
      const double res = fitLight(between_, coeff);
      if (res >= 0 && res < best) best = res, kernel_ = between_, std::copy(coeff, coeff + 6, light);
    }
  }
  fitLight(kernel_, coeff);  // (known_dark_ and known_share_ for the chosen kernel)
  return true;
}

bool QrPixelModel::estimate(const cv::Mat& gray, const cv::Matx33d& module_to_image, int n,
                            std::vector<uint8_t>& modules) {
  if (gray.empty() || gray.type() != CV_8UC1 || n < 21) return false;
  // 1. The grid: the code, its quiet zone and one more light ring (known).
  g_ = n + 4;
  const size_t gg = static_cast<size_t>(g_) * g_;
  known_.assign(gg, 1);
  x_.assign(gg, 0.0f);
  ones_.assign(gg, 1.0f);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) known_[static_cast<size_t>(r + 2) * g_ + c + 2] = 0;
  forEachFunctionModule(n, [&](int r, int c, bool dark) {
    const size_t m = static_cast<size_t>(r + 2) * g_ + c + 2;
    known_[m] = 1;
    x_[m] = dark ? 1.0f : 0.0f;
  });
  // 2. Each pixel's share of each module.
  if (!cover(gray, module_to_image, n)) return false;
  // 3. The blur and the light: the kernel that predicts the known pixels best.
  double best = -1, coeff[6] = {}, light[6] = {};
  if (!chooseBlur(best, light)) return false;
  if (!(light[3] < -8)) return false;  // a dark module must read darker
  // 4. The grid moved onto the pixels (the corners are off by a tenth of a
  // pixel or two, and a module is about one): kept while the known pixels
  // fit better.
  cv::Matx33d grid = module_to_image;
  for (int step = 0; step < stages_.align_steps; ++step) {
    cv::Matx33d moved;
    if (!alignStep(light, grid, moved) || !cover(gray, moved, n)) break;
    const double res = fitLight(kernel_, coeff);
    if (!(res >= 0 && res < best)) {
      cover(gray, grid, n);
      fitLight(kernel_, coeff);
      break;
    }
    best = res, grid = moved;
    std::copy(coeff, coeff + 6, light);
  }
  if (!(light[3] < -8)) return false;
  grid_ = grid;
  // 5. The targets: what the unknown modules must add to each fitted pixel.
  const RoiPlane plane(value_);
  for (int y = 0; y < value_.rows; ++y)
    for (int x = 0; x < value_.cols; ++x) {
      const double a = plane.a(light, x, y), b = plane.b(light, x, y);
      a_.at<float>(y, x) = static_cast<float>(a);
      b_.at<float>(y, x) = static_cast<float>(b);
      const bool fitted = valid_.at<uint8_t>(y, x) && b < -1;
      weight_.at<float>(y, x) = fitted ? 1.0f : 0.0f;
      target_.at<float>(y, x) =
          fitted ? static_cast<float>((value_.at<float>(y, x) - a) / b - known_dark_.at<float>(y, x)) : 0.0f;
    }
  // 6. The least-squares start, then flips while they fit the pixels better.
  solveLeastSquares(stages_.least_squares_iterations);
  buildFootprints();
  render(x_, true, tmp1_);
  render(x_, false, tmp2_);
  tmp1_ += tmp2_;
  convolve(tmp1_, tmp2_, kernel_, true, scratch_);
  residual_.assign(static_cast<size_t>(value_.rows) * value_.cols, 0.0f);
  for (int j = 0; j < value_.rows * value_.cols; ++j)
    if (weight_.ptr<float>()[j] != 0)
      residual_[static_cast<size_t>(j)] =
          value_.ptr<float>()[j] - a_.ptr<float>()[j] - b_.ptr<float>()[j] * tmp2_.ptr<float>()[j];
  descend();
  // 7. The modules (known ones as every code has them).
  modules.resize(static_cast<size_t>(n) * n);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c)
      modules[static_cast<size_t>(r) * n + c] = x_[static_cast<size_t>(r + 2) * g_ + c + 2] > 0.5f ? 1 : 0;
  return true;
}

}  // namespace ld::detail
