#include "sparse_system.hpp"

#include <cholmod.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <span>
#include <tuple>

#include "block_variables.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "huge_pages.hpp"
#include "source_runs.hpp"

namespace carat::internal {

SparseSystem::~SparseSystem() = default;

SparseSystem::SparseSystem(const Problem& problem, Ordering ordering)
    : cholmod_(std::make_unique<CholmodSession>()) {
  const int num_vars = problem.num_variables();
  var_offset_.assign(static_cast<std::size_t>(num_vars), -1);
  var_dim_.assign(static_cast<std::size_t>(num_vars), 0);
  std::vector<int> free_in_id_order;
  std::vector<int> id_rank(static_cast<std::size_t>(num_vars), -1);  // rank among free variables
  for (int v = 0; v < num_vars; ++v) {
    const VariableId id{v};
    var_dim_[static_cast<std::size_t>(v)] = problem.manifold(id).tangent_size();
    if (problem.is_constant(id)) continue;
    id_rank[static_cast<std::size_t>(v)] = static_cast<int>(free_in_id_order.size());
    free_in_id_order.push_back(v);
  }
  const std::size_t nb = free_in_id_order.size();
  // Own blocks are gathered from their linearizations; a block source's are added as they
  // arrive (add_source_blocks()), after them, but take part in the pattern like own blocks.
  const std::size_t num_own = problem.blocks().size();

  // Free variables of each block, as ranks.
  std::vector<std::size_t> block_free_begin{0};
  std::vector<std::pair<int, int>> block_free;  // (rank, local tangent offset)
  for_each_block_variables(problem, [&](std::span<const VariableId> variables) {
    int local = 0;
    for (VariableId v : variables) {
      const int rank = id_rank[static_cast<std::size_t>(v.index)];
      if (rank >= 0) block_free.emplace_back(rank, local);
      local += var_dim_[static_cast<std::size_t>(v.index)];
    }
    block_free_begin.push_back(block_free.size());
  });
  const std::size_t num_blocks = block_free_begin.size() - 1;
  if (num_blocks > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max()))
    throw Error("sparse system: " + std::to_string(num_blocks) + " residual blocks (at most " +
                std::to_string(std::numeric_limits<std::int32_t>::max()) + ")");

  cholmod_common& common = cholmod_->common();

  // 1. Fill-reducing, postordered ordering of the variable-level graph.
  std::vector<int> position(nb);
  std::iota(position.begin(), position.end(), 0);
  if (nb > 1) {
    std::vector<std::vector<SuiteSparse_long>> adjacency(nb);
    for (std::size_t bi = 0; bi < num_blocks; ++bi) {
      for (std::size_t a = block_free_begin[bi]; a < block_free_begin[bi + 1]; ++a) {
        for (std::size_t b = block_free_begin[bi]; b < block_free_begin[bi + 1]; ++b) {
          if (a != b)
            adjacency[static_cast<std::size_t>(block_free[a].first)].push_back(block_free[b].first);
        }
      }
    }
    std::size_t nnz = 0;
    for (std::size_t k = 0; k < nb; ++k) {
      auto& list = adjacency[k];
      list.push_back(static_cast<SuiteSparse_long>(k));
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
      nnz += list.size();
    }
    cholmod_sparse* G = cholmod_l_allocate_sparse(nb, nb, nnz, 1, 1, 0, CHOLMOD_PATTERN, &common);
    if (!G)
      throw Error("sparse system: out of memory while ordering " + std::to_string(nb) +
                  " variables");
    auto* Gp = static_cast<SuiteSparse_long*>(G->p);
    auto* Gi = static_cast<SuiteSparse_long*>(G->i);
    Gp[0] = 0;
    for (std::size_t k = 0; k < nb; ++k) {
      std::copy(adjacency[k].begin(), adjacency[k].end(), Gi + Gp[k]);
      Gp[k + 1] = Gp[k] + static_cast<SuiteSparse_long>(adjacency[k].size());
    }
    adjacency.clear();
    G->stype = 1;  // symmetric, both triangles stored: CHOLMOD uses the upper part
    common.supernodal = CHOLMOD_SIMPLICIAL;
    common.postorder = 1;
    cholmod_factor* LG = cholmod_->analyze_pattern(G, ordering);
    cholmod_l_free_sparse(&G, &common);
    if (!LG)
      throw Error("sparse system: ordering failed (CHOLMOD status " +
                  std::to_string(common.status) + ")");
    const auto* perm = static_cast<const SuiteSparse_long*>(LG->Perm);
    for (std::size_t k = 0; k < nb; ++k)
      position[static_cast<std::size_t>(perm[k])] = static_cast<int>(k);
    ordering_name_ = cholmod_->chosen_ordering();
    cholmod_l_free_factor(&LG, &common);
  } else {
    ordering_name_ = "natural";
  }

  // 2. Variables and scalar offsets in elimination order.
  free_vars_.assign(nb, -1);
  for (std::size_t r = 0; r < nb; ++r)
    free_vars_[static_cast<std::size_t>(position[r])] = free_in_id_order[r];
  var_position_.assign(static_cast<std::size_t>(num_vars), -1);
  for (std::size_t k = 0; k < nb; ++k) {
    var_offset_[static_cast<std::size_t>(free_vars_[k])] = n_;
    var_position_[static_cast<std::size_t>(free_vars_[k])] = static_cast<int>(k);
    n_ += var_dim_[static_cast<std::size_t>(free_vars_[k])];
  }

  // 3. Block pairs (column J <= row I in elimination order) and their contributions.
  struct Raw {
    int col;
    int row;
    std::int32_t block;
    std::int16_t row_local;
    std::int16_t col_local;
  };
  std::vector<Raw> raw;
  std::vector<std::tuple<int, std::int32_t, std::int16_t>> grad_raw;  // (position, block, local)
  for (std::size_t bi = 0; bi < num_blocks; ++bi) {
    for (std::size_t a = block_free_begin[bi]; a < block_free_begin[bi + 1]; ++a) {
      const int pa = position[static_cast<std::size_t>(block_free[a].first)];
      if (bi < num_own) {
        grad_raw.emplace_back(pa, static_cast<std::int32_t>(bi),
                              static_cast<std::int16_t>(block_free[a].second));
      }
      for (std::size_t b = block_free_begin[bi]; b < block_free_begin[bi + 1]; ++b) {
        const int pb = position[static_cast<std::size_t>(block_free[b].first)];
        if (pa < pb) continue;  // keep row >= column
        raw.push_back({pb, pa, static_cast<std::int32_t>(bi),
                       static_cast<std::int16_t>(block_free[a].second),
                       static_cast<std::int16_t>(block_free[b].second)});
      }
    }
  }
  for (std::size_t k = 0; k < nb; ++k)
    raw.push_back({static_cast<int>(k), static_cast<int>(k), -1, 0, 0});
  std::sort(raw.begin(), raw.end(), [](const Raw& x, const Raw& y) {
    return std::tie(x.col, x.row, x.block) < std::tie(y.col, y.row, y.block);
  });
  column_pair_begin_.assign(nb + 1, 0);
  for (std::size_t i = 0; i < raw.size();) {
    std::size_t j = i;
    PairEntry pair{raw[i].row, 0, contributions_.size(), 0};
    for (; j < raw.size() && raw[j].col == raw[i].col && raw[j].row == raw[i].row; ++j) {
      if (raw[j].block >= 0 && static_cast<std::size_t>(raw[j].block) < num_own)
        contributions_.push_back({raw[j].block, raw[j].row_local, raw[j].col_local});
    }
    pair.contrib_end = contributions_.size();
    pairs_.push_back(pair);
    column_pair_begin_[static_cast<std::size_t>(raw[i].col) + 1] = pairs_.size();
    i = j;
  }
  raw.clear();
  raw.shrink_to_fit();

  // 4. Scalar lower-triangular CSC: per scalar column c of block J, the diagonal block's rows
  // c..d_J-1, then every block below it.
  colptr_.assign(static_cast<std::size_t>(n_) + 1, 0);
  std::size_t scalar_col = 0;
  for (std::size_t J = 0; J < nb; ++J) {
    const int dJ = var_dim_[static_cast<std::size_t>(free_vars_[J])];
    std::int64_t below = 0;
    for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
      if (static_cast<std::size_t>(pairs_[p].row_var) == J) continue;
      pairs_[p].row_in_column = below;
      below += var_dim_[static_cast<std::size_t>(
          free_vars_[static_cast<std::size_t>(pairs_[p].row_var)])];
    }
    for (int c = 0; c < dJ; ++c, ++scalar_col) {
      colptr_[scalar_col + 1] = colptr_[scalar_col] + (dJ - c) + below;
    }
  }
  rows_.assign(static_cast<std::size_t>(colptr_.back()), 0);
  scalar_col = 0;
  for (std::size_t J = 0; J < nb; ++J) {
    const int vJ = free_vars_[J];
    const int dJ = var_dim_[static_cast<std::size_t>(vJ)];
    for (int c = 0; c < dJ; ++c, ++scalar_col) {
      std::int64_t pos = colptr_[scalar_col];
      for (int r = c; r < dJ; ++r)
        rows_[static_cast<std::size_t>(pos++)] = var_offset_[static_cast<std::size_t>(vJ)] + r;
      for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
        if (static_cast<std::size_t>(pairs_[p].row_var) == J) continue;
        const int I = free_vars_[static_cast<std::size_t>(pairs_[p].row_var)];
        for (int r = 0; r < var_dim_[static_cast<std::size_t>(I)]; ++r) {
          rows_[static_cast<std::size_t>(pos++)] = var_offset_[static_cast<std::size_t>(I)] + r;
        }
      }
    }
  }
  values_.assign(rows_.size(), 0.0);
  diag_pos_.assign(colptr_.begin(), colptr_.end() - 1);
  run_blocks_ = std::max<std::size_t>(std::size_t{1} << 15, 2 * nb);

  std::sort(grad_raw.begin(), grad_raw.end());
  grad_begin_.assign(nb + 1, 0);
  for (const auto& [pos, block, local] : grad_raw) {
    grad_sources_.emplace_back(block, local);
    grad_begin_[static_cast<std::size_t>(pos) + 1] = grad_sources_.size();
  }
  for (std::size_t k = 1; k <= nb; ++k)
    grad_begin_[k] = std::max(grad_begin_[k], grad_begin_[k - 1]);
  for (std::size_t k = 1; k <= nb; ++k)
    column_pair_begin_[k] = std::max(column_pair_begin_[k], column_pair_begin_[k - 1]);

  if (n_ == 0) return;

  // 5. CHOLMOD supernodal symbolic analysis, natural ordering on the pre-ordered matrix.
  // A is a header over this object's own arrays (CHOLMOD only reads them): no copy, and the
  // values it factorizes are the assembled ones (factorize() adds the damping to the diagonal
  // in place and restores it).
  cholmod_->set_lower_matrix(static_cast<std::size_t>(n_), colptr_.data(), rows_.data(),
                             values_.data(), rows_.size());
  common.supernodal = CHOLMOD_SUPERNODAL;
  common.nmethods = 1;
  common.method[0].ordering = CHOLMOD_NATURAL;
  common.postorder = 0;  // already postordered at the variable level
  // Larger relaxed supernodes: fewer, bigger BLAS calls for 6x6-block matrices.
  common.nrelax[0] = 16;
  common.nrelax[1] = 48;
  common.nrelax[2] = 96;
  common.zrelax[0] = 0.8;
  common.zrelax[1] = 0.2;
  common.zrelax[2] = 0.1;
  cholmod_->analyze("sparse system");
  // The factor's numeric storage now rather than in the first factorization, so that it can be
  // advised onto huge pages before CHOLMOD first writes it (see huge_pages.hpp).
  if (!cholmod_l_change_factor(CHOLMOD_REAL, /*to_ll=*/1, /*to_super=*/1, /*to_packed=*/1,
                               /*to_monotonic=*/1, cholmod_->factor(), &common)) {
    throw Error("sparse system: CHOLMOD could not allocate the factor (status " +
                std::to_string(common.status) + "; out of memory?)");
  }
  advise_huge_pages(cholmod_->factor()->x, cholmod_->factor()->xsize * sizeof(double));
  factor_nnz_ = static_cast<std::size_t>(common.lnz);
  factor_flops_ = common.fl;
  description_ = "cholmod supernodal, " + ordering_name_ + " ordering on the variable graph";
}

void SparseSystem::assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) {
  assemble_run(blocks, 0, blocks.dim.size(), gradient);
}

LinearizeReport SparseSystem::linearize(const BlockEvaluator& evaluator, int which,
                                        Eigen::VectorXd* gradient) {
  LinearizeReport report;
  const std::size_t num_blocks = evaluator.problem().blocks().size();
  if (storage_.dim.empty()) evaluator.allocate(&storage_, run_blocks_);
  std::size_t first = 0;
  do {  // once at least: the first run zeroes the system
    const std::size_t last = std::min(num_blocks, first + run_blocks_);
    Stopwatch t0;
    const bool ok = evaluator.linearize_run(which, first, last, &storage_, &report.error);
    report.time.linearize_s += t0.elapsed_s();
    if (!ok) return report;
    t0.restart();
    assemble_run(storage_, first, last, gradient);
    report.time.assembly_s += t0.elapsed_s();
    first = last;
  } while (first < num_blocks);
  finish_linearize(evaluator, which, gradient, &report);
  return report;
}

void SparseSystem::assemble_run(const BlockLinearizations& blocks, std::size_t first,
                                std::size_t last, Eigen::VectorXd* gradient) {
  const std::size_t num_cols = free_vars_.size();
  if (first == 0) gradient->setZero(n_);
  const std::size_t h_base = first < last ? blocks.h_offset[first] : 0;
  const std::size_t b_base = first < last ? blocks.b_offset[first] : 0;
  const auto in_run = [last](std::int32_t block) { return static_cast<std::size_t>(block) < last; };
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, num_cols, 16),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t J = range.begin(); J != range.end(); ++J) {
          const int vJ = free_vars_[J];
          const int dJ = var_dim_[static_cast<std::size_t>(vJ)];
          const int col0 = var_offset_[static_cast<std::size_t>(vJ)];
          if (first == 0) {
            for (int c = 0; c < dJ; ++c) {
              const std::int64_t begin = colptr_[static_cast<std::size_t>(col0 + c)];
              const std::int64_t end = colptr_[static_cast<std::size_t>(col0 + c) + 1];
              std::fill(values_.begin() + begin, values_.begin() + end, 0.0);
            }
          }
          for (std::size_t p = column_pair_begin_[J]; p < column_pair_begin_[J + 1]; ++p) {
            const PairEntry& pair = pairs_[p];
            const bool diagonal = static_cast<std::size_t>(pair.row_var) == J;
            const int dI = var_dim_[static_cast<std::size_t>(
                free_vars_[static_cast<std::size_t>(pair.row_var)])];
            // A pair's contributions ascend by block: this run's follow the earlier runs'.
            const auto* q = std::lower_bound(contributions_.data() + pair.contrib_begin,
                                             contributions_.data() + pair.contrib_end, first,
                                             [](const Contribution& c, std::size_t block) {
                                               return static_cast<std::size_t>(c.block) < block;
                                             });
            for (; q != contributions_.data() + pair.contrib_end && in_run(q->block); ++q) {
              const Contribution& src = *q;
              const auto bi = static_cast<std::size_t>(src.block);
              const auto D = static_cast<std::size_t>(blocks.dim[bi]);
              const double* H = blocks.h.data() + (blocks.h_offset[bi] - h_base);
              const auto row_local = static_cast<std::size_t>(src.row_local);
              const auto col_local = static_cast<std::size_t>(src.col_local);
              for (int c = 0; c < dJ; ++c) {
                double* column = values_.data() + colptr_[static_cast<std::size_t>(col0 + c)];
                const auto cc = static_cast<std::size_t>(c);
                if (diagonal) {
                  // H packed by columns: column col_local + c from its diagonal down.
                  const double* src_col = H + packed_column(D, col_local + cc);
                  for (int r = 0; r < dJ - c; ++r) column[r] += src_col[r];
                } else if (row_local > col_local) {
                  double* dst = column + (dJ - c) + pair.row_in_column;
                  const double* src_col =
                      H + packed_column(D, col_local + cc) + (row_local - col_local - cc);
                  for (int r = 0; r < dI; ++r) dst[r] += src_col[r];
                } else {
                  double* dst = column + (dJ - c) + pair.row_in_column;
                  for (int r = 0; r < dI; ++r) {
                    const auto rr = static_cast<std::size_t>(r);
                    dst[r] +=
                        H[packed_column(D, row_local + rr) + (col_local + cc - row_local - rr)];
                  }
                }
              }
            }
          }
          double* g = gradient->data() + col0;
          const auto* s = std::lower_bound(
              grad_sources_.data() + grad_begin_[J], grad_sources_.data() + grad_begin_[J + 1],
              first, [](const std::pair<std::int32_t, std::int16_t>& source, std::size_t block) {
                return static_cast<std::size_t>(source.first) < block;
              });
          for (; s != grad_sources_.data() + grad_begin_[J + 1] && in_run(s->first); ++s) {
            const auto [block, local] = *s;
            const double* b = blocks.b.data() +
                              (blocks.b_offset[static_cast<std::size_t>(block)] - b_base) + local;
            for (int r = 0; r < dJ; ++r) g[r] += b[r];
          }
        }
      });
}

void SparseSystem::add_source_block(std::span<const VariableId> variables, const double* record,
                                    double* gradient) {
  // The block's free variables: (elimination position, variable, offset inside the block's D).
  struct Free {
    int position;
    int variable;
    std::size_t local;
  };
  Free free[kMaxSourceVariables];
  std::size_t count = 0;
  std::size_t D = 0;
  for (const VariableId v : variables) {
    const auto index = static_cast<std::size_t>(v.index);
    if (var_position_[index] >= 0) free[count++] = {var_position_[index], v.index, D};
    D += static_cast<std::size_t>(var_dim_[index]);
  }
  const double* H = record;
  const double* b = record + D * (D + 1) / 2;
  // The same additions, in the same order per destination, as assemble() makes for an own block
  // that comes after every own block.
  for (std::size_t a = 0; a < count; ++a) {
    for (std::size_t q = 0; q < count; ++q) {
      if (free[a].position < free[q].position) continue;  // row >= column
      const auto J = static_cast<std::size_t>(free[q].position);
      const int dJ = var_dim_[static_cast<std::size_t>(free[q].variable)];
      const int dI = var_dim_[static_cast<std::size_t>(free[a].variable)];
      const int col0 = var_offset_[static_cast<std::size_t>(free[q].variable)];
      const std::size_t row_local = free[a].local;
      const std::size_t col_local = free[q].local;
      std::int64_t row_in_column = 0;
      if (a != q) {
        const auto first = pairs_.begin() + static_cast<std::ptrdiff_t>(column_pair_begin_[J]);
        const auto last = pairs_.begin() + static_cast<std::ptrdiff_t>(column_pair_begin_[J + 1]);
        const auto found =
            std::lower_bound(first, last, free[a].position,
                             [](const PairEntry& entry, int row) { return entry.row_var < row; });
        row_in_column = found->row_in_column;
      }
      for (int c = 0; c < dJ; ++c) {
        double* column = values_.data() + colptr_[static_cast<std::size_t>(col0 + c)];
        const auto cc = static_cast<std::size_t>(c);
        if (a == q) {
          const double* src_col = H + packed_column(D, col_local + cc);
          for (int r = 0; r < dJ - c; ++r) column[r] += src_col[r];
        } else if (row_local > col_local) {
          double* dst = column + (dJ - c) + row_in_column;
          const double* src_col =
              H + packed_column(D, col_local + cc) + (row_local - col_local - cc);
          for (int r = 0; r < dI; ++r) dst[r] += src_col[r];
        } else {
          double* dst = column + (dJ - c) + row_in_column;
          for (int r = 0; r < dI; ++r) {
            const auto rr = static_cast<std::size_t>(r);
            dst[r] += H[packed_column(D, row_local + rr) + (col_local + cc - row_local - rr)];
          }
        }
      }
    }
    double* g = gradient + var_offset_[static_cast<std::size_t>(free[a].variable)];
    const double* src = b + free[a].local;
    const int d = var_dim_[static_cast<std::size_t>(free[a].variable)];
    for (int r = 0; r < d; ++r) g[r] += src[r];
  }
}

bool SparseSystem::add_source_blocks(BlockSource& source, std::span<const double> values,
                                     std::size_t first_index, Eigen::VectorXd* gradient,
                                     LinearizeReport* report) {
  const std::size_t num_blocks = source.num_blocks();
  std::size_t next = 0;
  std::size_t bad = num_blocks;  // the first block whose record is not finite
  source.linearize(values, [&](std::size_t first, std::span<const double> records) {
    check_run_start(first, next, "records");
    std::size_t at = 0;
    while (at < records.size()) {
      if (next >= num_blocks) {
        throw Error("block source: records beyond its " + std::to_string(num_blocks) + " blocks");
      }
      const std::span<const VariableId> variables = source.variables(next);
      if (variables.size() > kMaxSourceVariables) {
        throw Error("block source: block " + std::to_string(next) + " has " +
                    std::to_string(variables.size()) + " variables (at most " +
                    std::to_string(kMaxSourceVariables) + ")");
      }
      int D = 0;
      for (const VariableId v : variables) D += var_dim_[static_cast<std::size_t>(v.index)];
      const std::size_t size = linearization_record_size(D);
      if (at + size > records.size()) {
        throw Error("block source: a run of records ends inside block " + std::to_string(next) +
                    "'s");
      }
      const double* record = records.data() + at;
      bool finite = true;
      for (std::size_t k = 0; k < size && finite; ++k) finite = std::isfinite(record[k]);
      if (!finite && bad == num_blocks) bad = next;
      if (bad == num_blocks) {
        add_source_block(variables, record, gradient->data());
        report->cost += record[size - 1];
      }
      at += size;
      ++next;
    }
  });
  check_runs_complete(next, num_blocks, "records");
  if (bad < num_blocks) {
    report->error = "residual block " + std::to_string(first_index + bad) + " (block " +
                    std::to_string(bad) + " of the block source): its H, b or cost is not finite";
    return false;
  }
  return true;
}

Eigen::VectorXd SparseSystem::diagonal() const {
  Eigen::VectorXd d(n_);
  for (int k = 0; k < n_; ++k)
    d[k] = values_[static_cast<std::size_t>(diag_pos_[static_cast<std::size_t>(k)])];
  return d;
}

bool SparseSystem::factorize(const Eigen::VectorXd& damping) {
  // Damping added to the assembled diagonal in place; the undamped values go back however this
  // function is left.
  saved_diagonal_.resize(static_cast<std::size_t>(n_));
  struct RestoreDiagonal {
    SparseSystem& system;
    ~RestoreDiagonal() {
      for (int k = 0; k < system.n_; ++k) {
        system.values_[static_cast<std::size_t>(system.diag_pos_[static_cast<std::size_t>(k)])] =
            system.saved_diagonal_[static_cast<std::size_t>(k)];
      }
    }
  };
  for (int k = 0; k < n_; ++k) {
    double& d = values_[static_cast<std::size_t>(diag_pos_[static_cast<std::size_t>(k)])];
    saved_diagonal_[static_cast<std::size_t>(k)] = d;
  }
  const RestoreDiagonal restore{*this};
  for (int k = 0; k < n_; ++k) {
    values_[static_cast<std::size_t>(diag_pos_[static_cast<std::size_t>(k)])] += damping[k];
  }
  return cholmod_->factorize();
}

void SparseSystem::multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const {
  y->setZero(n_);
  double* out = y->data();
  const double* in = x.data();
  // Lower triangle by columns: each off-diagonal entry (r, c) adds to rows r and c.
  for (int c = 0; c < n_; ++c) {
    const double x_c = in[c];
    double column_dot = 0.0;
    for (auto p = static_cast<std::size_t>(colptr_[static_cast<std::size_t>(c)]);
         p < static_cast<std::size_t>(colptr_[static_cast<std::size_t>(c) + 1]); ++p) {
      const auto r = static_cast<std::size_t>(rows_[p]);
      const double v = values_[p];
      if (r == static_cast<std::size_t>(c)) {
        column_dot += v * x_c;
      } else {
        out[r] += v * x_c;
        column_dot += v * in[r];
      }
    }
    out[c] += column_dot;
  }
}

void SparseSystem::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) {
  x->resize(n_);
  cholmod_->solve(rhs.data(), x->data(), "sparse system");
}

}  // namespace carat::internal
