#include "carat/registration/correspondences.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstdint>

namespace carat {

std::vector<GicpCorrespondence> find_correspondences(const PointCloud& target,
                                                     const KdTree& target_tree,
                                                     const PointCloud& source,
                                                     const Eigen::Isometry3d& T_target_source,
                                                     double max_distance) {
  const float max_sq = static_cast<float>(max_distance * max_distance);
  std::vector<std::int64_t> match(source.size(), -1);
  const Eigen::Isometry3f T = T_target_source.cast<float>();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, source.size(), 512), [&](const auto& range) {
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      std::uint32_t index = 0;
      float sq = 0.0f;
      if (target_tree.nearest_within(T * source.points[i], max_sq, &index, &sq)) match[i] = index;
    }
  });
  std::vector<GicpCorrespondence> out;
  out.reserve(source.size());
  for (std::size_t i = 0; i < source.size(); ++i) {
    if (match[i] < 0) continue;
    const auto t = static_cast<std::size_t>(match[i]);
    out.push_back({target.point(t), target.covariance(t), source.point(i), source.covariance(i)});
  }
  return out;
}

}  // namespace carat
