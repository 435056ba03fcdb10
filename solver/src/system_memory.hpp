#pragma once

// Internal: the memory each linear system would hold, estimated before it is built, so that
// make_linear_system() picks one that fits and refuses, with the estimate, when none does. The
// whole system holds its matrix (values and row indices) and its factor; the Schur complement
// holds the reduced system's matrix and factor and, per eliminated variable, its diagonal block,
// that block's inverse factor and its blocks with the kept variables.

#include <vector>

#include "carat/solver/problem.hpp"

namespace carat::internal {

/// Bytes sparse Cholesky of the whole system of `problem`'s free variables would hold, from the
/// exact fill of an AMD ordering of its block graph. Counting the factor stops once it alone
/// exceeds `cap` bytes (the result then exceeds `cap` too).
double whole_system_bytes(const Problem& problem, double cap);

/// An upper bound of whole_system_bytes() from the size alone (a dense factor), without analysis.
double whole_system_bound(const Problem& problem);

/// The Schur complement's estimate, and what the same pass shows of the whole system.
struct SchurMemory {
  double bytes = 0.0;              ///< the reduced system, its factor and the eliminated blocks
  double whole_lower_bound = 0.0;  ///< whole_system_bytes() is at least this (its matrix alone)
};

/// Bytes the Schur complement that eliminates `eliminate` (one flag per variable) would hold:
/// two kept variables share a block of the reduced system when a residual block or an eliminated
/// variable joins them. Counting stops as whole_system_bytes() does.
SchurMemory schur_system_bytes(const Problem& problem, const std::vector<char>& eliminate,
                               double cap);

}  // namespace carat::internal
