#include "ld/qr_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>
#include <zbar.h>

#include "ld/input_checks.hpp"
#include "ld/landmark_layout.hpp"
#include "qr_function_patterns.hpp"
#include "qr_pixel_model.hpp"
#include "qr_sampling.hpp"

namespace ld {
namespace {

using detail::moduleToImage;
using detail::toGray;

// How like a finder pattern (correlation of its 7 x 7 modules with the
// ideal) each of the three must look for the bent-sheet path to read a grid.
constexpr double kBentFinderMin = 0.6;

// Homography from the upright view (side px, QR square plus margin) to the image.
cv::Matx33d viewToImage(const std::array<cv::Point2f, 4>& corners, int side, double margin_u) {
  const cv::Matx33d sheet_to_image = layout::sheetToImage(corners);
  // view pixel (x, y) -> sheet u: u = q0 + (x + 0.5) * span / side
  const double q0 = layout::kQrMin - margin_u;
  const double span = (layout::kQrMax - layout::kQrMin) + 2 * margin_u;
  const double s = span / side;
  const cv::Matx33d view_to_sheet(s, 0, q0 + 0.5 * s, 0, s, q0 + 0.5 * s, 0, 0, 1);
  return sheet_to_image * view_to_sheet;
}

// How well the three finder patterns of an n-module grid of samples (values
// 0..255, dark = low) look like finder patterns: the correlation of their
// 7x7 samples with the ideal pattern, -1..1.
struct FinderCorrelation {
  double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  int count = 0;
  // module (r, c) of a finder (0..6) sampled as `sample`
  void add(int r, int c, double sample) {
    const int d = std::max(std::abs(r - 3), std::abs(c - 3));
    const double x = d == 2 ? 0.0 : 1.0;  // 1 = dark: rings at distance 0, 1 (centre 3x3) and 3
    const double y = 255.0 - sample;
    sx += x; sy += y; sxx += x * x; syy += y * y; sxy += x * y;
    ++count;
  }
  double value() const {
    const double cov = sxy - sx * sy / count, vx = sxx - sx * sx / count, vy = syy - sy * sy / count;
    return vx > 0 && vy > 0 ? cov / std::sqrt(vx * vy) : -1.0;
  }
};

double finderScore(const cv::Mat& samples, int n) {
  FinderCorrelation corr;
  for (const auto& [r0, c0] : {std::pair{0, 0}, {0, n - 7}, {n - 7, 0}})
    for (int r = 0; r < 7; ++r)
      for (int c = 0; c < 7; ++c) corr.add(r, c, samples.at<float>(r0 + r, c0 + c));
  return corr.value();
}

// The pixel model (qr_pixel_model.hpp) is tried for codes whose modules are
// under this many pixels: its cost grows with the pixels, and where a module
// has two or more the equaliser reads all a model would.
constexpr double kPixelModelMaxPx = 2.0;
// ... and whose QR square is at most this many pixels across: the fit's cost
// grows with the pixels (a 100-byte code at level H, 0.4 m away, took 120
// ms a try), and the far codes it reads are smaller (a 37-module code at
// 0.6 m is 67 px).
constexpr double kPixelModelMaxSide = 72.0;

// The grid as the corners put it: not moved (readBent moves it).
const cv::Matx23d kFlatGrid(1, 0, 0, 0, 1, 0);

// The projected side of the QR square, in pixels, when `image` is an 8-bit
// image and the corners are finite and give it at least 8 px: nothing to
// read otherwise.
std::optional<double> readableQrSide(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners) {
  if (image.empty() || image.depth() != CV_8U || !detail::finiteCorners(corners)) return std::nullopt;
  const double qr_px = layout::projectedQrSide(corners);
  if (!(qr_px >= 8.0)) return std::nullopt;
  return qr_px;
}

}  // namespace

struct QrReader::Impl {
  QrReaderParams params;
  zbar::ImageScanner scanner;
  cv::Mat gray, view, work, blurred, map, sampled, samples, sharpened, grid8, bits, clean;
  bool view_made = false;  // this decode() made `view` (lastView: none otherwise)
  std::vector<int8_t> known, grid;  // the equaliser's modules: -1 unknown, 0 light, 1 dark
  std::vector<uint8_t> fitted;      // the pixel model's modules (1 dark)
  int fitted_n = 0;                 // ... of a code this many modules across (0: none fitted this decode)
  detail::QrPixelModel pixel_model;
  std::vector<double> fit_a, fit_b;
  cv::Mat profile;                        // followTiming's samples along a line
  std::vector<double> col_at, row_at;     // the modules' middles it found (empty: evenly spaced)
  cv::Matx23d bend = kFlatGrid;           // readBent's move of the grid onto the finders (modules)
  cv::Vec2d bent(double x, double y) const { return bend * cv::Vec3d(x, y, 1.0); }

  // The QR read module by module: where the camera gives about a pixel per
  // module, zbar cannot find the finder patterns in the view, but the sheet
  // frame says where every module is. ld-generate prints an N-module code
  // with exactly one module of quiet zone in the QR square (docs/landmark.md),
  // so for each plausible version the modules are sampled from the image,
  // the version chosen by how like finder patterns its corners look, the
  // modules thresholded and redrawn as a clean code (its function patterns
  // ideal) for zbar, whose error correction rejects wrong versions and bad
  // reads.
  // The payload, and 0 when the equaliser's modules gave it, 1 when the
  // modules thresholded as read or after a fixed sharpening did, 2 when the
  // pixel model's did.
  std::optional<std::pair<std::string, int>> readGrid(const cv::Matx33d& sheet_to_image, double qr_px) {
    std::vector<std::pair<double, int>> candidates;  // (finder score, n)
    for (int version = 1; version <= 15; ++version) {
      const int n = 17 + 4 * version;
      if (qr_px / (n + 2) < 0.6) break;  // far under a pixel per module
      sampleModules(sheet_to_image, n);
      candidates.emplace_back(finderScore(samples, n), n);
    }
    std::sort(candidates.rbegin(), candidates.rend());
    // (the candidate whose finders the aligned grid fits best, for the pixel model)
    double top_score = -2;
    int top_n = 0;
    cv::Matx33d top_grid = sheet_to_image;
    for (size_t k = 0; k < candidates.size() && k < 3; ++k) {
      const int n = candidates[k].second;
      if (candidates[k].first < 0.3) break;
      // The corners are off by a fraction of a module in hard views: align
      // the grid (shift and scale about the QR's centre) to the finders.
      const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
      const double mid = (layout::kQrMin + layout::kQrMax) / 2;
      cv::Matx33d best = sheet_to_image;
      double best_score = -2;
      for (double scale : {0.98, 1.0, 1.02})
        for (double dy : {-0.3, 0.0, 0.3})
          for (double dx : {-0.3, 0.0, 0.3}) {
            const cv::Matx33d adjust(scale, 0, (1 - scale) * mid + dx * module,  //
                                     0, scale, (1 - scale) * mid + dy * module,  //
                                     0, 0, 1);
            sampleModules(sheet_to_image * adjust, n);
            const double score = finderScore(samples, n);
            if (score > best_score) best_score = score, best = sheet_to_image * adjust;
          }
      // The modules read at their centres alone: averaging 3x3 points of
      // each (as for the finders above) takes in more of the neighbours'
      // blur, which costs modules from about 1.5 px per module down.
      sampleModules(best, n, 1);
      if (auto r = readSamples(n)) return r;
      if (best_score > top_score) top_score = best_score, top_n = n, top_grid = best;
    }
    if (auto r = readBent(sheet_to_image, qr_px)) return r;
    // Last, the code fitted to the pixels (the slowest way: once, for the
    // version whose finders fit best, and only where its modules are under
    // kPixelModelMaxPx in a QR square of kPixelModelMaxSide at most: larger
    // ones the ways above read).
    if (params.fit_pixels && top_n > 0 && qr_px / (top_n + 2) < kPixelModelMaxPx && qr_px <= kPixelModelMaxSide)
      if (auto r = readPixels(top_grid, top_n)) return std::pair{*r, 2};
    return std::nullopt;
  }

  // A sheet that is not flat (curled, or round a pillar) moves its QR off
  // where the pattern's corners put it, by a module or two, and stretches
  // the modules unevenly: no homography follows them. Each finder is looked
  // for on its own within 2.5 modules, for each version whose modules are
  // 1.5 px or more; where all three look like finders, the grid is moved
  // onto them (the affine map of their centres), and then follows the QR's
  // own timing row and column (followTiming) before it is read.
  std::optional<std::pair<std::string, int>> readBent(const cv::Matx33d& sheet_to_image, double qr_px) {
    struct Fit {
      double score;
      int n;
      cv::Matx23d bend;
    };
    std::vector<Fit> fits;
    for (int version = 1; version <= 15; ++version) {
      const int n = 17 + 4 * version;
      if (qr_px / (n + 2) < 1.5) break;
      const double c = 3.5, f = n - 3.5;
      const cv::Point2f ideal[3] = {{static_cast<float>(c), static_cast<float>(c)},
                                    {static_cast<float>(f), static_cast<float>(c)},
                                    {static_cast<float>(c), static_cast<float>(f)}};
      cv::Point2f at[3];
      double score = 1;
      for (int k = 0; k < 3 && score >= kBentFinderMin; ++k) {
        // within 2.5 modules by half modules, then within a quarter by eighths
        cv::Point2f coarse;
        findFinder(sheet_to_image, n, ideal[k], 0.5, 5, coarse);
        score = std::min(score, findFinder(sheet_to_image, n, coarse, 0.125, 2, at[k]));
      }
      if (score < kBentFinderMin) continue;
      fits.push_back({score, n, cv::Matx23d(cv::getAffineTransform(ideal, at))});
    }
    std::sort(fits.begin(), fits.end(), [](const Fit& a, const Fit& b) { return a.score > b.score; });
    // (the grid flat and even again however this returns, a throw included)
    struct Flat {
      Impl& m;
      ~Flat() {
        m.bend = kFlatGrid;
        m.col_at.clear();
        m.row_at.clear();
      }
    } flat{*this};
    for (size_t k = 0; k < fits.size() && k < 2; ++k) {
      const int n = fits[k].n;
      bend = fits[k].bend;
      if (followTiming(sheet_to_image, n)) {
        sampleModules(sheet_to_image, n, 1);
        if (auto r = readSamples(n)) return r;
      }
    }
    return std::nullopt;
  }

  // The finder whose centre the grid puts near `ideal` (modules from the
  // symbol's edge): where within `reach` steps of `step` modules each way
  // its 7 x 7 modules look most like one (`at`), and how much (correlation,
  // -1..1).
  double findFinder(const cv::Matx33d& sheet_to_image, int n, cv::Point2f ideal, double step, int reach,
                    cv::Point2f& at) {
    const int offsets = 2 * reach + 1;
    const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
    map.create(offsets * offsets, 49, CV_32FC2);
    for (int o = 0; o < offsets * offsets; ++o) {
      const double dx = step * (o % offsets - reach), dy = step * (o / offsets - reach);
      for (int q = 0; q < 49; ++q)
        map.at<cv::Vec2f>(o, q) =
            moduleToImage(sheet_to_image, module, ideal.x + dx + (q % 7 - 3), ideal.y + dy + (q / 7 - 3));
    }
    cv::remap(gray, sampled, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    double best = -2;
    for (int o = 0; o < offsets * offsets; ++o) {
      FinderCorrelation corr;
      for (int q = 0; q < 49; ++q) corr.add(q / 7, q % 7, sampled.at<uint8_t>(o, q));
      const double score = corr.value();
      if (score > best) {
        best = score;
        at = {static_cast<float>(ideal.x + step * (o % offsets - reach)),
              static_cast<float>(ideal.y + step * (o / offsets - reach))};
      }
    }
    return best;
  }

  // The payload from `samples` (readGrid's pair): equalised, else sharpened
  // by fixed amounts and thresholded globally (Otsu) and locally.
  std::optional<std::pair<std::string, int>> readSamples(int n) {
    if (equalise(n))
      if (auto r = scanBits(n)) return std::pair{*r, 0};
    for (double k : {0.0, 1.4, 2.5})
      for (bool local : {false, true}) {
        thresholdModules(n, k, local);
        if (auto r = scanBits(n)) return std::pair{*r, 1};
      }
    return std::nullopt;
  }

  // The code from the pixel model (qr_pixel_model.hpp) on the grid that
  // `sheet_to_image` puts.
  std::optional<std::string> readPixels(const cv::Matx33d& sheet_to_image, int n) {
    if (!pixel_model.estimate(gray, sheet_to_image * detail::moduleToSheet(n), n, fitted)) return std::nullopt;
    fitted_n = n;
    return scanModules(n, fitted);
  }

  // The payload of an n-module code given module by module (1 dark).
  std::optional<std::string> scanModules(int n, const std::vector<uint8_t>& modules) {
    bits.create(n, n, CV_8U);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) bits.at<uint8_t>(r, c) = modules[static_cast<size_t>(r) * n + c] ? 0 : 255;
    return scanBits(n);
  }

  // Where each module column's and row's middle lies (in modules, from the
  // symbol's edge), as the QR's row 6 and column 6 show it: finder, timing
  // pattern, finder, a known sequence of dark and light modules with an
  // edge at 0, 7, 8, 9, ..., n - 8, n - 7 and n. Each edge is looked for
  // where the last two found predict it (a bend stretches the modules
  // gradually), and a cubic through the edges found gives col_at / row_at.
  // False (and both empty) when too few edges are found.
  bool followTiming(const cv::Matx33d& sheet_to_image, int n) {
    const bool ok = followLine(sheet_to_image, n, true, col_at) && followLine(sheet_to_image, n, false, row_at);
    if (!ok) col_at.clear(), row_at.clear();
    return ok;
  }

  bool followLine(const cv::Matx33d& sheet_to_image, int n, bool across, std::vector<double>& at) {
    constexpr int kStep = 8;  // profile samples per module
    const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
    // the profile along row 6 (across) or column 6, from 1.5 modules before the symbol to 1.5 after
    const int len = (n + 3) * kStep;
    map.create(1, len, CV_32FC2);
    // (column 6 where row 6's edges put it, when they have)
    const double line = across || col_at.size() < 7 ? 6.5 : col_at[6];
    for (int i = 0; i < len; ++i) {
      const double along = -1.5 + static_cast<double>(i) / kStep;  // modules from the symbol's edge
      const cv::Vec2d m = bent(across ? along : line, across ? 6.5 : along);
      map.at<cv::Vec2f>(0, i) = moduleToImage(sheet_to_image, module, m[0], m[1]);
    }
    cv::remap(gray, sampled, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    sampled.convertTo(profile, CV_32F);
    std::vector<float> sorted(profile.begin<float>(), profile.end<float>());
    std::sort(sorted.begin(), sorted.end());
    const double dark = sorted[sorted.size() / 10], light = sorted[sorted.size() * 9 / 10];
    if (!(light - dark > 30)) return false;
    const double mid = (dark + light) / 2;
    auto value = [&](double along) {  // the profile at a position in modules (linear)
      const double f = (along + 1.5) * kStep;
      const int i = std::clamp(static_cast<int>(std::floor(f)), 0, len - 2);
      const double t = std::clamp(f - i, 0.0, 1.0);
      return (1 - t) * profile.at<float>(0, i) + t * profile.at<float>(0, i + 1);
    };
    // the edges, in order, and whether the profile goes dark there
    std::vector<std::pair<int, bool>> edges{{0, true}, {7, false}};
    for (int e = 8; e <= n - 8; ++e) edges.emplace_back(e, e % 2 == 0);
    edges.emplace_back(n - 7, true);
    edges.emplace_back(n, false);
    std::vector<std::pair<double, double>> found;  // (expected, found) in modules
    double scale = 1;
    for (const auto& [e, to_dark] : edges) {
      double predict = e;
      if (!found.empty()) predict = found.back().second + (e - found.back().first) * scale;
      // the crossing of `mid` in the right direction nearest the prediction, within 0.6 modules
      double best = 1e9;
      for (double x = predict - 0.6; x <= predict + 0.6; x += 1.0 / kStep) {
        const double v0 = value(x), v1 = value(x + 1.0 / kStep);
        if (to_dark ? !(v0 >= mid && v1 < mid) : !(v0 < mid && v1 >= mid)) continue;
        const double cross = x + (v0 - mid) / (v0 - v1) / kStep;
        if (std::abs(cross - predict) < std::abs(best - predict)) best = cross;
      }
      if (best > 1e8) continue;
      if (!found.empty() && e - found.back().first <= 8) {
        const double s = (best - found.back().second) / (e - found.back().first);
        if (s > 0.6 && s < 1.6) scale = 0.5 * scale + 0.5 * s;
      }
      found.emplace_back(e, best);
    }
    if (static_cast<int>(found.size()) < std::max(8, static_cast<int>(edges.size()) * 2 / 3)) return false;
    // a cubic through them (least squares, in the symbol's half-widths for
    // conditioning), again without the edges it misses by over 0.25 modules
    const double h = n / 2.0;
    cv::Mat c;
    auto cubicAt = [&](double e) {
      const double t = (e - h) / h;
      return c.at<double>(0) + t * (c.at<double>(1) + t * (c.at<double>(2) + t * c.at<double>(3)));
    };
    for (int round = 0; round < 2; ++round) {
      if (found.size() < 6) return false;
      cv::Mat A(static_cast<int>(found.size()), 4, CV_64F), y(static_cast<int>(found.size()), 1, CV_64F);
      for (int i = 0; i < A.rows; ++i) {
        const double t = (found[static_cast<size_t>(i)].first - h) / h;
        for (int k = 0; k < 4; ++k) A.at<double>(i, k) = std::pow(t, k);
        y.at<double>(i) = found[static_cast<size_t>(i)].second;
      }
      if (!cv::solve(A, y, c, cv::DECOMP_SVD)) return false;
      if (round == 0)
        found.erase(std::remove_if(found.begin(), found.end(),
                                   [&](const auto& f) { return std::abs(cubicAt(f.first) - f.second) > 0.25; }),
                    found.end());
    }
    // edges kept near both ends (the cubic is not stretched over a finder),
    // and modules in order, none under half or over 1.6 of its width
    const bool ends = std::any_of(found.begin(), found.end(), [](const auto& f) { return f.first <= 7; }) &&
                      std::any_of(found.begin(), found.end(), [n](const auto& f) { return f.first >= n - 7; });
    if (!ends) return false;
    at.resize(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) {
      at[static_cast<size_t>(k)] = cubicAt(k + 0.5);
      if (k > 0) {
        const double step = at[static_cast<size_t>(k)] - at[static_cast<size_t>(k - 1)];
        if (!(step > 0.5 && step < 1.6)) return false;
      }
    }
    return true;
  }

  // `bits` (dark 0, light 255) from `samples`: the camera's blur spreads each
  // module over its neighbours, so some of it is undone first (a module
  // minus k times its neighbours' mean deviation), then the grid is
  // thresholded globally (Otsu) or locally (the mean of 9 x 9 modules).
  void thresholdModules(int n, double k, bool local) {
    cv::blur(samples, sharpened, {3, 3}, {-1, -1}, cv::BORDER_REPLICATE);
    sharpened = samples + k * (samples - sharpened);
    sharpened.convertTo(grid8, CV_8U);
    if (local)
      cv::adaptiveThreshold(grid8, bits, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY, std::min(n | 1, 9), 0);
    else
      cv::threshold(grid8, bits, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  }

  // `bits` (dark 0, light 255) from `samples` by a decision-feedback
  // equaliser: the camera's blur as a linear model, a module's sample = a +
  // b * its darkness + w_k * the darkness of each of its eight neighbours,
  // fitted on the modules whose whole neighbourhood is known (the function
  // patterns and the quiet zone); then each unknown module is what its sample
  // says once its neighbours' share is taken off, sweep after sweep in place
  // from a sharpened threshold. Undoes blur, directional (motion) included,
  // that a fixed sharpening cannot. False when the model does not fit (too
  // few known modules, no contrast).
  bool equalise(int n) {
    constexpr int kFeatures = 10;  // 1, the module, its eight neighbours
    const int m = n + 2;           // with the quiet zone's ring, light and known
    known.assign(static_cast<size_t>(m) * m, 0);
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) known[static_cast<size_t>(r + 1) * m + c + 1] = -1;
    detail::forEachFunctionModule(n, [&](int r, int c, bool dark) {
      known[static_cast<size_t>(r + 1) * m + c + 1] = dark ? 1 : 0;
    });
    auto at = [&](const std::vector<int8_t>& g, int r, int c) { return g[static_cast<size_t>(r + 1) * m + c + 1]; };
    auto features = [&](const std::vector<int8_t>& g, int r, int c, double* f) {
      f[0] = 1;
      int k = 1;
      for (int dr = -1; dr <= 1; ++dr)
        for (int dc = -1; dc <= 1; ++dc) f[k++] = at(g, r + dr, c + dc);
    };
    fit_a.clear();
    fit_b.clear();
    double f[kFeatures];
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) {
        bool all = true;
        for (int dr = -1; dr <= 1 && all; ++dr)
          for (int dc = -1; dc <= 1 && all; ++dc) all = at(known, r + dr, c + dc) >= 0;
        if (!all) continue;
        features(known, r, c, f);
        fit_a.insert(fit_a.end(), f, f + kFeatures);
        fit_b.push_back(samples.at<float>(r, c));
      }
    const int rows = static_cast<int>(fit_b.size());
    if (rows < 4 * kFeatures) return false;
    cv::Mat w;
    if (!cv::solve(cv::Mat(rows, kFeatures, CV_64F, fit_a.data()), cv::Mat(rows, 1, CV_64F, fit_b.data()), w,
                   cv::DECOMP_SVD))
      return false;
    const double own = w.at<double>(5);  // the module itself (f[5]: dr = dc = 0)
    if (!(own < -8.0)) return false;     // a dark module must read darker
    // Start from the sharpened grid's Otsu threshold.
    thresholdModules(n, 2.5, false);
    grid = known;
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c)
        if (at(known, r, c) < 0) grid[static_cast<size_t>(r + 1) * m + c + 1] = bits.at<uint8_t>(r, c) == 0;
    for (int sweep = 0; sweep < 8; ++sweep) {
      bool changed = false;
      for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
          if (at(known, r, c) >= 0) continue;
          features(grid, r, c, f);
          double rest = 0;
          for (int k = 0; k < kFeatures; ++k)
            if (k != 5) rest += w.at<double>(k) * f[k];
          const int8_t dark = (samples.at<float>(r, c) - rest) / own > 0.5;
          int8_t& g = grid[static_cast<size_t>(r + 1) * m + c + 1];
          changed |= g != dark;
          g = dark;
        }
      if (!changed) break;
    }
    for (int r = 0; r < n; ++r)
      for (int c = 0; c < n; ++c) bits.at<uint8_t>(r, c) = at(grid, r, c) ? 0 : 255;
    return true;
  }

  // The modules of an n-module grid sampled from the gray image (kSub x kSub
  // points a quarter module apart around each centre, averaged): `samples`,
  // n x n, CV_32F.
  void sampleModules(const cv::Matx33d& sheet_to_image, int n, int kSub = 3) {
    const double module = (layout::kQrMax - layout::kQrMin) / (n + 2);
    map.create(n * kSub, n * kSub, CV_32FC2);
    // (the middles of the modules' columns and rows: followTiming's, or evenly spaced)
    auto middle = [](const std::vector<double>& at, int k) { return at.empty() ? k + 0.5 : at[static_cast<size_t>(k)]; };
    for (int r = 0; r < n * kSub; ++r) {
      auto* row = map.ptr<cv::Vec2f>(r);
      const double y = middle(row_at, r / kSub) + ((r % kSub) - kSub / 2) * 0.25;
      for (int c = 0; c < n * kSub; ++c) {
        const cv::Vec2d m = bent(middle(col_at, c / kSub) + ((c % kSub) - kSub / 2) * 0.25, y);
        row[c] = moduleToImage(sheet_to_image, module, m[0], m[1]);
      }
    }
    cv::remap(gray, sampled, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    sampled.convertTo(sampled, CV_32F);
    cv::resize(sampled, samples, {n, n}, 0, 0, cv::INTER_AREA);
  }

  std::optional<std::string> scanBits(int n) {
    detail::forEachFunctionModule(n, [&](int r, int c, bool dark) { bits.at<uint8_t>(r, c) = dark ? 0 : 255; });
    constexpr int kPx = 4, kQuiet = 4;
    clean.create((n + 2 * kQuiet) * kPx, (n + 2 * kQuiet) * kPx, CV_8U);
    clean.setTo(255);
    cv::resize(bits, clean(cv::Rect(kQuiet * kPx, kQuiet * kPx, n * kPx, n * kPx)), {n * kPx, n * kPx},
               0, 0, cv::INTER_NEAREST);
    return scan(clean);
  }

  std::optional<std::string> scan(const cv::Mat& img) {
    cv::Mat cont = img.isContinuous() ? img : img.clone();
    zbar::Image z(static_cast<unsigned>(cont.cols), static_cast<unsigned>(cont.rows), "Y800",
                  cont.data, static_cast<unsigned long>(cont.total()));
    std::optional<std::string> found;
    if (scanner.scan(z) > 0) {
      for (auto s = z.symbol_begin(); s != z.symbol_end(); ++s)
        if (s->get_type() == zbar::ZBAR_QRCODE) {
          found = s->get_data();
          break;
        }
    }
    z.set_data(nullptr, 0);
    return found;
  }
};

QrReader::QrReader(const QrReaderParams& params) : impl_(std::make_unique<Impl>()) {
  // (min_side_px over max_side_px broke std::clamp's precondition; INT_MAX
  // sides asked for exabytes; a NaN upsample was taken)
  requireWithin("QrReaderParams", "upsample", params.upsample, 0.25, 16);
  requireWithin("QrReaderParams", "min_side_px", params.min_side_px, 16, 4096);
  requireWithin("QrReaderParams", "max_side_px", params.max_side_px, 16, 4096);
  if (params.min_side_px > params.max_side_px)  // (named as both: either may be the one set wrong)
    throw std::invalid_argument("QrReaderParams: min_side_px " + std::to_string(params.min_side_px) +
                                " is over max_side_px " + std::to_string(params.max_side_px));
  requireWithin("QrReaderParams", "margin_u", params.margin_u, 0, 1);
  impl_->params = params;
  impl_->scanner.set_config(zbar::ZBAR_NONE, zbar::ZBAR_CFG_ENABLE, 0);
  impl_->scanner.set_config(zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_ENABLE, 1);
  // The payload's bytes as encoded: zbar's text conversion guesses a charset
  // and turns short UTF-8 strings into Shift-JIS mojibake.
  impl_->scanner.set_config(zbar::ZBAR_QRCODE, zbar::ZBAR_CFG_BINARY, 1);
}
QrReader::~QrReader() = default;
QrReader::QrReader(QrReader&&) noexcept = default;
QrReader& QrReader::operator=(QrReader&&) noexcept = default;

const cv::Mat& QrReader::lastView() const {
  static const cv::Mat none;
  return impl_->view_made ? impl_->view : none;
}

const std::vector<uint8_t>* QrReader::lastFittedModules(int& n) const {
  n = impl_->fitted_n;
  return n > 0 ? &impl_->fitted : nullptr;
}

std::optional<QrResult> QrReader::decodeModules(int n, const std::vector<uint8_t>& modules) {
  if (n < 21 || n > 177 || (n - 17) % 4 != 0 || modules.size() != static_cast<size_t>(n) * n) return std::nullopt;
  if (auto s = impl_->scanModules(n, modules)) return QrResult{*s, 9};
  return std::nullopt;
}

std::optional<QrResult> QrReader::decode(const cv::Mat& image,
                                         const std::array<cv::Point2f, 4>& corners) {
  Impl& m = *impl_;
  const QrReaderParams& p = m.params;
  m.fitted_n = 0;
  m.view_made = false;
  requireReadableImage(image, "QrReader::decode");
  const auto readable = readableQrSide(image, corners);
  if (!readable) return std::nullopt;  // nothing to read
  const double qr_px = *readable;
  toGray(image, m.gray);

  const int side = std::clamp(static_cast<int>(std::lround(p.upsample * qr_px)), p.min_side_px,
                              p.max_side_px);
  const cv::Matx33d H = viewToImage(corners, side, p.margin_u);
  cv::warpPerspective(m.gray, m.view, H, {side, side}, cv::INTER_CUBIC | cv::WARP_INVERSE_MAP,
                      cv::BORDER_REPLICATE);
  m.view_made = true;

  int attempt = 0;
  if (auto s = m.scan(m.view)) return QrResult{*s, attempt};
  if (!p.retry_variations) return std::nullopt;

  // 1: Otsu binarization of the view.
  ++attempt;
  cv::threshold(m.view, m.work, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU);
  if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  // 2: unsharp mask against blur.
  ++attempt;
  cv::GaussianBlur(m.view, m.blurred, {0, 0}, std::max(1.0, side / 120.0));
  cv::addWeighted(m.view, 2.0, m.blurred, -1.0, 0, m.work);
  if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  // 3: adaptive threshold against uneven light (glare, gradient).
  ++attempt;
  const int block = (side / 8) | 1;
  cv::adaptiveThreshold(m.view, m.work, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY,
                        std::max(3, block), 5);
  if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  // 4, 5: other scales of the view.
  for (double scale : {0.6, 1.6}) {
    ++attempt;
    cv::resize(m.view, m.work, {}, scale, scale, scale < 1 ? cv::INTER_AREA : cv::INTER_CUBIC);
    if (auto s = m.scan(m.work)) return QrResult{*s, attempt};
  }
  // 6, 7: module by module, from the sheet frame (6: equalised, 7: thresholded).
  ++attempt;
  if (auto s = m.readGrid(layout::sheetToImage(corners), qr_px)) return QrResult{s->first, attempt + s->second};
  return std::nullopt;
}

// ===================================================================== QrStack

namespace {

// The stack's view (cubic interpolation, as the reader's own view: linear
// blurs the modules more and read fewer codes in ld-eval qr --stack): the
// QR square and half a unit around it, at twice the
// camera's resolution (at least 4 px a unit).
constexpr double kStackMargin = 0.5;
constexpr double kStackSpan = layout::kQrMax - layout::kQrMin + 2 * kStackMargin;
int stackSide(double qr_px) {
  return std::clamp(static_cast<int>(std::lround(2 * qr_px * kStackSpan / (layout::kQrMax - layout::kQrMin))),
                    static_cast<int>(4 * kStackSpan), 600);
}

}  // namespace

QrStack::QrStack(int max_frames) : max_frames_(max_frames) {
  if (max_frames < 1)
    throw std::invalid_argument("QrStack: max_frames must be 1 or more, not " + std::to_string(max_frames));
}

bool QrStack::add(const cv::Mat& image, const std::array<cv::Point2f, 4>& corners) {
  requireReadableImage(image, "QrStack::add");
  const auto qr_px = readableQrSide(image, corners);
  if (!qr_px) return false;
  // Another landmark (a tracker's ids swapped between two), not this one
  // seen again: a QR of another size, or one that jumped.
  if (n_ > 0 && std::abs(*qr_px - qr_px_) > 0.25 * qr_px_) restart();
  checkJump(corners, *qr_px);
  if (n_ == 0) qr_px_ = *qr_px;
  toGray(image, gray_);
  const int side = stackSide(qr_px_);
  cv::warpPerspective(gray_, view_, viewToImage(corners, side, kStackMargin), {side, side},
                      cv::INTER_CUBIC | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  if (n_ == 0) {
    view_.convertTo(mean_, CV_32F);
  } else {
    // mean += (view - mean) / min(n + 1, max_frames)
    const double w = 1.0 / std::min(n_ + 1, std::max(1, max_frames_));
    view_.convertTo(view_f_, CV_32F);
    cv::addWeighted(mean_, 1 - w, view_f_, w, 0, mean_);
  }
  ++n_;
  return true;
}

bool QrStack::follow(const std::array<cv::Point2f, 4>& corners) {
  if (!detail::finiteCorners(corners)) return false;
  return checkJump(corners, layout::projectedQrSide(corners));
}

bool QrStack::checkJump(const std::array<cv::Point2f, 4>& corners, double qr_px) {
  const cv::Point2f centre = (corners[0] + corners[1] + corners[2] + corners[3]) * 0.25f;
  const double pattern_px = qr_px * (layout::kPatternMax - layout::kPatternMin) / (layout::kQrMax - layout::kQrMin);
  const bool jumped = n_ > 0 && cv::norm(centre - centre_) > kMaxJump * pattern_px;
  if (jumped) restart();
  centre_ = centre;
  return jumped;
}

const cv::Mat& QrStack::meanView() {
  if (n_ > 0) mean_.convertTo(mean8_, CV_8U);
  else mean8_.release();
  return mean8_;
}

void QrStack::addModules(int n, const std::vector<uint8_t>& modules) {
  if (n_ == 0 || n <= 0 || modules.size() != static_cast<size_t>(n) * n) return;
  const size_t slots = static_cast<size_t>(std::max(1, max_frames_));
  if (fits_.size() < slots) fits_.resize(slots), fit_n_.resize(slots);
  fits_[static_cast<size_t>(next_fit_)].assign(modules.begin(), modules.end());  // (no allocation once warm)
  fit_n_[static_cast<size_t>(next_fit_)] = n;
  next_fit_ = (next_fit_ + 1) % static_cast<int>(slots);
  votes_ = std::min(votes_ + 1, static_cast<int>(slots));
}

std::optional<QrResult> QrStack::decode(QrReader& reader) {
  if (n_ == 0) return std::nullopt;
  if (auto r = decodeMean(reader)) return r;
  // The vote, over the fits of the code size most of them have.
  const int slots = static_cast<int>(fits_.size());
  int n = 0, most = 0, latest = -1;
  for (int k = 0; k < votes_; ++k) {
    const int i = (next_fit_ - 1 - k + 2 * slots) % slots;  // latest first
    const int count = static_cast<int>(std::count(fit_n_.begin(), fit_n_.begin() + votes_, fit_n_[static_cast<size_t>(i)]));
    if (count > most) most = count, n = fit_n_[static_cast<size_t>(i)], latest = i;
  }
  if (most < kMinVotes) return std::nullopt;
  const size_t cells = static_cast<size_t>(n) * n;
  dark_.assign(cells, 0);
  for (int k = 0; k < votes_; ++k)
    if (fit_n_[static_cast<size_t>(k)] == n) {
      const auto& f = fits_[static_cast<size_t>(k)];
      for (size_t m = 0; m < cells; ++m) dark_[m] += f[m];
    }
  voted_.resize(cells);
  const auto& last = fits_[static_cast<size_t>(latest)];
  for (size_t m = 0; m < cells; ++m) voted_[m] = 2 * dark_[m] == most ? last[m] : 2 * dark_[m] > most;
  return reader.decodeModules(n, voted_);
}

std::optional<QrResult> QrStack::decodeMean(QrReader& reader) {
  // The pattern square's corners in the view's pixels: the view maps sheet
  // u = q0 + (x + 0.5) * span / side.
  const int side = mean_.cols;
  const double q0 = layout::kQrMin - kStackMargin, s = kStackSpan / side;
  std::array<cv::Point2f, 4> corners;
  for (int i = 0; i < 4; ++i) {
    const auto& u = layout::kCornersU[static_cast<size_t>(i)];
    corners[static_cast<size_t>(i)] = {static_cast<float>((u[0] - q0) / s - 0.5),
                                       static_cast<float>((u[1] - q0) / s - 0.5)};
  }
  return reader.decode(meanView(), corners);
}

}  // namespace ld
