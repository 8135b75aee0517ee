// The QR tests' count of a module estimate against the printed code: the
// data modules (all but the function patterns, which the reader redraws
// ideal) it gets wrong. Tests include it by its path.
#pragma once

#include <cstdint>
#include <vector>

#include "ld/artwork.hpp"
#include "../qr_reader/src/qr_function_patterns.hpp"

namespace ld::test {

// 1 for each of an n-module code's function-pattern modules (row-major).
inline std::vector<uint8_t> functionModules(int n) {
  std::vector<uint8_t> function(static_cast<size_t>(n) * n, 0);
  ld::detail::forEachFunctionModule(n, [&](int r, int c, bool) { function[static_cast<size_t>(r) * n + c] = 1; });
  return function;
}

struct DataModulesWrong {
  int wrong = 0;  // data modules `modules` has otherwise than `qr`
  int count = 0;  // data modules in the code
};
// `modules`: n x n, 1 dark, as the pixel model estimates them (an empty or
// short estimate counts only the modules it has).
inline DataModulesWrong wrongDataModules(const ld::artwork::QrCode& qr, const std::vector<uint8_t>& modules) {
  const int n = qr.size;
  const std::vector<uint8_t> function = functionModules(n);
  DataModulesWrong w;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      const size_t i = static_cast<size_t>(r) * n + c;
      if (function[i]) continue;
      ++w.count;
      if (i < modules.size()) w.wrong += (modules[i] != 0) != qr.dark(c, r);
    }
  return w;
}

}  // namespace ld::test
