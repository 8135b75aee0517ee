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

  // 2. SHORTEST AUGMENTING PATHS WITH POTENTIALS (Kuhn-Munkres in the
  // Jonker-Volgenant form). Rows are assigned one at a time: Dijkstra over
  // the reduced costs a[i][j] - u[i] - v[j] >= 0, from the new row to the
  // nearest free column, then the potentials are updated (keeping every
  // reduced cost >= 0 and those of the assigned pairs at 0) and the path is
  // flipped. Each row costs O(n m): O(n^2 m) in all.
  const double inf = std::numeric_limits<double>::infinity();
  const auto N = static_cast<size_t>(n), M = static_cast<size_t>(m);
  u_.assign(N, 0.0);
  v_.assign(M, 0.0);
  col4row_.assign(N, -1);
  row4col_.assign(M, -1);
  shortest_.resize(M);
  path_.resize(M);
  remaining_.resize(M);
  in_tree_row_.resize(N);
  in_tree_col_.resize(M);
  for (int cur = 0; cur < n; ++cur) {
    // 2a. Dijkstra from row `cur` until a free column (the sink) is reached.
    std::fill(shortest_.begin(), shortest_.end(), inf);
    std::fill(in_tree_row_.begin(), in_tree_row_.end(), 0);
    std::fill(in_tree_col_.begin(), in_tree_col_.end(), 0);
    int n_remaining = m;
    for (int k = 0; k < m; ++k) remaining_[static_cast<size_t>(k)] = m - 1 - k;
    double min_val = 0.0;
    int i = cur, sink = -1;
    while (sink < 0) {
      in_tree_row_[static_cast<size_t>(i)] = 1;
      const double* row = &a_[static_cast<size_t>(i) * M];
      const double base = min_val - u_[static_cast<size_t>(i)];
      int best = -1;
      double lowest = inf;
      for (int k = 0; k < n_remaining; ++k) {
        const auto j = static_cast<size_t>(remaining_[static_cast<size_t>(k)]);
        const double r = base + row[j] - v_[j];
        if (r < shortest_[j]) {
          path_[j] = i;
          shortest_[j] = r;
        }
        // Ties go to a free column: shorter paths.
        if (shortest_[j] < lowest || (shortest_[j] == lowest && row4col_[j] < 0)) {
          lowest = shortest_[j];
          best = k;
        }
      }
      if (best < 0)  // only with costs so large that their sums overflow
        throw std::invalid_argument("Hungarian::solve: costs too large (sums overflow)");
      min_val = lowest;
      const int j = remaining_[static_cast<size_t>(best)];
      in_tree_col_[static_cast<size_t>(j)] = 1;
      remaining_[static_cast<size_t>(best)] = remaining_[static_cast<size_t>(--n_remaining)];
      if (row4col_[static_cast<size_t>(j)] < 0)
        sink = j;
      else
        i = row4col_[static_cast<size_t>(j)];
    }
    // 2b. Potentials.
    u_[static_cast<size_t>(cur)] += min_val;
    for (size_t r = 0; r < N; ++r)
      if (in_tree_row_[r] && static_cast<int>(r) != cur)
        u_[r] += min_val - shortest_[static_cast<size_t>(col4row_[r])];
    for (size_t c = 0; c < M; ++c)
      if (in_tree_col_[c]) v_[c] -= min_val - shortest_[c];
    // 2c. Flip the path from the sink back to row `cur`.
    for (int j = sink;;) {
      const int r = path_[static_cast<size_t>(j)];
      row4col_[static_cast<size_t>(j)] = r;
      std::swap(col4row_[static_cast<size_t>(r)], j);
      if (r == cur) break;
    }
  }

  // 3. READ THE ASSIGNMENT, dropping forbidden pairs.
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const int j = col4row_[static_cast<size_t>(i)];
    const int r = transposed ? j : i;
    const int c = transposed ? i : j;
    const double cr = cost[static_cast<size_t>(r) * cols + c];
    if (cr == kForbidden) continue;
    row_to_col[static_cast<size_t>(r)] = c;
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
