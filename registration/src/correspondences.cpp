#include "carat/registration/correspondences.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>

namespace carat {

std::vector<std::array<std::uint32_t, 2>> find_nearest_pairs(
    const PointCloud& target, const KdTree& target_tree, const PointCloud& source,
    const Eigen::Isometry3d& T_target_source, double max_distance,
    std::span<const std::array<std::uint32_t, 2>> previous) {
  constexpr std::uint32_t kNone = ~std::uint32_t{0};
  const float max_sq = static_cast<float>(max_distance * max_distance);
  std::vector<std::uint32_t> match(source.size(), kNone);
  for (const auto& [t, s] : previous)
    if (s < source.size() && t < target.size()) match[s] = t;
  const Eigen::Isometry3f T = T_target_source.cast<float>();
  if (previous.empty()) {
    // Runs of consecutive source points (neighbours in a voxel-ordered scan), each searched
    // from where the one before ended; fixed runs, so the answers do not depend on scheduling.
    constexpr std::size_t kRun = 512;
    const std::size_t runs = (source.size() + kRun - 1) / kRun;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, runs), [&](const auto& range) {
      std::array<Eigen::Vector3f, kRun> queries;
      std::array<float, kRun> distances;
      for (std::size_t run = range.begin(); run != range.end(); ++run) {
        const std::size_t begin = run * kRun, n = std::min(kRun, source.size() - begin);
        for (std::size_t i = 0; i < n; ++i) queries[i] = T * source.points[begin + i];
        target_tree.nearest_within(std::span(queries.data(), n), max_sq, match.data() + begin,
                                   distances.data());
      }
    });
  } else {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, source.size(), 512), [&](const auto& range) {
          for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Eigen::Vector3f q = T * source.points[i];
            float bound = max_sq;
            if (match[i] != kNone) {
              // The earlier partner's distance, summed as the tree sums it: the nearest point is no
              // farther.
              const Eigen::Vector3f d = target.points[match[i]] - q;
              bound = std::min(bound, d.x() * d.x() + d.y() * d.y() + d.z() * d.z());
            }
            std::uint32_t index = 0;
            float sq = 0.0f;
            if (target_tree.nearest_within(q, bound, &index, &sq) ||
                (bound < max_sq && target_tree.nearest_within(q, max_sq, &index, &sq))) {
              match[i] = index;
            } else {
              match[i] = kNone;
            }
          }
        });
  }
  std::vector<std::array<std::uint32_t, 2>> pairs;
  pairs.reserve(source.size());
  for (std::size_t i = 0; i < source.size(); ++i)
    if (match[i] != kNone) pairs.push_back({match[i], static_cast<std::uint32_t>(i)});
  return pairs;
}

std::vector<GicpCorrespondence> find_correspondences(const PointCloud& target,
                                                     const KdTree& target_tree,
                                                     const PointCloud& source,
                                                     const Eigen::Isometry3d& T_target_source,
                                                     double max_distance) {
  const auto pairs = find_nearest_pairs(target, target_tree, source, T_target_source, max_distance);
  std::vector<GicpCorrespondence> out;
  out.reserve(pairs.size());
  for (const auto& [t, s] : pairs)
    out.push_back({target.point(t), target.covariance(t), source.point(s), source.covariance(s)});
  return out;
}

}  // namespace carat
