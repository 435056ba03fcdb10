#include "carat/registration/voxel_grid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

PointCloud voxel_downsample(const PointCloud& cloud, double voxel_size) {
  if (!(voxel_size > 0.0) || !std::isfinite(voxel_size)) {
    throw Error("voxel_downsample: voxel size must be finite and > 0, got " +
                std::to_string(voxel_size));
  }
  constexpr std::int64_t kOffset = std::int64_t{1} << 20;  // 21 bits per axis
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keys;
  keys.reserve(cloud.size());
  const double inv = 1.0 / voxel_size;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      const double cell = std::floor(static_cast<double>(cloud.points[i][a]) * inv);
      // Range-check in floating point first: casting a huge or non-finite value is undefined.
      if (!(cell >= -static_cast<double>(kOffset) && cell < static_cast<double>(kOffset))) {
        char limit[64];
        std::snprintf(limit, sizeof(limit), "%g m voxels (|coordinate| < %g m)", voxel_size,
                      static_cast<double>(kOffset) * voxel_size);
        throw Error("point " + std::to_string(i) + " is too far from the origin for " + limit);
      }
      key = (key << 21) | static_cast<std::uint64_t>(static_cast<std::int64_t>(cell) + kOffset);
    }
    keys.emplace_back(key, static_cast<std::uint32_t>(i));
  }
  std::sort(keys.begin(), keys.end());
  PointCloud out;
  for (std::size_t i = 0; i < keys.size();) {
    std::size_t j = i;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (; j < keys.size() && keys[j].first == keys[i].first; ++j)
      sum += cloud.point(keys[j].second);
    out.points.push_back((sum / static_cast<double>(j - i)).cast<float>());
    i = j;
  }
  return out;
}

}  // namespace carat
