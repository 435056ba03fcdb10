#include "reduction.hpp"

#include <algorithm>
#include <cstddef>
#include <type_traits>

#include "elimination.hpp"
#include "lift.hpp"
#include "simd.hpp"

namespace carat::internal {
namespace {

/// acc[0..L) += w * p[0..L) (vectorizes over the coordinates).
inline void add_scaled(double* __restrict acc, const double* __restrict p, double w,
                       Eigen::Index L) {
  for (Eigen::Index l = 0; l < L; ++l) acc[l] += w * p[l];
}

/// Item-major weighted sums of contiguous clusters: out[c * L + l] = sum over i in
/// [begin[c], begin[c + 1]) of w[i] * p[i * L + l].
CARAT_MULTIVERSION
void cluster_sums(const double* __restrict p, const double* __restrict w, Eigen::Index L,
                  const int* begin, int clusters, double* __restrict out) {
  for (int c = 0; c < clusters; ++c) {
    double* acc = out + c * L;
    for (Eigen::Index l = 0; l < L; ++l) acc[l] = 0.0;
    for (int i = begin[c]; i < begin[c + 1]; ++i) add_scaled(acc, p + i * L, w[i], L);
  }
}

}  // namespace

long Items::rows() const {
  long total = 0;
  for (long c : counts) total += c;
  return total;
}

void Items::reset(Eigen::Index L, int count) {
  dim = L;
  lifted = L;
  packed_cols = 0;
  if (sums.size() < static_cast<std::size_t>(L * count)) {
    sums.resize(static_cast<std::size_t>(L * count));
  }
  counts.resize(static_cast<std::size_t>(count));
  weight.resize(static_cast<std::size_t>(count));
  ids.resize(static_cast<std::size_t>(count));
}

void Items::reset_packed(int r, int count) {
  reset(packed_stride(r), count);
  lifted = lifted_dim(r);
  packed_cols = r + 1;
}

void Items::filter(const std::vector<char>& keep) {
  const int n = size();
  int out = 0;
  for (int i = 0; i < n; ++i) {
    if (!keep[static_cast<std::size_t>(i)]) continue;
    if (out != i) {
      std::copy(item(i), item(i) + dim, item(out));
      counts[static_cast<std::size_t>(out)] = counts[static_cast<std::size_t>(i)];
      weight[static_cast<std::size_t>(out)] = weight[static_cast<std::size_t>(i)];
      ids[static_cast<std::size_t>(out)] = ids[static_cast<std::size_t>(i)];
    }
    ++out;
  }
  counts.resize(static_cast<std::size_t>(out));
  weight.resize(static_cast<std::size_t>(out));
  ids.resize(static_cast<std::size_t>(out));
}

void Items::truncate(int count) {
  counts.resize(static_cast<std::size_t>(count));
  weight.resize(static_cast<std::size_t>(count));
  ids.resize(static_cast<std::size_t>(count));
}

void Items::split_tail(int from, Items& tail) {
  const int n = size();
  tail.reset(dim, n - from);
  tail.lifted = lifted;
  tail.packed_cols = packed_cols;
  std::copy(item(from), item(n), tail.item(0));
  tail.counts.assign(counts.begin() + from, counts.end());
  tail.weight.assign(weight.begin() + from, weight.end());
  tail.ids.assign(ids.begin() + from, ids.end());
  counts.resize(static_cast<std::size_t>(from));
  weight.resize(static_cast<std::size_t>(from));
  ids.resize(static_cast<std::size_t>(from));
}

void Items::append(const Items& tail) {
  const int n = size();
  const int total = n + tail.size();
  if (sums.size() < static_cast<std::size_t>(dim * total)) {
    sums.resize(static_cast<std::size_t>(dim * total));
  }
  std::copy(tail.item(0), tail.item(tail.size()), item(n));
  counts.insert(counts.end(), tail.counts.begin(), tail.counts.end());
  weight.insert(weight.end(), tail.weight.begin(), tail.weight.end());
  ids.insert(ids.end(), tail.ids.begin(), tail.ids.end());
}

void reduce_level(Items& items, int clusters, long min_rows) {
  const int n = items.size();
  const Eigen::Index L = items.lifted;
  const Eigen::Index P = items.dim;
  const auto K = static_cast<std::size_t>(clusters);
  thread_local std::vector<double> sums, cluster_weight, new_weight;
  thread_local std::vector<long> cluster_rows;
  thread_local std::vector<int> begin;
  sums.resize(static_cast<std::size_t>(L) * K);
  cluster_weight.assign(K, 0.0);
  cluster_rows.assign(K, 0);
  begin.resize(K + 1);
  for (std::size_t c = 0; c <= K; ++c) {
    begin[c] = static_cast<int>(static_cast<long>(n) * static_cast<long>(c) / clusters);
  }
  for (std::size_t c = 0; c < K; ++c) {
    for (int i = begin[c]; i < begin[c + 1]; ++i) {
      const long count = items.counts[static_cast<std::size_t>(i)];
      cluster_weight[c] += items.weight[static_cast<std::size_t>(i)] * static_cast<double>(count);
      cluster_rows[c] += count;
    }
  }
  if (items.packed_cols > 0) {
    packed_cluster_sums(items.sums.data(), items.packed_cols - 1, items.weight.data(), begin.data(),
                        clusters, sums.data());
  } else {
    cluster_sums(items.sums.data(), items.weight.data(), L, begin.data(), clusters, sums.data());
  }
  // The clusters' means are their sums over their weights: the elimination reads the sums
  // item-major and scales them as it centres each coordinate.
  thread_local std::vector<double> inverse;
  inverse.resize(K);
  for (std::size_t c = 0; c < K; ++c) inverse[c] = 1.0 / cluster_weight[c];
  new_weight = cluster_weight;
  const std::vector<char>& alive =
      eliminate(sums.data(), L, clusters, PointLayout{1, L, inverse.data()}, new_weight.data(),
                cluster_rows, min_rows);
  // Kept clusters' items move down in place (clusters are contiguous and in order, so an item
  // never moves up) with their weights rescaled: one pass, no mask.
  // Packed rows of 8 or 16 doubles move by fixed-size copies (a call to memmove per row of
  // 128 bytes cost more than the move).
  const auto move_items = [&]<int S>(std::integral_constant<int, S>) {
    int out = 0;
    for (std::size_t c = 0; c < K; ++c) {
      if (!alive[c]) continue;
      const double scale = new_weight[c] / cluster_weight[c];
      for (int i = begin[c]; i < begin[c + 1]; ++i, ++out) {
        const auto o = static_cast<std::size_t>(out);
        const auto s = static_cast<std::size_t>(i);
        if (out != i) {
          if constexpr (S > 0) {
            __builtin_memcpy(items.item(out), items.item(i), S * sizeof(double));
          } else {
            std::copy(items.item(i), items.item(i) + P, items.item(out));
          }
          items.counts[o] = items.counts[s];
          items.ids[o] = items.ids[s];
        }
        items.weight[o] = items.weight[s] * scale;
      }
    }
    return out;
  };
  int out = 0;
  if (P == 8) {
    out = move_items(std::integral_constant<int, 8>{});
  } else if (P == 16) {
    out = move_items(std::integral_constant<int, 16>{});
  } else {
    out = move_items(std::integral_constant<int, 0>{});
  }
  items.truncate(out);
}

void reduce_final(Items& items, long min_rows) {
  const int n = items.size();
  const Eigen::Index L = items.lifted;
  thread_local std::vector<double> means, total;
  means.resize(static_cast<std::size_t>(L * n));
  total.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    total[static_cast<std::size_t>(i)] =
        items.weight[static_cast<std::size_t>(i)] *
        static_cast<double>(items.counts[static_cast<std::size_t>(i)]);
  }
  if (items.packed_cols > 0) {
    lift_packed(items.sums.data(), items.packed_cols - 1, n, means.data(), n);
  } else {
    for (int i = 0; i < n; ++i) {
      const double* p = items.item(i);
      const double inverse = 1.0 / static_cast<double>(items.counts[static_cast<std::size_t>(i)]);
      for (Eigen::Index l = 0; l < L; ++l)
        means[static_cast<std::size_t>(l * n + i)] = p[l] * inverse;
    }
  }
  const std::vector<char>& alive =
      eliminate(means.data(), L, n, PointLayout{n}, total.data(), items.counts, min_rows);
  for (int i = 0; i < n; ++i) {
    if (alive[static_cast<std::size_t>(i)]) {
      items.weight[static_cast<std::size_t>(i)] =
          total[static_cast<std::size_t>(i)] /
          static_cast<double>(items.counts[static_cast<std::size_t>(i)]);
    }
  }
  items.filter(alive);
}

}  // namespace carat::internal
