#pragma once

// Internal: the Schur complement. The free variables split into eliminated ones ("points": no
// residual block connects two of them, so their part of H is block diagonal) and the rest
// ("cameras"). With H = [A B; B^T C] and C block diagonal, each iteration forms the reduced
// system S = A - B C^-1 B^T (damping added to A and C first, as on the whole system), factorizes
// S with CHOLMOD (supernodal; symbolic analysis once) and recovers the points by
// back-substitution. Every sum is gathered per destination in a fixed order, so results are
// bit-identical for any number of threads. This class wires the parts: the symbolic structure
// (schur_structure.hpp), the assembly and fused linearization with its kernels
// (schur_linearization.hpp, schur_kernels.hpp) and the numeric elimination
// (schur_eliminator.hpp).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "cholmod_session.hpp"
#include "linear_system.hpp"
#include "schur_eliminator.hpp"
#include "schur_linearization.hpp"
#include "schur_structure.hpp"

namespace carat::internal {

class SchurSystem final : public LinearSystem {
 public:
  /// eliminate[v] != 0 marks variable v for elimination (it must be free, and no block may
  /// connect two marked variables; the constructor throws carat::Error otherwise).
  SchurSystem(const Problem& problem, const std::vector<char>& eliminate, Ordering ordering);
  ~SchurSystem() override;
  SchurSystem(const SchurSystem&) = delete;
  SchurSystem& operator=(const SchurSystem&) = delete;

  std::size_t hessian_nonzeros() const override { return structure_.rows.size(); }
  std::size_t factor_nonzeros() const override { return eliminator_.factor_nonzeros(); }
  double factor_flops() const override { return eliminator_.factor_flops(); }
  void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) override;
  /// Fused (every block with an eliminated variable touches at most one kept variable): the
  /// blocks with a point are evaluated a chunk of points at a time and scattered while in
  /// cache, without per-block storage; otherwise as LinearSystem::linearize().
  LinearizeReport linearize(const BlockEvaluator& evaluator, int which,
                            Eigen::VectorXd* gradient) override;
  Eigen::VectorXd diagonal() const override;
  bool factorize(const Eigen::VectorXd& damping) override;
  /// The right-hand side the next solve() will likely be given; linearize() and assemble() set
  /// -gradient, the solver's. factorize() reduces it while it forms S, and solve() with these
  /// very values uses that (the same result as without, fewer passes over W); an empty vector
  /// expects none.
  void expect_rhs(const Eigen::VectorXd& rhs) { eliminator_.expect_rhs(rhs); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const override;
  void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) override;
  double take_elimination_seconds() override { return eliminator_.take_seconds(); }
  double automatic_trust_region_growth() const override { return 3.0; }
  /// solve() reads W, so it needs the assembly the factorization was made from.
  bool reuses_factorization() const override { return false; }

  /// Size of the reduced system (tangent dimensions of the variables not eliminated).
  int reduced_size() const { return structure_.ns; }
  /// Number of eliminated variables.
  int num_eliminated() const { return static_cast<int>(structure_.num_points()); }

  // What the covariance reads after factorize() (see covariance.hpp): the factor of S, and per
  // eliminated variable p its V's inverse factor and its blocks W with the kept variables.

  /// The reduced system's CHOLMOD session; after factorize(), its factor is of S.
  CholmodSession& reduced_cholmod() { return eliminator_.cholmod(); }
  /// The eliminated variable whose tangent starts at system offset `offset`; -1 if none does.
  int eliminated_at(int offset) const;
  /// System offset of eliminated variable p.
  int eliminated_offset(std::size_t p) const { return structure_.pt_offset[p]; }
  /// Tangent size of eliminated variable p.
  int eliminated_dim(std::size_t p) const { return structure_.pt_dim[p]; }
  /// L^-1 (column-major, lower) with L L^T = V_p + damping of the last factorize().
  const double* eliminated_l_inverse(std::size_t p) const { return eliminator_.l_inverse(p); }
  /// Edges of eliminated variable p: [first, end) (kept variables sharing a block with it).
  std::pair<std::size_t, std::size_t> eliminated_edges(std::size_t p) const {
    return {structure_.pt_edge_begin[p], structure_.pt_edge_begin[p + 1]};
  }
  /// System offset of edge e's kept variable.
  int edge_offset(std::size_t e) const {
    return structure_.cam_offset[static_cast<std::size_t>(structure_.edge_cam[e])];
  }
  /// Tangent size of edge e's kept variable.
  int edge_dim(std::size_t e) const {
    return structure_.cam_dim[static_cast<std::size_t>(structure_.edge_cam[e])];
  }
  /// W = H(kept, eliminated) of edge e: edge_dim(e) x eliminated_dim(p), column-major.
  const double* edge_w(std::size_t e) const {
    return values_.w.data() + structure_.edge_w_offset[e];
  }
  /// V_p = H(p, p) of the last assembly (undamped; column-major).
  const double* eliminated_v(std::size_t p) const {
    return values_.v.data() + structure_.pt_v_offset[p];
  }
  /// S's lower triangle in compressed columns (kept variables in system order) as the last
  /// factorize() formed it, damping included: column pointers, rows, values.
  const std::vector<std::int64_t>& reduced_colptr() const { return structure_.colptr; }
  /// See reduced_colptr().
  const std::vector<std::int64_t>& reduced_rows() const { return structure_.rows; }
  /// See reduced_colptr().
  const std::vector<double>& reduced_values() const { return eliminator_.reduced_values(); }

 private:
  SchurStructure structure_;
  SchurValues values_;  // the assembled A, W and V
  SchurLinearization linearization_;
  SchurEliminator eliminator_;
};

}  // namespace carat::internal
