#include "symmetric_matrix_system.hpp"

#include <cholmod.h>

#include <algorithm>
#include <string>

#include "carat/base/error.hpp"

namespace carat::internal {

SymmetricMatrixSystem::SymmetricMatrixSystem(int n, std::vector<std::int64_t> colptr,
                                             std::vector<std::int64_t> rows,
                                             std::vector<double> values)
    : colptr_(std::move(colptr)),
      rows_(std::move(rows)),
      values_(std::move(values)),
      cholmod_(std::make_unique<CholmodSession>()) {
  n_ = n;
  var_offset_.clear();
  description_ = "cholmod supernodal, AMD ordering";
  diag_pos_.resize(static_cast<std::size_t>(n));
  for (int c = 0; c < n; ++c) {
    const auto begin = static_cast<std::size_t>(colptr_[static_cast<std::size_t>(c)]);
    if (begin >= rows_.size() || rows_[begin] != c) {
      throw Error("symmetric matrix: column " + std::to_string(c) +
                  " does not start at its diagonal");
    }
    diag_pos_[static_cast<std::size_t>(c)] = static_cast<std::int64_t>(begin);
  }
  factored_ = values_;
  if (n == 0) return;
  cholmod_->set_lower_matrix(static_cast<std::size_t>(n), colptr_.data(), rows_.data(),
                             factored_.data(), rows_.size());
  cholmod_common& common = cholmod_->common();
  common.supernodal = CHOLMOD_SUPERNODAL;
  common.nmethods = 1;
  common.method[0].ordering = CHOLMOD_AMD;
  cholmod_->analyze("symmetric matrix");
}

SymmetricMatrixSystem::~SymmetricMatrixSystem() = default;

std::size_t SymmetricMatrixSystem::factor_nonzeros() const {
  return static_cast<std::size_t>(cholmod_->common().lnz);
}

double SymmetricMatrixSystem::factor_flops() const { return cholmod_->common().fl; }

void SymmetricMatrixSystem::assemble(const BlockLinearizations&, Eigen::VectorXd*) {
  throw Error("symmetric matrix: the matrix is given, not assembled");
}

Eigen::VectorXd SymmetricMatrixSystem::diagonal() const {
  Eigen::VectorXd d(n_);
  for (int k = 0; k < n_; ++k) {
    d[k] = values_[static_cast<std::size_t>(diag_pos_[static_cast<std::size_t>(k)])];
  }
  return d;
}

bool SymmetricMatrixSystem::factorize(const Eigen::VectorXd& damping) {
  std::copy(values_.begin(), values_.end(), factored_.begin());  // CHOLMOD holds the address
  for (int k = 0; k < n_; ++k) {
    factored_[static_cast<std::size_t>(diag_pos_[static_cast<std::size_t>(k)])] += damping[k];
  }
  return n_ == 0 || cholmod_->factorize();
}

void SymmetricMatrixSystem::multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  y->setZero(n_);
  for (int c = 0; c < n_; ++c) {
    const auto cc = static_cast<std::size_t>(c);
    for (auto p = static_cast<std::size_t>(colptr_[cc]);
         p < static_cast<std::size_t>(colptr_[cc + 1]); ++p) {
      const auto r = static_cast<Eigen::Index>(rows_[p]);
      (*y)[r] += values_[p] * x[c];
      if (r != c) (*y)[c] += values_[p] * x[r];
    }
  }
}

void SymmetricMatrixSystem::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) {
  x->resize(n_);
  cholmod_->solve(rhs.data(), x->data(), "symmetric matrix");
}

}  // namespace carat::internal
