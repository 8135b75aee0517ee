// The detector's stages (see stages.hpp and include/ld/detector.hpp).
#include "stages.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <tuple>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include "ld/landmark_layout.hpp"

namespace ld::detail {
namespace {

int thresholdQ8(double saturation_threshold) {
  return std::clamp(static_cast<int>(std::lround(saturation_threshold * 256.0)), 0, 256);
}

// Symmetric 2x2 matrix helpers for the moments.
struct Sym2 {
  double xx = 0, xy = 0, yy = 0;
  double det() const { return xx * yy - xy * xy; }
};

Sym2 moments(const Region& r) { return {r.sxx, r.sxy, r.syy}; }

Sym2 mean(const Sym2& a, const Sym2& b) { return {(a.xx + b.xx) / 2, (a.xy + b.xy) / 2, (a.yy + b.yy) / 2}; }

// The metric M = inverse(S) / 12: v' M v is the squared length of v in units
// of the side of the square whose moments S are. False when degenerate.
bool metric(const Sym2& s, Sym2& m) {
  const double d = s.det();
  if (!(d > 1e-12)) return false;
  m = {s.yy / (12 * d), -s.xy / (12 * d), s.xx / (12 * d)};
  return true;
}

double quad(const Sym2& m, double x, double y) { return m.xx * x * x + 2 * m.xy * x * y + m.yy * y * y; }
double bilin(const Sym2& m, double ax, double ay, double bx, double by) {
  return m.xx * ax * bx + m.xy * (ax * by + ay * bx) + m.yy * ay * by;
}

double cross(const cv::Point2d& a, const cv::Point2d& b) { return a.x * b.y - a.y * b.x; }

cv::Point2d centre(const Region& r) { return {r.cx, r.cy}; }

// The image at a sub-pixel position, bilinearly interpolated; false outside.
bool sampleBgr(const cv::Mat& bgr, const cv::Point2d& p, double c[3]) {
  const int x0 = static_cast<int>(std::floor(p.x)), y0 = static_cast<int>(std::floor(p.y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= bgr.cols || y0 + 1 >= bgr.rows) return false;
  const double fx = p.x - x0, fy = p.y - y0;
  c[0] = c[1] = c[2] = 0;
  const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  for (int k = 0; k < 4; ++k) {
    const uint8_t* px = bgr.ptr<uint8_t>(y0 + (k >> 1)) + 3 * (x0 + (k & 1));
    for (int ch = 0; ch < 3; ++ch) c[ch] += w[k] * px[ch];
  }
  return true;
}

// Saturation (0..1), value (0..255) and mean of the channels at a sub-pixel
// position, and its colour when `colour` is given; false outside the image.
bool sampleSV(const cv::Mat& bgr, const cv::Point2d& p, double& s, double& v, double* mean = nullptr,
              double* colour = nullptr) {
  double own[3];
  double* c = colour ? colour : own;
  if (!sampleBgr(bgr, p, c)) return false;
  const double mx = std::max({c[0], c[1], c[2]}), mn = std::min({c[0], c[1], c[2]});
  v = mx;
  s = mx > 0 ? (mx - mn) / mx : 0.0;
  if (mean) *mean = (c[0] + c[1] + c[2]) / 3;
  return true;
}

// A hue's excess in a colour: blue b - max(g, r), red r - max(g, b).
double excess(const double c[3], uint8_t colour) {
  return colour == kBlue ? c[0] - std::max(c[1], c[2]) : c[2] - std::max(c[0], c[1]);
}

// Colour excess of a hue at a sub-pixel position (bilinear), or 0 outside.
double excessAt(const cv::Mat& bgr, const cv::Point2d& p, uint8_t colour) {
  double c[3];
  return sampleBgr(bgr, p, c) ? excess(c, colour) : 0;
}

// How much of the light a colour's ink absorbs that the paper reflects: the
// larger of the other two channels, negated (blue ink takes green and red,
// red ink green and blue; the paper reflects all three). NaN outside the
// image (no value there would be neutral).
double absorbedAt(const cv::Mat& bgr, const cv::Point2d& p, uint8_t colour) {
  double c[3];
  if (!sampleBgr(bgr, p, c)) return std::numeric_limits<double>::quiet_NaN();
  return colour == kBlue ? -std::max(c[1], c[2]) : -std::max(c[0], c[1]);
}

// A hue's excess over the brightness: a colour's strength whatever the
// light's level.
double chroma(const double c[3], uint8_t colour) {
  return excess(c, colour) / std::max(1.0, (c[0] + c[1] + c[2]) / 3);
}

// A sheet this bright (mean of the channels, 0..255) is at or near the
// sensor's white clip: glare, or the adapter's stretch of it.
constexpr double kClippedSheet = 235;
// A reflection on the QR alone: this many of its 25 points brighter than
// the sheet's brightest sample by this ratio.
constexpr int kGlaredSamples = 3;
constexpr double kGlaredOverSheet = 1.1;
// A QR on a clipped sheet read by its grey points' mean
// (DetectorParams::qr_clipped_max_brightness): this many of the 25 grey.
constexpr int kClippedQrGrey = 22;
// A QR washed out by a hot spot on a sheet clipped all round
// (DetectorParams::qr_washed_dip): this many of its grey points dip under
// the brightest.
constexpr int kWashedDips = 3;
// A band across the sheet: both sides of one opposite pair darker than both
// of the other pair, the brighter of them by this ratio or more (no light's
// gradient nor one shadow's edge darkens opposite sides alone; over
// thousands of landmarks in random scenes the ratio stays above 0.97).
constexpr double kBandSides = 0.85;
// Four sheets hung in a grid with narrow gaps (about a sixth of a sheet):
// where their corners meet, the TL of one, the TR of its left neighbour,
// the BL of the one above it and the AP of the one diagonally across lie as
// a smaller landmark's turned by 180 degrees, and the middle sample of each
// of its sides falls in a gap, on the wall. Every side's middle sample
// darker than both samples beside it by this ratio refuses the sheet (no
// light, even, falling off or shaded, dips at all four middles: over the
// random scenes of ld-eval's sweeps the largest of the four sides' ratios,
// middle to darker neighbour, stays at 0.98 or more; at such crossings of
// gaps it is 0.88 or less).
constexpr double kGapDip = 0.93;
// A piece of a split square: its centre within this many units of the
// square's centre, in the frame where the centres are 3 units apart and a
// square spans half a unit each way (a piece's centre lies inside that
// outline; the margin is for the square's own centre, a piece's, off by
// the split), and the square and its pieces together, by their moments, at
// most this many times as large as the printed square there (the blur's
// pixel each side, at squares of 8 px).
constexpr double kPieceReach = 0.75;
constexpr double kPieceSpan = 1.3;
// ... and a piece a tenth of the printed square or more (a square's edge
// against a background of its colour leaves crumbs of a few pixels there).
constexpr double kPieceMinArea = 0.1;
// Squares smaller than this (pixels) are left whole: a row under the
// threshold splits larger ones, and beside a few pixels' square a
// background's crumbs of its colour pass for pieces.
constexpr double kPieceMinSide = 8;
// Squares (joined) covering less than this fraction of the printed square
// under a glare veil's tint are pieces still: their centre is measured on
// the image (inkCentre(); on ld-synth's random scenes squares cover 0.6-1.0
// of it, under glare 0.6 from a few hundredths).
constexpr double kPieceWhole = 0.7;
constexpr int kInkRounds = 2;

// How much more of a hue than the sheet's a saturated landmark centre may
// have (printed blue and red have about 1 more).
constexpr double kCentreChroma = 0.3;

}  // namespace

double Region::side() const {
  const double d = sxx * syy - sxy * sxy;
  return d > 0 ? std::sqrt(12.0 * std::sqrt(d)) : 0.0;
}

// ====================================================================== front ends

void scaleChannels(const cv::Mat& bgr, const cv::Vec3d& gain, cv::Mat& out) {
  CV_Assert(bgr.type() == CV_8UC3 && out.type() == CV_8UC3 && out.size() == bgr.size());
  // Each channel's products, worked out once per value, not once per pixel.
  uint8_t table[3][256];
  for (int c = 0; c < 3; ++c)
    for (int v = 0; v < 256; ++v) table[c][v] = cv::saturate_cast<uint8_t>(v * gain[c]);
  for (int y = 0; y < bgr.rows; ++y) {
    const uint8_t* p = bgr.ptr<uint8_t>(y);
    uint8_t* q = out.ptr<uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x, p += 3, q += 3) {
      q[0] = table[0][p[0]];
      q[1] = table[1][p[1]];
      q[2] = table[2][p[2]];
    }
  }
}

void subtractChannels(const cv::Mat& bgr, const cv::Scalar& tint, cv::Mat& out, int keep_from) {
  CV_Assert(bgr.type() == CV_8UC3 && out.type() == CV_8UC3 && out.size() == bgr.size());
  CV_Assert(keep_from > 255 || out.data != bgr.data);  // (the kept pixels are read from bgr after the pass)
  // Saturating byte arithmetic (the loops vectorise): less `down`, plus `up`,
  // one of them 0 in each channel, laid out over 48 bytes (16 pixels).
  constexpr int kSpan = 48;
  uint8_t down[kSpan], up[kSpan];
  for (int k = 0; k < kSpan; ++k) {
    // (rounded, as cv::subtract rounds it; beyond 255 the result saturates alike)
    const int t = std::clamp(cvRound(std::clamp(tint[k % 3], -1e9, 1e9)), -255, 255);
    down[k] = static_cast<uint8_t>(t > 0 ? t : 0);
    up[k] = static_cast<uint8_t>(t < 0 ? -t : 0);
  }
  const auto sat = [](uint8_t v, uint8_t d, uint8_t u) {
    const uint8_t a = v > d ? static_cast<uint8_t>(v - d) : 0;
    return static_cast<uint8_t>(a < 255 - u ? a + u : 255);
  };
  const int n = 3 * bgr.cols;
  for (int y = 0; y < bgr.rows; ++y) {
    const uint8_t* p = bgr.ptr<uint8_t>(y);
    uint8_t* q = out.ptr<uint8_t>(y);
    int i = 0;
    for (; i + kSpan <= n; i += kSpan)
      for (int k = 0; k < kSpan; ++k) q[i + k] = sat(p[i + k], down[k], up[k]);
    for (int k = 0; i < n; ++i, ++k) q[i] = sat(p[i], down[k], up[k]);
    if (keep_from > 255) continue;
    for (int x = 0; x < n; x += 3)
      if (std::max({p[x], p[x + 1], p[x + 2]}) >= keep_from) q[x] = p[x], q[x + 1] = p[x + 1], q[x + 2] = p[x + 2];
  }
}

void colourFromBrightness(const cv::Mat& bgr, double white, cv::Mat& out, std::vector<float>& scratch) {
  CV_Assert(bgr.type() == CV_8UC3);
  const int w = bgr.cols, h = bgr.rows;
  out.create(h, w, CV_8UC3);
  if (w == 0 || h == 0) return;
  // Float planes (the loops vectorise) of the whole window: brightness y
  // (BT.601) and darkness d = white - y (>= 0); of one row: the colour
  // differences b - y and r - y; and the 3-pixel sums along each row (edges
  // replicated) of d, b - y and r - y.
  const size_t n = static_cast<size_t>(w) * h;
  scratch.resize(5 * n + 2 * static_cast<size_t>(w));
  float *Y = scratch.data(), *D = Y + n, *HD = D + n, *HB = HD + n, *HR = HB + n;
  float *CB = HR + n, *CR = CB + w;
  const float W = static_cast<float>(white);
  const auto rowSum = [w](const float* a, float* s) {
    if (w == 1) {
      s[0] = 3 * a[0];
      return;
    }
    s[0] = 2 * a[0] + a[1];
    for (int x = 1; x < w - 1; ++x) s[x] = a[x - 1] + a[x] + a[x + 1];
    s[w - 1] = a[w - 2] + 2 * a[w - 1];
  };
  for (int y = 0; y < h; ++y) {
    const uint8_t* p = bgr.ptr<uint8_t>(y);
    const size_t o = static_cast<size_t>(y) * w;
    float *Yr = Y + o, *Dr = D + o;
    int x = 0;
#if CV_SIMD
    {
      constexpr int L = cv::v_uint8::nlanes, Q = cv::v_float32::nlanes;
      const cv::v_float32 kb = cv::vx_setall_f32(0.114f), kg = cv::vx_setall_f32(0.587f),
                          kr = cv::vx_setall_f32(0.299f), vw = cv::vx_setall_f32(W), v0 = cv::vx_setzero_f32();
      for (; x <= w - L; x += L) {
        cv::v_uint8 b8, g8, r8;
        cv::v_load_deinterleave(p + 3 * x, b8, g8, r8);
        cv::v_uint16 b16[2], g16[2], r16[2];
        cv::v_expand(b8, b16[0], b16[1]);
        cv::v_expand(g8, g16[0], g16[1]);
        cv::v_expand(r8, r16[0], r16[1]);
        for (int k = 0; k < 2; ++k) {
          cv::v_uint32 b32[2], g32[2], r32[2];
          cv::v_expand(b16[k], b32[0], b32[1]);
          cv::v_expand(g16[k], g32[0], g32[1]);
          cv::v_expand(r16[k], r32[0], r32[1]);
          for (int j = 0; j < 2; ++j) {
            const cv::v_float32 fb = cv::v_cvt_f32(cv::v_reinterpret_as_s32(b32[j]));
            const cv::v_float32 fg = cv::v_cvt_f32(cv::v_reinterpret_as_s32(g32[j]));
            const cv::v_float32 fr = cv::v_cvt_f32(cv::v_reinterpret_as_s32(r32[j]));
            const cv::v_float32 yy = fb * kb + fg * kg + fr * kr;
            const int at = x + (2 * k + j) * Q;
            cv::v_store(Yr + at, yy);
            cv::v_store(Dr + at, cv::v_max(vw - yy, v0));
            cv::v_store(CB + at, fb - yy);
            cv::v_store(CR + at, fr - yy);
          }
        }
      }
    }
#endif
    for (; x < w; ++x) {
      const float b = p[3 * x], g = p[3 * x + 1], r = p[3 * x + 2];
      const float yy = 0.114f * b + 0.587f * g + 0.299f * r;
      Yr[x] = yy;
      Dr[x] = std::max(W - yy, 0.0f);
      CB[x] = b - yy;
      CR[x] = r - yy;
    }
    rowSum(Dr, HD + o);
    rowSum(CB, HB + o);
    rowSum(CR, HR + o);
  }
  // Neighbourhoods darker than a twentieth of white in all are pale: their
  // colour per darkness is taken over that much darkness at least.
  const float floor_d = 0.05f * 9 * W;
  for (int y = 0; y < h; ++y) {
    const size_t a = static_cast<size_t>(std::max(y - 1, 0)) * w, o = static_cast<size_t>(y) * w,
                 c = static_cast<size_t>(std::min(y + 1, h - 1)) * w;
    uint8_t* q = out.ptr<uint8_t>(y);
    int x = 0;
#if CV_SIMD
    {
      constexpr int L = cv::v_uint8::nlanes, Q = cv::v_float32::nlanes;
      const cv::v_float32 vfloor = cv::vx_setall_f32(floor_d), kgb = cv::vx_setall_f32(0.114f / 0.587f),
                          kgr = cv::vx_setall_f32(0.299f / 0.587f);
      for (; x <= w - L; x += L) {
        cv::v_int32 ob[4], og[4], orr[4];
        for (int j = 0; j < 4; ++j) {
          const int at = x + j * Q;
          const cv::v_float32 sd = cv::v_max(cv::vx_load(HD + a + at) + cv::vx_load(HD + o + at) + cv::vx_load(HD + c + at), vfloor);
          const cv::v_float32 f = cv::vx_load(D + o + at) / sd;
          const cv::v_float32 cb = f * (cv::vx_load(HB + a + at) + cv::vx_load(HB + o + at) + cv::vx_load(HB + c + at));
          const cv::v_float32 cr = f * (cv::vx_load(HR + a + at) + cv::vx_load(HR + o + at) + cv::vx_load(HR + c + at));
          const cv::v_float32 yy = cv::vx_load(Y + o + at);
          ob[j] = cv::v_round(yy + cb);
          og[j] = cv::v_round(yy - cb * kgb - cr * kgr);
          orr[j] = cv::v_round(yy + cr);
        }
        const auto pack = [](const cv::v_int32* v) {
          return cv::v_pack_u(cv::v_pack(v[0], v[1]), cv::v_pack(v[2], v[3]));
        };
        cv::v_store_interleave(q + 3 * x, pack(ob), pack(og), pack(orr));
      }
    }
#endif
    for (; x < w; ++x) {
      const float f = D[o + x] / std::max(HD[a + x] + HD[o + x] + HD[c + x], floor_d);
      const float cb = f * (HB[a + x] + HB[o + x] + HB[c + x]), cr = f * (HR[a + x] + HR[o + x] + HR[c + x]);
      const float yy = Y[o + x];
      q[3 * x] = cv::saturate_cast<uint8_t>(yy + cb);
      q[3 * x + 1] = cv::saturate_cast<uint8_t>(yy - (0.114f * cb + 0.299f * cr) / 0.587f);
      q[3 * x + 2] = cv::saturate_cast<uint8_t>(yy + cr);
    }
  }
}

void saturationMask(const cv::Mat& bgr, const MaskThresholds& mt, cv::Mat& labels) {
  CV_Assert(bgr.type() == CV_8UC3);
  labels.create(bgr.size(), CV_8UC1);
  const int thr_b = thresholdQ8(mt.blue), thr_r = thresholdQ8(mt.red);
  const int vmin = std::clamp(mt.value_min, 0, 255);
  const bool wide = mt.wide_blue;
  const int w = bgr.cols;
  for (int y = 0; y < bgr.rows; ++y) {
    const uint8_t* src = bgr.ptr<uint8_t>(y);
    uint8_t* dst = labels.ptr<uint8_t>(y);
    int x = 0;
#if CV_SIMD
    {
      const int n = cv::v_uint8::nlanes;
      const cv::v_uint16 vthr_b = cv::vx_setall_u16(static_cast<uint16_t>(thr_b));
      const cv::v_uint16 vthr_r = cv::vx_setall_u16(static_cast<uint16_t>(thr_r));
      const cv::v_uint8 vvmin = cv::vx_setall_u8(static_cast<uint8_t>(vmin));
      const cv::v_uint8 one = cv::vx_setall_u8(kBlue), two = cv::vx_setall_u8(kRed);
      const cv::v_uint8 vwide = cv::vx_setall_u8(wide ? 255 : 0), vzero = cv::vx_setzero_u8();
      for (; x <= w - n; x += n) {
        cv::v_uint8 b, g, r;
        cv::v_load_deinterleave(src + 3 * x, b, g, r);
        const cv::v_uint8 mx = cv::v_max(cv::v_max(b, g), r);
        const cv::v_uint8 mn = cv::v_min(cv::v_min(b, g), r);
        const cv::v_uint8 c = mx - mn;
        cv::v_uint16 m0, m1;
        cv::v_expand(mx, m0, m1);
        // threshold * max in 8.8 fixed point, back to 8 bits, for either hue
        const cv::v_uint8 tb = cv::v_pack(cv::v_shr<8>(cv::v_mul_wrap(m0, vthr_b)),
                                          cv::v_shr<8>(cv::v_mul_wrap(m1, vthr_b)));
        const cv::v_uint8 tr = cv::v_pack(cv::v_shr<8>(cv::v_mul_wrap(m0, vthr_r)),
                                          cv::v_shr<8>(cv::v_mul_wrap(m1, vthr_r)));
        const cv::v_uint8 bright = mx >= vvmin;
        // blue: hue within 210..270 degrees, so cyan, teal and violet are not
        // blue (wide: anywhere blue is largest and above red)
        const cv::v_uint8 hue_ok = (((b - g) > (g - r)) & ((b - r) > (r - g))) | (vwide & ((b - r) > vzero));
        const cv::v_uint8 isb = (b == mx) & (c > tb) & bright & hue_ok;
        // red: hue below 30 degrees (r - g > g - b), so yellow and warm-lit white
        // are not red (printed red and its blend with the paper stay below 15)
        const cv::v_uint8 isr = (r == mx) & ~(b == mx) & (c > tr) & bright & ((r - g) > (g - b));
        cv::v_store(dst + x, (isb & one) | (isr & two));
      }
    }
#endif
    for (; x < w; ++x) {
      const int b = src[3 * x], g = src[3 * x + 1], r = src[3 * x + 2];
      const int mx = std::max({b, g, r}), mn = std::min({b, g, r});
      const int c = mx - mn;
      dst[x] = mx < vmin                                 ? kNone
               : b == mx ? (c > ((mx * thr_b) >> 8) && (wide ? b > r : b - g > std::max(0, g - r) && b - r > std::max(0, r - g))
                                ? kBlue : kNone)
               : r == mx ? (c > ((mx * thr_r) >> 8) && r - g > std::max(0, g - b) ? kRed : kNone)
                         : kNone;
    }
  }
}

namespace {

int findRoot(std::vector<RunScratch::Run>& runs, int i) {
  while (runs[i].parent != i) {
    runs[i].parent = runs[runs[i].parent].parent;
    i = runs[i].parent;
  }
  return i;
}

void unite(std::vector<RunScratch::Run>& runs, int a, int b) {
  a = findRoot(runs, a);
  b = findRoot(runs, b);
  if (a == b) return;
  if (a < b) runs[b].parent = a;
  else runs[a].parent = b;
}

// Sum of x^2 for x in [0, n].
inline int64_t sumSq(int64_t n) { return n * (n + 1) * (2 * n + 1) / 6; }

// The first x >= from where row[x] != v (w where there is none), eight
// labels at a time: the first differing byte of a word is its lowest
// nonzero byte after an xor with v in every byte (little-endian loads).
inline int runEnd(const uint8_t* row, int from, int w, uint8_t v) {
  const uint64_t all = 0x0101010101010101ull * v;
  int x = from;
  for (; x + 8 <= w; x += 8) {
    uint64_t word;
    std::memcpy(&word, row + x, 8);
    if (const uint64_t diff = word ^ all) {
      if constexpr (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__) return x + __builtin_ctzll(diff) / 8;
      break;
    }
  }
  while (x < w && row[x] == v) ++x;
  return x;
}

}  // namespace

void extractRegions(const cv::Mat& labels, const cv::Mat& bgr, const MaskThresholds& mt, int min_area,
                    int max_area, double min_fill, RunScratch& scratch, std::vector<Region>& out) {
  CV_Assert(labels.type() == CV_8UC1 && bgr.type() == CV_8UC3 && labels.size() == bgr.size());
  out.clear();
  auto& runs = scratch.runs;
  runs.clear();
  const int w = labels.cols, h = labels.rows;

  // Runs of each row, united with the previous row's.
  int prev_begin = 0, prev_end = 0;
  for (int y = 0; y < h; ++y) {
    const uint8_t* L = labels.ptr<uint8_t>(y);
    const int cur_begin = static_cast<int>(runs.size());
    int x = 0;
    while (x < w) {
      x = runEnd(L, x, w, kNone);  // the background before the run
      if (x >= w) break;
      const uint8_t c = L[x];
      const int x0 = x;
      x = runEnd(L, x, w, c);
      runs.push_back({y, x0, x - 1, c, static_cast<int>(runs.size())});
    }
    const int cur_end = static_cast<int>(runs.size());
    // 4-connected union with the previous row's runs of the same colour (8
    // would join a square to the background through single blurred corners).
    int j = prev_begin;
    for (int i = cur_begin; i < cur_end; ++i) {
      const int x0 = runs[i].x0, x1 = runs[i].x1;
      while (j < prev_end && runs[j].x1 < x0) ++j;
      for (int k = j; k < prev_end && runs[k].x0 <= x1; ++k)
        if (runs[k].colour == runs[i].colour) unite(runs, i, k);
    }
    prev_begin = cur_begin;
    prev_end = cur_end;
  }

  // Area moments of every region from its runs (closed forms, no pixels).
  using Acc = RunScratch::Acc;
  auto& acc = scratch.acc;
  acc.clear();
  auto& region_of = scratch.region_of;
  region_of.resize(runs.size());
  for (int i = 0; i < static_cast<int>(runs.size()); ++i) {
    const auto& run = runs[i];
    const int root = findRoot(runs, i);
    if (root == i) {
      region_of[i] = static_cast<int>(acc.size());
      Acc a;
      a.x0 = run.x0, a.x1 = run.x1, a.y0 = run.y, a.y1 = run.y, a.colour = run.colour;
      acc.push_back(a);
    } else {
      region_of[i] = region_of[root];  // root < i: already set
    }
    Acc& a = acc[region_of[i]];
    const int64_t n = run.x1 - run.x0 + 1;
    const int64_t sx = n * (run.x0 + run.x1) / 2;  // n*(x0+x1) is always even
    a.n += n;
    a.sx += sx;
    a.sy += n * run.y;
    a.sxx += sumSq(run.x1) - (run.x0 > 0 ? sumSq(run.x0 - 1) : 0);
    a.syy += n * run.y * run.y;
    a.sxy += sx * run.y;
    a.x0 = std::min(a.x0, run.x0);
    a.x1 = std::max(a.x1, run.x1);
    a.y1 = std::max(a.y1, run.y);
  }

  // Regions of a square's size and shape; then their pixels: weighted
  // centroid and channel sums.
  auto& keep = scratch.keep;
  keep.assign(acc.size(), -1);
  for (int k = 0; k < static_cast<int>(acc.size()); ++k) {
    const Acc& a = acc[k];
    if (a.n < min_area || a.n > max_area) continue;
    Region r;
    r.colour = a.colour;
    r.x0 = a.x0, r.y0 = a.y0, r.x1 = a.x1, r.y1 = a.y1;
    r.area = static_cast<int>(a.n);
    const double n = static_cast<double>(a.n);
    const double mx = a.sx / n, my = a.sy / n;
    // + 1/12: a pixel's own extent, so a filled n x n block has the moments of an n x n square.
    r.sxx = a.sxx / n - mx * mx + 1.0 / 12;
    r.syy = a.syy / n - my * my + 1.0 / 12;
    r.sxy = a.sxy / n - mx * my;
    r.cx = mx, r.cy = my;
    r.n_sum = n;
    if (fill(r) < min_fill) continue;
    keep[k] = static_cast<int>(out.size());
    out.push_back(r);
  }
  if (out.empty()) return;
  auto& sums = scratch.sums;
  sums.assign(out.size(), {});
  const int thr_b = thresholdQ8(mt.blue), thr_r = thresholdQ8(mt.red);
#if CV_SIMD
  const int simd_n = cv::v_uint8::nlanes;
  const cv::v_uint16 vthr_b = cv::vx_setall_u16(static_cast<uint16_t>(thr_b));
  const cv::v_uint16 vthr_r = cv::vx_setall_u16(static_cast<uint16_t>(thr_r));
  const cv::v_uint8 ones = cv::vx_setall_u8(1);
  alignas(64) uint8_t lane_index[cv::v_uint8::nlanes];
  for (int i = 0; i < simd_n; ++i) lane_index[i] = static_cast<uint8_t>(i);
  const cv::v_uint8 lane = cv::vx_load_aligned(lane_index);
#endif
  for (int i = 0; i < static_cast<int>(runs.size()); ++i) {
    const int k = keep[region_of[i]];
    if (k < 0) continue;
    const auto& run = runs[i];
    const int thr = run.colour == kBlue ? thr_b : thr_r;
    const uint8_t* src = bgr.ptr<uint8_t>(run.y);
    int64_t sw = 0, swx = 0, sb = 0, sg = 0, sr = 0;
    int x = run.x0;
#if CV_SIMD
    // Vectors of the run as the loop below does it, in integers: the same
    // sums. Lanes past the run's end (still in the row) are masked out;
    // wt: a saturating c - t is 0 where c - t is negative.
    for (; x <= run.x1 && x + simd_n <= w; x += simd_n) {
      const cv::v_uint8 in_run = lane < cv::vx_setall_u8(static_cast<uint8_t>(std::min(run.x1 - x + 1, simd_n)));
      cv::v_uint8 b, g, r;
      cv::v_load_deinterleave(src + 3 * x, b, g, r);
      b &= in_run, g &= in_run, r &= in_run;
      const cv::v_uint8 mx = cv::v_max(cv::v_max(b, g), r), mn = cv::v_min(cv::v_min(b, g), r);
      cv::v_uint16 m0, m1;
      cv::v_expand(mx, m0, m1);
      const cv::v_uint16 vthr = run.colour == kBlue ? vthr_b : vthr_r;
      const cv::v_uint8 t = cv::v_pack(cv::v_shr<8>(cv::v_mul_wrap(m0, vthr)), cv::v_shr<8>(cv::v_mul_wrap(m1, vthr)));
      const cv::v_uint8 wt = cv::v_max((mx - mn) - t, ones) & in_run;
      const int64_t w_sum = cv::v_reduce_sum(cv::v_dotprod_expand(wt, ones));
      sw += w_sum;
      swx += w_sum * x + cv::v_reduce_sum(cv::v_dotprod_expand(wt, lane));
      sb += cv::v_reduce_sum(cv::v_dotprod_expand(b, ones));
      sg += cv::v_reduce_sum(cv::v_dotprod_expand(g, ones));
      sr += cv::v_reduce_sum(cv::v_dotprod_expand(r, ones));
    }
#endif
    for (; x <= run.x1; ++x) {
      const int b = src[3 * x], g = src[3 * x + 1], r = src[3 * x + 2];
      const int mx = std::max({b, g, r}), mn = std::min({b, g, r});
      const int wt = std::max(1, (mx - mn) - ((mx * thr) >> 8));
      sw += wt;
      swx += static_cast<int64_t>(wt) * x;
      sb += b, sg += g, sr += r;
    }
    auto& s = sums[k];
    s.w += sw, s.wx += swx, s.wy += sw * run.y, s.b += sb, s.g += sg, s.r += sr;
  }
  for (size_t k = 0; k < out.size(); ++k) {
    const auto& s = sums[k];
    Region& r = out[k];
    r.cx = static_cast<double>(s.wx) / static_cast<double>(s.w);
    r.cy = static_cast<double>(s.wy) / static_cast<double>(s.w);
    r.sum_b = static_cast<double>(s.b);
    r.sum_g = static_cast<double>(s.g);
    r.sum_r = static_cast<double>(s.r);
  }
}

namespace {

inline int hueExcess(const uint8_t* px, uint8_t colour) {
  const int b = px[0], g = px[1], r = px[2];
  return colour == kBlue ? b - std::max(g, r) : r - std::max(g, b);
}

}  // namespace

void saturationImage(const cv::Mat& bgr, cv::Mat& sat) {
  CV_Assert(bgr.type() == CV_8UC3);
  sat.create(bgr.size(), CV_8UC1);
  for (int y = 0; y < bgr.rows; ++y) {
    const uint8_t* src = bgr.ptr<uint8_t>(y);
    uint8_t* dst = sat.ptr<uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      const int b = src[3 * x], g = src[3 * x + 1], r = src[3 * x + 2];
      const int mx = std::max({b, g, r}), mn = std::min({b, g, r});
      dst[x] = mx ? static_cast<uint8_t>((255 * (mx - mn) + mx / 2) / mx) : 0;
    }
  }
}

void contourRegions(const cv::Mat& edges, const cv::Mat& bgr, int min_area, int max_area,
                    std::vector<std::vector<cv::Point>>& contours, std::vector<Region>& out) {
  out.clear();
  contours.clear();
  cv::findContours(edges, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  for (const auto& c : contours) {
    const cv::Rect rect = cv::boundingRect(c);
    const int area = rect.area();
    if (area < min_area || area > max_area) continue;
    Region r;
    r.x0 = rect.x, r.y0 = rect.y, r.x1 = rect.x + rect.width - 1, r.y1 = rect.y + rect.height - 1;
    r.area = area;
    r.cx = rect.x + (rect.width - 1) / 2.0;
    r.cy = rect.y + (rect.height - 1) / 2.0;
    // The rectangle's own moments: the paper's per-axis size constraints.
    r.sxx = rect.width * rect.width / 12.0;
    r.syy = rect.height * rect.height / 12.0;
    r.sxy = 0;
    const cv::Scalar s = cv::sum(bgr(rect));
    r.sum_b = s[0], r.sum_g = s[1], r.sum_r = s[2];
    r.n_sum = area;
    r.colour = r.sum_b >= r.sum_r ? kBlue : kRed;
    out.push_back(r);
  }
}

// ====================================================================== colour

bool isFip(const Region& r, double a, double b) {
  return r.sum_b > a * r.sum_r && r.sum_b > b * r.sum_g;
}

double fill(const Region& r) {
  const double s = r.side();
  return s > 0 ? r.area / (s * s) : 0.0;
}

bool isAp(const Region& r, double a, double b) {
  return r.sum_r > a * r.sum_b && r.sum_r > b * r.sum_g;
}

// ====================================================================== geometry

double normalisedDistance(const Region& a, const Region& b) {
  Sym2 m;
  if (!metric(mean(moments(a), moments(b)), m)) return -1.0;
  return std::sqrt(quad(m, a.cx - b.cx, a.cy - b.cy));
}

bool fipEdge(const Region& a, const Region& b, const DetectorParams& p) {
  const double wr2 = a.sxx / b.sxx, hr2 = a.syy / b.syy;
  if (wr2 < p.w_min * p.w_min || wr2 > p.w_max * p.w_max) return false;
  if (hr2 < p.h_min * p.h_min || hr2 > p.h_max * p.h_max) return false;
  const double d = normalisedDistance(a, b);
  return d >= p.d_min && d <= p.d_max;
}

void threeCycles(const std::vector<uint8_t>& adj, int n, std::vector<std::array<int, 3>>& out, size_t max_out) {
  out.clear();
  for (int i = 0; i < n; ++i) {
    const uint8_t* ai = &adj[static_cast<size_t>(i) * n];
    for (int j = i + 1; j < n; ++j) {
      if (!ai[j]) continue;
      const uint8_t* aj = &adj[static_cast<size_t>(j) * n];
      for (int k = j + 1; k < n; ++k)
        if (ai[k] && aj[k]) {
          if (out.size() >= max_out) return;
          out.push_back({i, j, k});
        }
    }
  }
}

void RegionIndex::build(const std::vector<Region>& regions) {
  order.resize(regions.size());
  for (size_t k = 0; k < regions.size(); ++k) order[k] = static_cast<int>(k);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return regions[a].cx < regions[b].cx; });
  xs.resize(regions.size());
  for (size_t k = 0; k < order.size(); ++k) xs[k] = regions[order[k]].cx;
}

namespace {
// The moments' eigenvalues as their mean t and half difference d (lambda = t +- d).
void eigenMeanAndHalfDiff(const Region& r, double& t, double& d) {
  t = (r.sxx + r.syy) / 2;
  d = std::sqrt(std::max(0.0, (r.sxx - r.syy) * (r.sxx - r.syy) / 4 + r.sxy * r.sxy));
}
}  // namespace

double maxAxis(const Region& r) {
  double t, d;
  eigenMeanAndHalfDiff(r, t, d);
  return std::sqrt(12.0 * (t + d));
}

double minAxis(const Region& r) {
  double t, d;
  eigenMeanAndHalfDiff(r, t, d);
  return std::sqrt(12.0 * std::max(0.0, t - d));
}

bool rightIsosceles(const std::array<int, 3>& cyc, const std::vector<Region>& fips, double tol, int* corner) {
  // d[k]: the side opposite vertex k.
  const double d[3] = {normalisedDistance(fips[cyc[1]], fips[cyc[2]]),
                       normalisedDistance(fips[cyc[0]], fips[cyc[2]]),
                       normalisedDistance(fips[cyc[0]], fips[cyc[1]])};
  const int k = d[0] >= d[1] ? (d[0] >= d[2] ? 0 : 2) : (d[1] >= d[2] ? 1 : 2);
  const double a = d[(k + 1) % 3], b = d[(k + 2) % 3];
  if (!(a > 0 && b > 0)) return false;
  const double r1 = d[k] / std::sqrt(2.0 * a * b), r2 = a / b;
  if (corner) *corner = k;
  return r1 < tol && r1 > 1 / tol && r2 < tol && r2 > 1 / tol;
}

void apChoices(const std::array<int, 3>& cycle, const std::vector<Region>& fips, const std::vector<Region>& aps,
               const DetectorParams& p, std::vector<Candidate>& out, const RegionIndex* ap_index, size_t max_out) {
  out.clear();
  const Region& f0 = fips[cycle[0]];
  const Region& f1 = fips[cycle[1]];
  const Region& f2 = fips[cycle[2]];
  Sym2 s{(f0.sxx + f1.sxx + f2.sxx) / 3, (f0.sxy + f1.sxy + f2.sxy) / 3, (f0.syy + f1.syy + f2.syy) / 3};
  Sym2 m;
  if (!metric(s, m)) return;
  const double fip_side = std::sqrt(12.0 * std::sqrt(s.det()));
  // For the prediction with the perspective the squares' sizes show: a
  // homography's denominator w is affine on the sheet, so w_AP = w_a + w_b -
  // w_c, and a square's side in the image goes as w^(-3/2) (its area as w^-3).
  double w[3];
  for (int k = 0; k < 3; ++k) w[k] = std::pow(std::max(fips[cycle[k]].side(), 1.0), -2.0 / 3);
  for (int corner = 0; corner < 3; ++corner) {
    const Region& c = fips[cycle[corner]];
    const Region& a = fips[cycle[(corner + 1) % 3]];
    const Region& b = fips[cycle[(corner + 2) % 3]];
    const double px = a.cx + b.cx - c.cx, py = a.cy + b.cy - c.cy;
    const double wc = w[corner], wa = w[(corner + 1) % 3], wb = w[(corner + 2) % 3];
    const double w_ap = wa + wb - wc;
    const bool perspective = w_ap > 0.25 * std::min({wa, wb, wc});
    const double qx = perspective ? (wa * a.cx + wb * b.cx - wc * c.cx) / w_ap : px;
    const double qy = perspective ? (wa * a.cy + wb * b.cy - wc * c.cy) / w_ap : py;
    const bool clockwise = cross(centre(a) - centre(c), centre(b) - centre(c)) > 0;
    auto consider = [&](int k) {
      const Region& ap = aps[k];
      const double e = std::min(std::sqrt(quad(m, ap.cx - px, ap.cy - py)), std::sqrt(quad(m, ap.cx - qx, ap.cy - qy)));
      if (e >= p.ap_max_offset) return;
      const double ratio = ap.side() / fip_side;
      if (ratio < p.ap_size_min || ratio > p.ap_size_max) return;
      Candidate cand;
      cand.tl = cycle[corner];
      cand.tr = clockwise ? cycle[(corner + 1) % 3] : cycle[(corner + 2) % 3];
      cand.bl = clockwise ? cycle[(corner + 2) % 3] : cycle[(corner + 1) % 3];
      cand.ap = k;
      cand.error = e / p.ap_max_offset;
      out.push_back(cand);
    };
    if (ap_index) {
      // |d| <= offset / sqrt(lambda_min(M)) = offset * sqrt(12 lambda_max(S)).
      Region mean_fip;
      mean_fip.sxx = s.xx, mean_fip.sxy = s.xy, mean_fip.syy = s.yy;
      // Each AP once, from a window around both predictions.
      const double r = p.ap_max_offset * maxAxis(mean_fip);
      const double half_x = std::abs(qx - px) / 2, half_y = std::abs(qy - py) / 2;
      ap_index->near(aps, (px + qx) / 2, (py + qy) / 2, r + std::max(half_x, half_y), consider);
    } else {
      for (int k = 0; k < static_cast<int>(aps.size()); ++k) consider(k);
    }
  }
  // Nearest first (ties: lower indices), at most max_out.
  std::sort(out.begin(), out.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.error, a.tl, a.ap) < std::tie(b.error, b.tl, b.ap);
  });
  if (out.size() > max_out) out.resize(max_out);
}

bool chooseAp(const std::array<int, 3>& cycle, const std::vector<Region>& fips,
              const std::vector<Region>& aps, const DetectorParams& p, Candidate& out,
              const RegionIndex* ap_index) {
  std::vector<Candidate> choices;
  apChoices(cycle, fips, aps, p, choices, ap_index, 1);
  if (choices.empty()) return false;
  out = choices[0];
  return true;
}

bool bestVerifiedChoice(const std::array<int, 3>& cycle, const std::vector<Region>& fips,
                        const std::vector<Region>& aps, const cv::Mat& bgr, const DetectorParams& p,
                        std::vector<Candidate>& choices, Candidate& out, const RegionIndex* ap_index,
                        bool glare_corrected) {
  apChoices(cycle, fips, aps, p, choices, ap_index);
  int best = -1;
  for (int k = 0; k < static_cast<int>(choices.size()); ++k)
    if (verify(choices[k], fips, aps, bgr, p, nullptr, glare_corrected) &&
        (best < 0 || choices[k].error < choices[best].error))
      best = k;
  if (best < 0) return false;
  out = choices[best];
  return true;
}

const char* checkName(Check check) {
  switch (check) {
    case Check::kNoAp: return "no AP";
    case Check::kNotConvex: return "not convex";
    case Check::kDegenerateMoments: return "degenerate moments";
    case Check::kSideLength: return "side length";
    case Check::kSideRatio: return "side ratio";
    case Check::kAngle: return "angle";
    case Check::kDegenerateSquare: return "degenerate square";
    case Check::kSquareAnisotropic: return "square anisotropic";
    case Check::kSquareScale: return "square scale";
    case Check::kSquareSize: return "square size";
    case Check::kOutsideImage: return "outside the image";
    case Check::kSheetSaturated: return "sheet saturated";
    case Check::kSheetDark: return "sheet dark";
    case Check::kSheetUneven: return "sheet uneven";
    case Check::kNoQr: return "no QR";
    case Check::kCentreSaturated: return "centre saturated";
    case Check::kCentreColoured: return "centre coloured";
    case Check::kCover: return "cover";
    case Check::kSquareAtCentre: return "square at the centre";
    case Check::kOtherSquares: return "other squares";
    case Check::kCount: break;
  }
  return "?";
}

namespace {

// A hue in degrees (0 red, 120 green, 240 blue) of a BGR colour.
double hueDegrees(const double c[3]) {
  const double b = c[0], g = c[1], r = c[2];
  const double mx = std::max({b, g, r}), mn = std::min({b, g, r});
  if (!(mx > mn)) return 0;
  double h = mx == r ? 60 * (g - b) / (mx - mn) : mx == g ? 120 + 60 * (b - r) / (mx - mn) : 240 + 60 * (r - g) / (mx - mn);
  return h < 0 ? h + 360 : h;
}

// One saturated spot on the sheet is tolerated in these hues (yellow to
// cyan: a sticker, a highlighter's mark), none that printed or lit inks,
// posters and look-alikes take (blue, violet, magenta, red, orange).
constexpr double kSpotHueMin = 40, kSpotHueMax = 180;

// Under a shadow across the sheet, the paper beside each FIP is at least
// this much brighter than the FIP (the sheet's evenness no longer says much).
constexpr double kShadedPaperOverInk = 1.3;
// ... unless the paper is at the sensor's clip, where the ratio is lost
// (the adaptive gains lift lit paper and ink alike): there, brighter at all.
constexpr double kClippedValue = 250;

// The paper's value under `over` times the ink's: a sheet too dark for its
// squares. Not where both are at the clip, where the sensor tells neither
// brighter (the artwork's pure blue, #0000FF, on a screen, a scan or its
// own PNG is as bright as the paper: a sample of 254 against 255 was dark).
bool darkerThanInk(double paper, double over, double ink) {
  return paper < over * ink && !(paper >= kClippedValue && ink >= kClippedValue);
}

// A light that falls off across the sheet (a lamp beside a pillar the
// landmark is wrapped round, or close to the wall): the samples' brightness
// `v` at image positions `at` lies on a plane over the image, every sample
// within this fraction of the plane's brightest ...
constexpr double kSmoothLightFit = 0.1;
// ... and the plane over the samples never under this fraction of its
// brightest.
constexpr double kSmoothLightMin = 0.25;

// The least-squares plane (v = a + b x + c y, in `plane`) of the samples
// when they lie on one as above.
bool smoothLight(const std::array<cv::Point2d, 12>& at, const std::array<double, 12>& v, cv::Vec3d& plane) {
  // the normal equations, about the samples' mean position (well conditioned)
  cv::Point2d mid(0, 0);
  for (const auto& q : at) mid += q * (1.0 / 12);
  cv::Matx33d AtA = cv::Matx33d::zeros();
  cv::Vec3d Atb(0, 0, 0);
  for (int j = 0; j < 12; ++j) {
    const cv::Vec3d row(1, at[j].x - mid.x, at[j].y - mid.y);
    AtA += row * row.t();
    Atb += row * v[j];
  }
  cv::Vec3d x;
  if (!cv::solve(AtA, Atb, x, cv::DECOMP_LU)) return false;
  plane = cv::Vec3d(x[0] - x[1] * mid.x - x[2] * mid.y, x[1], x[2]);
  double lo = HUGE_VAL, hi = -HUGE_VAL, worst = 0;
  for (int j = 0; j < 12; ++j) {
    const double fit = plane[0] + plane[1] * at[j].x + plane[2] * at[j].y;
    lo = std::min(lo, fit), hi = std::max(hi, fit);
    worst = std::max(worst, std::abs(v[j] - fit));
  }
  return hi > 0 && lo >= kSmoothLightMin * hi && worst <= kSmoothLightFit * hi;
}

// The sheet's samples `m` (in order around it) even (every one at least
// `uniformity` of the brightest: none shaded), or in a light part and a
// dark part, each even, the dark one a single run of neighbours around the
// sheet, as a straight shadow edge makes (it crosses the sheet's outline
// twice), or two runs apart, as a band of shadow across the sheet makes (a
// pole's or a cable's: it crosses the outline four times), with a sample
// on the edge itself, between the two, allowed at either end of a run: the
// runs' samples are shaded, each run holding a dark one (not edge samples
// alone: a lone grey sample is no band's). `runs`: how many (0 when even);
// `run_of`: each sample's run (1 or 2; 0 light).
bool sheetLight(const std::array<double, 12>& m, double uniformity, std::array<int, 12>& run_of, int& runs) {
  run_of.fill(0);
  runs = 0;
  const auto [lo, hi] = std::minmax_element(m.begin(), m.end());
  if (*lo >= uniformity * *hi) return true;
  enum { kLight, kDark, kEdge };
  std::array<int, 12> part;
  for (int j = 0; j < 12; ++j) part[j] = m[j] >= uniformity * *hi ? kLight : m[j] * uniformity <= *lo ? kDark : kEdge;
  // Runs of samples that are not light, edge samples only at their ends.
  for (int j = 0; j < 12; ++j) {
    if (part[j] == kLight || part[(j + 11) % 12] != kLight) continue;
    ++runs;
    int len = 0;
    bool dark = false;
    while (part[(j + len) % 12] != kLight) ++len;
    for (int k = 0; k < len; ++k) {
      const int i = (j + k) % 12;
      if (part[i] == kEdge && k > 0 && k + 1 < len) return false;
      dark |= part[i] == kDark;
      run_of[i] = runs;
    }
    if (!dark) return false;
  }
  return runs == 1 || runs == 2;
}

// The sheet's side means `side` from its samples' means (side i: samples
// 3i..3i+2), and the pair of opposite sides (0: sides 0 and 2, 1: sides 1
// and 3) both darker than both of the other pair by kBandSides: a band
// across the sheet. -1 when none is.
int bandPair(const std::array<double, 12>& means, std::array<double, 4>& side) {
  for (int i = 0; i < 4; ++i) side[i] = (means[3 * i] + means[3 * i + 1] + means[3 * i + 2]) / 3;
  for (int a : {0, 1})
    if (std::max(side[a], side[a + 2]) < kBandSides * std::min(side[a + 1], side[(a + 3) % 4])) return a;
  return -1;
}

// The samples `m` (in order around the sheet) dip in the middle of every
// side: the crossing of the gaps between four sheets (kGapDip).
bool crossOfGaps(const std::array<double, 12>& m) {
  for (int i = 0; i < 4; ++i)
    if (!(m[3 * i + 1] < kGapDip * std::min(m[3 * i], m[3 * i + 2]))) return false;
  return true;
}

// The sheet's light by its samples' means and values (brightest channels)
// against the squares' values (`fip_value` the FIPs' mean): even, or a
// shadow's two parts, or a band of shadow across it (sheetLight).
// Check::kCount where it passes, else the check that refuses it.
Check sheetLit(const std::array<double, 12>& means, const std::array<double, 12>& values, const double square_value[4],
               double fip_value, const DetectorParams& p) {
  std::array<int, 12> run_of;
  int runs = 0;
  if (!sheetLight(means, p.sheet_uniformity, run_of, runs)) return Check::kSheetUneven;
  if (runs == 0) {
    for (double v : values)
      if (darkerThanInk(v, p.sheet_min_value, fip_value)) return Check::kSheetDark;
    return Check::kCount;
  }
  bool fip_in_shadow = false;
  bool run_holds_square[3] = {false, false, false};  // by run (1, 2)
  for (int i : {0, 1, 2, 3}) {
    const int a = 3 * i, b = (3 * i + 11) % 12;  // its two nearest samples
    if (run_of[a] && run_of[a] == run_of[b]) run_holds_square[run_of[a]] = true;
    if (i == 2) continue;  // (the AP: no FIP's ink to hold the paper to)
    fip_in_shadow |= run_of[a] && run_of[b];
    const double paper = (run_of[a] != 0) == (run_of[b] != 0) ? std::min(values[a], values[b]) : std::max(values[a], values[b]);
    const double over = paper >= kClippedValue ? p.sheet_min_value : std::max(p.sheet_min_value, kShadedPaperOverInk);
    if (darkerThanInk(paper, over, square_value[i])) return Check::kSheetDark;
  }
  // A shadow over a FIP; with two runs, each over a square (a band across
  // two opposite corners).
  if (fip_in_shadow && (runs == 1 || (run_holds_square[1] && run_holds_square[2]))) return Check::kCount;
  // A band between the squares, none of them in it: across the middle, two
  // opposite sides in it (verify then holds the QR to the band's paper).
  if (runs == 2) {
    std::array<double, 4> side;
    if (bandPair(means, side) >= 0) return Check::kCount;
    // ... or at a slant through the middle, crossing two opposite sides
    // near their ends: each run within one side, the two sides opposite,
    // the runs where the band's straight course through the middle puts
    // them (each the other turned by half a turn about the middle: a
    // pattern's dark cells, a QR's modules, fall anywhere).
    int side_of[3] = {-1, -1, -1};
    bool within[3] = {true, true, true};
    for (int j = 0; j < 12; ++j) {
      const int r = run_of[j];
      if (!r) continue;
      if (side_of[r] < 0) side_of[r] = j / 3;
      within[r] &= side_of[r] == j / 3;
    }
    bool symmetric = true;  // through the middle: each run the other turned by half a turn
    for (int j = 0; j < 12; ++j) symmetric &= (run_of[j] != 0) == (run_of[(j + 6) % 12] != 0);
    if (within[1] && within[2] && symmetric && side_of[2] == (side_of[1] + 2) % 4) return Check::kCount;
  }
  return Check::kSheetUneven;
}

}  // namespace

bool verify(Candidate& c, const std::vector<Region>& fips, const std::vector<Region>& aps,
            const cv::Mat& bgr, const DetectorParams& p, Check* why, bool glare_corrected) {
  auto fail = [&](Check reason) {
    if (why) *why = reason;
    return false;
  };
  const Region* sq[4] = {&fips[c.tl], &fips[c.tr], &aps[c.ap], &fips[c.bl]};  // clockwise
  const cv::Point2d P[4] = {centre(*sq[0]), centre(*sq[1]), centre(*sq[2]), centre(*sq[3])};
  // Convex, clockwise in the image.
  for (int i = 0; i < 4; ++i)
    if (!(cross(P[(i + 1) % 4] - P[i], P[(i + 2) % 4] - P[(i + 1) % 4]) > 0)) return fail(Check::kNotConvex);

  // Layout in the frame of the squares' moments: a square of side 3.
  Sym2 s;
  for (const Region* r : sq) {
    s.xx += r->sxx / 4;
    s.xy += r->sxy / 4;
    s.yy += r->syy / 4;
  }
  Sym2 m;
  if (!metric(s, m)) return fail(Check::kDegenerateMoments);
  const cv::Point2d e1 = P[1] - P[0], e2 = P[3] - P[0];
  const cv::Point2d e3 = P[2] - P[1], e4 = P[2] - P[3];
  const double l1 = std::sqrt(quad(m, e1.x, e1.y)), l2 = std::sqrt(quad(m, e2.x, e2.y));
  const double l3 = std::sqrt(quad(m, e3.x, e3.y)), l4 = std::sqrt(quad(m, e4.x, e4.y));
  const double cosang = bilin(m, e1.x, e1.y, e2.x, e2.y) / (l1 * l2);
  const double tol = p.shape_tolerance;
  const double lmin = std::min({l1, l2, l3, l4}), lmax = std::max({l1, l2, l3, l4});
  if (lmin < p.d_min || lmax > p.d_max) return fail(Check::kSideLength);
  if (lmax > lmin * (1 + tol)) return fail(Check::kSideRatio);
  if (std::abs(cosang) > tol) return fail(Check::kAngle);

  // Each square as the centres predict it: a square of the landmark's frame
  // (not a bar or a stripe), of a plausible size.
  for (const Region* r : sq) {
    double scale, aniso;
    if (!squareConsistency(*r, e1, e2, scale, aniso)) return fail(Check::kDegenerateSquare);
    if (aniso > anisotropyLimit(p.max_anisotropy, r->area)) return fail(Check::kSquareAnisotropic);
    if (scale < p.square_scale_min || scale > p.square_scale_max) return fail(Check::kSquareScale);
  }
  // Sizes: every square within the AP size gates of the FIPs' mean side.
  const double side = std::sqrt(12.0 * std::sqrt(s.det()));
  for (const Region* r : sq) {
    const double ratio = r->side() / side;
    if (ratio < p.ap_size_min || ratio > p.ap_size_max) return fail(Check::kSquareSize);
  }

  // White, unsaturated sheet between the squares, and no colour at the centre.
  double fip_value = 0, square_value[4];
  for (int i = 0; i < 4; ++i) {
    const Region& r = *sq[i];
    square_value[i] = std::max({r.sum_b, r.sum_g, r.sum_r}) / std::max(1.0, r.n_sum);
    if (i != 2) fip_value += square_value[i] / 3;
  }
  // Three points on each side between the squares (a third, half and two
  // thirds of the way from one centre to the next: white paper between the
  // squares' edges at a sixth and five sixths).
  double sheet_bgr[3] = {0, 0, 0};
  std::array<double, 12> means, values;  // around the sheet, side by side
  std::array<cv::Point2d, 12> sample_at;
  int saturated_at = -1;
  for (int i = 0; i < 4; ++i)
    for (int k = 0; k < 3; ++k) {
      double sv, vv, mean;
      double c[3];
      const int j = 3 * i + k;
      sample_at[j] = P[i] + (P[(i + 1) % 4] - P[i]) * ((k + 2) / 6.0);
      if (!sampleSV(bgr, sample_at[j], sv, vv, &mean, c)) return fail(Check::kOutsideImage);
      if (sv > p.sheet_max_saturation) {
        // One spot of colour on the sheet (a sticker, a highlighter's mark)
        // stands aside, its neighbours speak for it; not in the inks' hues,
        // which look-alikes on coloured surfaces bring onto their "sheet".
        const double hue = hueDegrees(c);
        if (saturated_at >= 0 || hue < kSpotHueMin || hue > kSpotHueMax) return fail(Check::kSheetSaturated);
        saturated_at = j;
        continue;
      }
      for (int ch = 0; ch < 3; ++ch) sheet_bgr[ch] += c[ch] / 12;
      means[j] = mean;
      values[j] = vv;
    }
  if (saturated_at >= 0) {
    for (double& v : sheet_bgr) v *= 12.0 / 11;
    const int a = (saturated_at + 11) % 12, b = (saturated_at + 1) % 12;
    means[saturated_at] = (means[a] + means[b]) / 2;
    values[saturated_at] = (values[a] + values[b]) / 2;
  }
  double sheet_mean = 0;
  for (double v : means) sheet_mean += v / 12;
  // Even, or in two even parts, the darker one a shadow's: a single run of
  // neighbouring samples around the sheet (sheetLight). The paper is
  // brighter than the blue ink in the same light: every sample than the
  // FIPs, or under a shadow, each FIP's two nearest samples (the brighter of
  // them where the shadow's edge runs between) clearly brighter than the FIP
  // (kShadedPaperOverInk: printed blue's brightest channel is about half the
  // paper's), with at least one FIP in the shadow (a dark surface half under
  // a look-alike's squares, none of them on it, is not one; nor are a
  // letter's strokes with pieces of them for squares).
  // A light falling off smoothly across the sheet (smoothLight) is neither:
  // where those refuse it, the paper where each FIP lies, by the light's
  // plane, is as clearly brighter than the FIP.
  if (crossOfGaps(means)) return fail(Check::kSheetUneven);
  const Check lit = sheetLit(means, values, square_value, fip_value, p);
  if (lit != Check::kCount) {
    cv::Vec3d plane;
    if (!smoothLight(sample_at, values, plane)) return fail(lit);
    for (int i : {0, 1, 3})
      if (plane[0] + plane[1] * P[i].x + plane[2] * P[i].y < kShadedPaperOverInk * square_value[i]) return fail(lit);
  }
  // The QR: its square is darker than the sheet (black modules, or grey when
  // they are too small to resolve). A 5 x 5 grid over its middle, placed by
  // the affine frame of TL, TR, BL.
  {
    const cv::Point2d ex = (P[1] - P[0]) * (1.0 / 6), ey = (P[3] - P[0]) * (1.0 / 6);
    const double sheet_max = *std::max_element(means.begin(), means.end());
    double qr_mean = 0, grey_mean = 0;
    std::array<double, 25> grey_points{};  // the grey points' brightness, `grey` of them
    int dark = 0, glared = 0, grey = 0;
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i) {
        const double u = 3.1 + 0.7 * i - 1.5, v = 3.1 + 0.7 * j - 1.5;
        double sv, vv, b;
        if (!sampleSV(bgr, P[0] + ex * u + ey * v, sv, vv, &b)) return fail(Check::kOutsideImage);
        qr_mean += b / 25;
        if (sv > p.sheet_max_saturation) continue;  // (a coloured point: the mean's only)
        grey_mean += b;
        grey_points[static_cast<size_t>(grey++)] = b;
        dark += b < p.qr_dark_sample * sheet_mean;
        glared += b > kGlaredOverSheet * sheet_max;
      }
    // A sheet at the sensor's white clip (glare) hides the QR's white
    // modules and lifts its mean: there its dark modules are the evidence;
    // so they are where a reflection lies on the QR alone (a glossy sheet's:
    // points of it brighter than any of the sheet's).
    const bool clipped = sheet_mean >= kClippedSheet || glared >= kGlaredSamples;
    // A clipped sheet is brighter than it reads, by how much no one knows:
    // there a QR of grey points (kClippedQrGrey of the 25 or more: not a
    // coloured thing's) may read up to qr_clipped_max_brightness of it.
    const bool washed = clipped && grey >= kClippedQrGrey &&
                        grey_mean / grey <= p.qr_clipped_max_brightness * sheet_mean;
    // A hot spot's peak on the QR of a sheet it clipped all round lifts the
    // QR's grey to the sheet's and beyond: its dark modules are then grey
    // points a few levels under the brightest (a blank middle at the clip
    // is flat). Only in frames with a strong veil taken out: a bright wall
    // clipped in two channels has as much noise in the third. (Measured
    // only where every other rule refused the QR.)
    const auto dipped = [&] {
      if (!glare_corrected || !(p.qr_washed_dip > 0) || grey < kClippedQrGrey ||
          *std::min_element(means.begin(), means.end()) < kClippedSheet)
        return false;
      const auto end = grey_points.begin() + grey;
      const double top = *std::max_element(grey_points.begin(), end);
      return std::count_if(grey_points.begin(), end, [&](double b) { return b <= top - p.qr_washed_dip; }) >=
             kWashedDips;
    };
    if (qr_mean > p.qr_max_brightness * sheet_mean && !(clipped && dark >= p.qr_dark_samples) && !washed &&
        !dipped())
      return fail(Check::kNoQr);
    // Under a band across the sheet (two opposite sides darker than the
    // other two) the QR is as much darker than the band's paper: a shadow's
    // band frames it as the rest of the sheet does. Sheets hung in a grid
    // with gaps of about a third of a sheet are not: the squares along two
    // neighbouring sheets' facing edges lie as a landmark's, turned by 90
    // degrees, whose "sheet" is the two sheets' margins and the wall seen
    // through the gap between them, and whose "QR" is that same wall.
    if (!clipped) {
      std::array<double, 4> side;
      const int a = bandPair(means, side);
      if (a >= 0 && qr_mean > p.qr_max_brightness * (side[a] + side[a + 2]) / 2) return fail(Check::kNoQr);
    }
  }
  const cv::Point2d ctr = (P[0] + P[1] + P[2] + P[3]) * 0.25;
  {
    // A coloured square at the centre (a card's) saturates the centre and
    // the points half a unit around it, or the centre in a hue unlike the
    // sheet's. The QR's black-on-white edges saturate a point or two, in
    // the sheet's own hue (a warm light tints them orange).
    const cv::Point2d hx = (P[1] - P[0]) * (0.5 / 6), hy = (P[3] - P[0]) * (0.5 / 6);
    const cv::Point2d around[5] = {ctr, ctr + hx, ctr - hx, ctr + hy, ctr - hy};
    int saturated = 0;
    bool centre_saturated = false;
    double c[3];  // the centre's colour
    for (int k = 0; k < 5; ++k) {
      double sv, vv;
      if (!sampleSV(bgr, around[k], sv, vv, nullptr, k == 0 ? c : nullptr)) return fail(Check::kOutsideImage);
      const bool sat = vv >= p.value_min && sv > p.sheet_max_saturation;
      saturated += sat;
      if (k == 0) centre_saturated = sat;
    }
    if (saturated >= 3) return fail(Check::kCentreSaturated);
    if (centre_saturated && (chroma(c, kBlue) - chroma(sheet_bgr, kBlue) > kCentreChroma ||
                             chroma(c, kRed) - chroma(sheet_bgr, kRed) > kCentreChroma))
      return fail(Check::kCentreColoured);
  }
  // Each side: the squares cover a third of it. Their colour's profile says
  // so unless the camera smeared that colour (JPEG and the sensor's colour
  // mosaic keep colour at half the brightness's resolution): a dark square's
  // colour, printed blue under very warm light, then peaks in its middle and
  // fades before its edges, and a square a few pixels wide, seen steeply,
  // spreads its colour over the sheet around it. Where the colour's cover of
  // a side is out of bounds, the light the inks absorb, whose edges are the
  // brightness's and sharp, measures all four sides again, each near a
  // third (kAbsorbedCoverMin..Max, and within cover_min..cover_max: a striped
  // surface's "squares" pass one side's measure more easily than four).
  const uint8_t colours[4] = {kBlue, kBlue, kRed, kBlue};
  double f[4];
  bool smeared = false;
  for (int i = 0; i < 4; ++i) {
    f[i] = coverFraction(bgr, P[i], colours[i], P[(i + 1) % 4], colours[(i + 1) % 4]);
    smeared |= f[i] < p.cover_min || f[i] > p.cover_max;
  }
  if (smeared) {
    const double lo = std::max(kAbsorbedCoverMin, p.cover_min), hi = std::min(kAbsorbedCoverMax, p.cover_max);
    for (int i = 0; i < 4; ++i) {
      f[i] = coverFraction(bgr, P[i], colours[i], P[(i + 1) % 4], colours[(i + 1) % 4], CoverProfile::kAbsorbed);
      if (!(f[i] >= lo && f[i] <= hi)) return fail(Check::kCover);
    }
  }
  double cover_err = 0;
  for (int i = 0; i < 4; ++i) cover_err += std::abs(f[i] - 1.0 / 3) / 4;
  // Coloured squares of the squares' size (from half their measured side to
  // twice their printed one) besides the four: none at the centre (within
  // one side of it: a look-alike card's square), and none elsewhere on the
  // sheet either, where a patterned surface (stripes that noise and JPEG
  // blocks cut into pieces, a grid of dots) has them between its "squares".
  // Placed by the homography of the four centres (at 0 and 3 in units of a
  // square's side, the pattern square reaching half a side beyond them, the
  // QR square from 0.5 to 2.5); a piece within 0.8 sides of one of the four
  // centres is that square's own fragment. In the QR one is tolerated (warm
  // light and JPEG colour a module's edges: 2000 K does), but not one as
  // large as a printed square: a look-alike card's square beside the centre,
  // where the four squares measure small (faint fragments, the faint look's
  // pale ones: the centre's one-side circle is then small). Larger regions are
  // other things: a blue door or a red poster the sheet is stuck on is one
  // region around it, whose centre lies on the sheet.
  {
    static const std::array<cv::Point2d, 4> kCentres = {cv::Point2d(0, 0), {3, 0}, {3, 3}, {0, 3}};
    cv::Matx33d to_sheet;
    if (!homography4({P[0], P[1], P[2], P[3]}, kCentres, to_sheet)) return fail(Check::kDegenerateSquare);
    int around_qr = 0, in_qr = 0;
    // (the measured squares may be thresholded small: the side the centres give)
    const double printed_side = std::max(side, std::sqrt(std::abs(cross(e1, e2))) / 3);
    for (const auto* list : {&fips, &aps})
      for (const Region& r : *list) {
        if (r.side() <= 0.5 * side || r.side() > 2.0 * printed_side) continue;
        if (std::sqrt(quad(m, r.cx - ctr.x, r.cy - ctr.y)) < 1.0) return fail(Check::kSquareAtCentre);
        const cv::Point2d q = applyH(to_sheet, {r.cx, r.cy});
        if (!(q.x > -0.5 && q.x < 3.5 && q.y > -0.5 && q.y < 3.5)) continue;
        bool fragment = false;
        for (const cv::Point2d& k : kCentres) fragment |= cv::norm(q - k) < 0.8;
        if (fragment) continue;
        const bool qr = q.x > 0.35 && q.x < 2.65 && q.y > 0.35 && q.y < 2.65;
        if (qr && r.side() >= printed_side) return fail(Check::kOtherSquares);
        ++(qr ? in_qr : around_qr);
      }
    if (around_qr > 0 || in_qr > 1) return fail(Check::kOtherSquares);
  }

  const double shape_err = (lmax / lmin - 1) + std::abs(cosang);
  c.error += shape_err / tol + cover_err / 0.15;
  c.score = static_cast<float>(std::exp(-c.error));
  return true;
}

// Where a square's ink lies near `at` (sheet frame of joinPieces: a square
// half a unit each way): the offset within kInkSearch units at which a
// square of the printed size is darkest against a ring kInkRing wide of the
// sheet's margin around it (ink absorbs in its weakest channel, paper does
// not), by kInkMinContrast levels at least; searched in steps of a tenth,
// then of a fortieth of a unit around the best. Large squares are sampled
// on a grid of about kInkSamples pixels a side of the unit. False when no
// offset is dark enough.
static bool inkCentre(const cv::Mat& bgr, const cv::Matx33d& to_image, const cv::Matx33d& to_sheet, cv::Point2d at,
                      std::vector<cv::Point3f>& px, cv::Point2d& out) {
  constexpr double kInkSearch = 0.3, kInkRing = 0.2, kInkMinContrast = 16;
  constexpr double kReach = 0.5 + kInkSearch + kInkRing;
  constexpr int kInkSamples = 16;
  cv::Point2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const cv::Point2d d : {cv::Point2d(-1, -1), {1, -1}, {1, 1}, {-1, 1}}) {
    const cv::Point2d q = applyH(to_image, at + d * kReach);
    lo.x = std::min(lo.x, q.x), lo.y = std::min(lo.y, q.y), hi.x = std::max(hi.x, q.x), hi.y = std::max(hi.y, q.y);
  }
  const int x0 = std::max(0, static_cast<int>(std::floor(lo.x))), x1 = std::min(bgr.cols - 1, static_cast<int>(std::ceil(hi.x)));
  const int y0 = std::max(0, static_cast<int>(std::floor(lo.y))), y1 = std::min(bgr.rows - 1, static_cast<int>(std::ceil(hi.y)));
  if (x1 < x0 || y1 < y0) return false;
  const double unit = std::max(hi.x - lo.x, hi.y - lo.y) / (2 * kReach);  // pixels, about
  const int stride = std::max(1, static_cast<int>(unit / kInkSamples));
  px.clear();
  for (int y = y0; y <= y1; y += stride) {
    const uint8_t* row = bgr.ptr<uint8_t>(y);
    for (int x = x0; x <= x1; x += stride) {
      const cv::Point2d q = applyH(to_sheet, {double(x), double(y)}) - at;
      if (std::max(std::abs(q.x), std::abs(q.y)) > kReach) continue;
      px.push_back({static_cast<float>(q.x), static_cast<float>(q.y),
                    static_cast<float>(std::min({row[3 * x], row[3 * x + 1], row[3 * x + 2]}))});
    }
  }
  const auto contrast = [&](double ox, double oy) {
    double in = 0, ring = 0;
    int n_in = 0, n_ring = 0;
    for (const auto& p : px) {
      const double m = std::max(std::abs(p.x - ox), std::abs(p.y - oy));
      if (m <= 0.5) in += p.z, ++n_in;
      else if (m <= 0.5 + kInkRing) ring += p.z, ++n_ring;
    }
    return n_in > 0 && n_ring > 0 ? ring / n_ring - in / n_in : -1.0;
  };
  double bx = 0, by = 0, best = -1;
  for (const auto& [step, reach] : {std::pair{0.1, kInkSearch}, {0.025, 0.1}}) {
    const double cx = bx, cy = by;
    for (double oy = cy - reach; oy <= cy + reach + 1e-9; oy += step)
      for (double ox = cx - reach; ox <= cx + reach + 1e-9; ox += step) {
        const double c = contrast(ox, oy);
        if (c > best) best = c, bx = ox, by = oy;
      }
  }
  if (!(best >= kInkMinContrast)) return false;
  out = applyH(to_image, at + cv::Point2d(bx, by));
  return true;
}

void joinPieces(const cv::Mat& bgr, const std::array<const Region*, 4>& squares, const std::vector<Region>& fips,
                const std::vector<Region>& aps, const std::vector<uint8_t>& used, bool tinted,
                std::vector<cv::Point3f>& scratch, std::array<cv::Point2d, 4>& centres) {
  // The frame of the centres: 3 units from one to the next, a square 1 unit
  // across around its centre.
  static const std::array<cv::Point2d, 4> kCentres = {cv::Point2d(0, 0), {3, 0}, {0, 3}, {3, 3}};
  for (int i = 0; i < 4; ++i) centres[i] = {squares[i]->cx, squares[i]->cy};
  cv::Matx33d to_sheet, to_image;
  if (!homography4(centres, kCentres, to_sheet) || !homography4(kCentres, centres, to_image)) return;
  std::array<bool, 4> piece = {false, false, false, false};
  for (int i = 0; i < 4; ++i) {
    const Region& sq = *squares[i];
    const std::vector<Region>& list = i == 3 ? aps : fips;
    const size_t first = i == 3 ? fips.size() : 0;  // the list's first in `used`
    // the printed square's side here, pixels
    const cv::Point2d k = kCentres[i];
    const cv::Point2d dx = applyH(to_image, k + cv::Point2d(0.5, 0)) - applyH(to_image, k - cv::Point2d(0.5, 0));
    const cv::Point2d dy = applyH(to_image, k + cv::Point2d(0, 0.5)) - applyH(to_image, k - cv::Point2d(0, 0.5));
    const double printed = std::sqrt(std::abs(dx.x * dy.y - dx.y * dy.x));
    if (printed < kPieceMinSide) continue;
    // the union so far: area, centre, second central moments
    double w = sq.area, x = sq.cx, y = sq.cy, sxx = sq.sxx, sxy = sq.sxy, syy = sq.syy;
    // (the completion's squares, measured on the image, have no pieces)
    for (size_t j = 0; sq.pass >= 0 && j < list.size(); ++j) {
      const Region& r = list[j];
      if (&r == &sq || r.pass != sq.pass || (first + j < used.size() && used[first + j])) continue;  // (pass >= 0 here)
      if (r.area < kPieceMinArea * printed * printed) continue;
      // touching the square's box (the row between at most)
      if (r.x0 > sq.x1 + 2 || r.x1 < sq.x0 - 2 || r.y0 > sq.y1 + 2 || r.y1 < sq.y0 - 2) continue;
      const cv::Point2d q = applyH(to_sheet, {r.cx, r.cy}) - k;
      if (!(std::abs(q.x) < kPieceReach && std::abs(q.y) < kPieceReach)) continue;
      // and together no larger than a square (moments of the union)
      const double w2 = w + r.area, x2 = (w * x + r.area * r.cx) / w2, y2 = (w * y + r.area * r.cy) / w2;
      const double ax = x - x2, ay = y - y2, bx = r.cx - x2, by = r.cy - y2;
      const double uxx = (w * (sxx + ax * ax) + r.area * (r.sxx + bx * bx)) / w2;
      const double uxy = (w * (sxy + ax * ay) + r.area * (r.sxy + bx * by)) / w2;
      const double uyy = (w * (syy + ay * ay) + r.area * (r.syy + by * by)) / w2;
      const double side = std::sqrt(12.0 * std::sqrt(std::max(0.0, uxx * uyy - uxy * uxy)));
      if (!(side <= kPieceSpan * printed)) continue;
      w = w2, x = x2, y = y2, sxx = uxx, sxy = uxy, syy = uyy;
    }
    centres[i] = {x, y};
    // Still a piece where a glare veil's stretch tints the squares (parts of
    // a square under the threshold, in any shape): measured where its ink
    // is, below. (Elsewhere a square short of the printed area is as often
    // whole: a sheet bent round a pillar, seen through the flat sheet's
    // homography, reads 0.5-0.7 of it.)
    piece[i] = tinted && w < kPieceWhole * printed * printed;
  }
  // Each round in the frame of the centres so far (a piece's centre skews
  // the frame around it, and so the square's outline there).
  for (int round = 0; round < kInkRounds && (piece[0] || piece[1] || piece[2] || piece[3]); ++round) {
    if (!homography4(centres, kCentres, to_sheet) || !homography4(kCentres, centres, to_image)) return;
    std::array<cv::Point2d, 4> moved = centres;
    for (int i = 0; i < 4; ++i) {
      cv::Point2d ink;
      if (!piece[i] || !inkCentre(bgr, to_image, to_sheet, applyH(to_sheet, centres[i]), scratch, ink)) continue;
      const cv::Point2d q = applyH(to_sheet, ink) - kCentres[i];
      if (std::abs(q.x) < kPieceReach && std::abs(q.y) < kPieceReach) moved[i] = ink;
    }
    centres = moved;
  }
}

double coverFraction(const cv::Mat& bgr, cv::Point2d a, uint8_t ca, cv::Point2d b, uint8_t cb, CoverProfile profile) {
  const auto at = profile == CoverProfile::kAbsorbed ? absorbedAt : excessAt;
  constexpr int kMax = 64;
  const double len = cv::norm(b - a);
  if (!(len > 1)) return -1;
  const int n = std::clamp(static_cast<int>(2 * len), 8, kMax);
  double ea[kMax + 1], eb[kMax + 1];
  double lo = 1e9;
  for (int i = 0; i <= n; ++i) {
    const cv::Point2d q = a + (b - a) * (static_cast<double>(i) / n);
    ea[i] = at(bgr, q, ca);
    eb[i] = ca == cb ? ea[i] : at(bgr, q, cb);
    if (std::isnan(ea[i]) || std::isnan(eb[i])) return -1;  // (the absorbed light, outside the image)
  }
  // The gap: the lowest point of the middle of the profile, in both hues.
  for (int i = n / 4; i <= 3 * n / 4; ++i) lo = std::min(lo, std::max(ea[i], eb[i]));
  // Each end's peak near its centre.
  int ia = 0, ib = n;
  for (int i = 1; i <= n / 8; ++i) {
    if (ea[i] > ea[ia]) ia = i;
    if (eb[n - i] > eb[ib]) ib = n - i;
  }
  const double pa = ea[ia], pb = eb[ib];
  if (!(pa - lo > 4 && pb - lo > 4)) return -1;
  const double ha = (pa + lo) / 2, hb = (pb + lo) / 2;
  // Walk out of each square to its half level (linear interpolation).
  double ta = 0.5, tb = 0.5;
  for (int i = ia + 1; i <= n; ++i)
    if (ea[i] < ha) {
      ta = (i - 1 + (ea[i - 1] - ha) / (ea[i - 1] - ea[i])) / n;
      break;
    }
  for (int i = ib - 1; i >= 0; --i)
    if (eb[i] < hb) {
      tb = (n - i - 1 + (eb[i + 1] - hb) / (eb[i + 1] - eb[i])) / n;
      break;
    }
  return ta + tb;
}

double meanExcess(const Region& r) {
  if (!(r.n_sum > 0)) return 0;
  return (r.colour == kBlue ? r.sum_b - std::max(r.sum_g, r.sum_r) : r.sum_r - std::max(r.sum_g, r.sum_b)) / r.n_sum;
}

double meanChroma(const Region& r) {
  if (!(r.n_sum > 0)) return 0;
  const double c[3] = {r.sum_b / r.n_sum, r.sum_g / r.n_sum, r.sum_r / r.n_sum};
  return chroma(c, r.colour);
}

bool completeSquare(const cv::Mat& bgr, cv::Point2d guess, uint8_t colour, cv::Point2d e1, cv::Point2d e2,
                    double min_peak, Region& out) {
  // The layout frame at the guess: layout units u -> pixels is A = [e1 e2] / 6.
  const double a00 = e1.x / 6, a01 = e2.x / 6, a10 = e1.y / 6, a11 = e2.y / 6;
  const double det = a00 * a11 - a01 * a10;
  if (!(std::abs(det) > 1e-9)) return false;
  const double i00 = a11 / det, i01 = -a01 / det, i10 = -a10 / det, i11 = a00 / det;
  // Search 1.5 half-sides around the guess (the square's own half-side is 1u).
  constexpr double kReach = 1.25;
  const double rx = kReach * (std::abs(a00) + std::abs(a01)), ry = kReach * (std::abs(a10) + std::abs(a11));
  const int x0 = std::max(0, static_cast<int>(std::floor(guess.x - rx)));
  const int y0 = std::max(0, static_cast<int>(std::floor(guess.y - ry)));
  const int x1 = std::min(bgr.cols - 1, static_cast<int>(std::ceil(guess.x + rx)));
  const int y1 = std::min(bgr.rows - 1, static_cast<int>(std::ceil(guess.y + ry)));
  if (x1 < x0 || y1 < y0) return false;
  auto inside = [&](int x, int y) {
    const double dx = x - guess.x, dy = y - guess.y;
    return std::abs(i00 * dx + i01 * dy) <= kReach && std::abs(i10 * dx + i11 * dy) <= kReach;
  };
  // Row y's pixels inside: the parallelogram's span on the row (each of its
  // two strips |i * dx + c| <= kReach an interval of dx), a pixel wider on
  // either side against rounding, then trimmed at both ends by inside().
  auto span = [&](int y, int& xa, int& xb) {
    const double dy = y - guess.y;
    double lo = x0 - guess.x, hi = x1 - guess.x;
    for (const auto& [i, c] : {std::pair<double, double>{i00, i01 * dy}, {i10, i11 * dy}}) {
      if (std::abs(i) > 1e-12) {
        const double u = (-kReach - c) / i, v = (kReach - c) / i;
        lo = std::max(lo, std::min(u, v));
        hi = std::min(hi, std::max(u, v));
      } else if (std::abs(c) > kReach) {
        hi = lo - 1;
      }
    }
    if (!(lo <= hi)) {  // (also keeps the far bounds of nearly parallel strips out of the casts)
      xa = x0 + 1, xb = x0;
      return;
    }
    xa = std::max(x0, static_cast<int>(std::floor(guess.x + lo)) - 1);
    xb = std::min(x1, static_cast<int>(std::ceil(guess.x + hi)) + 1);
    // the pixels inside are one run (the parallelogram is convex)
    while (xa <= xb && !inside(xa, y)) ++xa;
    while (xb >= xa && !inside(xb, y)) --xb;
  };
  int peak = -255;
  for (int y = y0; y <= y1; ++y) {
    int xa, xb;
    span(y, xa, xb);
    const uint8_t* row = bgr.ptr<uint8_t>(y);
    for (int x = xa; x <= xb; ++x) peak = std::max(peak, hueExcess(row + 3 * x, colour));
  }
  if (peak < min_peak) return false;
  const int half = peak / 2;
  double sw = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, sb = 0, sg = 0, sr = 0;
  int n = 0;
  for (int y = y0; y <= y1; ++y) {
    int xa, xb;
    span(y, xa, xb);
    for (int x = xa; x <= xb; ++x) {
      const uint8_t* px = bgr.ptr<uint8_t>(y) + 3 * x;
      const int w = hueExcess(px, colour) - half;
      if (w <= 0) continue;
      sw += w, sx += w * x, sy += w * y;
      sxx += static_cast<double>(w) * x * x, syy += static_cast<double>(w) * y * y, sxy += static_cast<double>(w) * x * y;
      sb += px[0], sg += px[1], sr += px[2];
      ++n;
    }
  }
  if (sw <= 0) return false;
  out = Region();
  out.colour = colour;
  out.cx = sx / sw;
  out.cy = sy / sw;
  out.sxx = sxx / sw - out.cx * out.cx + 1.0 / 12;
  out.syy = syy / sw - out.cy * out.cy + 1.0 / 12;
  out.sxy = sxy / sw - out.cx * out.cy;
  out.x0 = x0, out.y0 = y0, out.x1 = x1, out.y1 = y1;
  out.area = n;
  out.sum_b = sb, out.sum_g = sg, out.sum_r = sr;
  out.n_sum = n;
  return true;
}

bool squareConsistency(const Region& r, cv::Point2d e1, cv::Point2d e2, double& scale, double& anisotropy) {
  const Sym2 e{(e1.x * e1.x + e2.x * e2.x) / 108, (e1.x * e1.y + e2.x * e2.y) / 108,
               (e1.y * e1.y + e2.y * e2.y) / 108};
  const double de = e.det();
  if (!(de > 1e-12)) return false;
  // Eigenvalues of inverse(E) * S: product det(S) / det(E), sum trace(inverse(E) * S).
  const Sym2 s = moments(r);
  const double prod = s.det() / de;
  const double sum = (e.yy * s.xx - 2 * e.xy * s.xy + e.xx * s.yy) / de;
  if (!(prod > 0)) return false;
  const double disc = std::sqrt(std::max(0.0, sum * sum / 4 - prod));
  const double lmax = sum / 2 + disc, lmin = sum / 2 - disc;
  if (!(lmin > 0)) return false;
  scale = std::sqrt(std::sqrt(prod));
  anisotropy = std::sqrt(lmax / lmin);
  return true;
}

void resolveOverlaps(std::vector<Candidate>& cands, int n_fips, int n_aps, std::vector<uint8_t>& used) {
  // (std::sort with a full tie-break: deterministic, and unlike stable_sort no allocation)
  std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.error, a.tl, a.tr, a.bl, a.ap) < std::tie(b.error, b.tl, b.tr, b.bl, b.ap);
  });
  used.assign(static_cast<size_t>(n_fips + n_aps), 0);
  size_t kept = 0;
  for (size_t i = 0; i < cands.size(); ++i) {
    const Candidate& c = cands[i];
    const int ids[4] = {c.tl, c.tr, c.bl, n_fips + c.ap};
    bool clash = false;
    for (int id : ids) clash |= used[id] != 0;
    if (clash) continue;
    for (int id : ids) used[id] = 1;
    cands[kept++] = c;
  }
  cands.resize(kept);
}

// ====================================================================== corners, pose

bool homography4(const std::array<cv::Point2d, 4>& src, const std::array<cv::Point2d, 4>& dst,
                 cv::Matx33d& H) {
  // Normalise both point sets (centre, scale) for conditioning.
  auto norm = [](const std::array<cv::Point2d, 4>& p, cv::Point2d& c, double& s) {
    c = (p[0] + p[1] + p[2] + p[3]) * 0.25;
    s = 0;
    for (const auto& q : p) s += cv::norm(q - c) / 4;
    s = s > 0 ? 1.0 / s : 0.0;
  };
  cv::Point2d cs, cd;
  double ss, sd;
  norm(src, cs, ss);
  norm(dst, cd, sd);
  if (ss == 0 || sd == 0) return false;
  double A[8][9];
  for (int i = 0; i < 4; ++i) {
    const double x = (src[i].x - cs.x) * ss, y = (src[i].y - cs.y) * ss;
    const double u = (dst[i].x - cd.x) * sd, v = (dst[i].y - cd.y) * sd;
    double* r0 = A[2 * i];
    double* r1 = A[2 * i + 1];
    const double a0[9] = {x, y, 1, 0, 0, 0, -u * x, -u * y, u};
    const double a1[9] = {0, 0, 0, x, y, 1, -v * x, -v * y, v};
    std::copy(a0, a0 + 9, r0);
    std::copy(a1, a1 + 9, r1);
  }
  for (int c = 0; c < 8; ++c) {
    int piv = c;
    for (int r = c + 1; r < 8; ++r)
      if (std::abs(A[r][c]) > std::abs(A[piv][c])) piv = r;
    if (std::abs(A[piv][c]) < 1e-12) return false;
    if (piv != c)
      for (int k = 0; k < 9; ++k) std::swap(A[c][k], A[piv][k]);
    for (int r = 0; r < 8; ++r) {
      if (r == c) continue;
      const double f = A[r][c] / A[c][c];
      if (f == 0) continue;
      for (int k = c; k < 9; ++k) A[r][k] -= f * A[c][k];
    }
  }
  double h[8];
  for (int i = 0; i < 8; ++i) h[i] = A[i][8] / A[i][i];
  const cv::Matx33d Hn(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
  const cv::Matx33d Ts(ss, 0, -ss * cs.x, 0, ss, -ss * cs.y, 0, 0, 1);
  const cv::Matx33d Td_inv(1 / sd, 0, cd.x, 0, 1 / sd, cd.y, 0, 0, 1);
  H = Td_inv * Hn * Ts;
  return true;
}

cv::Point2d applyH(const cv::Matx33d& H, const cv::Point2d& p) {
  const double w = H(2, 0) * p.x + H(2, 1) * p.y + H(2, 2);
  return {(H(0, 0) * p.x + H(0, 1) * p.y + H(0, 2)) / w, (H(1, 0) * p.x + H(1, 1) * p.y + H(1, 2)) / w};
}

bool fitCorners(const std::array<cv::Point2d, 4>& centres, int iterations,
                std::array<cv::Point2d, 4>& corrected, std::array<cv::Point2d, 4>& corners,
                cv::Matx33d* H_out) {
  std::array<cv::Point2d, 4> src;
  for (int i = 0; i < 4; ++i) src[i] = {layout::kCentresU[i][0], layout::kCentresU[i][1]};
  corrected = centres;
  cv::Matx33d H;
  if (!homography4(src, corrected, H)) return false;
  const double half = layout::kSquareSide / 2;
  for (int it = 0; it < iterations; ++it) {
    for (int i = 0; i < 4; ++i) {
      // Centroid of the projected square (a quadrilateral) vs the projected centre.
      cv::Point2d q[4];
      const double dx[4] = {-half, half, half, -half}, dy[4] = {-half, -half, half, half};
      for (int k = 0; k < 4; ++k) q[k] = applyH(H, {src[i].x + dx[k], src[i].y + dy[k]});
      double a2 = 0;
      cv::Point2d c(0, 0);
      for (int k = 0; k < 4; ++k) {
        const cv::Point2d& p0 = q[k];
        const cv::Point2d& p1 = q[(k + 1) % 4];
        const double cr = cross(p0, p1);
        a2 += cr;
        c += (p0 + p1) * cr;
      }
      if (std::abs(a2) < 1e-12) return false;
      c *= 1.0 / (3.0 * a2);
      corrected[i] = centres[i] + (applyH(H, src[i]) - c);
    }
    if (!homography4(src, corrected, H)) return false;
  }
  for (int i = 0; i < 4; ++i) corners[i] = applyH(H, {layout::kCornersU[i][0], layout::kCornersU[i][1]});
  if (H_out) *H_out = H;
  return true;
}

namespace {

// Sheet alignment: sheets whose longest side is at most kAlignMaxSide px (a
// 15 cm sheet from about 0.75 m on at f = 600 px) are fitted to the model
// given, those over kAlignDenseSide on every other pixel each way. Larger
// ones, to kAlignNearMaxSide px (15 cm from about 0.2 m), are fitted to the
// finer near model, when there is one, on every (longest /
// kAlignNearSamples)'th pixel each way (at least every other one: 60-120
// pixels each way): the fit's time goes with the pixels it reads. The fit
// halves a step that made its error larger and stops at one that lowered
// it by less than kAlignMinGain. An alignment
// that moves a centre by more than kAlignMaxShift of its square's smaller
// projected side is not taken (a fit that slid, as along the thin squares
// of a steeply seen sheet).
constexpr double kAlignMaxSide = 120;
constexpr double kAlignDenseSide = 60;
constexpr double kAlignNearMaxSide = 480;
constexpr double kAlignNearSamples = 60;
constexpr double kAlignMinGain = 0.001;
constexpr double kAlignMaxShift = 0.25;

}  // namespace

void sheetModel(int per_unit, SheetModel& model) {
  const int n = static_cast<int>(layout::kUnits) * per_unit;
  model.per_unit = per_unit;
  cv::Mat sheet(n, n, CV_32F, cv::Scalar(255));
  model.valid.create(n, n, CV_8U);
  model.valid.setTo(255);
  const auto units = [per_unit](double u) { return static_cast<int>(std::lround(u * per_unit)); };
  const int side = units(layout::kSquareSide);
  for (const auto& c : layout::kCentresU)
    sheet(cv::Rect(units(c[0] - layout::kSquareSide / 2), units(c[1] - layout::kSquareSide / 2), side, side)).setTo(0);
  const int qr = units(layout::kQrMax - layout::kQrMin);
  model.valid(cv::Rect(units(layout::kQrMin), units(layout::kQrMin), qr, qr)).setTo(0);
  cv::GaussianBlur(sheet, model.value, {3, 3}, 0, 0, cv::BORDER_REPLICATE);
  // its derivatives, central differences (levels per pixel)
  cv::Sobel(model.value, model.dx, CV_32F, 1, 0, 1, 0.5, 0, cv::BORDER_REPLICATE);
  cv::Sobel(model.value, model.dy, CV_32F, 0, 1, 1, 0.5, 0, cv::BORDER_REPLICATE);
}

namespace {

// The green channel of `bgr` (8-bit BGR) smoothed by the 3x3 Gaussian (1 2
// 1 / 4 each way, the border replicated) at every `stride`'th pixel each
// way, into `out` (CV_32F, ceil(rows / stride) x ceil(cols / stride)): what
// cv::GaussianBlur of the whole would give there, without smoothing the
// pixels never read.
void greenSmoothedEvery(const cv::Mat& bgr, int stride, cv::Mat& out) {
  out.create((bgr.rows + stride - 1) / stride, (bgr.cols + stride - 1) / stride, CV_32F);
  const auto g = [&bgr](int y, int x) {
    return static_cast<float>(bgr.ptr<uint8_t>(std::clamp(y, 0, bgr.rows - 1))[3 * std::clamp(x, 0, bgr.cols - 1) + 1]);
  };
  for (int yo = 0; yo < out.rows; ++yo) {
    float* o = out.ptr<float>(yo);
    const int y = yo * stride;
    for (int xo = 0; xo < out.cols; ++xo) {
      const int x = xo * stride;
      const float up = g(y - 1, x - 1) + 2 * g(y - 1, x) + g(y - 1, x + 1);
      const float mid = g(y, x - 1) + 2 * g(y, x) + g(y, x + 1);
      const float down = g(y + 1, x - 1) + 2 * g(y + 1, x) + g(y + 1, x + 1);
      o[xo] = (up + 2 * mid + down) / 16;
    }
  }
}

// One Gauss-Newton fit of the sheet `m` to `view` (the crop's green, float,
// smoothed; of a crop of `crop` pixels, every `stride`'th each way):
// view(x) ~ gain * sheet(W(x)) + offset over the view's pixels (every
// `step`'th each way) that W takes onto the known sheet, W a homography
// from the crop's pixels to the sheet's, started at `W`. Returns false
// when degenerate.
bool fitSheet(const cv::Mat& view, cv::Size crop, int stride, const SheetModel& m, int iterations, int step,
              cv::Matx33d& W) {
  if (iterations < 1) return false;
  const int n = m.value.cols;
  const double lim = n - 1.001;
  // the crop's pixels centred and scaled (a well conditioned system)
  const double cx = (crop.width - 1) / 2.0, cy = (crop.height - 1) / 2.0, sc = std::max(crop.width, crop.height) / 2.0;
  const cv::Matx33d N(1 / sc, 0, -cx / sc, 0, 1 / sc, -cy / sc, 0, 0, 1);
  cv::Matx33d G = W * N.inv();  // normalised view -> sheet px
  G *= 1.0 / G(2, 2);
  double gain = 1, offset = 0, prev_mse = 1e300, prev_gain = 1, prev_offset = 0;
  int halvings = 0;
  cv::Matx33d prev_G = G;
  // it 0: the light alone (gain, offset) at the start; then all ten, up to
  // `iterations` steps; the last pass only measures the last step
  for (int it = 0; it <= iterations + 1; ++it) {
    const bool light_only = it == 0, last = it == iterations + 1;
    cv::Matx<double, 10, 10> A = cv::Matx<double, 10, 10>::zeros();
    cv::Vec<double, 10> r = cv::Vec<double, 10>::all(0);
    int used = 0;
    double sse = 0;
    for (int yv = 0; yv < view.rows; yv += step) {
      const float* v = view.ptr<float>(yv);
      const double yn = (yv * stride - cy) / sc;
      for (int x = 0; x < view.cols; x += step) {
        if (!(v[x] == v[x])) continue;  // (NaN: outside the frame, through the distortion)
        const double xn = (x * stride - cx) / sc;
        const double Z = G(2, 0) * xn + G(2, 1) * yn + G(2, 2);
        if (!(Z > 1e-9)) continue;
        const double u = (G(0, 0) * xn + G(0, 1) * yn + G(0, 2)) / Z, w = (G(1, 0) * xn + G(1, 1) * yn + G(1, 2)) / Z;
        if (!(u >= 0 && u <= lim && w >= 0 && w <= lim)) continue;
        const int u0 = static_cast<int>(u), w0 = static_cast<int>(w);
        if (!m.valid.at<uint8_t>(w0, u0)) continue;
        const double fu = u - u0, fw = w - w0;
        const auto bilinear = [&](const cv::Mat& img) {
          const float* a = img.ptr<float>(w0) + u0;
          const float* b = img.ptr<float>(w0 + 1) + u0;
          return (1 - fw) * ((1 - fu) * a[0] + fu * a[1]) + fw * ((1 - fu) * b[0] + fu * b[1]);
        };
        const double s = bilinear(m.value);
        const double e = gain * s + offset - v[x];
        sse += e * e;
        ++used;
        if (last) continue;  // (the last pass measures the error alone)
        double J[10];
        J[8] = s;
        J[9] = 1;
        int k0 = 8;
        // (where the sheet is flat, on paper or ink, only the light's terms)
        const double sx = light_only ? 0.0 : bilinear(m.dx), sy = light_only ? 0.0 : bilinear(m.dy);
        if (sx != 0 || sy != 0) {
          const double gx = gain * sx / Z, gy = gain * sy / Z;
          J[0] = gx * xn, J[1] = gx * yn, J[2] = gx;
          J[3] = gy * xn, J[4] = gy * yn, J[5] = gy;
          J[6] = -(gx * u + gy * w) * xn, J[7] = -(gx * u + gy * w) * yn;
          k0 = 0;
        }
        for (int i = k0; i < 10; ++i) {
          r[i] += J[i] * e;
          for (int j = i; j < 10; ++j) A(i, j) += J[i] * J[j];
        }
      }
    }
    if (used < 16) return false;
    // A step that made the error larger overshot (a flat error surface, as
    // along a motion blur): half of it, from where it started, at most
    // three times a step (none after the last: back to where it started);
    // one that lowered it by less than kAlignMinGain ends the fit.
    const double mse = sse / used;
    if (!light_only && it > 1) {
      if (mse > prev_mse) {
        if (last || ++halvings > 3) {
          G = prev_G, gain = prev_gain, offset = prev_offset;
          break;
        }
        G = prev_G + 0.5 * (G - prev_G);
        gain = prev_gain + 0.5 * (gain - prev_gain), offset = prev_offset + 0.5 * (offset - prev_offset);
        continue;
      }
      if (last || mse > prev_mse * (1 - kAlignMinGain)) break;
    }
    prev_mse = mse, prev_G = G, prev_gain = gain, prev_offset = offset;
    halvings = 0;
    if (light_only) {
      // the 2x2 system of gain and offset alone
      const double det = A(8, 8) * A(9, 9) - A(8, 9) * A(8, 9);
      if (!(std::abs(det) > 1e-9)) return false;
      gain -= (A(9, 9) * r[8] - A(8, 9) * r[9]) / det;
      offset -= (A(8, 8) * r[9] - A(8, 9) * r[8]) / det;
      continue;
    }
    for (int i = 0; i < 10; ++i)
      for (int j = 0; j < i; ++j) A(i, j) = A(j, i);
    cv::Vec<double, 10> d;
    if (!cv::solve(A, -r, d, cv::DECOMP_CHOLESKY)) return false;
    G(0, 0) += d[0], G(0, 1) += d[1], G(0, 2) += d[2];
    G(1, 0) += d[3], G(1, 1) += d[4], G(1, 2) += d[5];
    G(2, 0) += d[6], G(2, 1) += d[7];
    gain += d[8], offset += d[9];
    if (!(gain > 0)) return false;
    // converged: the view's corners move by under a hundredth of a sheet
    // pixel (prev_G: where this step started)
    double moved = 0;
    for (const double xn : {-1.0, 1.0})
      for (const double yn : {-1.0, 1.0}) {
        moved = std::max(moved, cv::norm(applyH(G, {xn, yn}) - applyH(prev_G, {xn, yn})));
      }
    if (!(moved < 1e3)) return false;
    if (moved < 0.01) break;
  }
  W = G * N;
  return true;
}

}  // namespace

bool alignSheet(const cv::Mat& bgr, const CameraModel* distorting, const SheetModel& far_model, int iterations,
                std::array<cv::Point2d, 4>& centres, std::array<cv::Point2d, 4>& corners, AlignScratch& scratch,
                const SheetModel* near_model) {
  if (iterations <= 0 || bgr.type() != CV_8UC3) return false;
  std::array<cv::Point2d, 4> pattern;
  for (int i = 0; i < 4; ++i) pattern[i] = {layout::kCornersU[i][0], layout::kCornersU[i][1]};
  cv::Matx33d H;
  if (!homography4(pattern, corners, H)) return false;
  // The sheet's outline: its size decides whether to align.
  std::array<cv::Point2f, 4> outline;
  for (int i = 0; i < 4; ++i)
    outline[i] = applyH(H, {i % 3 ? layout::kUnits : 0.0, i < 2 ? 0.0 : layout::kUnits});
  double longest = 0;
  for (int i = 0; i < 4; ++i) longest = std::max(longest, cv::norm(outline[(i + 1) % 4] - outline[i]));
  const bool near = !(longest <= kAlignMaxSide);
  if (near && !(near_model && longest <= kAlignNearMaxSide)) return false;
  const SheetModel& model = near ? *near_model : far_model;
  // The landmark's crop: the sheet's bounding box and 3 px around it, in the
  // undistorted image's pixels (through the lens's distortion when there is
  // one: a homography maps the sheet to the undistorted image only).
  // (an outline far off the frame, as a distortion model that does not
  // invert there puts it, is no sheet to align; its box's arithmetic would
  // overflow: found by tests/fuzz/fuzz_camera)
  const float reach = 2.0f * static_cast<float>(std::max(bgr.cols, bgr.rows));
  for (const auto& p : outline)
    if (!(std::abs(p.x) <= reach && std::abs(p.y) <= reach)) return false;
  cv::Rect box = cv::boundingRect(cv::Mat(4, 1, CV_32FC2, outline.data())) + cv::Size(6, 6) - cv::Point(3, 3);
  const cv::Rect frame(0, 0, bgr.cols, bgr.rows);
  // (a near sheet is read on every stride'th pixel each way: its view holds
  // those alone, each smoothed as the whole crop would be)
  const int stride = near ? std::max(2, static_cast<int>(longest / kAlignNearSamples)) : 1;
  if (!distorting) {
    box &= frame;
    if (box.width < 4 || box.height < 4) return false;
  } else {
    // where each of the box's pixels lies in the frame
    const cv::Matx33d Ki = distorting->K.inv();
    scratch.rays.clear();
    for (int y = 0; y < box.height; ++y)
      for (int x = 0; x < box.width; ++x) {
        const cv::Vec3d r = Ki * cv::Vec3d(box.x + x, box.y + y, 1.0);
        scratch.rays.emplace_back(static_cast<float>(r[0] / r[2]), static_cast<float>(r[1] / r[2]), 1.0f);
      }
    cv::projectPoints(scratch.rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cv::Mat(distorting->K), distorting->dist,
                      scratch.at);
    const cv::Mat map(box.height, box.width, CV_32FC2, scratch.at.data());
    cv::remap(bgr, scratch.undistorted, map, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  }
  const cv::Mat crop = distorting ? scratch.undistorted : bgr(box);
  if (stride > 1) {
    greenSmoothedEvery(crop, stride, scratch.view);
  } else {
    cv::extractChannel(crop, scratch.green, 1);
    scratch.green.convertTo(scratch.view, CV_32F);
    cv::GaussianBlur(scratch.view, scratch.view, {3, 3}, 0, 0, cv::BORDER_REPLICATE);
  }
  if (distorting) {
    // the view's pixels the distortion takes out of the frame: not seen
    // (NaN, which the fit skips)
    const cv::Rect2f inside(0, 0, static_cast<float>(bgr.cols - 1), static_cast<float>(bgr.rows - 1));
    for (int y = 0; y < scratch.view.rows; ++y)
      for (int x = 0; x < scratch.view.cols; ++x)
        if (!inside.contains(scratch.at[static_cast<size_t>(y * stride) * box.width + x * stride]))
          scratch.view.at<float>(y, x) = std::numeric_limits<float>::quiet_NaN();
  }
  // image px -> view px, sheet px -> sheet u
  const cv::Matx33d to_view(1, 0, -box.x, 0, 1, -box.y, 0, 0, 1);
  const double s = model.per_unit;
  const cv::Matx33d sheet_px_to_u(1 / s, 0, 0.5 / s, 0, 1 / s, 0.5 / s, 0, 0, 1);
  // the fit's warp takes the view's pixels to the sheet's
  cv::Matx33d W = (to_view * H * sheet_px_to_u).inv();
  if (!(std::abs(W(2, 2)) > 1e-12)) return false;
  W *= 1.0 / W(2, 2);
  // (a far sheet over kAlignDenseSide px fitted on every other pixel each
  // way: plenty of them, a quarter of the time; a near one on its view's
  // every pixel, 60-120 each way)
  const int step = !near && longest > kAlignDenseSide ? 2 : 1;
  if (!fitSheet(scratch.view, box.size(), stride, model, iterations, step, W)) return false;
  const cv::Matx33d Hn = to_view.inv() * W.inv() * sheet_px_to_u.inv();
  std::array<cv::Point2d, 4> aligned;
  for (int i = 0; i < 4; ++i) {
    const double x = layout::kCentresU[i][0], y = layout::kCentresU[i][1], h = layout::kSquareSide / 2;
    aligned[i] = applyH(Hn, {x, y});
    const double across = cv::norm(applyH(H, {x - h, y}) - applyH(H, {x + h, y}));
    const double down = cv::norm(applyH(H, {x, y - h}) - applyH(H, {x, y + h}));
    if (!(cv::norm(aligned[i] - centres[i]) <= kAlignMaxShift * std::min(across, down))) return false;
  }
  centres = aligned;
  for (int i = 0; i < 4; ++i) corners[i] = applyH(Hn, {layout::kCornersU[i][0], layout::kCornersU[i][1]});
  return true;
}

void undistortPixels(const CameraModel& camera, std::array<cv::Point2d, 4>& pts) {
  const cv::Mat in(4, 1, CV_64FC2, pts.data());
  cv::Mat out;
  cv::undistortPoints(in, out, cv::Mat(camera.K), camera.dist, cv::noArray(), cv::Mat(camera.K));
  for (int i = 0; i < 4; ++i) pts[i] = out.at<cv::Point2d>(i);
}

void distortPixels(const CameraModel& camera, std::array<cv::Point2d, 4>& pts) {
  const cv::Matx33d Ki = camera.K.inv();
  std::array<cv::Point3d, 4> rays;
  for (int i = 0; i < 4; ++i) {
    const cv::Vec3d r = Ki * cv::Vec3d(pts[i].x, pts[i].y, 1.0);
    rays[i] = {r[0] / r[2], r[1] / r[2], 1.0};
  }
  std::vector<cv::Point2d> out;
  cv::projectPoints(cv::Mat(4, 1, CV_64FC3, rays.data()), cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                    cv::Mat(camera.K), camera.dist, out);
  for (int i = 0; i < 4; ++i) pts[i] = out[i];
}

bool estimatePose(const std::array<cv::Point2f, 4>& corners, const CameraModel& camera,
                  double side_m, Pose& out) {
  // IPPE_SQUARE's object frame has y up and the points in the order
  // (-h, h), (h, h), (h, -h), (-h, -h): our TL, TR, BR, BL seen in a frame
  // turned 180 degrees about x from ours (y down, z into the wall).
  const double h = side_m * (layout::kPatternMax - layout::kPatternMin) / layout::kUnits / 2;
  const cv::Point3f obj[4] = {{static_cast<float>(-h), static_cast<float>(h), 0},
                              {static_cast<float>(h), static_cast<float>(h), 0},
                              {static_cast<float>(h), static_cast<float>(-h), 0},
                              {static_cast<float>(-h), static_cast<float>(-h), 0}};
  const cv::Mat obj_m(4, 1, CV_32FC3, const_cast<cv::Point3f*>(obj));
  const cv::Mat img_m(4, 1, CV_32FC2, const_cast<cv::Point2f*>(corners.data()));
  cv::Vec3d rvec, tvec;
  bool ok = false;
  try {
    ok = cv::solvePnP(obj_m, img_m, cv::Mat(camera.K), camera.dist, rvec, tvec, false,
                      cv::SOLVEPNP_IPPE_SQUARE);
  } catch (const cv::Exception&) {
    return false;
  }
  if (!ok || !std::isfinite(tvec[2]) || tvec[2] <= 0) return false;
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  const cv::Matx33d flip(1, 0, 0, 0, -1, 0, 0, 0, -1);
  cv::Rodrigues(R * flip, rvec);
  out.rvec = rvec;
  out.t = tvec;
  out.distance = cv::norm(tvec);
  return true;
}

}  // namespace ld::detail
