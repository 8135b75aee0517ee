#include "qr_codewords.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "qr_function_patterns.hpp"

namespace ld::detail {
namespace {

// GF(256) with the QR's field polynomial x^8 + x^4 + x^3 + x^2 + 1.
struct Gf {
  std::array<uint8_t, 512> exp{};
  std::array<int, 256> log{};
  Gf() {
    int x = 1;
    for (int i = 0; i < 255; ++i) {
      exp[static_cast<size_t>(i)] = static_cast<uint8_t>(x);
      log[static_cast<size_t>(x)] = i;
      x <<= 1;
      if (x & 0x100) x ^= 0x11d;
    }
    for (int i = 255; i < 512; ++i) exp[static_cast<size_t>(i)] = exp[static_cast<size_t>(i - 255)];
  }
  uint8_t mul(uint8_t a, uint8_t b) const {
    return a && b ? exp[static_cast<size_t>(log[a] + log[b])] : 0;
  }
  uint8_t inv(uint8_t a) const { return exp[static_cast<size_t>(255 - log[a])]; }
  uint8_t pow(int i) const { return exp[static_cast<size_t>(((i % 255) + 255) % 255)]; }
};
const Gf& gf() {
  static const Gf g;
  return g;
}

// Polynomials below are coefficient arrays, lowest degree first.
uint8_t evalLow(const uint8_t* p, int len, uint8_t x) {
  uint8_t y = 0;
  for (int i = len - 1; i >= 0; --i) y = static_cast<uint8_t>(gf().mul(y, x) ^ p[i]);
  return y;
}

// The block's syndromes S_i = c(a^i), i < ec, with the first codeword the
// highest power; true when all are zero.
bool syndromes(const std::vector<uint8_t>& block, int ec, std::array<uint8_t, 256>& s) {
  bool zero = true;
  for (int i = 0; i < ec; ++i) {
    const uint8_t x = gf().pow(i);
    uint8_t y = 0;
    for (uint8_t c : block) y = static_cast<uint8_t>(gf().mul(y, x) ^ c);
    s[static_cast<size_t>(i)] = y;
    zero &= y == 0;
  }
  return zero;
}

// ISO/IEC 18004 table 9, versions 1..15, levels L, M, Q, H: check codewords
// per block, blocks of the shorter kind, their data codewords, blocks of the
// longer kind (one data codeword more).
constexpr QrBlocks kBlocks[15][4] = {
    {{7, 1, 19, 0}, {10, 1, 16, 0}, {13, 1, 13, 0}, {17, 1, 9, 0}},
    {{10, 1, 34, 0}, {16, 1, 28, 0}, {22, 1, 22, 0}, {28, 1, 16, 0}},
    {{15, 1, 55, 0}, {26, 1, 44, 0}, {18, 2, 17, 0}, {22, 2, 13, 0}},
    {{20, 1, 80, 0}, {18, 2, 32, 0}, {26, 2, 24, 0}, {16, 4, 9, 0}},
    {{26, 1, 108, 0}, {24, 2, 43, 0}, {18, 2, 15, 2}, {22, 2, 11, 2}},
    {{18, 2, 68, 0}, {16, 4, 27, 0}, {24, 4, 19, 0}, {28, 4, 15, 0}},
    {{20, 2, 78, 0}, {18, 4, 31, 0}, {18, 2, 14, 4}, {26, 4, 13, 1}},
    {{24, 2, 97, 0}, {22, 2, 38, 2}, {22, 4, 18, 2}, {26, 4, 14, 2}},
    {{30, 2, 116, 0}, {22, 3, 36, 2}, {20, 4, 16, 4}, {24, 4, 12, 4}},
    {{18, 2, 68, 2}, {26, 4, 43, 1}, {24, 6, 19, 2}, {28, 6, 15, 2}},
    {{20, 4, 81, 0}, {30, 1, 50, 4}, {28, 4, 22, 4}, {24, 3, 12, 8}},
    {{24, 2, 92, 2}, {22, 6, 36, 2}, {26, 4, 20, 6}, {28, 7, 14, 4}},
    {{26, 4, 107, 0}, {22, 8, 37, 1}, {24, 8, 20, 4}, {22, 12, 11, 4}},
    {{30, 3, 115, 1}, {24, 4, 40, 5}, {20, 11, 16, 5}, {24, 11, 12, 5}},
    {{22, 5, 87, 1}, {24, 5, 41, 5}, {30, 5, 24, 7}, {24, 11, 12, 7}},
};

// A block's checks that must stay unused for a correction to be trusted:
// with e errors and f erasures, 2e + f <= ec - kSpareChecks. Each spare check
// makes a wrong correction of a block that is in fact beyond repair about
// 256 times less likely; zbar's parse of the payload catches most of the rest.
constexpr int kSpareChecks = 3;

// The format information's modules (row, column), most significant bit first,
// its first copy (around the top-left finder) and its second (split between
// the bottom-left and top-right finders).
std::array<std::array<int, 2>, 15> formatCopy(int n, int copy) {
  if (copy == 0)
    return {{{8, 0}, {8, 1}, {8, 2}, {8, 3}, {8, 4}, {8, 5}, {8, 7}, {8, 8},
             {7, 8}, {5, 8}, {4, 8}, {3, 8}, {2, 8}, {1, 8}, {0, 8}}};
  std::array<std::array<int, 2>, 15> at{};
  for (int k = 0; k < 7; ++k) at[static_cast<size_t>(k)] = {n - 1 - k, 8};
  for (int k = 0; k < 8; ++k) at[static_cast<size_t>(7 + k)] = {8, n - 8 + k};
  return at;
}

// The version information (versions 7 and up): 6 data bits and 12 of BCH.
int versionBits(int version) {
  int rem = version << 12;
  for (int b = 17; b >= 12; --b)
    if (rem & (1 << b)) rem ^= 0x1f25 << (b - 12);
  return (version << 12) | rem;
}

bool masked(int mask, int r, int c) {
  switch (mask) {
    case 0: return (r + c) % 2 == 0;
    case 1: return r % 2 == 0;
    case 2: return c % 3 == 0;
    case 3: return (r + c) % 3 == 0;
    case 4: return (r / 2 + c / 3) % 2 == 0;
    case 5: return (r * c) % 2 + (r * c) % 3 == 0;
    case 6: return ((r * c) % 2 + (r * c) % 3) % 2 == 0;
    default: return ((r + c) % 2 + (r * c) % 3) % 2 == 0;
  }
}

// The format's level bits: L 01, M 00, Q 11, H 10.
constexpr int kLevelBits[4] = {1, 0, 3, 2};

}  // namespace

QrBlocks qrBlocks(int version, QrLevel level) {
  return kBlocks[version - 1][static_cast<int>(level)];
}

int qrFormatBits(QrLevel level, int mask) {
  const int data = (kLevelBits[static_cast<int>(level)] << 3) | mask;
  int rem = data << 10;
  for (int b = 14; b >= 10; --b)
    if (rem & (1 << b)) rem ^= 0x537 << (b - 10);
  return ((data << 10) | rem) ^ 0x5412;
}

std::vector<uint8_t> qrDataModules(int n) {
  std::vector<uint8_t> data(static_cast<size_t>(n) * n, 1);
  auto clear = [&](int r, int c) { data[static_cast<size_t>(r) * n + c] = 0; };
  forEachFunctionModule(n, [&](int r, int c, bool) { clear(r, c); });
  for (int copy = 0; copy < 2; ++copy)
    for (const auto& rc : formatCopy(n, copy)) clear(rc[0], rc[1]);
  if ((n - 17) / 4 >= 7)
    for (int k = 0; k < 18; ++k) {
      clear(k / 3, n - 11 + k % 3);
      clear(n - 11 + k % 3, k / 3);
    }
  return data;
}

int rsCorrect(std::vector<uint8_t>& block, int ec, const std::vector<int>& erasures) {
  const Gf& g = gf();
  const int len = static_cast<int>(block.size());
  const int f = static_cast<int>(erasures.size());
  if (ec <= 0 || ec > 255 || len > 255 || len <= ec || f > ec) return -1;
  for (int pos : erasures)
    if (pos < 0 || pos >= len) return -1;
  std::array<uint8_t, 256> s{};
  if (syndromes(block, ec, s)) return 0;
  // The erasures' locator, then Berlekamp-Massey from it for the errors
  // (the errata locator Lambda and its degree L).
  std::array<uint8_t, 257> lambda{}, b{}, t{};
  lambda[0] = 1;
  for (int pos : erasures) {
    const uint8_t x = g.pow(len - 1 - pos);
    for (int i = f; i >= 1; --i) lambda[static_cast<size_t>(i)] ^= g.mul(lambda[static_cast<size_t>(i - 1)], x);
  }
  b = lambda;
  int L = f;
  for (int k = f; k < ec; ++k) {
    uint8_t delta = 0;
    for (int i = 0; i <= std::min(k, ec); ++i)
      delta ^= g.mul(lambda[static_cast<size_t>(i)], s[static_cast<size_t>(k - i)]);
    // b <- x b (in both branches but the one that replaces it)
    for (int i = ec; i >= 1; --i) b[static_cast<size_t>(i)] = b[static_cast<size_t>(i - 1)];
    b[0] = 0;
    if (delta == 0) continue;
    for (int i = 0; i <= ec; ++i)
      t[static_cast<size_t>(i)] = lambda[static_cast<size_t>(i)] ^ g.mul(delta, b[static_cast<size_t>(i)]);
    if (2 * L <= k + f) {
      const uint8_t inv = g.inv(delta);
      for (int i = 0; i <= ec; ++i) b[static_cast<size_t>(i)] = g.mul(lambda[static_cast<size_t>(i)], inv);
      L = k + 1 + f - L;
    }
    lambda = t;
  }
  int degree = 0;
  for (int i = 0; i <= ec; ++i)
    if (lambda[static_cast<size_t>(i)]) degree = i;
  if (degree != L || L > ec || 2 * (L - f) + f > ec) return -1;
  // Omega = S Lambda mod x^ec, and Lambda's formal derivative.
  std::array<uint8_t, 256> omega{}, dlambda{};
  for (int i = 0; i < ec; ++i)
    for (int j = 0; j <= i && j <= L; ++j)
      omega[static_cast<size_t>(i)] ^= g.mul(s[static_cast<size_t>(i - j)], lambda[static_cast<size_t>(j)]);
  for (int i = 1; i <= L; i += 2) dlambda[static_cast<size_t>(i - 1)] = lambda[static_cast<size_t>(i)];
  // Chien search over the block's positions, Forney for each root's value.
  std::array<std::pair<int, uint8_t>, 256> fix{};
  int roots = 0;
  for (int pos = 0; pos < len; ++pos) {
    const uint8_t x = g.pow(len - 1 - pos), x_inv = g.inv(x);
    if (evalLow(lambda.data(), L + 1, x_inv) != 0) continue;
    const uint8_t denom = evalLow(dlambda.data(), L, x_inv);
    if (denom == 0) return -1;
    const uint8_t value = g.mul(g.mul(x, evalLow(omega.data(), ec, x_inv)), g.inv(denom));
    fix[static_cast<size_t>(roots++)] = {pos, value};
  }
  if (roots != L) return -1;
  for (int i = 0; i < roots; ++i) block[static_cast<size_t>(fix[static_cast<size_t>(i)].first)] ^= fix[static_cast<size_t>(i)].second;
  if (!syndromes(block, ec, s)) {  // (cannot happen for a root count that matches; kept as a guard)
    for (int i = 0; i < roots; ++i) block[static_cast<size_t>(fix[static_cast<size_t>(i)].first)] ^= fix[static_cast<size_t>(i)].second;
    return -1;
  }
  int errors = 0;
  for (int i = 0; i < roots; ++i)
    errors += std::find(erasures.begin(), erasures.end(), fix[static_cast<size_t>(i)].first) == erasures.end();
  return errors;
}

bool QrCorrector::correct(int n, const float* darkness, std::vector<uint8_t>& modules) {
  const int version = (n - 17) / 4;
  if (version < 1 || version > 15 || n != 17 + 4 * version) return false;
  // The format: the (level, mask) whose 15 bits, in both copies, agree best
  // with the modules, each module weighed by how sure it is.
  auto dark = [&](int r, int c) { return std::clamp(darkness[static_cast<size_t>(r) * n + c], 0.0f, 1.0f); };
  std::array<std::pair<float, int>, 32> formats{};
  for (int k = 0; k < 32; ++k) {
    const int bits = qrFormatBits(static_cast<QrLevel>(k / 8), k % 8);
    float agree = 0;
    for (int copy = 0; copy < 2; ++copy) {
      const auto at = formatCopy(n, copy);
      for (int i = 0; i < 15; ++i) {
        const bool one = (bits >> (14 - i)) & 1;
        const float d = dark(at[static_cast<size_t>(i)][0], at[static_cast<size_t>(i)][1]) - 0.5f;
        agree += one ? d : -d;
      }
    }
    formats[static_cast<size_t>(k)] = {agree, k};
  }
  std::partial_sort(formats.begin(), formats.begin() + 2, formats.end(),
                    [](const auto& a, const auto& b) { return a.first > b.first; });
  for (int k = 0; k < 2; ++k) {
    const int f = formats[static_cast<size_t>(k)].second;
    if (correctAs(n, version, static_cast<QrLevel>(f / 8), f % 8, darkness, modules)) return true;
  }
  return false;
}

bool QrCorrector::correctAs(int n, int version, QrLevel level, int mask, const float* darkness,
                            std::vector<uint8_t>& modules) {
  if (data_n_ != n) {
    data_ = qrDataModules(n);
    data_n_ = n;
    // the data modules in placement order: two columns at a time from the
    // right, up then down, skipping the vertical timing column
    order_.clear();
    bool up = true;
    for (int c = n - 1; c > 0; c -= 2) {
      if (c == 6) --c;
      for (int k = 0; k < n; ++k) {
        const int r = up ? n - 1 - k : k;
        for (int cc : {c, c - 1})
          if (data_[static_cast<size_t>(r) * n + cc]) order_.push_back(r * n + cc);
      }
      up = !up;
    }
  }
  const QrBlocks spec = qrBlocks(version, level);
  const int codewords = static_cast<int>(order_.size()) / 8;
  if (spec.total() != codewords) return false;
  // The codewords as read, each as sure as its least sure module.
  raw_.assign(static_cast<size_t>(codewords), 0);
  sure_.assign(static_cast<size_t>(codewords), 1.0f);
  for (int i = 0; i < codewords * 8; ++i) {
    const int at = order_[static_cast<size_t>(i)], r = at / n, c = at % n;
    const float d = std::clamp(darkness[at], 0.0f, 1.0f);
    const bool bit = (d > 0.5f) != masked(mask, r, c);
    uint8_t& w = raw_[static_cast<size_t>(i / 8)];
    w = static_cast<uint8_t>(w | (bit << (7 - i % 8)));
    float& s = sure_[static_cast<size_t>(i / 8)];
    s = std::min(s, std::abs(d - 0.5f));
  }
  // Each block from the interleaved codewords: data codeword i of every
  // block in turn (the longer blocks' last one after all others), then check
  // codeword i of every block.
  const int nblocks = spec.blocks1 + spec.blocks2;
  if (static_cast<int>(blocks_.size()) < nblocks) blocks_.resize(static_cast<size_t>(nblocks));
  auto dataOf = [&](int j) { return spec.data1 + (j >= spec.blocks1 ? 1 : 0); };
  // (block j's codeword i <-> index into raw_)
  auto rawIndex = [&](int j, int i) {
    if (i < spec.data1) return i * nblocks + j;
    if (i == spec.data1 && j >= spec.blocks1 && i < dataOf(j)) return spec.data1 * nblocks + (j - spec.blocks1);
    const int data_total = spec.blocks1 * spec.data1 + spec.blocks2 * (spec.data1 + 1);
    return data_total + (i - dataOf(j)) * nblocks + j;
  };
  int erased_total = 0, errors_total = 0;
  for (int j = 0; j < nblocks; ++j) {
    const int len = dataOf(j) + spec.ec;
    std::vector<uint8_t>& blk = blocks_[static_cast<size_t>(j)];
    blk.resize(static_cast<size_t>(len));
    block_sure_.resize(static_cast<size_t>(len));
    for (int i = 0; i < len; ++i) {
      blk[static_cast<size_t>(i)] = raw_[static_cast<size_t>(rawIndex(j, i))];
      block_sure_[static_cast<size_t>(i)] = sure_[static_cast<size_t>(rawIndex(j, i))];
    }
    by_doubt_.resize(static_cast<size_t>(len));
    std::iota(by_doubt_.begin(), by_doubt_.end(), 0);
    std::stable_sort(by_doubt_.begin(), by_doubt_.end(), [&](int a, int b) {
      return block_sure_[static_cast<size_t>(a)] < block_sure_[static_cast<size_t>(b)];
    });
    // Generalised minimum distance: erase the f least sure codewords, f = 0,
    // 2, 4, ..., and keep the first correction that leaves kSpareChecks.
    bool done = false;
    for (int f = 0; f <= spec.ec - kSpareChecks && !done; f += 2) {
      erasures_.assign(by_doubt_.begin(), by_doubt_.begin() + f);
      block_ = blk;
      const int e = rsCorrect(block_, spec.ec, erasures_);
      if (e >= 0 && 2 * e + f <= spec.ec - kSpareChecks) {
        blk.swap(block_);
        erased_total += f;
        errors_total += e;
        done = true;
      }
    }
    if (!done) return false;
  }
  // The corrected symbol: codewords back in their places, masked; the
  // function patterns, format and version ideal; remainder bits light.
  for (int j = 0; j < nblocks; ++j)
    for (int i = 0; i < dataOf(j) + spec.ec; ++i)
      raw_[static_cast<size_t>(rawIndex(j, i))] = blocks_[static_cast<size_t>(j)][static_cast<size_t>(i)];
  modules.assign(static_cast<size_t>(n) * n, 0);
  for (size_t i = 0; i < order_.size(); ++i) {
    const int at = order_[i], r = at / n, c = at % n;
    const bool bit = static_cast<int>(i) < codewords * 8 && ((raw_[i / 8] >> (7 - i % 8)) & 1);
    modules[static_cast<size_t>(at)] = bit != masked(mask, r, c);
  }
  forEachFunctionModule(n, [&](int r, int c, bool d) { modules[static_cast<size_t>(r) * n + c] = d; });
  const int format = qrFormatBits(level, mask);
  for (int copy = 0; copy < 2; ++copy) {
    const auto at = formatCopy(n, copy);
    for (int i = 0; i < 15; ++i)
      modules[static_cast<size_t>(at[static_cast<size_t>(i)][0]) * n + at[static_cast<size_t>(i)][1]] =
          (format >> (14 - i)) & 1;
  }
  if (version >= 7) {
    const int bits = versionBits(version);
    for (int k = 0; k < 18; ++k) {
      const bool d = (bits >> k) & 1;
      modules[static_cast<size_t>(k / 3) * n + n - 11 + k % 3] = d;
      modules[static_cast<size_t>(n - 11 + k % 3) * n + k / 3] = d;
    }
  }
  last_erasures_ = erased_total;
  last_errors_ = errors_total;
  return true;
}

}  // namespace ld::detail
