// The GLES backend's filters (filters.hpp): OpenGL ES 3.0 fragment shaders,
// and OpenGL ES 3.1 compute shaders where they exist and are faster, on a
// headless EGL context (egl_context.hpp).
//
// A frame goes up once, through a pixel unpack buffer, as its BGR bytes just
// as they are, four to an RGBA8UI texel (kRaw: no format conversion in the
// driver). Then, per front end:
//   fast:  label pass: kNone/kBlue/kRed per pixel, four pixels (three texels
//          of the frame) per fragment into an RGBA8 texel, read back
//          (glReadPixels into the CPU's buffer) as the single-channel label
//          image (one byte a pixel) the CPU's region stage takes. With a blur (not the
//          default) the frame is unpacked and blurred pixel by pixel first,
//          and the blurred image comes back too (the regions' colour sums
//          are taken over it).
//   paper: fragment path, four pixels a fragment throughout: blur H (from
//          the frame, into two targets) -> blur V + saturation + threshold
//          -> Sobel (L1 magnitude and direction sector) -> non-maximum
//          suppression and double threshold (0, 1 weak, 2 strong), read back
//          as a single-channel map. Compute path: blur + saturation, then
//          Sobel + suppression, two dispatches sharing each tile's
//          neighbourhood in shared memory, into a storage buffer read back.
//          The faster path is measured on the first frames. The hysteresis
//          runs on the CPU (filters.hpp: a flood fill over a sparse map, not
//          worth a GPU's many passes).
// All of it is integer arithmetic, the same as the CPU's: labels,
// saturation, Sobel and suppression exactly; the blur is OpenCV's 8-bit fixed
// point with the weights rounded to 1/256 as OpenCV rounds them (its error
// carried from the outside in) and its border (reflected again and again
// for a kernel wider than the frame), for every kernel the parameters take.
// The colour sums of the regions stay on the CPU: they are taken over the
// few pixels of the few regions that look like squares, less work than a
// pass over the frame would be.
//
// Each stage ends in glFinish, so that its time is the GPU's and the stage
// times ("upload", "blur", "saturation", "edges", "readback") add up.
#include <GLES3/gl31.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <errno.h>
#include <initializer_list>
#include <iostream>
#include <map>

#include <opencv2/imgproc.hpp>

#include "egl_context.hpp"
#include "filters.hpp"

namespace ld::detail {
namespace {

const char* kVertex = R"(#version 300 es
// One triangle covering the viewport.
void main() {
  vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
  gl_Position = vec4(p, 0.0, 1.0);
}
)";

const char* kHeader = R"(#version 300 es
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp usampler2D;
)";

// The frame as uploaded: its BGR bytes as they are, four to an RGBA8UI
// texel (no format conversion on the way up, where drivers convert RGB8 on
// the CPU), rows padded to whole groups of four pixels (three texels).
const char* kRaw = R"(
uniform usampler2D raw;
uvec3 pixel(ivec2 p) {
  int b = 3 * p.x, t = b >> 2, o = b & 3;
  uvec4 a = texelFetch(raw, ivec2(t, p.y), 0);
  if (o == 0) return a.xyz;
  if (o == 1) return a.yzw;
  uvec4 c = texelFetch(raw, ivec2(t + 1, p.y), 0);
  return o == 2 ? uvec3(a.zw, c.x) : uvec3(a.w, c.xy);
}
)";

// OpenCV's default border (reflect 101: -1 is 1, n is n - 2) for an index
// into n pixels, the one reflection every blur here reads its border with;
// the clamp keeps an index further out (a radius wider than the image)
// inside the image.
const char* kReflect101 = R"(
int reflect101(int i, int n) {  // (as OpenCV's borderInterpolate: again and again for a kernel wider than the frame)
  if (n == 1) return 0;
  for (int k = 0; k < 64 && (i < 0 || i >= n); ++k) i = i < 0 ? -i : 2 * n - 2 - i;
  return clamp(i, 0, n - 1);
}
)";

// Labels of four pixels per texel, the arithmetic of saturationMask; the
// four pixels are three texels of the raw frame (or, BLURRED, four of the
// blurred RGBA8 image).
const char* kLabel = R"(
#ifdef BLURRED
uniform sampler2D src;  // b, g, r in .rgb
#endif
uniform int width;
uniform int thr_b, thr_r, vmin;
out vec4 o;
float label(int x, uvec3 px) {
  if (x >= width) return 0.0;
  ivec3 v = ivec3(px);
  int b = v.x, g = v.y, r = v.z;
  int mx = max(b, max(g, r)), mn = min(b, min(g, r)), c = mx - mn;
  if (mx < vmin) return 0.0;
  if (b == mx) return c > ((mx * thr_b) >> 8) && b - g > max(0, g - r) && b - r > max(0, r - g) ? 1.0 : 0.0;
  if (r == mx) return c > ((mx * thr_r) >> 8) && r - g > max(0, g - b) ? 2.0 : 0.0;
  return 0.0;
}
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  int x = q.x * 4;
#ifdef BLURRED
  uvec3 p0 = uvec3(round(texelFetch(src, ivec2(x, q.y), 0).rgb * 255.0));
  uvec3 p1 = uvec3(round(texelFetch(src, ivec2(x + 1, q.y), 0).rgb * 255.0));
  uvec3 p2 = uvec3(round(texelFetch(src, ivec2(x + 2, q.y), 0).rgb * 255.0));
  uvec3 p3 = uvec3(round(texelFetch(src, ivec2(x + 3, q.y), 0).rgb * 255.0));
#else
  uvec4 a = texelFetch(raw, ivec2(3 * q.x, q.y), 0);
  uvec4 b = texelFetch(raw, ivec2(3 * q.x + 1, q.y), 0);
  uvec4 c = texelFetch(raw, ivec2(3 * q.x + 2, q.y), 0);
  uvec3 p0 = a.xyz, p1 = uvec3(a.w, b.xy), p2 = uvec3(b.zw, c.x), p3 = c.yzw;
#endif
  o = vec4(label(x, p0), label(x + 1, p1), label(x + 2, p2), label(x + 3, p3)) / 255.0;
}
)";

// One pixel a texel (b, g, r, 0 in RGBA8UI) from the raw frame, for the
// passes that read many neighbours of each pixel.
const char* kUnpack = R"(
out uvec4 o;
void main() { o = uvec4(pixel(ivec2(gl_FragCoord.xy)), 0u); }
)";

// Separable Gaussian in OpenCV's fixed point, which it reproduces exactly:
// weights in 1/256 (rounded, the centre taking what the rounding left), the
// horizontal pass's sums kept whole (8.8), the vertical pass's rounded back
// to 8 bits; OpenCV's default border (reflect 101). This per-pixel form is
// the fast front end's (when it blurs at all): RADIUS and VERTICAL are
// defined before this; the horizontal pass reads the unpacked frame
// (kUnpack) and writes OUT_TMP (RGBA16UI), the vertical one reads that and
// writes the blurred image (RGBA8).
const char* kBlur = R"(
uniform usampler2D src;
uniform int w[RADIUS + 1];
uniform int n;  // pixels along the pass
#ifdef OUT_TMP
out uvec4 o;
#else
out vec4 o;
#endif
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  ivec3 s = ivec3(0);
  for (int k = -RADIUS; k <= RADIUS; ++k) {
#ifdef VERTICAL
    ivec2 q = ivec2(p.x, reflect101(p.y + k, n));
#else
    ivec2 q = ivec2(reflect101(p.x + k, n), p.y);
#endif
    s += w[abs(k)] * ivec3(texelFetch(src, q, 0).rgb);
  }
#ifdef OUT_TMP
  o = uvec4(uvec3(s), 0u);
#else
  o = vec4(vec3((s + 32768) >> 16) / 255.0, 1.0);
#endif
}
)";

// ---- The paper front end's formulas, each written once and put into the
// shaders of both its paths (fragment and compute), so that the two cannot
// drift apart in their arithmetic.

// HSV saturation as saturationImage, cut to zero at or below thr as
// cv::threshold TOZERO does.
const char* kSaturation = R"(
uniform int thr;
uint saturation(ivec3 v) {
  int mx = max(v.x, max(v.y, v.z)), mn = min(v.x, min(v.y, v.z));
  int sat = mx > 0 ? (255 * (mx - mn) + mx / 2) / mx : 0;
  return uint(sat > thr ? sat : 0);
}
)";

// Sobel (3x3) of a pixel from its eight neighbours, a to i row by row with
// the pixel itself (e) left out: L1 magnitude and direction sector (0
// horizontal, 1 vertical, 2 and 3 the diagonals), magnitude | sector << 16.
const char* kGradient = R"(
uint gradient(int a, int b, int c, int d, int f, int g, int h, int i) {
  int dx = (c + 2 * f + i) - (a + 2 * d + g);
  int dy = (g + 2 * h + i) - (a + 2 * b + c);
  int ax = abs(dx), ay = abs(dy);
  // tan(22.5 deg) and tan(67.5 deg) in 15-bit fixed point
  int t22 = ax * 13573, t67 = t22 + (ax << 16);
  int sector = (ay << 15) < t22 ? 0 : (ay << 15) > t67 ? 1 : ((dx ^ dy) < 0 ? 3 : 2);
  return uint(ax + ay) | (uint(sector) << 16);
}
)";

// Non-maximum suppression along the gradient and the double threshold of a
// pixel: 0, 1 (above low) or 2 (above high), from its gradient (as kGradient
// gives it) and its neighbours' magnitudes, named by compass point (n above).
// Ties go to the pixel before (left, above), as OpenCV's Canny breaks them.
const char* kClassify = R"(
uniform int low, high;
uint classify(uint g, int nw, int n, int ne, int w, int e, int sw, int s, int se) {
  int mag = int(g & 0xffffu), sector = int(g >> 16);
  if (mag <= low) return 0u;
  bool peak;
  if (sector == 0) peak = mag > w && mag >= e;
  else if (sector == 1) peak = mag > n && mag >= s;
  else if (sector == 2) peak = mag > nw && mag > se;
  else peak = mag > ne && mag > sw;
  return !peak ? 0u : mag > high ? 2u : 1u;
}
)";

// ---- The paper front end on fragment shaders: every pass four pixels a
// fragment (a group: one texel of each W/4 x H target), which cuts the
// fragments, and the texel fetches, four-fold.

// No blur: the saturation of a group, from its three texels of the raw frame.
const char* kGroupSat = R"(
out uvec4 o;
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  uvec4 a = texelFetch(raw, ivec2(3 * q.x, q.y), 0);
  uvec4 b = texelFetch(raw, ivec2(3 * q.x + 1, q.y), 0);
  uvec4 c = texelFetch(raw, ivec2(3 * q.x + 2, q.y), 0);
  o = uvec4(saturation(ivec3(a.xyz)), saturation(ivec3(a.w, b.xy)), saturation(ivec3(b.zw, c.x)),
            saturation(ivec3(c.yzw)));
}
)";

// Horizontal blur of a group, straight from the raw frame: the groups within
// reach (G each side) are read whole, three texels each; near the left and
// right borders, pixel by pixel with the reflection. The twelve sums (8.8,
// 16 bits each: pixel k's channel c is number 3k + c, two to a word) go to
// two targets, RGBA32UI and RG32UI.
const char* kGroupBlurH = R"(
uniform int w[RADIUS + 1];
uniform int width;
layout(location = 0) out uvec4 o0;
layout(location = 1) out uvec2 o1;
#define G ((RADIUS + 3) / 4)
#define N (4 * (2 * G + 1))
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  int x0 = 4 * (q.x - G);  // the first pixel of px
  uvec3 px[N];
  if (q.x >= G && 4 * q.x + 3 + RADIUS <= width - 1) {
    for (int g = 0; g < 2 * G + 1; ++g) {
      int t = 3 * (q.x - G + g);
      uvec4 a = texelFetch(raw, ivec2(t, q.y), 0);
      uvec4 b = texelFetch(raw, ivec2(t + 1, q.y), 0);
      uvec4 c = texelFetch(raw, ivec2(t + 2, q.y), 0);
      px[4 * g] = a.xyz;
      px[4 * g + 1] = uvec3(a.w, b.xy);
      px[4 * g + 2] = uvec3(b.zw, c.x);
      px[4 * g + 3] = c.yzw;
    }
  } else {
    for (int i = 0; i < N; ++i) px[i] = pixel(ivec2(reflect101(x0 + i, width), q.y));
  }
  uvec3 s[4];
  for (int k = 0; k < 4; ++k) {
    uvec3 acc = uvec3(0u);
    for (int t = -RADIUS; t <= RADIUS; ++t) acc += uint(w[abs(t)]) * px[4 * G + k + t];
    s[k] = acc;
  }
  o0 = uvec4(s[0].x | (s[0].y << 16), s[0].z | (s[1].x << 16), s[1].y | (s[1].z << 16), s[2].x | (s[2].y << 16));
  o1 = uvec2(s[2].z | (s[3].x << 16), s[3].y | (s[3].z << 16));
}
)";

// Vertical blur of a group's horizontal sums, rounded to 8 bits, and its
// saturation.
const char* kGroupBlurV = R"(
uniform usampler2D h0;
uniform usampler2D h1;
uniform int w[RADIUS + 1];
uniform int height;
out uvec4 o;
ivec3 lo(uint a, uint b) { return ivec3(int(a & 0xffffu), int(a >> 16), int(b & 0xffffu)); }
ivec3 hi(uint a, uint b) { return ivec3(int(a >> 16), int(b & 0xffffu), int(b >> 16)); }
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  ivec3 s0 = ivec3(0), s1 = ivec3(0), s2 = ivec3(0), s3 = ivec3(0);
  for (int t = -RADIUS; t <= RADIUS; ++t) {
    ivec2 r = ivec2(q.x, reflect101(q.y + t, height));
    uvec4 a = texelFetch(h0, r, 0);
    uvec2 b = texelFetch(h1, r, 0).xy;
    int k = w[abs(t)];
    s0 += k * lo(a.x, a.y);
    s1 += k * hi(a.y, a.z);
    s2 += k * lo(a.w, b.x);
    s3 += k * hi(b.x, b.y);
  }
  o = uvec4(saturation((s0 + 32768) >> 16), saturation((s1 + 32768) >> 16), saturation((s2 + 32768) >> 16),
            saturation((s3 + 32768) >> 16));
}
)";

// Sobel (kGradient, replicated border) on a group of the saturation. Each
// row needs the pixels from one before the group to one after it.
const char* kGroupSobel = R"(
uniform usampler2D sat;
uniform ivec2 size;  // pixels
out uvec4 o;
void row(int y, int q, out int v[6]) {
  y = clamp(y, 0, size.y - 1);
  int w4 = (size.x + 3) / 4;
  uvec4 l = texelFetch(sat, ivec2(max(q - 1, 0), y), 0);
  uvec4 m = texelFetch(sat, ivec2(q, y), 0);
  uvec4 r = texelFetch(sat, ivec2(min(q + 1, w4 - 1), y), 0);
  if (q >= 1 && 4 * q + 4 <= size.x - 1) {
    v = int[6](int(l.w), int(m.x), int(m.y), int(m.z), int(m.w), int(r.x));
  } else {  // at a border: pixel indices clamped (the replicated border)
    uint a[12] = uint[12](l.x, l.y, l.z, l.w, m.x, m.y, m.z, m.w, r.x, r.y, r.z, r.w);
    for (int i = 0; i < 6; ++i) v[i] = int(a[clamp(4 * q - 1 + i, 0, size.x - 1) - 4 * q + 4]);
  }
}
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  int t[6], m[6], b[6];
  row(q.y - 1, q.x, t);
  row(q.y, q.x, m);
  row(q.y + 1, q.x, b);
  uint g[4];
  for (int k = 0; k < 4; ++k)
    g[k] = gradient(t[k], t[k + 1], t[k + 2], m[k], m[k + 2], b[k], b[k + 1], b[k + 2]);
  o = uvec4(g[0], g[1], g[2], g[3]);
}
)";

// Suppression and double threshold (kClassify) of a group, one byte a
// pixel; outside the image the magnitude is 0.
const char* kGroupNms = R"(
uniform usampler2D grad;
uniform ivec2 size;
out vec4 o;
void row(int y, int q, out int v[6]) {
  int w4 = (size.x + 3) / 4;
  if (y < 0 || y >= size.y) {
    v = int[6](0, 0, 0, 0, 0, 0);
    return;
  }
  uvec4 l = q >= 1 ? texelFetch(grad, ivec2(q - 1, y), 0) : uvec4(0u);
  uvec4 m = texelFetch(grad, ivec2(q, y), 0);
  uvec4 r = q + 1 < w4 ? texelFetch(grad, ivec2(q + 1, y), 0) : uvec4(0u);
  uint a[6] = uint[6](l.w, m.x, m.y, m.z, m.w, r.x);
  for (int i = 0; i < 6; ++i) {
    int p = 4 * q - 1 + i;
    v[i] = p >= 0 && p < size.x ? int(a[i] & 0xffffu) : 0;
  }
}
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  int t[6], m[6], b[6];
  row(q.y - 1, q.x, t);
  row(q.y, q.x, m);
  row(q.y + 1, q.x, b);
  uvec4 c = texelFetch(grad, q, 0);
  uint g[4] = uint[4](c.x, c.y, c.z, c.w);
  float cl[4];
  for (int k = 0; k < 4; ++k)
    cl[k] = 4 * q.x + k < size.x
                ? float(classify(g[k], t[k], t[k + 1], t[k + 2], m[k], m[k + 2], b[k], b[k + 1], b[k + 2]))
                : 0.0;
  o = vec4(cl[0], cl[1], cl[2], cl[3]) / 255.0;
}
)";

// ---- OpenGL ES 3.1 compute path of the paper front end: two dispatches
// where the fragment path needs four passes and three intermediate
// textures; tiles of T x T pixels share their neighbourhoods in shared memory.
const char* kComputeHeader = R"(#version 310 es
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp usampler2D;
precision highp uimage2D;
)";

// Blur (OpenCV's fixed point, as kBlur), saturation and threshold
// (kSaturation) in one dispatch: the tile and its halo loaded once, the
// horizontal sums kept in shared memory, the vertical ones per pixel. RADIUS
// 0 with w[0] = 256: the saturation alone.
const char* kComputeBlurSat = R"(
layout(local_size_x = T, local_size_y = T) in;
layout(r32ui, binding = 0) writeonly uniform highp uimage2D sat_out;
uniform ivec2 size;
uniform int w[RADIUS + 1];
#define S (T + 2 * RADIUS)
shared uint px[S * S];   // b | g << 8 | r << 16
shared uvec2 hs[S * T];  // horizontal sums: b | g << 16, r
void main() {
  ivec2 o = ivec2(gl_WorkGroupID.xy) * T;
  int lid = int(gl_LocalInvocationIndex);
  for (int i = lid; i < S * S; i += T * T) {
    ivec2 q = o - RADIUS + ivec2(i % S, i / S);
    q = ivec2(reflect101(q.x, size.x), reflect101(q.y, size.y));
    uvec3 c = pixel(q);
    px[i] = c.x | (c.y << 8) | (c.z << 16);
  }
  barrier();
  for (int i = lid; i < S * T; i += T * T) {
    int row = i / T, col = i % T;
    uvec3 s = uvec3(0u);
    for (int k = -RADIUS; k <= RADIUS; ++k) {
      uint p = px[row * S + col + RADIUS + k];
      s += uint(w[abs(k)]) * uvec3(p & 255u, (p >> 8) & 255u, p >> 16);
    }
    hs[i] = uvec2(s.x | (s.y << 16), s.z);
  }
  barrier();
  ivec2 l = ivec2(gl_LocalInvocationID.xy);
  ivec2 p = o + l;
  if (p.x >= size.x || p.y >= size.y) return;
  ivec3 v = ivec3(0);
  for (int k = -RADIUS; k <= RADIUS; ++k) {
    uvec2 h = hs[(l.y + RADIUS + k) * T + l.x];
    v += w[abs(k)] * ivec3(int(h.x & 0xffffu), int(h.x >> 16), int(h.y));
  }
  imageStore(sat_out, p, uvec4(saturation((v + 32768) >> 16)));
}
)";

// Sobel, non-maximum suppression and double threshold (kGradient and
// kClassify) in one dispatch, four pixels a word into a storage buffer laid
// out as the single-channel map read back.
const char* kComputeEdges = R"(
layout(local_size_x = T, local_size_y = T) in;
uniform usampler2D sat;
uniform ivec2 size;
uniform int w4;
layout(std430, binding = 0) writeonly buffer Out { uint packed_map[]; };
#define A (T + 4)
#define B (T + 2)
shared int sv[A * A];    // saturation, replicated border
shared uint g[B * B];    // magnitude | sector << 16; 0 outside the image
shared uint cls[T * T];
int magnitude(int i) { return int(g[i] & 0xffffu); }
void main() {
  ivec2 o = ivec2(gl_WorkGroupID.xy) * T;
  int lid = int(gl_LocalInvocationIndex);
  for (int i = lid; i < A * A; i += T * T) {
    ivec2 q = clamp(o - 2 + ivec2(i % A, i / A), ivec2(0), size - 1);
    sv[i] = int(texelFetch(sat, q, 0).r);
  }
  barrier();
  for (int i = lid; i < B * B; i += T * T) {
    ivec2 b = ivec2(i % B, i / B);
    ivec2 q = o - 1 + b;
    if (q.x < 0 || q.y < 0 || q.x >= size.x || q.y >= size.y) {
      g[i] = 0u;
      continue;
    }
    int c = (b.y + 1) * A + b.x + 1;
    g[i] = gradient(sv[c - A - 1], sv[c - A], sv[c - A + 1], sv[c - 1], sv[c + 1], sv[c + A - 1], sv[c + A],
                    sv[c + A + 1]);
  }
  barrier();
  ivec2 l = ivec2(gl_LocalInvocationID.xy);
  ivec2 p = o + l;
  uint cl = 0u;
  if (p.x < size.x && p.y < size.y) {
    int c = (l.y + 1) * B + l.x + 1;
    cl = classify(g[c], magnitude(c - B - 1), magnitude(c - B), magnitude(c - B + 1), magnitude(c - 1),
                  magnitude(c + 1), magnitude(c + B - 1), magnitude(c + B), magnitude(c + B + 1));
  }
  cls[l.y * T + l.x] = cl;
  barrier();
  if ((l.x & 3) == 0 && p.x < size.x && p.y < size.y) {
    int k = l.y * T + l.x;
    packed_map[p.y * w4 + p.x / 4] = cls[k] | (cls[k + 1] << 8) | (cls[k + 2] << 16) | (cls[k + 3] << 24);
  }
}
)";

std::string glError(GLenum e) {
  switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    default: return "GL error " + std::to_string(e);
  }
}

void check(const char* what) {
  const GLenum e = glGetError();
  if (e != GL_NO_ERROR) throw BackendFailure(std::string("GLES ") + what + ": " + glError(e));
}

GLuint compile(GLenum type, const std::string& src) {
  const GLuint s = glCreateShader(type);
  const char* p = src.c_str();
  glShaderSource(s, 1, &p, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[1024] = {0};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    glDeleteShader(s);
    throw BackendFailure(std::string("GLES shader does not compile: ") + log);
  }
  return s;
}

// A program of the given compiled shaders (deleted here, linked or not).
GLuint linkProgram(std::initializer_list<GLuint> shaders, const char* what) {
  const GLuint prog = glCreateProgram();
  for (GLuint sh : shaders) glAttachShader(prog, sh);
  glLinkProgram(prog);
  for (GLuint sh : shaders) glDeleteShader(sh);
  GLint ok = 0;
  glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[1024] = {0};
    glGetProgramInfoLog(prog, sizeof log, nullptr, log);
    glDeleteProgram(prog);
    throw BackendFailure(std::string("GLES ") + what + " does not link: " + log);
  }
  return prog;
}

GLuint link(const std::string& fragment) {
  const GLuint vs = compile(GL_VERTEX_SHADER, kVertex);
  GLuint fs = 0;
  try {
    fs = compile(GL_FRAGMENT_SHADER, fragment);
  } catch (...) {
    glDeleteShader(vs);
    throw;
  }
  return linkProgram({vs, fs}, "program");
}

GLuint linkCompute(const std::string& src) {
  return linkProgram({compile(GL_COMPUTE_SHADER, src)}, "compute program");
}

class GlesFilters final : public Filters {
 public:
  /// LD_GLES_FAIL_AT_FRAME counts from here (the caller's frames, not the self test's).
  void countFramesFromNow() { frames_ = 0, counting_ = true; }
  /// compute: 0 never, 1 always where OpenGL ES 3.1 has them, -1 where they are measured faster.
  GlesFilters(std::unique_ptr<EglContext> ctx, int compute) : ctx_(std::move(ctx)) {
    glGenVertexArrays(1, &vao_);
    glGenFramebuffers(1, &fbo_);
    glGenBuffers(1, &pbo_up_);
    label_ = program("label", std::string(kHeader) + kRaw + kLabel);
    label_blurred_ = program("label_blurred", std::string(kHeader) + "#define BLURRED\n" + kLabel);
    group_sat_ = program("groupSat", std::string(kHeader) + kRaw + kSaturation + kGroupSat);
    group_sobel_ = program("groupSobel", std::string(kHeader) + kGradient + kGroupSobel);
    group_nms_ = program("groupNms", std::string(kHeader) + kClassify + kGroupNms);
    unpack_ = program("unpack", std::string(kHeader) + kRaw + kUnpack);
    check("setup");
    // Compute shaders where OpenGL ES 3.1 has them (and they compile);
    // otherwise the fragment path does everything.
    const auto& i = ctx_->info();
    if (compute != 0 && (i.major > 3 || (i.major == 3 && i.minor >= 1))) {
      // 16 x 16 tiles where 256 invocations fit (ES 3.1 promises 128); the
      // shared memory stays under the 16 KiB ES 3.1 promises up to a 31 tap blur.
      GLint invocations = 0;
      glGetIntegerv(GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS, &invocations);
      tile_ = invocations >= 256 ? 16 : 8;
      try {
        edges_cs_ = computeProgram("edges", std::string(kGradient) + kClassify + kComputeEdges, -1);
        glGenBuffers(1, &ssbo_);
        compute_ = glGetError() == GL_NO_ERROR;
        if (compute_) path_ = compute > 0 ? Path::Compute : Path::Measure;
      } catch (const BackendFailure& e) {
        compute_note_ = e.what();
      }
    }
  }

  void releaseThread() override { ctx_->release(); }

  ~GlesFilters() override {
    if (!ctx_->makeCurrent()) return;  // the context is gone: nothing to free
    for (auto& [key, prog] : programs_) glDeleteProgram(prog);
    freeTextures();
    glDeleteBuffers(1, &pbo_up_);
    if (ssbo_) glDeleteBuffers(1, &ssbo_);
    glDeleteFramebuffers(1, &fbo_);
    glDeleteVertexArrays(1, &vao_);
  }

  const char* name() const override { return "gles"; }

  bool settled(bool paper) const override { return !paper || path_ != Path::Measure; }

  std::string info(bool paper) const override {
    const auto& i = ctx_->info();
    std::string path = !paper                   ? "fragment shaders"
                       : path_ == Path::Compute ? "compute shaders"
                       : path_ == Path::Measure ? "compute or fragment shaders, the faster on the first frames"
                       : compute_               ? "fragment shaders (measured faster than compute here)"
                                                : "fragment shaders";
    if (paper && !compute_note_.empty()) path += " (no compute: " + compute_note_ + ")";
    return "gles: " + i.renderer + " (" + i.version + ") via EGL " + i.platform + "; " +
           (paper ? "paper" : "fast") + " front end on " + path;
  }

  void labelMap(const cv::Mat& bgr, const FilterSettings& s, cv::Mat& labels, const cv::Mat*& filtered,
                StageTimer& timer) override {
    begin(bgr);
    upload(bgr);
    timer.stamp("upload");
    GLuint prog = label_;
    if (s.blur_kernel > 1) {
      blur(s);
      prog = label_blurred_;
      glUseProgram(prog);
      bindTexture(0, blurred_tex_, "src", prog);
      timer.stamp("blur");
    } else {
      glUseProgram(prog);
      bindTexture(0, src_tex_, "raw", prog);
    }
    glUniform1i(glGetUniformLocation(prog, "width"), w_);
    glUniform1i(glGetUniformLocation(prog, "thr_b"), q8(s.mask.blue));
    glUniform1i(glGetUniformLocation(prog, "thr_r"), q8(s.mask.red));
    glUniform1i(glGetUniformLocation(prog, "vmin"), std::clamp(s.mask.value_min, 0, 255));
    draw(packed_tex_, w4_, h_);
    finish("saturation");
    timer.stamp("saturation");
    readPacked();
    labels = packed_.colRange(0, w_);
    filtered = &bgr;
    if (s.blur_kernel > 1) {
      readRgba(blurred_tex_, blurred_rgba_);
      cv::cvtColor(blurred_rgba_, blurred_bgr_, cv::COLOR_BGRA2BGR);
      filtered = &blurred_bgr_;
    }
    timer.stamp("readback");
  }

  void edgeMap(const cv::Mat& bgr, const FilterSettings& s, cv::Mat& edges, StageTimer& timer) override {
    begin(bgr);
    upload(bgr);
    timer.stamp("upload");
    const int thr = static_cast<int>(std::floor(s.saturation_threshold * 255.0));
    if (path_ != Path::Measure) {
      if (path_ == Path::Compute) edgeMapCompute(s, thr, edges, timer);
      else edgeMapFragment(s, thr, edges, timer);
      return;
    }
    // The first frames alternate between the paths (both give the same
    // edges), the first of each a warm-up (shaders compile on first use);
    // then the one with the shorter best time stays (the best of four: a
    // busy machine's hiccups do not decide).
    const bool compute = trial_ % 2 == 0;
    const auto t0 = StageTimer::Clock::now();
    if (compute) edgeMapCompute(s, thr, edges, timer);
    else edgeMapFragment(s, thr, edges, timer);
    const double ms = std::chrono::duration<double, std::milli>(StageTimer::Clock::now() - t0).count();
    if (trial_ >= 2) {
      double& best = compute ? compute_ms_ : fragment_ms_;
      best = std::min(best, ms);
    }
    if (++trial_ == kTrials) path_ = compute_ms_ < fragment_ms_ ? Path::Compute : Path::Fragment;
  }

 private:
  // The fragment path of edgeMap: blur H, blur V + saturation + threshold,
  // Sobel, suppression + double threshold, read back.
  void edgeMapFragment(const FilterSettings& s, int thr, cv::Mat& edges, StageTimer& timer) {
    if (s.blur_kernel > 1) {
      // blur H (raw frame -> sums), blur V + saturation + threshold
      const int radius = s.blur_kernel / 2;
      setWeights(s);
      if (group_blur_radius_ != radius) {  // compiled once per radius, not per frame
        const std::string defs = std::string(kHeader) + "#define RADIUS " + std::to_string(radius) + "\n";
        group_blur_h_ = program("groupBlurH" + std::to_string(radius), defs + kRaw + kReflect101 + kGroupBlurH);
        group_blur_v_ = program("groupBlurV" + std::to_string(radius), defs + kSaturation + kReflect101 + kGroupBlurV);
        group_blur_radius_ = radius;
      }
      glUseProgram(group_blur_h_);
      bindTexture(0, src_tex_, "raw", group_blur_h_);
      glUniform1iv(glGetUniformLocation(group_blur_h_, "w"), radius + 1, weights_.data());
      glUniform1i(glGetUniformLocation(group_blur_h_, "width"), w_);
      draw(hsum0_tex_, w4_, h_, hsum1_tex_);
      glUseProgram(group_blur_v_);
      bindTexture(0, hsum0_tex_, "h0", group_blur_v_);
      bindTexture(1, hsum1_tex_, "h1", group_blur_v_);
      glUniform1iv(glGetUniformLocation(group_blur_v_, "w"), radius + 1, weights_.data());
      glUniform1i(glGetUniformLocation(group_blur_v_, "height"), h_);
      glUniform1i(glGetUniformLocation(group_blur_v_, "thr"), thr);
      draw(gsat_tex_, w4_, h_);
      finish("blur");
      timer.stamp("blur");  // the saturation is fused into its vertical pass
    } else {
      glUseProgram(group_sat_);
      bindTexture(0, src_tex_, "raw", group_sat_);
      glUniform1i(glGetUniformLocation(group_sat_, "thr"), thr);
      draw(gsat_tex_, w4_, h_);
      finish("saturation");
    }
    timer.stamp("saturation");
    // Sobel, then suppression and double threshold
    glUseProgram(group_sobel_);
    bindTexture(0, gsat_tex_, "sat", group_sobel_);
    glUniform2i(glGetUniformLocation(group_sobel_, "size"), w_, h_);
    draw(ggrad_tex_, w4_, h_);
    glUseProgram(group_nms_);
    bindTexture(0, ggrad_tex_, "grad", group_nms_);
    glUniform2i(glGetUniformLocation(group_nms_, "size"), w_, h_);
    glUniform1i(glGetUniformLocation(group_nms_, "low"), static_cast<int>(std::floor(s.canny_low)));
    glUniform1i(glGetUniformLocation(group_nms_, "high"), static_cast<int>(std::floor(s.canny_high)));
    draw(packed_tex_, w4_, h_);
    finish("edges");
    timer.stamp("edges");
    readPacked();
    timer.stamp("readback");
    hysteresis(packed_.colRange(0, w_), edges, stack_);
    timer.stamp("hysteresis");
  }

 public:
  // Small frames through the label pass and both edge paths, against the
  // CPU: a driver that gets integer arithmetic, texel fetches or shared
  // memory wrong is no backend (or, for compute shaders only, no compute).
  bool selfTest(std::string& why) {
    cv::Mat img(29, 37, CV_8UC3);
    cv::RNG rng(7);
    rng.fill(img, cv::RNG::UNIFORM, 0, 256);
    cv::rectangle(img, {5, 5}, {15, 15}, {200, 40, 30}, cv::FILLED);   // blue
    cv::rectangle(img, {20, 8}, {30, 20}, {30, 60, 200}, cv::FILLED);  // red
    const FilterSettings s = FilterSettings::from(DetectorParams::paper());
    auto cpu = makeCpuFilters();
    std::vector<StageTime> st;
    StageTimer timer(st);
    cv::Mat want, got, edges;  // (got: a view of packed_ after labelMap)
    const cv::Mat* filtered = nullptr;
    FilterSettings no_blur = s;
    no_blur.blur_kernel = 0;
    cpu->labelMap(img, no_blur, want, filtered, timer);
    labelMap(img, no_blur, got, filtered, timer);
    if (cv::countNonZero(want != got) != 0) {
      why = "GLES self-test: the GPU's label map differs from the CPU's";
      return false;
    }
    cpu->edgeMap(img, s, want, timer);
    const Path path = path_;
    path_ = Path::Fragment;
    edgeMap(img, s, edges, timer);
    if (cv::countNonZero(want != edges) != 0) {
      why = "GLES self-test: the GPU's edge map differs from the CPU's";
      return false;
    }
    path_ = path;
    if (compute_) {
      const int thr = static_cast<int>(std::floor(s.saturation_threshold * 255.0));
      try {
        edgeMapCompute(s, thr, edges, timer);
        if (cv::countNonZero(want != edges) != 0) compute_note_ = "the compute shaders' edge map differs from the CPU's";
      } catch (const BackendFailure& e) {
        for (int k = 0; k < 8 && glGetError() != GL_NO_ERROR; ++k) {
        }  // the error flags, cleared for the fragment path
        compute_note_ = e.what();
      }
      if (!compute_note_.empty()) {
        compute_ = false;
        path_ = Path::Fragment;
      }
    }
    return true;
  }

 private:
  // The compute path of edgeMap: blur + saturation, then Sobel + suppression
  // + double threshold, straight into the storage buffer read back.
  void edgeMapCompute(const FilterSettings& s, int thr, cv::Mat& edges, StageTimer& timer) {
    const int radius = s.blur_kernel > 1 ? s.blur_kernel / 2 : 0;
    if (radius > 0) setWeights(s);
    if (blur_sat_radius_ != radius) {  // compiled once per radius, not per frame
      blur_sat_cs_ = computeProgram("blursat", std::string(kSaturation) + kReflect101 + kComputeBlurSat, radius);
      blur_sat_radius_ = radius;
    }
    const GLuint bs = blur_sat_cs_;
    const int no_blur = 256;  // both passes' weight: 256 * 256 >> 16 = 1
    const GLuint groups_x = static_cast<GLuint>((w_ + tile_ - 1) / tile_),
                 groups_y = static_cast<GLuint>((h_ + tile_ - 1) / tile_);
    glUseProgram(bs);
    bindTexture(0, src_tex_, "raw", bs);
    glUniform1iv(glGetUniformLocation(bs, "w"), radius + 1, radius > 0 ? weights_.data() : &no_blur);
    glUniform2i(glGetUniformLocation(bs, "size"), w_, h_);
    glUniform1i(glGetUniformLocation(bs, "thr"), thr);
    glBindImageTexture(0, sat32_tex_, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32UI);
    glDispatchCompute(groups_x, groups_y, 1);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
    finish(radius > 0 ? "blur" : "saturation");
    if (radius > 0) timer.stamp("blur");  // the saturation is fused into it
    timer.stamp("saturation");
    glUseProgram(edges_cs_);
    bindTexture(0, sat32_tex_, "sat", edges_cs_);
    glUniform2i(glGetUniformLocation(edges_cs_, "size"), w_, h_);
    glUniform1i(glGetUniformLocation(edges_cs_, "low"), static_cast<int>(std::floor(s.canny_low)));
    glUniform1i(glGetUniformLocation(edges_cs_, "high"), static_cast<int>(std::floor(s.canny_high)));
    glUniform1i(glGetUniformLocation(edges_cs_, "w4"), w4_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, ssbo_);
    glDispatchCompute(groups_x, groups_y, 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    finish("edges");
    timer.stamp("edges");
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, ssbo_);
    const void* src = glMapBufferRange(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(packed_.total()),
                                       GL_MAP_READ_BIT);
    if (!src) {
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
      check("read-back map");
      throw BackendFailure("GLES: cannot map the storage buffer");
    }
    std::memcpy(packed_.data, src, packed_.total());
    glUnmapBuffer(GL_SHADER_STORAGE_BUFFER);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    check("read-back");
    timer.stamp("readback");
    hysteresis(packed_.colRange(0, w_), edges, stack_);
    timer.stamp("hysteresis");
  }

  // A compute program for this tile size (and blur radius, >= 0), compiled once.
  GLuint computeProgram(const std::string& key, const std::string& body, int radius) {
    const std::string k = key + std::to_string(radius);
    auto it = programs_.find(k);
    if (it != programs_.end()) return it->second;
    std::string src = std::string(kComputeHeader) + kRaw + "#define T " + std::to_string(tile_) + "\n";
    if (radius >= 0) src += "#define RADIUS " + std::to_string(radius) + "\n";
    const GLuint p = linkCompute(src + body);
    programs_[k] = p;
    return p;
  }

  static int q8(double t) { return std::clamp(static_cast<int>(std::lround(t * 256.0)), 0, 256); }

  GLuint program(const std::string& key, const std::string& fragment) {
    auto it = programs_.find(key);
    if (it != programs_.end()) return it->second;
    const GLuint p = link(fragment);
    programs_[key] = p;
    return p;
  }

  void begin(const cv::Mat& bgr) {
    CV_Assert(bgr.type() == CV_8UC3 && !bgr.empty());
    // (a test's GPU that fails mid-run: LD_GLES_FAIL_AT_FRAME=N fails the Nth frame)
    if (counting_ && ++frames_ == fail_at_frame_) throw BackendFailure("GLES: failure forced by LD_GLES_FAIL_AT_FRAME");
    if (static_cast<int64_t>(bgr.cols) * bgr.rows > kMaxGlesPixels)
      throw FrameTooLarge("GLES: a " + std::to_string(bgr.cols) + "x" + std::to_string(bgr.rows) +
                          " frame is over the backend's " + std::to_string(kMaxGlesPixels) + " pixels (its memory)");
    if (!ctx_->makeCurrent()) throw BackendFailure("GLES: cannot make the EGL context current");
    if (bgr.cols != w_ || bgr.rows != h_) allocate(bgr.cols, bgr.rows);
  }

  GLuint texture(GLenum format, int w, int h) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexStorage2D(GL_TEXTURE_2D, 1, format, w, h);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    return t;
  }

  void freeTextures() {
    for (GLuint* t : {&src_tex_, &unpacked_tex_, &tmp_tex_, &blurred_tex_, &packed_tex_, &hsum0_tex_, &hsum1_tex_,
                      &gsat_tex_, &ggrad_tex_, &sat32_tex_})
      if (*t) {
        glDeleteTextures(1, t);
        *t = 0;
      }
  }

  void allocate(int w, int h) {
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    if (w > max_size || h > max_size)
      throw FrameTooLarge("GLES: a " + std::to_string(w) + "x" + std::to_string(h) +
                          " frame exceeds the GPU's texture size limit " + std::to_string(max_size));
    freeTextures();
    w_ = w, h_ = h, w4_ = (w + 3) / 4;
    src_tex_ = texture(GL_RGBA8UI, w4_ * 3, h);
    unpacked_tex_ = texture(GL_RGBA8UI, w, h);
    tmp_tex_ = texture(GL_RGBA16UI, w, h);
    blurred_tex_ = texture(GL_RGBA8, w, h);
    hsum0_tex_ = texture(GL_RGBA32UI, w4_, h);
    hsum1_tex_ = texture(GL_RG32UI, w4_, h);
    gsat_tex_ = texture(GL_RGBA8UI, w4_, h);
    ggrad_tex_ = texture(GL_RGBA32UI, w4_, h);
    packed_tex_ = texture(GL_RGBA8, w4_, h);
    packed_.create(h, w4_ * 4, CV_8UC1);
    if (compute_) {
      sat32_tex_ = texture(GL_R32UI, w, h);
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, ssbo_);
      glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(packed_.total()), nullptr, GL_STREAM_READ);
      glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    }
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo_up_);
    glBufferData(GL_PIXEL_UNPACK_BUFFER, static_cast<GLsizeiptr>(w4_) * 12 * h, nullptr, GL_STREAM_DRAW);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    check("allocation");
  }

  void upload(const cv::Mat& bgr) {
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, pbo_up_);
    const size_t row = static_cast<size_t>(w_) * 3, pitch = static_cast<size_t>(w4_) * 12;
    void* dst = glMapBufferRange(GL_PIXEL_UNPACK_BUFFER, 0, static_cast<GLsizeiptr>(pitch * h_),
                                 GL_MAP_WRITE_BIT | GL_MAP_INVALIDATE_BUFFER_BIT);
    if (!dst) {
      glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
      check("upload map");
      throw BackendFailure("GLES: cannot map the upload buffer");
    }
    if (bgr.isContinuous() && row == pitch) std::memcpy(dst, bgr.data, row * h_);
    else
      for (int y = 0; y < h_; ++y) std::memcpy(static_cast<uint8_t*>(dst) + pitch * y, bgr.ptr(y), row);
    glUnmapBuffer(GL_PIXEL_UNPACK_BUFFER);
    glBindTexture(GL_TEXTURE_2D, src_tex_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w4_ * 3, h_, GL_RGBA_INTEGER, GL_UNSIGNED_BYTE, nullptr);
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, 0);
    finish("upload");
  }

  void bindTexture(int unit, GLuint tex, const char* uniform, GLuint prog) {
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(GL_TEXTURE_2D, tex);
    glUniform1i(glGetUniformLocation(prog, uniform), unit);
  }

  // The bound program over w x h pixels into target, and into target1 too
  // where there is one (the horizontal blur's sums). Attachment 1 is emptied
  // when not drawn to: a framebuffer's attachments of different sizes would
  // cut the drawing to the smallest.
  void draw(GLuint target, int w, int h, GLuint target1 = 0) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, target, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, target1, 0);
    const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(target1 ? 2 : 1, buffers);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw BackendFailure("GLES: incomplete framebuffer");
    glViewport(0, 0, w, h);
    glBindVertexArray(vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }

  void finish(const char* what) {
    glFinish();
    check(what);
  }

  // OpenCV's Gaussian in 1/256: rounded, the centre taking the remainder.
  void setWeights(const FilterSettings& s) {
    if (kernel_size_ == s.blur_kernel && kernel_sigma_ == s.blur_sigma) return;
    const int radius = s.blur_kernel / 2;
    // As OpenCV makes its 8-bit kernel (getGaussianKernelFixedPoint_ED):
    // from the outside in, each weight in 1/256 rounded to nearest (ties to
    // even) with the error carried to the next, and the centre the rest.
    // (Rounded each on its own, kernels of 7 and 11 at sigma 3 came out
    // otherwise, and so did some blurred pixels and edges.)
    const cv::Mat k = cv::getGaussianKernel(s.blur_kernel, s.blur_sigma, CV_64F);
    weights_.assign(static_cast<size_t>(radius) + 1, 0);
    int sum = 0;
    double err = 0;
    for (int i = 0; i < radius; ++i) {
      const double adjusted = k.at<double>(i) * 256.0 + err;
      const int wq = static_cast<int>(std::nearbyint(adjusted));
      err = adjusted - wq;
      weights_[static_cast<size_t>(radius - i)] = wq;
      sum += 2 * wq;
    }
    weights_[0] = 256 - sum;
    kernel_size_ = s.blur_kernel;
    kernel_sigma_ = s.blur_sigma;
  }

  // The fast front end's blur, pixel by pixel: the frame unpacked, H into
  // tmp, V into the blurred image.
  void blur(const FilterSettings& s) {
    const int radius = s.blur_kernel / 2;
    setWeights(s);
    if (blur_radius_ != radius) {  // programs for this radius (compiled once, not per frame)
      const std::string defs = std::string(kHeader) + "#define RADIUS " + std::to_string(radius) + "\n";
      blur_h_ = program("blurH" + std::to_string(radius), defs + "#define OUT_TMP\n" + kReflect101 + kBlur);
      blur_v_ = program("blurV" + std::to_string(radius), defs + "#define VERTICAL\n" + kReflect101 + kBlur);
      blur_radius_ = radius;
    }
    glUseProgram(unpack_);
    bindTexture(0, src_tex_, "raw", unpack_);
    draw(unpacked_tex_, w_, h_);
    glUseProgram(blur_h_);
    bindTexture(0, unpacked_tex_, "src", blur_h_);
    glUniform1iv(glGetUniformLocation(blur_h_, "w"), radius + 1, weights_.data());
    glUniform1i(glGetUniformLocation(blur_h_, "n"), w_);
    draw(tmp_tex_, w_, h_);
    glUseProgram(blur_v_);
    bindTexture(0, tmp_tex_, "src", blur_v_);
    glUniform1iv(glGetUniformLocation(blur_v_, "w"), radius + 1, weights_.data());
    glUniform1i(glGetUniformLocation(blur_v_, "n"), h_);
    draw(blurred_tex_, w_, h_);
    finish("blur");
  }

  // Reads the attachment of fbo_ (w x h RGBA8) into `dst`, straight into
  // the caller's memory. (Through a pixel pack buffer and a fence instead,
  // NVIDIA's driver made the next frame's upload wait about 0.9 ms whenever
  // the CPU worked between frames, as a detector does: docs/benchmarks.md.)
  void readInto(GLuint tex, int w, int h, uint8_t* dst, size_t bytes) {
    CV_Assert(bytes == static_cast<size_t>(w) * h * 4);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, dst);
    check("read-back");
  }

  void readPacked() {
    CV_Assert(packed_.isContinuous());
    readInto(packed_tex_, w4_, h_, packed_.data, packed_.total());
  }

  void readRgba(GLuint tex, cv::Mat& dst) {
    dst.create(h_, w_, CV_8UC4);
    CV_Assert(dst.isContinuous());
    readInto(tex, w_, h_, dst.data, dst.total() * 4);
  }

  std::unique_ptr<EglContext> ctx_;
  GLuint vao_ = 0, fbo_ = 0, pbo_up_ = 0;
  GLuint label_ = 0, label_blurred_ = 0, unpack_ = 0;
  GLuint group_sat_ = 0, group_sobel_ = 0, group_nms_ = 0, group_blur_h_ = 0, group_blur_v_ = 0;
  int group_blur_radius_ = -1;
  bool compute_ = false;     // compute shaders usable
  // The paper front end's path: fragment or compute shaders, or measuring
  // which is faster on the first frames.
  enum class Path { Fragment, Compute, Measure } path_ = Path::Fragment;
  static constexpr int kTrials = 10;  // two warm-ups, then four of each
  int trial_ = 0;
  double compute_ms_ = 1e300, fragment_ms_ = 1e300;
  std::string compute_note_; // why not, when they exist but fail to compile
  int tile_ = 16;            // compute tiles: tile_ x tile_ invocations
  GLuint edges_cs_ = 0, ssbo_ = 0, sat32_tex_ = 0;
  GLuint blur_sat_cs_ = 0;
  int blur_sat_radius_ = -1;
  int blur_radius_ = -1;
  GLuint blur_h_ = 0, blur_v_ = 0;
  std::map<std::string, GLuint> programs_;
  GLuint src_tex_ = 0, unpacked_tex_ = 0, tmp_tex_ = 0, blurred_tex_ = 0, packed_tex_ = 0;
  GLuint hsum0_tex_ = 0, hsum1_tex_ = 0, gsat_tex_ = 0, ggrad_tex_ = 0;  // groups of four pixels
  int w_ = 0, h_ = 0, w4_ = 0;
  int64_t frames_ = 0;
  bool counting_ = false;
  const int64_t fail_at_frame_ = [] {
    const char* env = std::getenv("LD_GLES_FAIL_AT_FRAME");
    return env ? std::atoll(env) : int64_t{-1};
  }();
  int kernel_size_ = -1;
  double kernel_sigma_ = -1;
  std::vector<int> weights_;
  cv::Mat packed_, blurred_rgba_, blurred_bgr_;
  std::vector<int> stack_;
};

}  // namespace

bool glesBuilt() { return true; }

std::unique_ptr<Filters> makeGlesFilters(std::string& why, bool allow_compute, bool hardware_only) {
  std::unique_ptr<EglContext> ctx = EglContext::create(why);
  if (!ctx) return nullptr;
  if (hardware_only && ctx->info().software) {
    why = "no GPU, only the software renderer " + ctx->info().renderer + ", slower than the CPU backend";
    return nullptr;
  }
  try {
    const char* env = std::getenv("LD_GLES_COMPUTE");
    if (env && *env && std::strcmp(env, "0") != 0 && std::strcmp(env, "1") != 0) {
      static bool said = false;  // (once a process)
      if (!said)
        std::cerr << program_invocation_short_name << ": warning: LD_GLES_COMPUTE=" << env
                  << " is neither 0 nor 1: ignored (the faster shader path is measured)\n";
      said = true;
    }
    const int compute = !allow_compute ? 0 : env && std::strcmp(env, "0") == 0 ? 0 : env && std::strcmp(env, "1") == 0 ? 1 : -1;
    auto f = std::make_unique<GlesFilters>(std::move(ctx), compute);
    if (!f->selfTest(why)) return nullptr;
    f->countFramesFromNow();  // (LD_GLES_FAIL_AT_FRAME counts the caller's frames, not the self test's)
    f->releaseThread();       // (a detector made in one thread may run in another)
    return f;
  } catch (const std::exception& e) {
    why = e.what();
    return nullptr;
  }
}

}  // namespace ld::detail
