#pragma once

// Internal: one CHOLMOD session over a symmetric matrix whose lower triangle its owner keeps in
// compressed columns (64-bit indices). It holds CHOLMOD's settings for library use (it never
// prints and calls no error handler), the matrix header over the owner's arrays (no copy), the
// factor, and the dense workspaces that repeated solves reuse. Both linear systems use it, and
// both choose their fill-reducing ordering through set_ordering().

#include <cstddef>
#include <cstdint>
#include <memory>

#include "carat/solver/solver_options.hpp"

// CHOLMOD's types, declared here so that this header does not need CHOLMOD's (the tests include
// the linear systems' headers without CHOLMOD on their include path).
struct cholmod_common_struct;
struct cholmod_factor_struct;

namespace carat::internal {

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

  /// The fill-reducing ordering of the next analysis (of the matrix, or of any pattern analyzed
  /// with common()): kAmd and kMetis alone; kAuto tries AMD, METIS and NESDIS and CHOLMOD keeps
  /// the one whose factor needs the fewest flops (see Ordering::kAuto).
  void set_ordering(Ordering ordering);

  /// The ordering the last analysis chose: "AMD", "METIS", "NESDIS" or "natural".
  const char* chosen_ordering() const;

  /// Symbolic analysis of the matrix with common()'s settings. Throws carat::Error ("`who`:
  /// CHOLMOD symbolic analysis failed ...") if it fails.
  void analyze(const char* who);

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
