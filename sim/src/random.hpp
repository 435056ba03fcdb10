#pragma once

// Portable seeded random numbers for the synthetic world, the drift model and the frame noise:
// std::mt19937_64 bits (fixed by the C++ standard) seeded through splitmix64 and turned into
// uniforms and Gaussians here, so results do not depend on the standard library's distributions.

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace carat::sim_detail {

inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Portable random numbers: std::mt19937_64 bits turned into uniforms and Gaussians here.
class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(splitmix64(seed)) {}
  /// Uniform in [0, 1).
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  /// Uniform in [a, b).
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  /// True with probability p.
  bool chance(double p) { return uniform() < p; }
  /// Standard normal (Box-Muller, cosine branch).
  double normal() {
    const double u1 = 1.0 - uniform();  // (0, 1]
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  std::mt19937_64 engine_;
};

}  // namespace carat::sim_detail
