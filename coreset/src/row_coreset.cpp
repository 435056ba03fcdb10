#include "carat/coreset/row_coreset.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "carat/solver/error.hpp"
#include "reduction.hpp"
#include "shuffle.hpp"
#include "simd.hpp"

namespace carat {
namespace {

constexpr long kChunkRows = 32;

/// Writes the sum of the lifted rows [begin, end) to out (L numbers): upper(a a^T) row by row,
/// then a e, then e^2. J is row-major with r columns.
template <int R>
void lift_sum_fixed(const double* J, const double* e, long begin, long end, double* out) {
  constexpr int L = R * (R + 1) / 2 + R + 1;
  double acc[L] = {};
  for (long i = begin; i < end; ++i) {
    double x[R + 1];
    for (int j = 0; j < R; ++j) x[j] = J[i * R + j];
    x[R] = e[i];
    int idx = 0;
    for (int j = 0; j < R; ++j) {
      for (int k = j; k < R; ++k) acc[idx++] += x[j] * x[k];
    }
    for (int j = 0; j < R; ++j) acc[idx++] += x[j] * x[R];
    acc[idx] += x[R] * x[R];
  }
  for (int l = 0; l < L; ++l) out[l] = acc[l];
}

/// The r = 6 kernel: four rows at a time in vector lanes (28 vector accumulators), each lane a
/// separate partial sum, added up at the end in a fixed order.
CARAT_MULTIVERSION
void lift_sum_6(const double* J, const double* e, long begin, long end, double* out) {
  typedef double v4d __attribute__((vector_size(32)));
  v4d acc[28];
  for (auto& a : acc) a = v4d{0.0, 0.0, 0.0, 0.0};
  long i = begin;
  for (; i + 3 < end; i += 4) {
    const double* r0 = J + i * 6;
    v4d x[7];
    for (int j = 0; j < 6; ++j) x[j] = v4d{r0[j], r0[6 + j], r0[12 + j], r0[18 + j]};
    x[6] = v4d{e[i], e[i + 1], e[i + 2], e[i + 3]};
    int idx = 0;
    for (int j = 0; j < 6; ++j) {
      for (int k = j; k < 6; ++k) acc[idx++] += x[j] * x[k];
    }
    for (int j = 0; j < 6; ++j) acc[idx++] += x[j] * x[6];
    acc[idx] += x[6] * x[6];
  }
  for (int l = 0; l < 28; ++l) out[l] = (acc[l][0] + acc[l][1]) + (acc[l][2] + acc[l][3]);
  if (i < end) {  // the last 1-3 rows
    double tail[28];
    lift_sum_fixed<6>(J, e, i, end, tail);
    for (int l = 0; l < 28; ++l) out[l] += tail[l];
  }
}

void lift_sum_dynamic(const double* J, const double* e, int r, long begin, long end, double* out) {
  const int L = r * (r + 1) / 2 + r + 1;
  std::fill(out, out + L, 0.0);
  std::vector<double> x(static_cast<std::size_t>(r) + 1);
  for (long i = begin; i < end; ++i) {
    for (int j = 0; j < r; ++j) x[static_cast<std::size_t>(j)] = J[i * r + j];
    x[static_cast<std::size_t>(r)] = e[i];
    int idx = 0;
    for (int j = 0; j < r; ++j) {
      for (int k = j; k < r; ++k)
        out[idx++] += x[static_cast<std::size_t>(j)] * x[static_cast<std::size_t>(k)];
    }
    for (int j = 0; j < r; ++j)
      out[idx++] += x[static_cast<std::size_t>(j)] * x[static_cast<std::size_t>(r)];
    out[idx] += x[static_cast<std::size_t>(r)] * x[static_cast<std::size_t>(r)];
  }
}

void lift_sum(const double* J, const double* e, int r, long begin, long end, double* out) {
  switch (r) {
    case 6:
      lift_sum_6(J, e, begin, end, out);
      return;
    case 3:
      lift_sum_fixed<3>(J, e, begin, end, out);
      return;
    case 12:
      lift_sum_fixed<12>(J, e, begin, end, out);
      return;
    default:
      lift_sum_dynamic(J, e, r, begin, end, out);
  }
}

/// Writes the lifted row i to out.
void lift_row(const double* J, const double* e, int r, long i, double* out) {
  if (r == 6) {
    lift_sum_fixed<6>(J, e, i, i + 1, out);
  } else {
    lift_sum_dynamic(J, e, r, i, i + 1, out);
  }
}

/// Re-solves the final weights against the exact target sums (minimum-norm correction of the
/// weights so that sum w_k [p_k; 1] = target), which removes the rounding the levels left
/// behind. Kept only if every weight stays positive and the residual shrinks.
void polish_weights(const double* J, const double* e, int r, const Eigen::VectorXd& target,
                    internal::Items& rows) {
  const int m = rows.size();
  const Eigen::Index L = target.size() - 1;
  Eigen::MatrixXd P(L + 1, m);
  Eigen::VectorXd w(m);
  for (int k = 0; k < m; ++k) {
    lift_row(J, e, r, rows.ids[static_cast<std::size_t>(k)], P.col(k).data());
    P(L, k) = 1.0;
    w[k] = rows.weight[static_cast<std::size_t>(k)];
  }
  // Scale each equation to unit size so that every coordinate counts alike.
  Eigen::VectorXd scale(L + 1);
  for (Eigen::Index l = 0; l <= L; ++l) {
    const double s = std::max(P.row(l).cwiseAbs().maxCoeff(), std::abs(target[l]));
    scale[l] = s > 0.0 ? 1.0 / s : 0.0;
  }
  const Eigen::MatrixXd Ps = scale.asDiagonal() * P;
  const Eigen::VectorXd residual = scale.asDiagonal() * target - Ps * w;
  // Minimum-norm correction through the (L+1) x (L+1) Gram matrix (semi-definite LDL^T: the
  // directions the rows do not span get no correction, and need none).
  const Eigen::MatrixXd gram = Ps * Ps.transpose();
  const Eigen::VectorXd delta = Ps.transpose() * gram.ldlt().solve(residual);
  const Eigen::VectorXd polished = w + delta;
  if (!polished.allFinite() || polished.minCoeff() <= 0.0) return;
  const Eigen::VectorXd after = scale.asDiagonal() * target - Ps * polished;
  if (!(after.norm() < residual.norm())) return;
  for (int k = 0; k < m; ++k) rows.weight[static_cast<std::size_t>(k)] = polished[k];
}

/// Splits items [from, size) off into a new Items.
internal::Items split_tail(internal::Items& items, int from) {
  internal::Items tail;
  const int n = items.size();
  tail.sums = items.sums.middleCols(from, n - from);
  tail.counts.assign(items.counts.begin() + from, items.counts.end());
  tail.weight.assign(items.weight.begin() + from, items.weight.end());
  tail.ids.assign(items.ids.begin() + from, items.ids.end());
  items.counts.resize(static_cast<std::size_t>(from));
  items.weight.resize(static_cast<std::size_t>(from));
  items.ids.resize(static_cast<std::size_t>(from));
  return tail;
}

void append(internal::Items& items, const internal::Items& tail) {
  const int n = items.size();
  if (items.sums.cols() < n + tail.size())
    items.sums.conservativeResize(Eigen::NoChange, n + tail.size());
  items.sums.middleCols(n, tail.size()) = tail.sums.leftCols(tail.size());
  items.counts.insert(items.counts.end(), tail.counts.begin(), tail.counts.end());
  items.weight.insert(items.weight.end(), tail.weight.begin(), tail.weight.end());
  items.ids.insert(items.ids.end(), tail.ids.begin(), tail.ids.end());
}

/// Reduces single-row items to `target` rows (exactly, if exact and the data allow it).
void reduce_rows(internal::Items& items, long target, bool exact, int clusters, int L) {
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
      internal::Items excess = split_tail(items, keep);
      reduce_rows(excess, L + 1, true, clusters, L);
      append(items, excess);
      return;
    }
    internal::reduce_level(items, clusters, exact ? target : 0);
    if (items.size() == n) return;  // nothing left to eliminate
  }
}

}  // namespace

int minimum_coreset_rows(int reduced_dim) {
  return reduced_dim * (reduced_dim + 1) / 2 + reduced_dim + 2;
}

RowCoreset select_coreset_rows(
    const Eigen::Ref<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>&
        J_r,
    const Eigen::Ref<const Eigen::VectorXd>& e, const RowCoresetOptions& options) {
  const long N = J_r.rows();
  const int r = static_cast<int>(J_r.cols());
  if (e.size() != N) {
    throw Error("coreset: " + std::to_string(N) + " Jacobian rows but " + std::to_string(e.size()) +
                " residuals");
  }
  if (r < 1) throw Error("coreset: the Jacobian has no columns");
  if (N < 1) throw Error("coreset: no rows to compress");
  const int L = r * (r + 1) / 2 + r + 1;
  const int minimum = L + 1;
  const long M = options.target_rows == 0 ? minimum : options.target_rows;
  if (M < minimum) {
    throw Error("coreset: target of " + std::to_string(M) + " rows is below the minimum of " +
                std::to_string(minimum) + " for reduced dimension " + std::to_string(r));
  }
  if (options.clusters < L + 2) {
    throw Error("coreset: " + std::to_string(options.clusters) +
                " clusters cannot make progress for reduced dimension " + std::to_string(r) +
                " (lifted dimension " + std::to_string(L) + "); use at least " +
                std::to_string(L + 2));
  }
  RowCoreset out;
  if (N <= M) {  // nothing to compress: every row, weight 1
    out.rows.resize(static_cast<std::size_t>(N));
    std::iota(out.rows.begin(), out.rows.end(), 0);
    out.weights.assign(static_cast<std::size_t>(N), 1.0);
    return out;
  }

  // Row-major rows with unit stride, as the lift kernel reads them.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J_copy;
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

  // Phase 1: chunks of kChunkRows consecutive rows, summed in one sequential pass, visited in
  // a seeded random order (clusters are contiguous runs of that order).
  const long chunks = (N + kChunkRows - 1) / kChunkRows;
  const std::vector<int> chunk_order =
      internal::seeded_permutation(static_cast<int>(chunks), options.seed);
  thread_local internal::Items items;  // reused: fresh memory costs page faults every call
  items.reset(L, static_cast<int>(chunks));
  std::fill(items.weight.begin(), items.weight.end(), 1.0);
  for (long k = 0; k < chunks; ++k) {
    const long c = chunk_order[static_cast<std::size_t>(k)];
    const long begin = c * kChunkRows;
    const long end = std::min(N, begin + kChunkRows);
    auto sum = items.sums.col(k);
    lift_sum(J, E, r, begin, end, sum.data());
    if (!sum.allFinite()) check_rows(begin, end);
    items.counts[static_cast<std::size_t>(k)] = end - begin;
    items.ids[static_cast<std::size_t>(k)] = static_cast<int>(c);
  }
  // The exact target: the sum of every lifted row (and the total weight N), for the final polish.
  Eigen::VectorXd target(L + 1);
  target.head(L) = items.sums.leftCols(chunks).rowwise().sum();
  target[L] = static_cast<double>(N);
  const long row_phase = std::max<long>(8 * M, static_cast<long>(options.clusters) * kChunkRows);
  while (items.size() > options.clusters && items.rows() > row_phase) {
    const int before = items.size();
    internal::reduce_level(items, options.clusters, M);
    if (items.size() == before) break;
  }

  // Phase 2: the surviving chunks' rows become items of their own (shuffled again, seeded).
  std::vector<int> row_ids;
  std::vector<double> row_weight;
  for (int c = 0; c < items.size(); ++c) {
    const long begin = static_cast<long>(items.ids[static_cast<std::size_t>(c)]) * kChunkRows;
    const long end = std::min(N, begin + kChunkRows);
    for (long i = begin; i < end; ++i) {
      row_ids.push_back(static_cast<int>(i));
      row_weight.push_back(items.weight[static_cast<std::size_t>(c)]);
    }
  }
  const auto survivors = static_cast<long>(row_ids.size());
  const std::vector<int> row_order =
      internal::seeded_permutation(static_cast<int>(survivors), options.seed + 1);
  thread_local internal::Items rows;
  rows.reset(L, static_cast<int>(survivors));
  std::fill(rows.counts.begin(), rows.counts.end(), 1);
  for (long k = 0; k < survivors; ++k) {
    const auto src = static_cast<std::size_t>(row_order[static_cast<std::size_t>(k)]);
    const long i = row_ids[src];
    lift_row(J, E, r, i, rows.sums.col(k).data());
    rows.weight[static_cast<std::size_t>(k)] = row_weight[src];
    rows.ids[static_cast<std::size_t>(k)] = static_cast<int>(i);
  }

  // Phase 3: rows down to M.
  reduce_rows(rows, M, options.exact_size, options.clusters, L);

  polish_weights(J, E, r, target, rows);

  std::vector<int> idx(static_cast<std::size_t>(rows.size()));
  std::iota(idx.begin(), idx.end(), 0);
  std::sort(idx.begin(), idx.end(), [&](int a, int b) {
    return rows.ids[static_cast<std::size_t>(a)] < rows.ids[static_cast<std::size_t>(b)];
  });
  for (int k : idx) {
    out.rows.push_back(rows.ids[static_cast<std::size_t>(k)]);
    out.weights.push_back(rows.weight[static_cast<std::size_t>(k)]);
  }
  return out;
}

}  // namespace carat
