#include "system_inverse.hpp"

#include <cholmod.h>

#include "carat/base/error.hpp"
#include "schur_system.hpp"
#include "sparse_system.hpp"

namespace carat::internal {
namespace {

std::size_t at(int k) { return static_cast<std::size_t>(k); }

}  // namespace

SystemInverse::SystemInverse(LinearSystem& system) : system_(system) {
  if (auto* sparse = dynamic_cast<SparseSystem*>(&system)) {
    kept_size_ = sparse->size();
    if (kept_size_ > 0) inverse_.emplace(*sparse->cholmod().factor());
  } else if ((schur_ = dynamic_cast<SchurSystem*>(&system))) {
    kept_size_ = schur_->reduced_size();
    if (kept_size_ > 0) inverse_.emplace(*schur_->reduced_cholmod().factor());
  } else {
    throw Error("covariance: unknown linear system");
  }
}

bool SystemInverse::on_pattern(int a0, int b0) const {
  if (a0 < kept_size_ && b0 < kept_size_) return inverse_->has(at(a0), at(b0));
  return a0 == b0;  // an eliminated variable's own block
}

Eigen::MatrixXd SystemInverse::block(int a0, int da, int b0, int db) {
  if (a0 < kept_size_ && b0 < kept_size_) {
    Eigen::MatrixXd out(da, db);
    if (inverse_->block(at(a0), da, at(b0), db, out.data())) return out;
  } else if (a0 == b0) {
    return eliminated_block(schur_->eliminated_at(a0));
  }
  return solved_block(a0, da, b0, db);
}

Eigen::MatrixXd SystemInverse::eliminated_block(int p) {
  const auto pp = at(p);
  const int dp = schur_->eliminated_dim(pp);
  const Eigen::Map<const Eigen::MatrixXd> L_inverse(schur_->eliminated_l_inverse(pp), dp, dp);
  const Eigen::MatrixXd V_inverse = L_inverse.transpose() * L_inverse;
  const auto [first, end] = schur_->eliminated_edges(pp);
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(dp, dp);  // sum_ab W_a^T G_ab W_b
  Eigen::MatrixXd G_ab;
  for (std::size_t a = first; a < end; ++a) {
    const int da = schur_->edge_dim(a);
    const Eigen::Map<const Eigen::MatrixXd> W_a(schur_->edge_w(a), da, dp);
    for (std::size_t b = first; b < end; ++b) {
      const int db = schur_->edge_dim(b);
      const Eigen::Map<const Eigen::MatrixXd> W_b(schur_->edge_w(b), db, dp);
      G_ab.resize(da, db);
      if (!inverse_->block(at(schur_->edge_offset(a)), da, at(schur_->edge_offset(b)), db,
                           G_ab.data())) {
        G_ab = block(schur_->edge_offset(a), da, schur_->edge_offset(b), db);
      }
      sum.noalias() += W_a.transpose() * G_ab * W_b;
    }
  }
  return V_inverse + V_inverse * sum * V_inverse;
}

Eigen::MatrixXd SystemInverse::solved_block(int a0, int da, int b0, int db) {
  if (cached_column_ != b0 || cached_.cols() != db) {
    const int n = system_.size();
    cached_.resize(n, db);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n);
    Eigen::VectorXd x;
    for (int k = 0; k < db; ++k) {
      rhs[b0 + k] = 1.0;
      system_.solve(rhs, &x);
      rhs[b0 + k] = 0.0;
      cached_.col(k) = x;
    }
    cached_column_ = b0;
  }
  return cached_.middleRows(a0, da);
}

Eigen::VectorXd SystemInverse::diagonal_bound() const {
  const int n = system_.size();
  Eigen::VectorXd d(n);
  for (int j = 0; j < kept_size_; ++j) d[j] = (*inverse_)(at(j), at(j));
  for (int j = kept_size_; j < n;) {
    const auto p = at(schur_->eliminated_at(j));
    const int dp = schur_->eliminated_dim(p);
    const Eigen::Map<const Eigen::MatrixXd> L_inverse(schur_->eliminated_l_inverse(p), dp, dp);
    for (int k = 0; k < dp; ++k) d[j + k] = L_inverse.col(k).squaredNorm();
    j += dp;
  }
  return d;
}

}  // namespace carat::internal
