#pragma once

// The solid primitives of the synthetic world and their ray intersections.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

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
inline double intersect(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                        double t_best) {
  constexpr double kEps = 1e-9;
  switch (p.shape) {
    case Shape::kBox: {
      const double px = o.x() - p.center.x(), py = o.y() - p.center.y();
      const double lo[3] = {p.cos_yaw * px + p.sin_yaw * py, -p.sin_yaw * px + p.cos_yaw * py,
                            o.z() - p.center.z()};
      const double ld[3] = {p.cos_yaw * d.x() + p.sin_yaw * d.y(),
                            -p.sin_yaw * d.x() + p.cos_yaw * d.y(), d.z()};
      double t_min = -std::numeric_limits<double>::infinity(),
             t_max = std::numeric_limits<double>::infinity();
      for (int a = 0; a < 3; ++a) {
        if (ld[a] == 0.0) {
          if (std::abs(lo[a]) > p.half[a]) return t_best;
          continue;
        }
        const double inv = 1.0 / ld[a];
        double t1 = (-p.half[a] - lo[a]) * inv, t2 = (p.half[a] - lo[a]) * inv;
        if (t1 > t2) std::swap(t1, t2);
        t_min = std::max(t_min, t1);
        t_max = std::min(t_max, t2);
        if (t_min > t_max) return t_best;
      }
      if (t_min > kEps && t_min < t_best) return t_min;
      return t_best;
    }
    case Shape::kCylinder: {
      double best = t_best;
      const double px = o.x() - p.center.x(), py = o.y() - p.center.y();
      const double a = d.x() * d.x() + d.y() * d.y();
      if (a > 0.0) {
        const double b = px * d.x() + py * d.y();
        const double c = px * px + py * py - p.radius * p.radius;
        const double disc = b * b - a * c;
        if (disc >= 0.0) {
          const double t = (-b - std::sqrt(disc)) / a;
          const double z = o.z() + t * d.z();
          if (t > kEps && t < best && z >= p.z0 && z <= p.z1) best = t;
        }
      }
      if (d.z() != 0.0) {
        for (const double zc : {p.z0, p.z1}) {
          const double t = (zc - o.z()) / d.z();
          if (t <= kEps || t >= best) continue;
          const double x = px + t * d.x(), y = py + t * d.y();
          if (x * x + y * y <= p.radius * p.radius) best = t;
        }
      }
      return best;
    }
    case Shape::kSphere: {
      const Eigen::Vector3d q = o - p.center;
      const double b = q.dot(d);
      const double c = q.squaredNorm() - p.radius * p.radius;
      const double disc = b * b - c;
      if (disc < 0.0) return t_best;
      const double t = -b - std::sqrt(disc);
      return t > kEps && t < t_best ? t : t_best;
    }
  }
  return t_best;
}

}  // namespace carat::sim_detail
