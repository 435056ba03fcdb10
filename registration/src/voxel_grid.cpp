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
  constexpr std::uint64_t kEmpty = ~std::uint64_t{0};      // no key has the top bit set
  // Open addressing from voxel key to voxel, at most half full: each voxel sums its points in
  // input order, and only the occupied voxels are sorted (by key) for the output.
  int bits = 4;
  while ((std::size_t{1} << bits) < 2 * cloud.size()) ++bits;
  struct Entry {
    std::uint64_t key = kEmpty;
    std::uint32_t voxel = 0;
  };
  std::vector<Entry> table(std::size_t{1} << bits);
  const std::size_t mask = table.size() - 1;
  struct Voxel {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::uint32_t count = 0;
  };
  std::vector<Voxel> voxels;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keys;  // (key, voxel)
  std::uint64_t last_key = kEmpty;
  std::uint32_t last_voxel = 0;
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
    if (key != last_key) {  // consecutive points of a scan often share a voxel
      std::size_t slot = static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits));
      while (table[slot].key != key && table[slot].key != kEmpty) slot = (slot + 1) & mask;
      if (table[slot].key == kEmpty) {
        table[slot] = {key, static_cast<std::uint32_t>(voxels.size())};
        keys.emplace_back(key, static_cast<std::uint32_t>(voxels.size()));
        voxels.emplace_back();
      }
      last_key = key;
      last_voxel = table[slot].voxel;
    }
    Voxel& voxel = voxels[last_voxel];
    voxel.sum += cloud.point(i);
    ++voxel.count;
  }
  std::sort(keys.begin(), keys.end());
  PointCloud out;
  out.points.reserve(keys.size());
  for (const auto& [key, v] : keys)
    out.points.push_back((voxels[v].sum / static_cast<double>(voxels[v].count)).cast<float>());
  return out;
}

}  // namespace carat
