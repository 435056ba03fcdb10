#include "carat/sim/drift.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "carat/base/error.hpp"
#include "carat/solver/se3.hpp"
#include "random.hpp"

namespace carat {

std::vector<Eigen::Isometry3d> apply_drift(std::span<const Eigen::Isometry3d> T_world_frame,
                                           const DriftOptions& options) {
  if (!std::isfinite(options.translation_sigma) || options.translation_sigma < 0.0) {
    throw Error("DriftOptions.translation_sigma: must be finite and >= 0, got " +
                std::to_string(options.translation_sigma));
  }
  if (!std::isfinite(options.rotation_sigma_deg) || options.rotation_sigma_deg < 0.0) {
    throw Error("DriftOptions.rotation_sigma_deg: must be finite and >= 0, got " +
                std::to_string(options.rotation_sigma_deg));
  }
  if (!std::isfinite(options.heading_bias_deg)) {
    throw Error("DriftOptions.heading_bias_deg: must be finite, got " +
                std::to_string(options.heading_bias_deg));
  }
  std::vector<Eigen::Isometry3d> out(T_world_frame.begin(), T_world_frame.end());
  if (out.empty() || (options.translation_sigma == 0.0 && options.rotation_sigma_deg == 0.0 &&
                      options.heading_bias_deg == 0.0)) {
    return out;
  }
  sim_detail::Random rng(options.seed);
  const double rotation_sigma = options.rotation_sigma_deg * std::numbers::pi / 180.0;
  for (std::size_t k = 1; k < out.size(); ++k) {
    const Eigen::Isometry3d relative = T_world_frame[k - 1].inverse() * T_world_frame[k];
    const double distance = relative.translation().norm();
    se3::Vector6d xi;
    for (int i = 0; i < 3; ++i) xi[i] = rotation_sigma * distance * rng.normal();
    for (int i = 3; i < 6; ++i) xi[i] = options.translation_sigma * distance * rng.normal();
    xi[2] += options.heading_bias_deg * std::numbers::pi / 180.0 * distance;
    out[k] = out[k - 1] * relative * se3::exp(xi);
  }
  return out;
}

}  // namespace carat
