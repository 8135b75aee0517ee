// Optimal assignment: the Hungarian (Kuhn-Munkres) algorithm with potentials
// and shortest augmenting paths (the Jonker-Volgenant form), O(n^2 m) for an
// n x m cost matrix with n <= m (a matrix with more rows than columns is
// solved transposed). Written for the tracker (section IV of the
// paper: pool landmarks are the agents, new landmarks the tasks), usable on
// any rectangular matrix.
//
// A solver keeps its buffers between calls: once it has seen the largest
// matrix, solve() does not allocate.
#pragma once

#include <limits>
#include <vector>

namespace ld {

class Hungarian {
 public:
  /// A pair that must not be assigned (a gated pair in the tracker).
  static constexpr double kForbidden = std::numeric_limits<double>::infinity();

  /// Solves the assignment problem on `cost`, a rows x cols matrix stored row
  /// by row (cost[r * cols + c]), whose entries are finite or kForbidden.
  ///
  /// Among the assignments of min(rows, cols) pairs (each row and each column
  /// used at most once), it finds one that uses the fewest forbidden pairs and,
  /// among those, has the least total cost: forbidden pairs are prohibitive
  /// costs, so a pair that must not be made never displaces an allowed one.
  /// On return row_to_col[r] is the column of row r, or -1 when row r is not
  /// assigned or only to a forbidden pair. Returns the total cost of the
  /// assigned (allowed) pairs.
  ///
  /// Throws std::invalid_argument on a negative size or a NaN or -infinity
  /// entry.
  double solve(const double* cost, int rows, int cols, std::vector<int>& row_to_col);

 private:
  std::vector<double> a_;         // the matrix as solved: n <= m, forbidden pairs priced
  std::vector<double> u_, v_;     // row and column potentials
  std::vector<double> shortest_;  // Dijkstra distances to the columns
  std::vector<int> path_;         // row before each column on the shortest path
  std::vector<int> col4row_, row4col_, remaining_;
  std::vector<char> in_tree_row_, in_tree_col_;
};

/// One-shot convenience: solves `cost` (rows x cols, row by row) with a fresh
/// solver; see Hungarian::solve.
double solveAssignment(const std::vector<double>& cost, int rows, int cols,
                       std::vector<int>& row_to_col);

}  // namespace ld
