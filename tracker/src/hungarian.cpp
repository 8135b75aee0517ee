#include "ld/hungarian.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace ld {

double Hungarian::solve(const double* cost, int rows, int cols, std::vector<int>& row_to_col) {
  if (rows < 0 || cols < 0)
    throw std::invalid_argument("Hungarian::solve: negative matrix size " + std::to_string(rows) +
                                "x" + std::to_string(cols));
  row_to_col.assign(static_cast<size_t>(rows), -1);
  if (rows == 0 || cols == 0) return 0.0;

  // 1. CHECK AND PRICE THE MATRIX. Forbidden pairs get a finite price larger
  // than any difference between two sums of allowed costs, so that every
  // assignment with one forbidden pair fewer is cheaper.
  const bool transposed = rows > cols;
  const int n = transposed ? cols : rows;  // n <= m
  const int m = transposed ? rows : cols;
  const size_t total = static_cast<size_t>(rows) * static_cast<size_t>(cols);
  double max_abs = 0.0;
  bool any_forbidden = false;
  for (size_t k = 0; k < total; ++k) {
    const double c = cost[k];
    if (std::isnan(c) || c == -kForbidden)
      throw std::invalid_argument("Hungarian::solve: cost entry " + std::to_string(k) +
                                  " is NaN or -infinity");
    if (c == kForbidden)
      any_forbidden = true;
    else
      max_abs = std::max(max_abs, std::fabs(c));
  }
  const double forbidden_price = any_forbidden ? 2.0 * (n + 1) * (max_abs + 1.0) : 0.0;
  a_.resize(total);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < m; ++j) {
      const double c = transposed ? cost[static_cast<size_t>(j) * cols + i]
                                  : cost[static_cast<size_t>(i) * cols + j];
      a_[static_cast<size_t>(i) * m + j] = c == kForbidden ? forbidden_price : c;
    }

  // 2. SHORTEST AUGMENTING PATHS WITH POTENTIALS. Rows are added one at a time;
  // each addition grows a Dijkstra-like tree over the columns on reduced
  // costs a[i][j] - u[i] - v[j] until it reaches a free column, then flips the
  // path. Indices are 1-based; column 0 is the virtual root.
  const double inf = std::numeric_limits<double>::infinity();
  u_.assign(static_cast<size_t>(n) + 1, 0.0);
  v_.assign(static_cast<size_t>(m) + 1, 0.0);
  p_.assign(static_cast<size_t>(m) + 1, 0);
  way_.assign(static_cast<size_t>(m) + 1, 0);
  for (int i = 1; i <= n; ++i) {
    p_[0] = i;
    int j0 = 0;
    minv_.assign(static_cast<size_t>(m) + 1, inf);
    used_.assign(static_cast<size_t>(m) + 1, 0);
    do {
      used_[j0] = 1;
      const int i0 = p_[j0];
      const double* row = &a_[static_cast<size_t>(i0 - 1) * m];
      const double ui0 = u_[i0];
      double delta = inf;
      int j1 = 0;
      for (int j = 1; j <= m; ++j) {
        if (used_[j]) continue;
        const double cur = row[j - 1] - ui0 - v_[j];
        if (cur < minv_[j]) {
          minv_[j] = cur;
          way_[j] = j0;
        }
        if (minv_[j] < delta) {
          delta = minv_[j];
          j1 = j;
        }
      }
      for (int j = 0; j <= m; ++j) {
        if (used_[j]) {
          u_[p_[j]] += delta;
          v_[j] -= delta;
        } else {
          minv_[j] -= delta;
        }
      }
      j0 = j1;
    } while (p_[j0] != 0);
    do {  // flip the augmenting path back to the root
      const int j1 = way_[j0];
      p_[j0] = p_[j1];
      j0 = j1;
    } while (j0 != 0);
  }

  // 3. READ THE ASSIGNMENT, dropping forbidden pairs.
  double sum = 0.0;
  for (int j = 1; j <= m; ++j) {
    if (p_[j] == 0) continue;
    const int r = transposed ? j - 1 : p_[j] - 1;
    const int c = transposed ? p_[j] - 1 : j - 1;
    const double cr = cost[static_cast<size_t>(r) * cols + c];
    if (cr == kForbidden) continue;
    row_to_col[r] = c;
    sum += cr;
  }
  return sum;
}

double solveAssignment(const std::vector<double>& cost, int rows, int cols,
                       std::vector<int>& row_to_col) {
  if (rows < 0 || cols < 0 ||
      cost.size() != static_cast<size_t>(rows) * static_cast<size_t>(cols))
    throw std::invalid_argument("solveAssignment: cost has " + std::to_string(cost.size()) +
                                " entries, not " + std::to_string(rows) + "x" +
                                std::to_string(cols));
  Hungarian h;
  return h.solve(cost.data(), rows, cols, row_to_col);
}

}  // namespace ld
