#include "carat/registration/overlap.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "carat/base/error.hpp"

namespace carat {
namespace {

constexpr double kMaxCoordinate = 1 << 20;  // 21 bits per axis, offset to non-negative

/// Packs integer voxel coordinates into one key; false when outside the grid.
bool voxel_key(const Eigen::Vector3d& p, double inverse_size, std::uint64_t* key) {
  std::uint64_t out = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double c = std::floor(p[axis] * inverse_size);
    if (!(c >= -kMaxCoordinate && c < kMaxCoordinate)) return false;  // also rejects NaN
    out = (out << 21) | static_cast<std::uint64_t>(static_cast<std::int64_t>(c + kMaxCoordinate));
  }
  *key = out;
  return true;
}

}  // namespace

VoxelOccupancy::VoxelOccupancy(const PointCloud& cloud, double voxel_size)
    : voxel_size_(voxel_size) {
  if (!(std::isfinite(voxel_size) && voxel_size > 0.0))
    throw Error("VoxelOccupancy: voxel size must be finite and > 0, got " +
                std::to_string(voxel_size));
  const double inverse = 1.0 / voxel_size;
  keys_.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    std::uint64_t key = 0;
    if (!voxel_key(cloud.point(i), inverse, &key)) {
      throw Error("VoxelOccupancy: point " + std::to_string(i) +
                  " is not finite or too far from the origin for a " + std::to_string(voxel_size) +
                  " m grid");
    }
    keys_.push_back(key);
  }
  std::sort(keys_.begin(), keys_.end());
  keys_.erase(std::unique(keys_.begin(), keys_.end()), keys_.end());
}

bool VoxelOccupancy::occupied(const Eigen::Vector3d& p) const {
  std::uint64_t key = 0;
  if (!voxel_key(p, 1.0 / voxel_size_, &key)) return false;
  return std::binary_search(keys_.begin(), keys_.end(), key);
}

double overlap_fraction(const VoxelOccupancy& target, const PointCloud& source,
                        const Eigen::Isometry3d& T_target_source, int stride) {
  const std::size_t step = static_cast<std::size_t>(std::max(stride, 1));
  std::size_t inside = 0, total = 0;
  for (std::size_t i = 0; i < source.size(); i += step, ++total)
    inside += target.occupied(T_target_source * source.point(i)) ? 1 : 0;
  return total == 0 ? 0.0 : static_cast<double>(inside) / static_cast<double>(total);
}

}  // namespace carat
