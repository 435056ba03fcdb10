#include "carat/registration/overlap.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "carat/base/error.hpp"

namespace carat {
namespace {

constexpr double kMaxCoordinate = 1 << 20;  // 21 bits per axis, offset to non-negative
/// An empty slot of the table (no key has bit 63 set).
constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
/// Fibonacci hashing's multiplier, 2^64 / golden ratio: spreads a key's bits over the top ones.
constexpr std::uint64_t kMultiplier = 0x9E3779B97F4A7C15ull;

/// The integer voxel coordinates of p, offset to [0, 2^21); false when outside the grid.
[[gnu::always_inline]] inline bool voxel_coordinates(const Eigen::Vector3d& p, double inverse_size,
                                                     std::int64_t* c) {
  for (int axis = 0; axis < 3; ++axis) {
    // floor(x) is in [-2^20, 2^20) exactly when x is (the bounds are integers); NaN is not.
    const double x = p[axis] * inverse_size;
    if (!(x >= -kMaxCoordinate && x < kMaxCoordinate)) return false;
    // floor without a libm call: truncate, then step down below zero.
    auto v = static_cast<std::int64_t>(x);
    v -= static_cast<double>(v) > x ? 1 : 0;
    c[axis] = v + (std::int64_t{1} << 20);
  }
  return true;
}

/// One key of the three coordinates, 21 bits each.
[[gnu::always_inline]] inline std::uint64_t voxel_key(const std::int64_t* c) {
  return (static_cast<std::uint64_t>(c[0]) << 42) | (static_cast<std::uint64_t>(c[1]) << 21) |
         static_cast<std::uint64_t>(c[2]);
}

/// Coordinate `axis` (0, 1, 2) of a key.
[[gnu::always_inline]] inline std::int64_t key_coordinate(std::uint64_t key, std::size_t axis) {
  return static_cast<std::int64_t>((key >> (42 - 21 * axis)) & ((1u << 21) - 1));
}

/// Whether the voxel of grid coordinates c (offset as voxel_coordinates() gives them) is set in
/// the bitmap over the box [begin, begin + size) (false outside the box).
[[gnu::always_inline]] inline bool in_bitmap(const std::int64_t* c, const std::int64_t* begin,
                                             const std::int64_t* size, const std::uint64_t* bits) {
  std::int64_t at = 0;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    const std::int64_t offset = c[axis] - begin[axis];
    if (static_cast<std::uint64_t>(offset) >= static_cast<std::uint64_t>(size[axis])) return false;
    at = at * size[axis] + offset;
  }
  return (bits[static_cast<std::size_t>(at) / 64] >> (at % 64)) & 1u;
}

}  // namespace

VoxelOccupancy::VoxelOccupancy(const PointCloud& cloud, double voxel_size)
    : voxel_size_(voxel_size), inverse_size_(1.0 / voxel_size) {
  if (!(std::isfinite(voxel_size) && voxel_size > 0.0))
    throw Error("VoxelOccupancy: voxel size must be finite and > 0, got " +
                std::to_string(voxel_size));
  keys_.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    std::int64_t c[3];
    if (!voxel_coordinates(cloud.point(i), inverse_size_, c)) {
      throw Error("VoxelOccupancy: point " + std::to_string(i) +
                  " is not finite or too far from the origin for a " + std::to_string(voxel_size) +
                  " m grid");
    }
    keys_.push_back(voxel_key(c));
  }
  std::sort(keys_.begin(), keys_.end());
  keys_.erase(std::unique(keys_.begin(), keys_.end()), keys_.end());
  if (keys_.empty()) return;
  // A bitmap over the occupied voxels' box when it is small: one load a lookup.
  std::array<std::int64_t, 3> lo{}, hi{};
  lo.fill(std::numeric_limits<std::int64_t>::max());
  hi.fill(std::numeric_limits<std::int64_t>::min());
  for (const std::uint64_t key : keys_) {
    for (std::size_t axis = 0; axis < 3; ++axis) {
      const auto c = key_coordinate(key, axis);
      lo[axis] = std::min(lo[axis], c);
      hi[axis] = std::max(hi[axis], c);
    }
  }
  double volume = 1.0;
  for (std::size_t axis = 0; axis < 3; ++axis)
    volume *= static_cast<double>(hi[axis] - lo[axis] + 1);
  if (volume <= 256.0 * static_cast<double>(keys_.size())) {
    box_begin_ = lo;
    for (std::size_t axis = 0; axis < 3; ++axis) box_size_[axis] = hi[axis] - lo[axis] + 1;
    bits_.assign((static_cast<std::size_t>(volume) + 63) / 64, 0);
    for (const std::uint64_t key : keys_) {
      std::int64_t at = 0;
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const auto c = key_coordinate(key, axis);
        at = at * box_size_[axis] + (c - box_begin_[axis]);
      }
      bits_[static_cast<std::size_t>(at) / 64] |= std::uint64_t{1} << (at % 64);
    }
    return;
  }
  // Else a table at most half full: a lookup probes about 1.5 slots, where a binary search over
  // the sorted keys would make a dozen dependent loads.
  int bits = 1;
  while ((std::size_t{1} << bits) < 2 * keys_.size()) ++bits;
  shift_ = 64 - bits;
  table_.assign(std::size_t{1} << bits, kEmpty);
  const std::size_t mask = table_.size() - 1;
  for (const std::uint64_t key : keys_) {
    std::size_t slot = static_cast<std::size_t>((key * kMultiplier) >> shift_);
    while (table_[slot] != kEmpty) slot = (slot + 1) & mask;
    table_[slot] = key;
  }
}

bool VoxelOccupancy::occupied(const Eigen::Vector3d& p) const {
  std::int64_t c[3];
  if (keys_.empty() || !voxel_coordinates(p, inverse_size_, c)) return false;
  if (box_size_[0] > 0) return in_bitmap(c, box_begin_.data(), box_size_.data(), bits_.data());
  const std::uint64_t key = voxel_key(c);
  const std::size_t mask = table_.size() - 1;
  for (std::size_t slot = static_cast<std::size_t>((key * kMultiplier) >> shift_);;
       slot = (slot + 1) & mask) {
    if (table_[slot] == key) return true;
    if (table_[slot] == kEmpty) return false;
  }
}

std::size_t VoxelOccupancy::count_occupied(const PointCloud& source,
                                           const Eigen::Isometry3d& T_target_source,
                                           std::size_t stride) const {
  const std::size_t step = std::max<std::size_t>(stride, 1);
  const std::size_t count = (source.size() + step - 1) / step;  // points visited
  std::size_t inside = 0, k = 0;
  if (box_size_[0] > 0) {
    // occupied()'s bitmap path, inlined into the loop.
    for (; k < count; ++k) {
      std::int64_t c[3];
      if (voxel_coordinates(T_target_source * source.point(k * step), inverse_size_, c))
        inside += in_bitmap(c, box_begin_.data(), box_size_.data(), bits_.data()) ? 1 : 0;
    }
  }
  for (; k < count; ++k) inside += occupied(T_target_source * source.point(k * step)) ? 1 : 0;
  return inside;
}

double overlap_fraction(const VoxelOccupancy& target, const PointCloud& source,
                        const Eigen::Isometry3d& T_target_source, int stride) {
  const auto step = static_cast<std::size_t>(std::max(stride, 1));
  const std::size_t total = (source.size() + step - 1) / step;
  const std::size_t inside = target.count_occupied(source, T_target_source, step);
  return total == 0 ? 0.0 : static_cast<double>(inside) / static_cast<double>(total);
}

}  // namespace carat
