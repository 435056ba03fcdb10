#include "sparse_system.hpp"

#include <algorithm>
#include <cstring>
#include <numeric>
#include <tuple>

#include <amd.h>
#include <cholmod.h>
#include <tbb/parallel_for.h>

#include "carat/solver/error.hpp"

namespace carat::internal {

struct SparseSystem::Impl {
  cholmod_common common{};
  cholmod_sparse* A = nullptr;
  cholmod_factor* L = nullptr;
  cholmod_dense* B = nullptr;
  cholmod_dense* X = nullptr;
  cholmod_dense* Y = nullptr;
  cholmod_dense* E = nullptr;
  bool started = false;

  ~Impl() {
    if (!started) return;
    cholmod_l_free_dense(&B, &common);
    cholmod_l_free_dense(&X, &common);
    cholmod_l_free_dense(&Y, &common);
    cholmod_l_free_dense(&E, &common);
    cholmod_l_free_factor(&L, &common);
    cholmod_l_free_sparse(&A, &common);
    cholmod_l_finish(&common);
  }
};

SparseSystem::~SparseSystem() = default;

SparseSystem::SparseSystem(const Problem& problem, Ordering ordering) : impl_(std::make_unique<Impl>()) {
  const int num_vars = problem.num_variables();
  var_offset_.assign(static_cast<std::size_t>(num_vars), -1);
  var_dim_.assign(static_cast<std::size_t>(num_vars), 0);
  for (int v = 0; v < num_vars; ++v) {
    const VariableId id{v};
    var_dim_[static_cast<std::size_t>(v)] = problem.manifold(id).tangent_size();
    if (problem.is_constant(id)) continue;
    var_offset_[static_cast<std::size_t>(v)] = n_;
    n_ += var_dim_[static_cast<std::size_t>(v)];
    free_vars_.push_back(v);
  }
  // Column index (position among free variables) of each variable.
  std::vector<int> column_of(static_cast<std::size_t>(num_vars), -1);
  for (std::size_t k = 0; k < free_vars_.size(); ++k) {
    column_of[static_cast<std::size_t>(free_vars_[k])] = static_cast<int>(k);
  }

  // (column J, row I, block, local row offset, local col offset), I <= J by column index.
  struct Raw {
    int col;
    int row;
    std::int32_t block;
    std::int16_t row_local;
    std::int16_t col_local;
  };
  std::vector<Raw> raw;
  std::vector<std::tuple<int, std::int32_t, std::int16_t>> grad_raw;  // (column, block, local)
  const auto blocks = problem.blocks();
  for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
    const auto& vars = blocks[bi].variables;
    std::vector<std::pair<int, int>> free_local;  // (column index, local offset)
    int local = 0;
    for (VariableId v : vars) {
      const int col = column_of[static_cast<std::size_t>(v.index)];
      if (col >= 0) free_local.emplace_back(col, local);
      local += var_dim_[static_cast<std::size_t>(v.index)];
    }
    for (std::size_t a = 0; a < free_local.size(); ++a) {
      grad_raw.emplace_back(free_local[a].first, static_cast<std::int32_t>(bi),
                            static_cast<std::int16_t>(free_local[a].second));
      for (std::size_t b = 0; b < free_local.size(); ++b) {
        if (free_local[a].first > free_local[b].first) continue;
        raw.push_back({free_local[b].first, free_local[a].first, static_cast<std::int32_t>(bi),
                       static_cast<std::int16_t>(free_local[a].second),
                       static_cast<std::int16_t>(free_local[b].second)});
      }
    }
  }
  // Every free variable has its diagonal block, touched or not.
  for (std::size_t k = 0; k < free_vars_.size(); ++k) {
    raw.push_back({static_cast<int>(k), static_cast<int>(k), -1, 0, 0});
  }
  std::sort(raw.begin(), raw.end(), [](const Raw& x, const Raw& y) {
    return std::tie(x.col, x.row, x.block) < std::tie(y.col, y.row, y.block);
  });

  const std::size_t num_cols = free_vars_.size();
  column_pair_begin_.assign(num_cols + 1, 0);
  for (std::size_t i = 0; i < raw.size();) {
    std::size_t j = i;
    PairEntry pair{raw[i].row, 0, contributions_.size(), 0};
    for (; j < raw.size() && raw[j].col == raw[i].col && raw[j].row == raw[i].row; ++j) {
      if (raw[j].block >= 0) {
        contributions_.push_back({raw[j].block, raw[j].row_local, raw[j].col_local});
      }
    }
    pair.contrib_end = contributions_.size();
    pairs_.push_back(pair);
    column_pair_begin_[static_cast<std::size_t>(raw[i].col) + 1] = pairs_.size();
    i = j;
  }
  for (std::size_t k = 1; k <= num_cols; ++k) {
    column_pair_begin_[k] = std::max(column_pair_begin_[k], column_pair_begin_[k - 1]);
  }

  // Scalar CSC pattern of the upper triangle.
  colptr_.assign(static_cast<std::size_t>(n_) + 1, 0);
  std::size_t scalar_col = 0;
  for (std::size_t J = 0; J < num_cols; ++J) {
    const int dJ = var_dim_[static_cast<std::size_t>(free_vars_[J])];
    std::int64_t above = 0;
    for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
      pairs_[p].row_in_column = above;
      if (static_cast<std::size_t>(pairs_[p].row_var) != J) {
        above += var_dim_[static_cast<std::size_t>(free_vars_[static_cast<std::size_t>(pairs_[p].row_var)])];
      }
    }
    for (int c = 0; c < dJ; ++c) {
      colptr_[scalar_col + 1] = colptr_[scalar_col] + above + c + 1;
      ++scalar_col;
    }
  }
  rows_.resize(static_cast<std::size_t>(colptr_.back()));
  scalar_col = 0;
  for (std::size_t J = 0; J < num_cols; ++J) {
    const int dJ = var_dim_[static_cast<std::size_t>(free_vars_[J])];
    for (int c = 0; c < dJ; ++c) {
      std::int64_t pos = colptr_[scalar_col];
      for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
        const int I = free_vars_[static_cast<std::size_t>(pairs_[p].row_var)];
        const int dI = var_dim_[static_cast<std::size_t>(I)];
        const int count = (static_cast<std::size_t>(pairs_[p].row_var) == J) ? c + 1 : dI;
        for (int r = 0; r < count; ++r) rows_[static_cast<std::size_t>(pos++)] = var_offset_[static_cast<std::size_t>(I)] + r;
      }
      ++scalar_col;
    }
  }
  values_.assign(rows_.size(), 0.0);
  diag_pos_.resize(static_cast<std::size_t>(n_));
  for (int k = 0; k < n_; ++k) diag_pos_[static_cast<std::size_t>(k)] = colptr_[static_cast<std::size_t>(k) + 1] - 1;

  // Gradient gather lists.
  std::sort(grad_raw.begin(), grad_raw.end());
  grad_begin_.assign(num_cols + 1, 0);
  for (const auto& [col, block, local] : grad_raw) {
    grad_sources_.emplace_back(block, local);
    grad_begin_[static_cast<std::size_t>(col) + 1] = grad_sources_.size();
  }
  for (std::size_t k = 1; k <= num_cols; ++k) grad_begin_[k] = std::max(grad_begin_[k], grad_begin_[k - 1]);

  if (n_ == 0) return;

  // CHOLMOD: matrix, ordering, symbolic analysis (once).
  Impl& im = *impl_;
  cholmod_l_start(&im.common);
  im.started = true;
  im.common.print = 0;  // library code never prints
  im.common.error_handler = nullptr;
  im.common.supernodal = CHOLMOD_SUPERNODAL;
  im.A = cholmod_l_allocate_sparse(static_cast<std::size_t>(n_), static_cast<std::size_t>(n_),
                                   rows_.size(), 1, 1, 1, CHOLMOD_REAL, &im.common);
  if (!im.A) throw Error("sparse system: CHOLMOD could not allocate the matrix (out of memory?)");
  std::memcpy(im.A->p, colptr_.data(), colptr_.size() * sizeof(std::int64_t));
  std::memcpy(im.A->i, rows_.data(), rows_.size() * sizeof(std::int64_t));
  std::fill_n(static_cast<double*>(im.A->x), rows_.size(), 0.0);

  std::vector<SuiteSparse_long> perm;
  if (ordering == Ordering::kBlockAmd) {
    // AMD on the variable graph (both triangles, no diagonal), expanded to scalars.
    std::vector<std::vector<SuiteSparse_long>> adjacency(num_cols);
    for (std::size_t J = 0; J < num_cols; ++J) {
      for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
        const auto I = static_cast<std::size_t>(pairs_[p].row_var);
        if (I == J) continue;
        adjacency[J].push_back(static_cast<SuiteSparse_long>(I));
        adjacency[I].push_back(static_cast<SuiteSparse_long>(J));
      }
    }
    std::vector<SuiteSparse_long> Ap(num_cols + 1, 0);
    std::vector<SuiteSparse_long> Ai;
    for (std::size_t J = 0; J < num_cols; ++J) {
      auto& list = adjacency[J];
      std::sort(list.begin(), list.end());
      Ai.insert(Ai.end(), list.begin(), list.end());
      Ap[J + 1] = static_cast<SuiteSparse_long>(Ai.size());
    }
    if (Ai.empty()) Ai.push_back(0);  // AMD wants a non-null array
    std::vector<SuiteSparse_long> block_perm(num_cols);
    double control[AMD_CONTROL];
    double info[AMD_INFO];
    amd_l_defaults(control);
    const SuiteSparse_long status =
        amd_l_order(static_cast<SuiteSparse_long>(num_cols), Ap.data(), Ai.data(),
                    block_perm.data(), control, info);
    if (status < AMD_OK) throw Error("sparse system: AMD ordering failed (status " + std::to_string(status) + ")");
    perm.reserve(static_cast<std::size_t>(n_));
    for (SuiteSparse_long k : block_perm) {
      const int v = free_vars_[static_cast<std::size_t>(k)];
      for (int d = 0; d < var_dim_[static_cast<std::size_t>(v)]; ++d) {
        perm.push_back(var_offset_[static_cast<std::size_t>(v)] + d);
      }
    }
    im.common.nmethods = 1;
    im.common.method[0].ordering = CHOLMOD_GIVEN;
    im.common.postorder = 1;
    description_ = "cholmod supernodal, block AMD ordering";
  } else {
    description_ = "cholmod supernodal, cholmod default ordering";
  }
  im.L = cholmod_l_analyze_p(im.A, perm.empty() ? nullptr : perm.data(), nullptr, 0, &im.common);
  if (!im.L) throw Error("sparse system: CHOLMOD symbolic analysis failed (status " + std::to_string(im.common.status) + ")");
  factor_nnz_ = static_cast<std::size_t>(im.common.lnz);
  im.B = cholmod_l_zeros(static_cast<std::size_t>(n_), 1, CHOLMOD_REAL, &im.common);
  if (!im.B) throw Error("sparse system: CHOLMOD could not allocate the right-hand side");
}

void SparseSystem::assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) {
  const std::size_t num_cols = free_vars_.size();
  gradient->setZero(n_);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, num_cols, 16),
                    [&](const tbb::blocked_range<std::size_t>& range) {
    for (std::size_t J = range.begin(); J != range.end(); ++J) {
      const int vJ = free_vars_[J];
      const int dJ = var_dim_[static_cast<std::size_t>(vJ)];
      const int col0 = var_offset_[static_cast<std::size_t>(vJ)];
      for (int c = 0; c < dJ; ++c) {
        const std::int64_t begin = colptr_[static_cast<std::size_t>(col0 + c)];
        const std::int64_t end = colptr_[static_cast<std::size_t>(col0 + c) + 1];
        std::fill(values_.begin() + begin, values_.begin() + end, 0.0);
      }
      for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
        const PairEntry& pair = pairs_[p];
        const bool diagonal = static_cast<std::size_t>(pair.row_var) == J;
        const int dI = var_dim_[static_cast<std::size_t>(free_vars_[static_cast<std::size_t>(pair.row_var)])];
        for (std::size_t q = pair.contrib_begin; q < pair.contrib_end; ++q) {
          const Contribution& src = contributions_[q];
          const auto bi = static_cast<std::size_t>(src.block);
          const int D = blocks.dim[bi];
          const double* H = blocks.h.data() + blocks.h_offset[bi];
          for (int c = 0; c < dJ; ++c) {
            double* dst = values_.data() + colptr_[static_cast<std::size_t>(col0 + c)] + pair.row_in_column;
            const double* col = H + static_cast<std::size_t>(src.col_local + c) * static_cast<std::size_t>(D) + src.row_local;
            const int count = diagonal ? c + 1 : dI;
            for (int r = 0; r < count; ++r) dst[r] += col[r];
          }
        }
      }
      double* g = gradient->data() + col0;
      for (std::size_t s = grad_begin_[J]; s < grad_begin_[J + 1]; ++s) {
        const auto [block, local] = grad_sources_[s];
        const double* b = blocks.b.data() + blocks.b_offset[static_cast<std::size_t>(block)] + local;
        for (int r = 0; r < dJ; ++r) g[r] += b[r];
      }
    }
  });
}

Eigen::VectorXd SparseSystem::diagonal() const {
  Eigen::VectorXd d(n_);
  for (int k = 0; k < n_; ++k) d[k] = values_[static_cast<std::size_t>(diag_pos_[static_cast<std::size_t>(k)])];
  return d;
}

bool SparseSystem::factorize(const Eigen::VectorXd& damping) {
  Impl& im = *impl_;
  auto* x = static_cast<double*>(im.A->x);
  std::copy(values_.begin(), values_.end(), x);
  for (int k = 0; k < n_; ++k) x[diag_pos_[static_cast<std::size_t>(k)]] += damping[k];
  const int ok = cholmod_l_factorize(im.A, im.L, &im.common);
  return ok && im.common.status == CHOLMOD_OK && im.L->minor == static_cast<std::size_t>(n_);
}

void SparseSystem::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) {
  Impl& im = *impl_;
  std::copy(rhs.data(), rhs.data() + n_, static_cast<double*>(im.B->x));
  if (!cholmod_l_solve2(CHOLMOD_A, im.L, im.B, nullptr, &im.X, nullptr, &im.Y, &im.E, &im.common)) {
    throw Error("sparse system: CHOLMOD solve failed (status " + std::to_string(im.common.status) + ")");
  }
  x->resize(n_);
  std::copy_n(static_cast<const double*>(im.X->x), n_, x->data());
}

}  // namespace carat::internal
