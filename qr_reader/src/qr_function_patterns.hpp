// The fixed modules of a QR symbol, for the QR reader's module-by-module
// path (qr_reader.cpp). Not a public interface; tests include it by its path.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <utility>
#include <vector>

namespace ld::detail {

// The function patterns of an n-module QR symbol (version (n - 17) / 4),
// which carry no data and are the same in every code: the three finders
// with their white separators, the timing rows, the alignment patterns
// (ISO/IEC 18004 table E.1, versions 1-15) and the dark module. `f(r, c,
// dark)` for each of their modules. Redrawn ideal in a code read module by
// module, one wrong module in a finder no longer hides the code from zbar
// (data modules have error correction; these do not).
template <typename F>
void forEachFunctionModule(int n, F&& f) {
  const int version = (n - 17) / 4;
  for (const auto& [r0, c0] : {std::pair{0, 0}, {0, n - 7}, {n - 7, 0}})
    for (int r = -1; r <= 7; ++r)
      for (int c = -1; c <= 7; ++c) {
        const int rr = r0 + r, cc = c0 + c;
        if (rr < 0 || cc < 0 || rr >= n || cc >= n) continue;
        const int d = std::max(std::abs(r - 3), std::abs(c - 3));
        f(rr, cc, d != 2 && d != 4);  // d 4: the separator
      }
  for (int i = 8; i < n - 8; ++i) {
    f(6, i, i % 2 == 0);
    f(i, 6, i % 2 == 0);
  }
  static const std::vector<std::vector<int>> kAlignment{
      {}, {}, {6, 18}, {6, 22}, {6, 26}, {6, 30}, {6, 34}, {6, 22, 38}, {6, 24, 42}, {6, 26, 46},
      {6, 28, 50}, {6, 30, 54}, {6, 32, 58}, {6, 34, 62}, {6, 26, 46, 66}, {6, 26, 48, 70}};
  if (version >= 2 && version < static_cast<int>(kAlignment.size())) {
    const auto& at = kAlignment[static_cast<size_t>(version)];
    for (int ar : at)
      for (int ac : at) {
        if ((ar == 6 && ac == 6) || (ar == 6 && ac == at.back()) || (ar == at.back() && ac == 6)) continue;
        for (int r = -2; r <= 2; ++r)
          for (int c = -2; c <= 2; ++c) f(ar + r, ac + c, std::max(std::abs(r), std::abs(c)) != 1);
      }
  }
  if (version >= 1) f(4 * version + 9, 8, true);
}

}  // namespace ld::detail
