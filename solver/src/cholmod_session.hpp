#pragma once

// Internal: one CHOLMOD session over a symmetric matrix whose lower triangle its owner keeps in
// compressed columns (64-bit indices). It holds CHOLMOD's settings for library use (it never
// prints and calls no error handler), the matrix header over the owner's arrays (no copy), the
// factor, and the dense workspaces that repeated solves reuse. Both linear systems use it, and
// both choose their fill-reducing ordering through analyze_pattern() / analyze(who, ordering).

#include <cstddef>
#include <cstdint>
#include <memory>

#include "carat/solver/solver_options.hpp"

// CHOLMOD's types, declared here so that this header does not need CHOLMOD's (the tests include
// the linear systems' headers without CHOLMOD on their include path).
struct cholmod_common_struct;
struct cholmod_factor_struct;
struct cholmod_sparse_struct;

namespace carat::internal {

/// Ordering::kAuto tries the nested dissections only where AMD's factor holds at least this many
/// times the nonzeros of the analyzed triangle (diagonal included). Below it AMD has left little
/// fill for them to remove: on the pose graphs and Schur complements of docs/benchmarks.md AMD's
/// fill is 1.0-3.4 where AMD was also the fewest-flops choice or within 3 % of it, and 5.9-6.5
/// where a nested dissection saved 13-38 % of the flops.
inline constexpr double kNestedDissectionFill = 4.0;

class CholmodSession {
 public:
  CholmodSession();
  ~CholmodSession();
  CholmodSession(const CholmodSession&) = delete;
  CholmodSession& operator=(const CholmodSession&) = delete;

  /// CHOLMOD's settings and statistics (orderings, supernodal, lnz, fl, status).
  cholmod_common_struct& common();

  /// Points the matrix at the owner's n x n lower triangle (colptr n + 1, rows and values nnz;
  /// sorted, packed). The arrays must outlive the session's use of them; CHOLMOD only reads the
  /// pattern.
  void set_lower_matrix(std::size_t n, const std::int64_t* colptr, const std::int64_t* rows,
                        double* values, std::size_t nnz);

  /// The ordering the last analyze_pattern() or analyze(who, ordering) chose: "AMD", "METIS" or
  /// "NESDIS".
  const char* chosen_ordering() const;

  /// Symbolic analysis of the pattern `A` (its own stype) with a fill-reducing `ordering` and
  /// common()'s other settings (supernodal, postorder); the caller owns the factor, null if
  /// CHOLMOD fails (common().status says why). kAmd and kMetis alone; kAuto is AMD first, and
  /// METIS and CHOLMOD's NESDIS as well only where AMD's factor holds at least
  /// kNestedDissectionFill times the nonzeros of A's triangle, the one whose factor needs the
  /// fewest flops kept (AMD on a tie). common()'s lnz and fl are the kept ordering's.
  cholmod_factor_struct* analyze_pattern(cholmod_sparse_struct* A, Ordering ordering);

  /// Symbolic analysis of the matrix with common()'s settings, ordering included. Throws
  /// carat::Error ("`who`: CHOLMOD symbolic analysis failed ...") if it fails.
  void analyze(const char* who);
  /// The same with a fill-reducing `ordering` chosen as analyze_pattern() chooses it.
  void analyze(const char* who, Ordering ordering);

  /// The factor of the last analysis (null before).
  cholmod_factor_struct* factor();

  /// Numeric factorization of the matrix's current values, with CHOLMOD's OpenMP regions run
  /// single-threaded; false if the matrix is not positive definite.
  bool factorize();

  /// x = A^-1 rhs with the last successful factorization (n doubles each). Throws carat::Error
  /// ("`who`: CHOLMOD solve failed ...") if CHOLMOD fails.
  void solve(const double* rhs, double* x, const char* who);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace carat::internal
