#include "carat/registration/voxel_grid.hpp"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"

namespace carat {

PointCloud voxel_downsample(const PointCloud& cloud, double voxel_size, int num_threads) {
  if (!(voxel_size > 0.0) || !std::isfinite(voxel_size)) {
    throw Error("voxel_downsample: voxel size must be finite and > 0, got " +
                std::to_string(voxel_size));
  }
  constexpr std::int64_t kOffset = std::int64_t{1} << 20;  // 21 bits per axis
  constexpr std::uint64_t kEmpty = ~std::uint64_t{0};      // no key has the top bit set
  const std::size_t n = cloud.size();
  const double inv = 1.0 / voxel_size;
  tbb::task_arena arena(std::clamp(num_threads, 1, tbb::info::default_concurrency()));
  // Voxel keys, in parallel; the first point off the grid is the error, whatever the scheduling.
  std::vector<std::uint64_t> keys(n);
  std::atomic<std::size_t> first_bad{n};
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& range) {
      for (std::size_t i = range.begin(); i != range.end(); ++i) {
        std::uint64_t key = 0;
        for (int a = 0; a < 3; ++a) {
          const double cell = std::floor(static_cast<double>(cloud.points[i][a]) * inv);
          // Range-check in floating point first: casting a huge or non-finite value is undefined.
          if (!(cell >= -static_cast<double>(kOffset) && cell < static_cast<double>(kOffset))) {
            std::size_t seen = first_bad.load(std::memory_order_relaxed);
            while (i < seen && !first_bad.compare_exchange_weak(seen, i)) {
            }
            return;
          }
          key = (key << 21) | static_cast<std::uint64_t>(static_cast<std::int64_t>(cell) + kOffset);
        }
        keys[i] = key;
      }
    });
  });
  if (first_bad.load() < n) {
    char limit[64];
    std::snprintf(limit, sizeof(limit), "%g m voxels (|coordinate| < %g m)", voxel_size,
                  static_cast<double>(kOffset) * voxel_size);
    throw Error("point " + std::to_string(first_bad.load()) + " is too far from the origin for " +
                limit);
  }
  // Each part owns the voxels whose key hashes to it and sums their points in input order (so a
  // centroid has the same bits whatever the number of parts), in an open-addressing table from
  // voxel key to voxel, at most half full.
  const auto hash = [](std::uint64_t key) { return key * 0x9E3779B97F4A7C15ull; };
  const int parts = n < 8192 ? 1 : std::clamp(num_threads, 1, 16);
  struct Voxel {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::uint32_t count = 0;
  };
  struct Part {
    std::vector<Voxel> voxels;
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keys;  // (key, voxel)
  };
  std::vector<Part> part(static_cast<std::size_t>(parts));
  const auto fill = [&](std::size_t index) {
    int bits = 4;
    // Room for as many voxels as half the points of a part (it grows if need be).
    while ((std::size_t{1} << bits) < n / static_cast<std::size_t>(parts) + 2) ++bits;
    struct Entry {
      std::uint64_t key = kEmpty;
      std::uint32_t voxel = 0;
    };
    std::vector<Entry> table(std::size_t{1} << bits);
    // The slot of `key`, or the empty slot where it goes.
    const auto find = [&](std::uint64_t key) {
      const std::size_t mask = table.size() - 1;
      auto slot = static_cast<std::size_t>(hash(key) >> (64 - bits));
      while (table[slot].key != key && table[slot].key != kEmpty) slot = (slot + 1) & mask;
      return slot;
    };
    Part& out = part[index];
    std::uint64_t last_key = kEmpty;
    std::uint32_t last_voxel = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint64_t key = keys[i];
      if (key != last_key) {  // consecutive points of a scan often share a voxel
        const std::uint64_t h = hash(key);
        if (parts > 1 && (((h & 0xffff) * static_cast<std::uint64_t>(parts)) >> 16) != index)
          continue;
        std::size_t slot = find(key);
        if (table[slot].key == kEmpty) {
          const auto voxel = static_cast<std::uint32_t>(out.voxels.size());
          out.keys.emplace_back(key, voxel);
          out.voxels.emplace_back();
          if (2 * out.keys.size() > table.size()) {  // keep it at most half full
            ++bits;
            table.assign(std::size_t{1} << bits, Entry{});
            for (const auto& [k, v] : out.keys) table[find(k)] = {k, v};
            slot = find(key);
          }
          table[slot] = {key, voxel};
        }
        last_key = key;
        last_voxel = table[slot].voxel;
      }
      Voxel& voxel = out.voxels[last_voxel];
      voxel.sum += cloud.point(i);
      ++voxel.count;
    }
  };
  if (parts == 1) {
    fill(0);
  } else {
    arena.execute([&] { tbb::parallel_for(std::size_t{0}, part.size(), fill); });
  }
  // The occupied voxels in key order.
  std::vector<std::pair<std::uint64_t, const Voxel*>> order;
  for (const Part& p : part)
    for (const auto& [key, v] : p.keys) order.emplace_back(key, &p.voxels[v]);
  std::sort(order.begin(), order.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  PointCloud out;
  out.points.reserve(order.size());
  for (const auto& [key, voxel] : order)
    out.points.push_back((voxel->sum / static_cast<double>(voxel->count)).cast<float>());
  return out;
}

}  // namespace carat
