#include "reduction.hpp"

#include <algorithm>

#include "elimination.hpp"

namespace carat::internal {

long Items::rows() const {
  long total = 0;
  for (long c : counts) total += c;
  return total;
}

void Items::reset(Eigen::Index L, int count) {
  if (sums.rows() != L || sums.cols() < count) sums.resize(L, std::max<Eigen::Index>(count, 64));
  counts.resize(static_cast<std::size_t>(count));
  weight.resize(static_cast<std::size_t>(count));
  ids.resize(static_cast<std::size_t>(count));
}

void Items::filter(const std::vector<char>& keep) {
  int out = 0;
  for (int i = 0; i < size(); ++i) {
    if (!keep[static_cast<std::size_t>(i)]) continue;
    if (out != i) {
      sums.col(out) = sums.col(i);
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

void reduce_level(Items& items, int clusters, long min_rows) {
  const int n = items.size();
  const Eigen::Index L = items.sums.rows();
  Eigen::MatrixXd means = Eigen::MatrixXd::Zero(L, clusters);
  Eigen::VectorXd cluster_weight = Eigen::VectorXd::Zero(clusters);
  std::vector<long> cluster_rows(static_cast<std::size_t>(clusters), 0);
  std::vector<int> begin(static_cast<std::size_t>(clusters) + 1);
  for (int c = 0; c <= clusters; ++c) {
    begin[static_cast<std::size_t>(c)] = static_cast<int>(static_cast<long>(n) * c / clusters);
  }
  for (int c = 0; c < clusters; ++c) {
    auto mean = means.col(c);
    for (int i = begin[static_cast<std::size_t>(c)]; i < begin[static_cast<std::size_t>(c) + 1];
         ++i) {
      const double w = items.weight[static_cast<std::size_t>(i)];
      mean.noalias() += w * items.sums.col(i);
      cluster_weight[c] += w * static_cast<double>(items.counts[static_cast<std::size_t>(i)]);
      cluster_rows[static_cast<std::size_t>(c)] += items.counts[static_cast<std::size_t>(i)];
    }
    mean /= cluster_weight[c];
  }
  Eigen::VectorXd new_weight = cluster_weight;
  const std::vector<char> alive = eliminate(means, new_weight, cluster_rows, min_rows);
  std::vector<char> keep(static_cast<std::size_t>(n), 0);
  for (int c = 0; c < clusters; ++c) {
    if (!alive[static_cast<std::size_t>(c)]) continue;
    const double scale = new_weight[c] / cluster_weight[c];
    for (int i = begin[static_cast<std::size_t>(c)]; i < begin[static_cast<std::size_t>(c) + 1];
         ++i) {
      keep[static_cast<std::size_t>(i)] = 1;
      items.weight[static_cast<std::size_t>(i)] *= scale;
    }
  }
  items.filter(keep);
}

void reduce_final(Items& items, long min_rows) {
  const int n = items.size();
  Eigen::MatrixXd means(items.sums.rows(), n);
  Eigen::VectorXd total(n);
  for (int i = 0; i < n; ++i) {
    const double count = static_cast<double>(items.counts[static_cast<std::size_t>(i)]);
    means.col(i) = items.sums.col(i) / count;
    total[i] = items.weight[static_cast<std::size_t>(i)] * count;
  }
  Eigen::VectorXd new_total = total;
  const std::vector<char> alive = eliminate(means, new_total, items.counts, min_rows);
  for (int i = 0; i < n; ++i) {
    if (alive[static_cast<std::size_t>(i)]) {
      items.weight[static_cast<std::size_t>(i)] =
          new_total[i] / static_cast<double>(items.counts[static_cast<std::size_t>(i)]);
    }
  }
  items.filter(alive);
}

}  // namespace carat::internal
