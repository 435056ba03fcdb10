#pragma once

// The solid primitives of the synthetic world and their ray intersections.

#include <Eigen/Core>
#include <cstdint>

namespace carat::sim_detail {

enum class Shape : std::uint8_t { kBox, kCylinder, kSphere };

/// One primitive. Box: centre, half extents, yaw about z. Cylinder: vertical, centre (x, y),
/// radius, z range. Sphere: centre, radius.
struct Primitive {
  Shape shape = Shape::kBox;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d half = Eigen::Vector3d::Zero();                // box half extents
  double cos_yaw = 1.0, sin_yaw = 0.0;                           // box orientation
  double radius = 0.0;                                           // cylinder, sphere
  double z0 = 0.0, z1 = 0.0;                                     // cylinder
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0, max_z = 0;  // bounds
};

/// Nearest hit of the ray o + t d (world frame, d a unit vector, t in metres) with t in
/// (0, t_best) on a primitive, or t_best.
double intersect(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                 double t_best);

}  // namespace carat::sim_detail
