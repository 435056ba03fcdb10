#pragma once

// Internal: the block-sparse normal equations H delta = -b of a Problem. The free variables
// are ordered once (fill-reducing, postordered, on the variable-level graph) and the system
// is laid out directly in that order as the lower triangle of H in CHOLMOD's compressed-column
// arrays. CHOLMOD then factorizes it with the natural ordering: no permutation or transpose
// per iteration. Values are gathered through precomputed lists (deterministic), and CHOLMOD's
// supernodal symbolic analysis runs once.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "cholmod_session.hpp"
#include "huge_pages.hpp"
#include "linear_system.hpp"

namespace carat::internal {

class SparseSystem final : public LinearSystem {
 public:
  SparseSystem(const Problem& problem, Ordering ordering);
  ~SparseSystem();
  SparseSystem(const SparseSystem&) = delete;
  SparseSystem& operator=(const SparseSystem&) = delete;

  std::size_t hessian_nonzeros() const override { return rows_.size(); }
  std::size_t factor_nonzeros() const override { return factor_nnz_; }
  /// Flops of one numeric factorization (CHOLMOD's estimate).
  double factor_flops() const override { return factor_flops_; }

  /// Gathers blocks' H and b into the undamped matrix values and the gradient (parallel over
  /// columns; each destination sums its sources in a fixed order).
  void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) override;
  /// Linearizes the own blocks in runs of run_blocks_, each assembled before the next is
  /// evaluated, so that only one run's H and b are held (a map's hundreds of thousands of
  /// factors would otherwise hold ~0.7 KB each for the whole solve); the sums are assemble()'s,
  /// bit for bit. A block that is not finite ends it with the system partly assembled (the
  /// solve stops there).
  LinearizeReport linearize(const BlockEvaluator& evaluator, int which,
                            Eigen::VectorXd* gradient) override;

  /// Adds the linearizations of `source`'s blocks at `values` to the assembled system and the
  /// gradient, after the own blocks' (the same sums as for own blocks after them), and their
  /// costs to report->cost; false with report->error naming the first block (global index
  /// first_index + k) whose record is not finite.
  bool add_source_blocks(BlockSource& source, std::span<const double> values,
                         std::size_t first_index, Eigen::VectorXd* gradient,
                         LinearizeReport* report) override;

  /// Undamped diagonal of H.
  Eigen::VectorXd diagonal() const override;

  /// Factorizes H + diag(damping) numerically; false if not positive definite.
  bool factorize(const Eigen::VectorXd& damping) override;

  /// y = H x with the undamped values of the last assembly.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const override;

  /// Solves (H + diag(damping)) x = rhs with the last successful factorization.
  void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) override;

  /// The CHOLMOD session; after factorize(), its factor is of H + diag(damping) in the system's
  /// own order (natural ordering: the variables were ordered before assembly).
  CholmodSession& cholmod() { return *cholmod_; }

 private:
  std::size_t factor_nnz_ = 0;
  double factor_flops_ = 0.0;
  std::string ordering_name_;
  std::vector<int> var_dim_;
  // Lower-triangular CSC pattern, columns in elimination order.
  std::vector<std::int64_t> colptr_;
  // CHOLMOD's matrix A points at these arrays (no copy of the pattern or the values).
  HugeVector<std::int64_t> rows_;
  HugeVector<double> values_;
  std::vector<std::int64_t> diag_pos_;
  // Gather lists for H: per block column J (elimination position), the block rows I >= J with
  // their offset below the diagonal block, and for each such pair a list of contributions.
  struct PairEntry {
    int row_var;                 // elimination position of the row block
    std::int64_t row_in_column;  // offset of the row block below the diagonal block
    std::size_t contrib_begin;
    std::size_t contrib_end;
  };
  struct Contribution {
    std::int32_t block;
    std::int16_t row_local;  // offset of the row variable inside the block's D
    std::int16_t col_local;  // offset of the column variable inside the block's D
  };
  /// Blocks evaluated and assembled together by linearize(): at least 2^15, and at least twice
  /// the free variables (each run visits every column, so a run's H and b then take about what
  /// the matrix itself does, or less).
  std::size_t run_blocks_ = 0;
  /// assemble() for blocks [first, last) alone, their H and b at their offsets less block
  /// first's: adds them after blocks [0, first) (zeroing the system when first is 0).
  void assemble_run(const BlockLinearizations& blocks, std::size_t first, std::size_t last,
                    Eigen::VectorXd* gradient);
  /// Adds one source block's linearization record (see block_source.hpp).
  void add_source_block(std::span<const VariableId> variables, const double* record,
                        double* gradient);
  static constexpr std::size_t kMaxSourceVariables = 64;

  std::vector<int> free_vars_;                  // free variable at each elimination position
  std::vector<int> var_position_;               // elimination position per variable, -1: constant
  std::vector<std::size_t> column_pair_begin_;  // per elimination position
  std::vector<PairEntry> pairs_;
  std::vector<Contribution> contributions_;
  // Gradient gather: per free variable, (block, local offset).
  std::vector<std::size_t> grad_begin_;
  std::vector<std::pair<std::int32_t, std::int16_t>> grad_sources_;
  std::unique_ptr<CholmodSession> cholmod_;  // the matrix is a header over colptr_, rows_, values_
  std::vector<double> saved_diagonal_;       // undamped diagonal during a factorization
};

}  // namespace carat::internal
