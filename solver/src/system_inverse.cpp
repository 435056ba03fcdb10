#include "system_inverse.hpp"

#include <cholmod.h>

#include "carat/base/error.hpp"
#include "schur_system.hpp"
#include "sparse_system.hpp"

namespace carat::internal {
namespace {

std::size_t at(int k) { return static_cast<std::size_t>(k); }

using ConstMap = Eigen::Map<const Eigen::MatrixXd>;

/// V_p^-1 = L^-T L^-1 of the Schur system's last factorization.
Eigen::MatrixXd v_inverse(const SchurSystem& schur, std::size_t p) {
  const int dp = schur.eliminated_dim(p);
  const ConstMap L_inverse(schur.eliminated_l_inverse(p), dp, dp);
  return L_inverse.transpose() * L_inverse;
}

}  // namespace

SystemInverse::SystemInverse(SparseSystem& sparse)
    : kept_(sparse.cholmod()), kept_size_(sparse.size()) {
  if (kept_size_ > 0) inverse_.emplace(*kept_.factor());
}

SystemInverse::SystemInverse(const SchurSystem& schur, CholmodSession& kept)
    : schur_(&schur), kept_(kept), kept_size_(schur.reduced_size()) {
  if (kept_size_ > 0) inverse_.emplace(*kept_.factor());
}

bool SystemInverse::on_pattern(int a0, int b0) const {
  if (a0 < kept_size_ && b0 < kept_size_) return inverse_->has(at(a0), at(b0));
  if (a0 != b0) return false;
  return true;  // an eliminated variable's own block: its kept pairs share it
}

void SystemInverse::remove_free_directions(Eigen::MatrixXd N, Eigen::MatrixXd Q,
                                           Eigen::MatrixXd K) {
  N_ = std::move(N);
  Q_ = std::move(Q);
  K_ = std::move(K);
}

Eigen::MatrixXd SystemInverse::kept_block(int a0, int da, int b0, int db) {
  Eigen::MatrixXd out(da, db);
  if (!inverse_->block(at(a0), da, at(b0), db, out.data())) out = solved_block(a0, da, b0, db);
  if (N_.cols() > 0) {
    const auto Na = N_.middleRows(a0, da);
    const auto Nb = N_.middleRows(b0, db);
    out -= Na * Q_.middleRows(b0, db).transpose() + Q_.middleRows(a0, da) * Nb.transpose();
    out += Na * K_ * Nb.transpose();
  }
  return out;
}

Eigen::MatrixXd SystemInverse::solved_block(int a0, int da, int b0, int db) {
  if (cached_column_ != b0 || cached_.cols() != db) {
    cached_.resize(kept_size_, db);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(kept_size_);
    for (int k = 0; k < db; ++k) {
      rhs[b0 + k] = 1.0;
      kept_.solve(rhs.data(), cached_.col(k).data(), "covariance");
      rhs[b0 + k] = 0.0;
    }
    cached_column_ = b0;
  }
  return cached_.middleRows(a0, da);
}

Eigen::MatrixXd SystemInverse::edges_times_kept(int p, int b0, int db) {
  const auto pp = at(p);
  const int dp = schur_->eliminated_dim(pp);
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(dp, db);
  const auto [first, end] = schur_->eliminated_edges(pp);
  for (std::size_t e = first; e < end; ++e) {
    const int de = schur_->edge_dim(e);
    sum.noalias() += ConstMap(schur_->edge_w(e), de, dp).transpose() *
                     kept_block(schur_->edge_offset(e), de, b0, db);
  }
  return sum;
}

Eigen::MatrixXd SystemInverse::block(int a0, int da, int b0, int db) {
  if (a0 < kept_size_ && b0 < kept_size_) return kept_block(a0, da, b0, db);
  if (a0 < kept_size_) return block(b0, db, a0, da).transpose();
  const int p = schur_->eliminated_at(a0);
  const Eigen::MatrixXd Vp_inverse = v_inverse(*schur_, at(p));
  if (b0 < kept_size_) return -Vp_inverse * edges_times_kept(p, b0, db);
  // Both eliminated: sum over q's edges f of (sum_e W_e^T G_{c(e), c(f)}) W_f.
  const int q = schur_->eliminated_at(b0);
  const auto [first, end] = schur_->eliminated_edges(at(q));
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(da, db);
  for (std::size_t f = first; f < end; ++f) {
    const int df = schur_->edge_dim(f);
    sum.noalias() +=
        edges_times_kept(p, schur_->edge_offset(f), df) * ConstMap(schur_->edge_w(f), df, db);
  }
  const Eigen::MatrixXd Vq_inverse = p == q ? Vp_inverse : v_inverse(*schur_, at(q));
  Eigen::MatrixXd out = Vp_inverse * sum * Vq_inverse;
  if (p == q) out += Vp_inverse;
  return out;
}

Eigen::VectorXd SystemInverse::diagonal_bound() const {
  const int n = schur_ ? schur_->size() : kept_size_;
  Eigen::VectorXd d(n);
  for (int j = 0; j < kept_size_; ++j) d[j] = (*inverse_)(at(j), at(j));
  for (int j = kept_size_; j < n;) {
    const auto p = at(schur_->eliminated_at(j));
    const int dp = schur_->eliminated_dim(p);
    const ConstMap L_inverse(schur_->eliminated_l_inverse(p), dp, dp);
    for (int k = 0; k < dp; ++k) d[j + k] = L_inverse.col(k).squaredNorm();
    j += dp;
  }
  return d;
}

Eigen::MatrixXd lift_eliminated(const SchurSystem& schur, int p, const Eigen::MatrixXd& X_kept) {
  const auto pp = at(p);
  const int dp = schur.eliminated_dim(pp);
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(dp, X_kept.cols());
  const auto [first, end] = schur.eliminated_edges(pp);
  for (std::size_t e = first; e < end; ++e) {
    const int de = schur.edge_dim(e);
    sum.noalias() +=
        ConstMap(schur.edge_w(e), de, dp).transpose() * X_kept.middleRows(schur.edge_offset(e), de);
  }
  return -v_inverse(schur, pp) * sum;
}

}  // namespace carat::internal
