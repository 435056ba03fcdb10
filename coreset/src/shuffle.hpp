#pragma once

// Internal: a seeded permutation that is the same on every platform (Fisher-Yates on
// std::mt19937_64 with a division-free bounded draw).

#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

namespace carat::internal {

/// A permutation of 0..n-1 determined by `seed` alone.
inline std::vector<int> seeded_permutation(int n, std::uint64_t seed) {
  std::vector<int> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  std::mt19937_64 rng(seed);
  for (int i = n - 1; i > 0; --i) {
    const auto bound = static_cast<unsigned __int128>(static_cast<std::uint64_t>(i) + 1);
    const auto j = static_cast<int>((static_cast<unsigned __int128>(rng()) * bound) >> 64);
    std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
  }
  return order;
}

}  // namespace carat::internal
