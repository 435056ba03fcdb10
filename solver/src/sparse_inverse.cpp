#include "sparse_inverse.hpp"

#include <cholmod.h>

#include <Eigen/Core>
#include <algorithm>
#include <string>

#include "carat/base/error.hpp"

namespace carat::internal {
namespace {

using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic>;
using MapMatrix = Eigen::Map<Matrix>;
using ConstMapMatrix = Eigen::Map<const Matrix>;

std::size_t at(std::int64_t k) { return static_cast<std::size_t>(k); }

int blas_int(Eigen::Index k) { return static_cast<int>(k); }

}  // namespace
}  // namespace carat::internal

// The reference BLAS and LAPACK interfaces of the libraries CHOLMOD links (32-bit integers).
extern "C" {
void dtrsm_(const char* side, const char* uplo, const char* transa, const char* diag, const int* m,
            const int* n, const double* alpha, const double* a, const int* lda, double* b,
            const int* ldb);
void dsymm_(const char* side, const char* uplo, const int* m, const int* n, const double* alpha,
            const double* a, const int* lda, const double* b, const int* ldb, const double* beta,
            double* c, const int* ldc);
void dpotri_(const char* uplo, const int* n, double* a, const int* lda, int* info);
void dgemm_(const char* transa, const char* transb, const int* m, const int* n, const int* k,
            const double* alpha, const double* a, const int* lda, const double* b, const int* ldb,
            const double* beta, double* c, const int* ldc);
}

namespace carat::internal {
namespace {

template <typename T>
std::vector<std::int64_t> copy_indices(const void* data, std::size_t count) {
  const auto* p = static_cast<const T*>(data);
  return std::vector<std::int64_t>(p, p + count);
}

}  // namespace

SparseInverse::SparseInverse(const cholmod_factor& L) : n_(L.n) {
  if (!L.is_super || !L.is_ll || L.xtype != CHOLMOD_REAL || L.itype != CHOLMOD_LONG ||
      L.minor < L.n) {
    throw Error("sparse inverse: needs a numeric supernodal LL' factor with 64-bit indices");
  }
  const std::size_t nsuper = L.nsuper;
  super_ = copy_indices<SuiteSparse_long>(L.super, nsuper + 1);
  pi_ = copy_indices<SuiteSparse_long>(L.pi, nsuper + 1);
  px_ = copy_indices<SuiteSparse_long>(L.px, nsuper + 1);
  rows_ = copy_indices<SuiteSparse_long>(L.s, at(pi_[nsuper]));
  inverse_perm_.resize(n_);
  const auto* perm = static_cast<const SuiteSparse_long*>(L.Perm);
  for (std::size_t k = 0; k < n_; ++k) inverse_perm_[perm ? at(perm[k]) : k] = std::int64_t(k);
  column_super_.resize(n_);
  for (std::size_t s = 0; s < nsuper; ++s) {
    for (std::int64_t c = super_[s]; c < super_[s + 1]; ++c) column_super_[at(c)] = std::int64_t(s);
    // Each supernode's rows: its own columns first, then strictly increasing rows below them.
    const std::int64_t nc = super_[s + 1] - super_[s];
    for (std::int64_t k = 0; k < pi_[s + 1] - pi_[s]; ++k) {
      const std::int64_t row = rows_[at(pi_[s] + k)];
      const bool ok = k < nc ? row == super_[s] + k : row > rows_[at(pi_[s] + k - 1)];
      if (!ok) throw Error("sparse inverse: the factor's row indices are not sorted");
    }
  }

  const auto* Lx = static_cast<const double*>(L.x);
  z_.assign(at(px_[nsuper]), 0.0);
  Matrix zrr, y;
  std::vector<std::int64_t> pos;  // position of each row of R in the supernode holding a column
  for (std::size_t s = nsuper; s-- > 0;) {
    const std::int64_t k1 = super_[s];
    const auto nc = static_cast<Eigen::Index>(super_[s + 1] - k1);
    const auto m = static_cast<Eigen::Index>(pi_[s + 1] - pi_[s]);
    const Eigen::Index nr = m - nc;
    const std::int64_t* R = rows_.data() + pi_[s] + nc;
    const ConstMapMatrix Ls(Lx + px_[s], m, nc);

    // Z(R, R), gathered from the supernodes that hold R's columns.
    zrr.resize(nr, nr);
    pos.resize(at(nr));
    for (Eigen::Index a = 0; a < nr;) {
      const auto t = at(column_super_[at(R[a])]);
      const std::int64_t* rows_t = rows_.data() + pi_[t];
      const std::int64_t m_t = pi_[t + 1] - pi_[t];
      // Rows R[a..] in t: the columns of t at their own place, the rest by search.
      std::int64_t from = 0;
      for (Eigen::Index b = a; b < nr; ++b) {
        const std::int64_t* found = std::lower_bound(rows_t + from, rows_t + m_t, R[b]);
        if (found == rows_t + m_t || *found != R[b]) {
          throw Error("sparse inverse: the factor's pattern is not closed (supernode " +
                      std::to_string(s) + ")");
        }
        pos[at(b)] = found - rows_t;
        from = pos[at(b)] + 1;
      }
      const double* Zt = z_.data() + px_[t];
      Eigen::Index b_end = a;
      while (b_end < nr && R[b_end] < super_[t + 1]) ++b_end;
      for (; a < b_end; ++a) {
        const double* column = Zt + (R[a] - super_[t]) * m_t;
        for (Eigen::Index b = a; b < nr; ++b) zrr(b, a) = column[pos[at(b)]];
      }
    }

    // Z(S, S) = (L_D L_D^T)^-1 (LAPACK's dpotri on L_D), then with Y = L_B L_D^-1:
    // Z(R, S) = -Z(R, R) Y and Z(S, S) -= Y^T Z(R, S). Only lower triangles are read later (and
    // computed here), and the products run through the BLAS CHOLMOD factorizes with.
    MapMatrix Zs(z_.data() + px_[s], m, nc);
    Zs.topRows(nc) = Ls.topRows(nc);
    const int bm = blas_int(m), bnr = blas_int(nr), bnc = blas_int(nc);
    int info = 0;
    dpotri_("L", &bnc, Zs.data(), &bm, &info);
    if (info != 0) throw Error("sparse inverse: the factor has a zero pivot (LAPACK dpotri)");
    if (nr > 0) {
      y = Ls.bottomRows(nr);
      const double one = 1.0, minus_one = -1.0, zero = 0.0;
      dtrsm_("R", "L", "N", "N", &bnr, &bnc, &one, Ls.data(), &bm, y.data(), &bnr);
      dsymm_("L", "L", &bnr, &bnc, &minus_one, zrr.data(), &bnr, y.data(), &bnr, &zero,
             Zs.data() + nc, &bm);
      dgemm_("T", "N", &bnc, &bnc, &bnr, &minus_one, y.data(), &bnr, Zs.data() + nc, &bm, &one,
             Zs.data(), &bm);
    }
  }
}

std::int64_t SparseInverse::position(std::size_t r, std::size_t c) const {
  const auto s = at(column_super_[c]);
  const std::int64_t* rows_s = rows_.data() + pi_[s];
  const std::int64_t m = pi_[s + 1] - pi_[s];
  const std::int64_t own = std::int64_t(c) - super_[s];
  const std::int64_t* found = std::lower_bound(rows_s + own, rows_s + m, std::int64_t(r));
  if (found == rows_s + m || *found != std::int64_t(r)) return -1;
  return px_[s] + own * m + (found - rows_s);
}

bool SparseInverse::has(std::size_t i, std::size_t j) const {
  const auto a = at(inverse_perm_[i]);
  const auto b = at(inverse_perm_[j]);
  return position(std::max(a, b), std::min(a, b)) >= 0;
}

double SparseInverse::operator()(std::size_t i, std::size_t j) const {
  const auto a = at(inverse_perm_[i]);
  const auto b = at(inverse_perm_[j]);
  const std::int64_t p = position(std::max(a, b), std::min(a, b));
  if (p < 0) {
    throw Error("sparse inverse: entry (" + std::to_string(i) + ", " + std::to_string(j) +
                ") is not on the factor's pattern");
  }
  return z_[at(p)];
}

bool SparseInverse::block(std::size_t i0, int rows, std::size_t j0, int cols, double* out) const {
  for (int c = 0; c < cols; ++c) {
    for (int r = 0; r < rows; ++r) {
      const auto a = at(inverse_perm_[i0 + static_cast<std::size_t>(r)]);
      const auto b = at(inverse_perm_[j0 + static_cast<std::size_t>(c)]);
      const std::int64_t p = position(std::max(a, b), std::min(a, b));
      if (p < 0) return false;
      out[static_cast<std::size_t>(c) * static_cast<std::size_t>(rows) +
          static_cast<std::size_t>(r)] = z_[at(p)];
    }
  }
  return true;
}

}  // namespace carat::internal
