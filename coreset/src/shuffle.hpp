#pragma once

// Internal: a seeded permutation that is the same on every platform: Fisher-Yates driven by
// xoshiro256** (state seeded through splitmix64) with a division-free bounded draw. A generator
// with a 32-byte state: std::mt19937_64's 2.5 KB state took longer to seed than the shuffle of
// a thousand items, and every compression seeds two.

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <unordered_set>
#include <vector>

namespace carat::internal {

/// xoshiro256** (Blackman and Vigna), its four words of state filled by splitmix64 from the seed.
class SmallRng {
 public:
  /// A generator determined by `seed` alone.
  explicit SmallRng(std::uint64_t seed) {
    for (auto& word : state_) {
      seed += 0x9e3779b97f4a7c15ULL;
      std::uint64_t z = seed;
      z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
      z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
      word = z ^ (z >> 31);
    }
  }
  /// A draw in [0, bound) (bound >= 1): the next 64 bits scaled, without a division.
  std::uint64_t below(std::uint64_t bound) {
    __extension__ typedef unsigned __int128 Wide;  // GCC and Clang's 128-bit integer
    return static_cast<std::uint64_t>((static_cast<Wide>(next()) * bound) >> 64);
  }
  /// The next 64 random bits.
  std::uint64_t next() {
    const std::uint64_t result = rotl(state_[1] * 5, 7) * 9;
    const std::uint64_t t = state_[1] << 17;
    state_[2] ^= state_[0];
    state_[3] ^= state_[1];
    state_[1] ^= state_[2];
    state_[0] ^= state_[3];
    state_[2] ^= t;
    state_[3] = rotl(state_[3], 45);
    return result;
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::uint64_t state_[4];
};

/// Fills `order` with a permutation of 0..n-1 determined by `seed` alone.
inline void seeded_permutation(int n, std::uint64_t seed, std::vector<int>& order) {
  order.resize(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), 0);
  SmallRng rng(seed);
  for (int i = n - 1; i > 0; --i) {
    const auto j = static_cast<int>(rng.below(static_cast<std::uint64_t>(i) + 1));
    std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
  }
}

/// k distinct indices of 0..n-1 (0 <= k <= n), ascending, drawn uniformly by Floyd's algorithm
/// (k draws, no permutation of all n) and determined by `seed` alone.
inline std::vector<int> seeded_sample(int n, int k, std::uint64_t seed) {
  std::vector<int> out;
  out.reserve(static_cast<std::size_t>(k));
  // Which indices are taken: a bitmap (n bits) unless n is large and k only a few of them.
  const bool dense = n <= (1 << 23) || static_cast<long>(k) * 64 > static_cast<long>(n);
  std::unordered_set<int> chosen;
  std::vector<bool> taken(dense ? static_cast<std::size_t>(n) : 0);
  if (!dense) chosen.reserve(static_cast<std::size_t>(2 * k));
  const auto take = [&](int i) {  // true if i was free
    if (!dense) return chosen.insert(i).second;
    if (taken[static_cast<std::size_t>(i)]) return false;
    taken[static_cast<std::size_t>(i)] = true;
    return true;
  };
  SmallRng rng(seed);
  for (int j = n - k; j < n; ++j) {
    const auto t = static_cast<int>(rng.below(static_cast<std::uint64_t>(j) + 1));
    if (take(t)) {
      out.push_back(t);
    } else {  // t taken already: j is new for sure (every earlier pick is below j)
      take(j);
      out.push_back(j);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// A permutation of 0..n-1 determined by `seed` alone.
inline std::vector<int> seeded_permutation(int n, std::uint64_t seed) {
  std::vector<int> order;
  seeded_permutation(n, seed, order);
  return order;
}

}  // namespace carat::internal
