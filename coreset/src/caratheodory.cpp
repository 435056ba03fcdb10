#include "carat/coreset/caratheodory.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>

#include "carat/base/error.hpp"
#include "elimination.hpp"
#include "reduction.hpp"
#include "shuffle.hpp"

namespace carat {
namespace {

void validate(const Eigen::MatrixXd& points, std::span<const double> weights, const char* who) {
  if (static_cast<std::size_t>(points.cols()) != weights.size()) {
    throw Error(std::string(who) + ": " + std::to_string(points.cols()) + " points but " +
                std::to_string(weights.size()) + " weights");
  }
  if (points.cols() == 0) throw Error(std::string(who) + ": the point set is empty");
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (!points.col(i).allFinite()) {
      throw Error(std::string(who) + ": point " + std::to_string(i) +
                  " has a non-finite coordinate");
    }
    const double w = weights[static_cast<std::size_t>(i)];
    if (!std::isfinite(w) || !(w > 0.0)) {
      throw Error(std::string(who) + ": weight " + std::to_string(i) + " is " + std::to_string(w) +
                  "; weights must be finite and > 0");
    }
  }
}

WeightedSubset to_subset(const internal::Items& items) {
  std::vector<int> order(static_cast<std::size_t>(items.size()));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return items.ids[static_cast<std::size_t>(a)] < items.ids[static_cast<std::size_t>(b)];
  });
  WeightedSubset out;
  for (int k : order) {
    out.indices.push_back(items.ids[static_cast<std::size_t>(k)]);
    out.weights.push_back(items.weight[static_cast<std::size_t>(k)]);
  }
  return out;
}

}  // namespace

WeightedSubset caratheodory(const Eigen::MatrixXd& points, std::span<const double> weights,
                            int min_points) {
  validate(points, weights, "caratheodory");
  const Eigen::Index L = points.rows();
  const Eigen::Index n = points.cols();
  // Coordinate-major copy, as the elimination reads it.
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> by_coordinate =
      points;
  std::vector<double> w(weights.begin(), weights.end());
  const std::vector<char>& alive = internal::eliminate(
      by_coordinate.data(), L, n, internal::PointLayout{n}, w.data(), {}, min_points);
  WeightedSubset out;
  for (std::size_t i = 0; i < alive.size(); ++i) {
    if (!alive[i]) continue;
    out.indices.push_back(static_cast<int>(i));
    out.weights.push_back(w[i]);
  }
  return out;
}

WeightedSubset fast_caratheodory(const Eigen::MatrixXd& points, std::span<const double> weights,
                                 const CaratheodoryOptions& options) {
  validate(points, weights, "fast_caratheodory");
  const auto L = static_cast<int>(points.rows());
  if (options.clusters < L + 2) {
    throw Error("fast_caratheodory: " + std::to_string(options.clusters) +
                " clusters cannot make progress in dimension " + std::to_string(L) +
                "; use at least " + std::to_string(L + 2));
  }
  const auto n = static_cast<int>(points.cols());
  const std::vector<int> order = internal::seeded_permutation(n, options.seed);
  internal::Items items;
  items.reset(points.rows(), n);
  std::fill(items.counts.begin(), items.counts.end(), 1);
  items.ids = order;
  for (int k = 0; k < n; ++k) {
    for (Eigen::Index l = 0; l < points.rows(); ++l) {
      items.item(k)[l] = points(l, order[static_cast<std::size_t>(k)]);
    }
    items.weight[static_cast<std::size_t>(k)] =
        weights[static_cast<std::size_t>(order[static_cast<std::size_t>(k)])];
  }
  while (items.size() > options.clusters) {
    const int before = items.size();
    internal::reduce_level(items, options.clusters, options.min_points);
    if (items.size() == before) break;  // min_points reached
  }
  if (items.size() <= options.clusters) internal::reduce_final(items, options.min_points);
  return to_subset(items);
}

}  // namespace carat
