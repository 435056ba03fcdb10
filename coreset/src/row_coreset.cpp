#include "carat/coreset/row_coreset.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <numeric>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/interruption.hpp"
#include "carat/coreset/row_coreset_cost.hpp"
#include "elimination.hpp"
#include "lift.hpp"
#include "reduction.hpp"
#include "shuffle.hpp"
#include "simd.hpp"

namespace carat {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Rows per chunk of the first phase (summed in one pass, then reduced as units).
constexpr long kChunkRows = 32;
/// Largest scratch (bytes) kept per thread between calls, as compress() keeps its own.
constexpr double kMaxReusedBytes = 64.0 * (1 << 20);

/// Re-solves the final weights against the exact target sums (minimum-norm correction of the
/// weights so that sum w_k [p_k; 1] = target), which removes the rounding the levels left
/// behind. Kept only if every weight stays positive and the residual shrinks.
void polish_weights(const double* J, const double* e, int r, const Eigen::VectorXd& target,
                    internal::Items& rows) {
  const int m = rows.size();
  const Eigen::Index L = target.size() - 1;
  // Scratch of this thread, reused (no heap traffic per call; see eliminate).
  thread_local Eigen::MatrixXd P, gram;
  thread_local Eigen::VectorXd w, scale, residual, delta, polished, after;
  thread_local Eigen::LDLT<Eigen::MatrixXd> ldlt;
  thread_local std::vector<double> lifted;
  P.resize(L + 1, m);
  w.resize(m);
  lifted.resize(static_cast<std::size_t>(L));
  for (int k = 0; k < m; ++k) {
    internal::lift_rows(J, e, r, &rows.ids[static_cast<std::size_t>(k)], 1, lifted.data());
    for (Eigen::Index l = 0; l < L; ++l) P(l, k) = lifted[static_cast<std::size_t>(l)];
    P(L, k) = 1.0;
    w[k] = rows.weight[static_cast<std::size_t>(k)];
  }
  // Scale each equation to unit size so that every coordinate counts alike.
  scale.resize(L + 1);
  for (Eigen::Index l = 0; l <= L; ++l) {
    const double s = std::max(P.row(l).cwiseAbs().maxCoeff(), std::abs(target[l]));
    scale[l] = s > 0.0 ? 1.0 / s : 0.0;
  }
  P = scale.asDiagonal() * P;
  residual.noalias() = scale.cwiseProduct(target);
  residual.noalias() -= P * w;
  const double before = residual.norm();
  // Keeps w + delta if every weight stays positive and the residual shrinks.
  const auto accept = [&]() {
    polished = w + delta;
    if (!polished.allFinite() || polished.minCoeff() <= 0.0) return false;
    after.noalias() = scale.cwiseProduct(target);
    after.noalias() -= P * polished;
    if (!(after.norm() < before)) return false;
    for (int k = 0; k < m; ++k) rows.weight[static_cast<std::size_t>(k)] = polished[k];
    return true;
  };
  // Exactly L + 1 rows (the minimum): the correction is P^-1 residual when P is regular.
  if (m == L + 1) {
    delta.resize(m);
    if (internal::solve_square(P.data(), m, residual.data(), delta.data()) && accept()) return;
  }
  // Minimum-norm correction through the (L+1) x (L+1) Gram matrix (semi-definite LDL^T: the
  // directions the rows do not span get no correction, and need none).
  gram.setZero(L + 1, L + 1);
  gram.selfadjointView<Eigen::Lower>().rankUpdate(P);  // P P^T, one triangle (LDLT reads it)
  ldlt.compute(gram);
  delta.noalias() = P.transpose() * ldlt.solve(residual);
  accept();
}

/// Reduces single-row items to `target` rows (exactly, if exact and the data allow it).
void reduce_rows(internal::Items& items, long target, bool exact, int clusters, int L,
                 int depth = 0) {
  while (items.size() > target) {
    const int n = items.size();
    if (n <= clusters) {
      internal::reduce_final(items, exact ? target : 0);
      return;
    }
    if (exact && static_cast<long>(n) * (L + 1) / clusters < target) {
      // The next level would undershoot: keep target - (L + 1) rows as they are and reduce the
      // excess to L + 1 rows.
      const int keep = static_cast<int>(target) - (L + 1);
      // One Items per recursion depth, reused across calls (the recursion is at most two deep;
      // a deque keeps the shallower ones in place while a deeper one is added).
      thread_local std::deque<internal::Items> excess_by_depth;
      while (excess_by_depth.size() <= static_cast<std::size_t>(depth)) {
        excess_by_depth.emplace_back();
      }
      internal::Items& excess = excess_by_depth[static_cast<std::size_t>(depth)];
      items.split_tail(keep, excess);
      reduce_rows(excess, L + 1, true, clusters, L, depth + 1);
      items.append(excess);
      return;
    }
    interruption_point();
    internal::reduce_level(items, clusters, exact ? target : 0);
    if (items.size() == n) return;  // nothing left to eliminate
  }
}

}  // namespace

int minimum_coreset_rows(int reduced_dim) {
  return reduced_dim * (reduced_dim + 1) / 2 + reduced_dim + 2;
}

int default_coreset_clusters(int reduced_dim) {
  return std::max(64, 2 * (internal::lifted_dim(reduced_dim) + 1));
}

RowCoresetCost estimate_row_coreset(long rows, int reduced_dim, const RowCoresetOptions& options) {
  if (rows < 0 || reduced_dim < 1 || options.target_rows < 0 || options.clusters < 0) {
    throw Error("estimate_row_coreset: negative size, target or clusters");
  }
  RowCoresetCost cost;
  const int L = internal::lifted_dim(reduced_dim);
  cost.lifted_dim = L;
  cost.clusters = options.clusters == 0 ? default_coreset_clusters(reduced_dim) : options.clusters;
  const auto N = static_cast<double>(rows);
  const double K = cost.clusters;
  const double M = options.target_rows == 0 ? L + 1.0 : options.target_rows;
  if (N <= M) {
    cost.bytes = 16.0 * N;  // the indices and weights returned
    return cost;
  }
  // Phase 1 sums chunks of kChunkRows rows and reduces them until at most max(8 M, K chunks)
  // rows remain; those are lifted one by one (packed when narrow) for the row phase.
  const double row_phase = std::max(8.0 * M, K * static_cast<double>(kChunkRows));
  cost.lifted_rows = static_cast<long>(std::min(N, row_phase));
  const int packed = internal::packed_stride(reduced_dim);
  const double row_doubles = packed > 0 && internal::wide_kernels() ? packed : L;
  const double chunks = std::ceil(N / static_cast<double>(kChunkRows));
  // An elimination of n points holds their means, the centred copy and the free-column tableau:
  // about three L x n arrays, n at most K (a level) or the rows left (the last one).
  const double eliminated = std::min(K, static_cast<double>(cost.lifted_rows));
  cost.bytes =
      8.0 * (chunks * (L + 3.0) + static_cast<double>(cost.lifted_rows) * (row_doubles + 3.0) +
             3.0 * (L + 1.0) * eliminated + (L + 1.0) * (L + 1.0 + M));
  // (K < L + 2 makes no progress; select_coreset_rows() refuses it.)
  cost.levels = K > L + 1.0 ? std::max(1.0, std::log(N / M) / std::log(K / (L + 1.0))) : 1.0;
  cost.operations = cost.levels * K * static_cast<double>(L) * L + 4.0 * N * L;
  return cost;
}

RowCoreset select_coreset_rows(const Eigen::Ref<const RowMatrix>& J_r,
                               const Eigen::Ref<const Eigen::VectorXd>& e,
                               const RowCoresetOptions& options) {
  const long N = J_r.rows();
  const int r = static_cast<int>(J_r.cols());
  if (e.size() != N) {
    throw Error("coreset: " + std::to_string(N) + " Jacobian rows but " + std::to_string(e.size()) +
                " residuals");
  }
  if (r < 1) throw Error("coreset: the Jacobian has no columns");
  if (N < 1) throw Error("coreset: no rows to compress");
  if (N > std::numeric_limits<int>::max()) {
    throw Error("coreset: " + std::to_string(N) + " rows are more than an int can index");
  }
  const int L = internal::lifted_dim(r);
  const int minimum = L + 1;
  if (options.target_rows < 0) {
    throw Error("coreset: target of " + std::to_string(options.target_rows) +
                " rows is negative (0 selects the minimum)");
  }
  const long M = options.target_rows == 0 ? minimum : options.target_rows;
  if (M < minimum) {
    throw Error("coreset: target of " + std::to_string(M) + " rows is below the minimum of " +
                std::to_string(minimum) + " for reduced dimension " + std::to_string(r));
  }
  const int K = options.clusters == 0 ? default_coreset_clusters(r) : options.clusters;
  if (K < L + 2) {
    throw Error("coreset: " + std::to_string(options.clusters) +
                " clusters cannot make progress for reduced dimension " + std::to_string(r) +
                " (lifted dimension " + std::to_string(L) + "); use at least " +
                std::to_string(L + 2) + ", or 0 for the default " +
                std::to_string(default_coreset_clusters(r)));
  }
  // The scratch grows as L x K (the eliminations' tableaus), L x N / 32 (the chunk sums) and L
  // per lifted row: refuse what cannot be held instead of failing inside an allocation.
  constexpr double kMaxScratchBytes = 4e9;
  const double scratch = estimate_row_coreset(N, r, options).bytes;
  if (scratch > kMaxScratchBytes) {
    throw Error("coreset: reduced dimension " + std::to_string(r) + " (lifted dimension " +
                std::to_string(L) + ") with " + std::to_string(K) + " clusters needs about " +
                std::to_string(static_cast<long>(scratch / 1e6)) +
                " MB of scratch, more than the 4000 MB allowed; compress a reduced Jacobian "
                "(reduced_dim()) or fewer rows at a time");
  }

  // Row-major rows with unit stride, as the lift kernels read them.
  RowMatrix J_copy;
  const double* J = J_r.data();
  if (J_r.outerStride() != r) {
    J_copy = J_r;
    J = J_copy.data();
  }
  const double* E = e.data();
  const auto check_rows = [&](long begin, long end) {
    for (long i = begin; i < end; ++i) {
      if (!std::isfinite(E[i]) || !J_r.row(i).allFinite()) {
        throw Error("coreset: row " + std::to_string(i) +
                    " has a non-finite residual or Jacobian entry");
      }
    }
    throw Error("coreset: rows " + std::to_string(begin) + ".." + std::to_string(end - 1) +
                " overflow when squared (values too large for double)");
  };

  RowCoreset out;
  if (N <= M) {  // nothing to compress: every row, weight 1 (after the same finiteness check)
    std::vector<double> sum(static_cast<std::size_t>(L));
    internal::lift_sum(J, E, r, N, 0, N, sum.data());
    for (double v : sum) {
      if (!std::isfinite(v)) check_rows(0, N);
    }
    out.rows.resize(static_cast<std::size_t>(N));
    std::iota(out.rows.begin(), out.rows.end(), 0);
    out.weights.assign(static_cast<std::size_t>(N), 1.0);
    return out;
  }

  // Phase 1: chunks of kChunkRows consecutive rows, summed in one sequential pass, visited in
  // a seeded random order (clusters are contiguous runs of that order).
  const long chunks = (N + kChunkRows - 1) / kChunkRows;
  // Scratch of this thread, reused: fresh heap pages cost a page fault each (see eliminate).
  thread_local std::vector<int> chunk_order;
  internal::seeded_permutation(static_cast<int>(chunks), options.seed, chunk_order);
  thread_local internal::Items items;  // reused: fresh memory costs page faults every call
  items.reset(L, static_cast<int>(chunks));
  std::fill(items.weight.begin(), items.weight.end(), 1.0);
  Eigen::VectorXd target = Eigen::VectorXd::Zero(L + 1);
  // Chunks are summed in memory order (streaming reads) and stored at their shuffled position.
  thread_local std::vector<int> position;
  position.resize(static_cast<std::size_t>(chunks));
  for (long k = 0; k < chunks; ++k)
    position[static_cast<std::size_t>(chunk_order[static_cast<std::size_t>(k)])] =
        static_cast<int>(k);
  internal::lift_chunk_sums(J, E, r, N, kChunkRows, position.data(), items.sums.data(),
                            target.data());
  for (long c = 0; c < chunks; ++c) {
    const auto k = static_cast<std::size_t>(position[static_cast<std::size_t>(c)]);
    items.counts[k] = std::min(N, (c + 1) * kChunkRows) - c * kChunkRows;
    items.ids[k] = static_cast<int>(c);
  }
  // A non-finite entry anywhere makes the total non-finite: only then look for the chunk.
  if (!target.head(L).allFinite()) {
    for (long c = 0; c < chunks; ++c) {
      const double* chunk_sum = items.item(position[static_cast<std::size_t>(c)]);
      if (!std::all_of(chunk_sum, chunk_sum + L, [](double v) { return std::isfinite(v); })) {
        check_rows(c * kChunkRows, std::min(N, (c + 1) * kChunkRows));
      }
    }
    throw Error("coreset: the sums of all " + std::to_string(N) +
                " rows overflow (values too large for double)");
  }
  target[L] = static_cast<double>(N);
  const long row_phase = std::max<long>(8 * M, static_cast<long>(K) * kChunkRows);
  while (items.size() > K && items.rows() > row_phase) {
    const int before = items.size();
    interruption_point();
    internal::reduce_level(items, K, M);
    if (items.size() == before) break;
  }

  // Phase 2: the surviving chunks' rows become items of their own (shuffled again, seeded).
  thread_local std::vector<int> row_ids;
  thread_local std::vector<double> row_weight;
  row_ids.clear();
  row_weight.clear();
  for (int c = 0; c < items.size(); ++c) {
    const long begin = static_cast<long>(items.ids[static_cast<std::size_t>(c)]) * kChunkRows;
    const long end = std::min(N, begin + kChunkRows);
    for (long i = begin; i < end; ++i) {
      row_ids.push_back(static_cast<int>(i));
      row_weight.push_back(items.weight[static_cast<std::size_t>(c)]);
    }
  }
  const auto survivors = static_cast<int>(row_ids.size());
  thread_local std::vector<int> row_order;
  internal::seeded_permutation(survivors, options.seed + 1, row_order);
  thread_local internal::Items rows;
  // Rows of up to kMaxPackedCols - 1 columns travel packed (lifted on the fly) where the wide
  // kernels pay off; otherwise, and for wider rows, lifted.
  const bool packed = internal::packed_stride(r) > 0 && internal::wide_kernels();
  if (packed) {
    rows.reset_packed(r, survivors);
  } else {
    rows.reset(L, survivors);
  }
  std::fill(rows.counts.begin(), rows.counts.end(), 1);
  for (int k = 0; k < survivors; ++k) {
    const auto src = static_cast<std::size_t>(row_order[static_cast<std::size_t>(k)]);
    rows.weight[static_cast<std::size_t>(k)] = row_weight[src];
    rows.ids[static_cast<std::size_t>(k)] = row_ids[src];
  }
  if (packed) {
    internal::pack_rows(J, E, r, rows.ids.data(), survivors, rows.sums.data());
  } else {
    internal::lift_rows(J, E, r, rows.ids.data(), survivors, rows.sums.data());
  }

  // Phase 3: rows down to M.
  interruption_point();
  reduce_rows(rows, M, options.exact_size, K, L);

  polish_weights(J, E, r, target, rows);

  thread_local std::vector<int> idx;
  idx.resize(static_cast<std::size_t>(rows.size()));
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](int a, int b) {
    return rows.ids[static_cast<std::size_t>(a)] < rows.ids[static_cast<std::size_t>(b)];
  });
  if (scratch > kMaxReusedBytes) {  // a huge block's scratch is not kept for the next call
    std::vector<int>().swap(chunk_order);
    std::vector<int>().swap(position);
    items = internal::Items();
  }
  out.rows.reserve(idx.size());
  out.weights.reserve(idx.size());
  for (int k : idx) {
    out.rows.push_back(rows.ids[static_cast<std::size_t>(k)]);
    out.weights.push_back(rows.weight[static_cast<std::size_t>(k)]);
  }
  return out;
}

}  // namespace carat
