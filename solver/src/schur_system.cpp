#include "schur_system.hpp"

#include <algorithm>
#include <string>

namespace carat::internal {
namespace {

template <int R, int C>
using ConstMapMatrix = Eigen::Map<const Eigen::Matrix<double, R, C>>;

std::size_t at(int k) { return static_cast<std::size_t>(k); }

}  // namespace

SchurSystem::SchurSystem(const Problem& problem, const std::vector<char>& eliminate,
                         Ordering ordering)
    : structure_(problem, eliminate),
      values_(structure_),
      linearization_(problem, structure_, values_),
      eliminator_(structure_, values_, ordering) {
  n_ = structure_.n;
  var_offset_ = structure_.var_offset;
  description_ = "schur complement of " + std::to_string(structure_.num_points()) +
                 " eliminated variables, cholmod supernodal on the reduced system (" +
                 std::to_string(structure_.ns) + " x " + std::to_string(structure_.ns) + ", " +
                 eliminator_.ordering_name() + " ordering)";
}

SchurSystem::~SchurSystem() = default;

void SchurSystem::assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) {
  linearization_.assemble(blocks, gradient);
  eliminator_.expect_rhs(-*gradient);
}

LinearizeReport SchurSystem::linearize(const BlockEvaluator& evaluator, int which,
                                       Eigen::VectorXd* gradient) {
  const LinearizeReport report = structure_.fused
                                     ? linearization_.linearize(evaluator, which, gradient)
                                     : LinearSystem::linearize(evaluator, which, gradient);
  // The solver's next right-hand side is -gradient: factorize() reduces it on its pass over W.
  eliminator_.expect_rhs(-*gradient);
  return report;
}

Eigen::VectorXd SchurSystem::diagonal() const {
  Eigen::VectorXd d(structure_.n);
  for (std::size_t j = 0; j < structure_.cam_dim.size(); ++j) {
    const int dj = structure_.cam_dim[j];
    const double* A =
        values_.a.data() +
        structure_.pairs[structure_.column_pair_begin[j]].h_offset;  // diagonal pair first
    for (int r = 0; r < dj; ++r) d[structure_.cam_offset[j] + r] = A[at(r) * at(dj) + at(r)];
  }
  for (std::size_t p = 0; p < structure_.pt_dim.size(); ++p) {
    const int dp = structure_.pt_dim[p];
    const double* V = values_.v.data() + structure_.pt_v_offset[p];
    for (int r = 0; r < dp; ++r) d[structure_.pt_offset[p] + r] = V[at(r) * at(dp) + at(r)];
  }
  return d;
}

bool SchurSystem::factorize(const Eigen::VectorXd& damping) {
  return eliminator_.factorize(damping);
}

void SchurSystem::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) {
  eliminator_.solve(rhs, x);
}

void SchurSystem::multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  y->setZero(structure_.n);
  for (std::size_t j = 0; j < structure_.cam_dim.size(); ++j) {
    const int dj = structure_.cam_dim[j];
    for (std::size_t k = structure_.column_pair_begin[j]; k < structure_.column_pair_begin[j + 1];
         ++k) {
      const SchurStructure::Pair& pair = structure_.pairs[k];
      const auto i = at(pair.row_cam);
      const int di = structure_.cam_dim[i];
      const ConstMapMatrix<Eigen::Dynamic, Eigen::Dynamic> A(values_.a.data() + pair.h_offset, di,
                                                             dj);
      y->segment(structure_.cam_offset[i], di).noalias() +=
          A * x.segment(structure_.cam_offset[j], dj);
      if (i != j) {
        y->segment(structure_.cam_offset[j], dj).noalias() +=
            A.transpose() * x.segment(structure_.cam_offset[i], di);
      }
    }
  }
  for (std::size_t p = 0; p < structure_.pt_dim.size(); ++p) {
    const int dp = structure_.pt_dim[p];
    const ConstMapMatrix<Eigen::Dynamic, Eigen::Dynamic> V(
        values_.v.data() + structure_.pt_v_offset[p], dp, dp);
    y->segment(structure_.pt_offset[p], dp).noalias() += V * x.segment(structure_.pt_offset[p], dp);
    for (std::size_t e = structure_.pt_edge_begin[p]; e < structure_.pt_edge_begin[p + 1]; ++e) {
      const auto c = at(structure_.edge_cam[e]);
      const int dc = structure_.cam_dim[c];
      const ConstMapMatrix<Eigen::Dynamic, Eigen::Dynamic> W(
          values_.w.data() + structure_.edge_w_offset[e], dc, dp);
      y->segment(structure_.cam_offset[c], dc).noalias() +=
          W * x.segment(structure_.pt_offset[p], dp);
      y->segment(structure_.pt_offset[p], dp).noalias() +=
          W.transpose() * x.segment(structure_.cam_offset[c], dc);
    }
  }
}

int SchurSystem::eliminated_at(int offset) const {
  const auto it =
      std::lower_bound(structure_.pt_offset.begin(), structure_.pt_offset.end(), offset);
  if (it == structure_.pt_offset.end() || *it != offset) return -1;
  return static_cast<int>(it - structure_.pt_offset.begin());
}

}  // namespace carat::internal
