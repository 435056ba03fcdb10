#include "carat/registration/pose_perturbation.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <string>

#include "carat/base/error.hpp"

namespace carat {

std::vector<Eigen::Isometry3d> perturb_poses(std::span<const Eigen::Isometry3d> poses,
                                             double metres, double degrees, std::uint64_t seed,
                                             std::size_t first) {
  if (!(std::isfinite(metres) && metres >= 0.0))
    throw Error("perturb_poses: the translation must be finite and >= 0, got " +
                std::to_string(metres));
  if (!(std::isfinite(degrees) && degrees >= 0.0))
    throw Error("perturb_poses: the rotation must be finite and >= 0, got " +
                std::to_string(degrees));
  std::mt19937_64 rng(seed);
  // A uniform direction: rejection sampling in the unit ball, from 53-bit uniforms.
  const auto direction = [&] {
    while (true) {
      Eigen::Vector3d v;
      for (int k = 0; k < 3; ++k) v[k] = std::ldexp(static_cast<double>(rng() >> 11), -52) - 1.0;
      const double norm = v.norm();
      if (norm > 1e-3 && norm <= 1.0) return Eigen::Vector3d(v / norm);
    }
  };
  std::vector<Eigen::Isometry3d> out(poses.begin(), poses.end());
  for (std::size_t i = first; i < out.size(); ++i) {
    const Eigen::Vector3d axis = direction();
    const Eigen::Vector3d shift = direction() * metres;
    Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
    delta.linear() = Eigen::AngleAxisd(degrees * std::numbers::pi / 180.0, axis).matrix();
    delta.translation() = shift;
    out[i] = out[i] * delta;
  }
  return out;
}

}  // namespace carat
