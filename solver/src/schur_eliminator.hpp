#pragma once

// Internal: the Schur complement's numeric elimination. With H = [A W; W^T V] assembled
// (SchurValues) and V block diagonal, factorize() factors each point's V + damping = L L^T
// (keeping L^-1), forms the reduced system S = A + damping - W V^-1 W^T into the pattern of the
// SchurStructure, and factorizes S with CHOLMOD (supernodal; the symbolic analysis, with its
// fill-reducing ordering, once, when made). solve() reduces the right-hand side, solves with S's
// factor and recovers the points by back-substitution. Every sum is gathered per destination in
// a fixed order, so results are bit-identical for any number of threads.

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "carat/solver/solver_options.hpp"
#include "cholmod_session.hpp"
#include "huge_pages.hpp"
#include "schur_structure.hpp"

namespace carat::internal {

class SchurEliminator {
 public:
  /// Analyzes S's pattern with `ordering` (CholmodSession::analyze_pattern()); the structure and
  /// the values must outlive this object.
  SchurEliminator(const SchurStructure& structure, const SchurValues& values, Ordering ordering);
  ~SchurEliminator();
  SchurEliminator(const SchurEliminator&) = delete;
  SchurEliminator& operator=(const SchurEliminator&) = delete;

  /// Eliminates the points from H + diag(damping) and factorizes S; false if a V + damping or
  /// S is not positive definite.
  bool factorize(const Eigen::VectorXd& damping);
  /// The right-hand side the next solve() will likely be given (the solver's -gradient): each
  /// factorize() then reduces it while it reads W for S, and solve() with exactly these values
  /// skips its own pass over W (same result either way).
  void expect_rhs(const Eigen::VectorXd& rhs);
  /// x = (H + diag(damping))^-1 rhs with the last successful factorize() (which reads the
  /// values it was made from: W is not copied).
  void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x);

  /// Seconds spent eliminating (forming S, reducing the right-hand side, back-substitution)
  /// since the last call; CHOLMOD's factorization and solve not included.
  double take_seconds();
  /// Nonzeros of S's Cholesky factor (0 with no cameras).
  std::size_t factor_nonzeros() const { return factor_nnz_; }
  /// Flops of one numeric factorization of S, as CHOLMOD's analysis counts them.
  double factor_flops() const { return factor_flops_; }
  /// The ordering CHOLMOD chose for S ("AMD", "METIS", "NESDIS"; "none" with no cameras).
  const std::string& ordering_name() const { return ordering_name_; }
  /// S's CHOLMOD session; after factorize(), its factor is of S.
  CholmodSession& cholmod() { return *cholmod_; }
  /// L^-1 (column-major, lower) with L L^T = V_p + damping of point p, from the last factorize().
  const double* l_inverse(std::size_t p) const { return l_inverse_.data() + s_.pt_v_offset[p]; }
  /// S's values in the structure's pattern as the last factorize() formed them, damping included.
  const std::vector<double>& reduced_values() const { return reduced_; }

 private:
  template <int DC, int DP>
  bool eliminate_points(const Eigen::VectorXd& damping);
  template <int DC, int DP>
  bool eliminate(const Eigen::VectorXd& damping);
  template <int DC, int DP>
  void point_rhs(const double* rhs);
  template <int DC, int DP>
  void run_groups(const Eigen::VectorXd* damping, const double* rhs, double* reduced_rhs);
  template <int DC, int DP>
  void reduce_rhs(const Eigen::VectorXd& rhs, double* reduced);
  template <int DC, int DP>
  void back_substitute(const Eigen::VectorXd& rhs, const double* x_cameras, double* x) const;

  const SchurStructure& s_;
  const SchurValues& h_;
  // L^-1 per point (V + damping = L L^T; Y = W L^-T is formed where needed, not stored), on
  // huge pages (see huge_pages.hpp); u: L^-1 rhs of the points in the last reduction.
  HugeVector<double> l_inverse_;
  std::vector<double> u_;
  std::vector<double> expected_rhs_;   // expect_rhs()'s values (empty: none)
  std::vector<double> fused_reduced_;  // expected_rhs_ reduced by the last factorize()
  bool fused_ready_ = false;
  std::vector<double> reduced_;              // S's values (CHOLMOD's matrix is a header on them)
  std::unique_ptr<CholmodSession> cholmod_;  // S over the structure's colptr, rows and reduced_
  std::vector<double> x_cameras_;            // the reduced solve's solution
  std::size_t factor_nnz_ = 0;
  double factor_flops_ = 0.0;
  std::string ordering_name_ = "none";
  double seconds_ = 0.0;
};

}  // namespace carat::internal
