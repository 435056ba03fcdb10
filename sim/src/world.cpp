#include "carat/sim/world.hpp"

#include <cmath>

#include "carat/base/error.hpp"
#include "scene.hpp"

namespace carat {

namespace {

using sim_detail::Random;

}  // namespace

double SyntheticWorld::ground_height(double x, double y) const { return scene_->height(x, y); }

Eigen::Vector3d SyntheticWorld::ground_normal() const {
  return Eigen::Vector3d(-scene_->plane_gx, -scene_->plane_gy, 1.0).normalized();
}

double SyntheticWorld::cast_ray(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                double max_distance) const {
  const double t = scene_->cast(origin, direction.normalized(), max_distance);
  return std::isfinite(t) ? t : -1.0;
}

std::size_t SyntheticWorld::num_primitives() const { return scene_->primitives.size(); }

PointCloud SyntheticWorld::scan(const Eigen::Isometry3d& T_world_sensor,
                                std::uint64_t noise_seed) const {
  if (!T_world_sensor.matrix().allFinite()) throw Error("scan: T_world_sensor is not finite");
  const Scene& scene = *scene_;
  const SyntheticWorldOptions& o = options_;
  const Eigen::Vector3d origin = T_world_sensor.translation();
  const Eigen::Matrix3d R = T_world_sensor.linear();
  const double t_limit = o.max_range + 6.0 * o.range_noise;
  Random rng(noise_seed);
  PointCloud cloud;
  cloud.points.reserve(static_cast<std::size_t>(o.beams) * o.azimuth_steps / 2);
  for (int b = 0; b < o.beams; ++b) {
    for (int a = 0; a < o.azimuth_steps; ++a) {
      const Eigen::Vector3d d_sensor(scene.cos_el[b] * scene.cos_az[a],
                                     scene.cos_el[b] * scene.sin_az[a], scene.sin_el[b]);
      const double t = scene.cast(origin, R * d_sensor, t_limit);
      if (!std::isfinite(t)) continue;
      const double range = o.range_noise > 0.0 ? t + o.range_noise * rng.normal() : t;
      if (range < o.min_range || range > o.max_range) continue;
      cloud.points.push_back((range * d_sensor).cast<float>());
    }
  }
  return cloud;
}

}  // namespace carat
