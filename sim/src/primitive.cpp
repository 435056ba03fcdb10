#include "primitive.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace carat::sim_detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

double intersect(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                 double t_best) {
  constexpr double kEps = 1e-9;
  switch (p.shape) {
    case Shape::kBox: {
      const double px = o.x() - p.center.x(), py = o.y() - p.center.y();
      const double lo[3] = {p.cos_yaw * px + p.sin_yaw * py, -p.sin_yaw * px + p.cos_yaw * py,
                            o.z() - p.center.z()};
      const double ld[3] = {p.cos_yaw * d.x() + p.sin_yaw * d.y(),
                            -p.sin_yaw * d.x() + p.cos_yaw * d.y(), d.z()};
      double t_min = -kInf, t_max = kInf;
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
