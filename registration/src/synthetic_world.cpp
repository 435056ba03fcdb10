#include "carat/registration/synthetic_world.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <string>

#include "carat/registration/io/kitti_io.hpp"
#include "carat/solver/atomic_file.hpp"
#include "carat/solver/error.hpp"
#include "carat/solver/se3.hpp"

namespace carat {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kLaneClearance = 3.0;  // metres either side of a street centre line kept empty
constexpr double kCellSize = 4.0;       // metres, edge of a cell of the 2-D acceleration grid

std::uint64_t splitmix64(std::uint64_t x) {
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
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
  }

 private:
  std::mt19937_64 engine_;
};

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

/// Nearest hit of the ray o + t d with t in (0, t_best) on a primitive, or t_best.
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

void require(bool ok, const std::string& field, const std::string& problem) {
  if (!ok) throw Error("SyntheticWorldOptions." + field + ": " + problem);
}

void validate(const SyntheticWorldOptions& o) {
  auto finite = [](double v) { return std::isfinite(v); };
  require(finite(o.block_size) && o.block_size >= 10.0, "block_size",
          "must be finite and >= 10 m, got " + std::to_string(o.block_size));
  require(finite(o.street_width) && o.street_width >= 8.0, "street_width",
          "must be finite and >= 8 m, got " + std::to_string(o.street_width));
  require(o.blocks_x >= 1 && o.blocks_x <= 64, "blocks_x",
          "must be in [1, 64], got " + std::to_string(o.blocks_x));
  require(o.blocks_y >= 1 && o.blocks_y <= 64, "blocks_y",
          "must be in [1, 64], got " + std::to_string(o.blocks_y));
  require(finite(o.ground_slope) && std::abs(o.ground_slope) <= 0.2, "ground_slope",
          "must be finite with |slope| <= 0.2 rad, got " + std::to_string(o.ground_slope));
  require(finite(o.ground_roughness) && o.ground_roughness >= 0.0 && o.ground_roughness <= 0.5,
          "ground_roughness",
          "must be finite and in [0, 0.5] m, got " + std::to_string(o.ground_roughness));
  require(o.beams >= 1 && o.beams <= 4096, "beams",
          "must be in [1, 4096], got " + std::to_string(o.beams));
  require(finite(o.min_elevation_deg) && o.min_elevation_deg > -90.0, "min_elevation_deg",
          "must be finite and > -90, got " + std::to_string(o.min_elevation_deg));
  require(
      finite(o.max_elevation_deg) && o.max_elevation_deg < 90.0 &&
          o.max_elevation_deg >= o.min_elevation_deg,
      "max_elevation_deg",
      "must be finite, < 90 and >= min_elevation_deg, got " + std::to_string(o.max_elevation_deg));
  require(o.azimuth_steps >= 8 && o.azimuth_steps <= (1 << 20), "azimuth_steps",
          "must be in [8, 1048576], got " + std::to_string(o.azimuth_steps));
  require(finite(o.min_range) && o.min_range > 0.0, "min_range",
          "must be finite and > 0, got " + std::to_string(o.min_range));
  require(finite(o.max_range) && o.max_range > o.min_range, "max_range",
          "must be finite and > min_range, got " + std::to_string(o.max_range));
  require(finite(o.range_noise) && o.range_noise >= 0.0, "range_noise",
          "must be finite and >= 0, got " + std::to_string(o.range_noise));
  require(finite(o.sensor_height) && o.sensor_height > 0.0 && o.sensor_height <= 2.5,
          "sensor_height",
          "must be finite and in (0, 2.5] m, got " + std::to_string(o.sensor_height));
}

}  // namespace

/// The scene: ground parameters, primitives and a 2-D uniform grid over them.
struct SyntheticWorld::Scene {
  // Ground: z = plane_gx * x + plane_gy * y + sum_k amp_k sin(kx_k x + ky_k y + phase_k).
  double plane_gx = 0.0, plane_gy = 0.0;
  std::array<double, 3> amp{}, kx{}, ky{}, phase{};
  double relief = 0.0;  // bound of |relief|, sum of |amp_k|

  std::vector<Primitive> primitives;
  double top_z = -kInf;  // highest point of any primitive

  // Grid: cells of kCellSize, cell (i, j) covers [x0 + i s, x0 + (i + 1) s) x [...]; the
  // primitives overlapping cell c are cell_items[cell_start[c] .. cell_start[c + 1]).
  double x0 = 0.0, y0 = 0.0;
  int nx = 0, ny = 0;
  std::vector<std::uint32_t> cell_start, cell_items;

  // Ray directions of the sensor.
  std::vector<double> cos_el, sin_el, cos_az, sin_az;

  double height(double x, double y) const {
    double z = plane_gx * x + plane_gy * y;
    for (int k = 0; k < 3; ++k) z += amp[k] * std::sin(kx[k] * x + ky[k] * y + phase[k]);
    return z;
  }
  double plane(double x, double y) const { return plane_gx * x + plane_gy * y; }

  /// Signed height of o + t d above the ground and its derivative in t.
  double above(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t,
               double* derivative) const {
    const double x = o.x() + t * d.x(), y = o.y() + t * d.y();
    double f = o.z() + t * d.z() - plane_gx * x - plane_gy * y;
    double df = d.z() - plane_gx * d.x() - plane_gy * d.y();
    for (int k = 0; k < 3; ++k) {
      const double arg = kx[k] * x + ky[k] * y + phase[k];
      f -= amp[k] * std::sin(arg);
      df -= amp[k] * std::cos(arg) * (kx[k] * d.x() + ky[k] * d.y());
    }
    if (derivative != nullptr) *derivative = df;
    return f;
  }

  /// First ground hit in (0, t_limit), or kInf. The relief lies within +-relief of the plane,
  /// so the crossing lies between the plane's shifted copies; that bracket is scanned in
  /// 0.25 m steps for the first sign change, which Newton steps (safeguarded by bisection)
  /// refine to |height| < 1e-10 m.
  double ground_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_limit) const {
    const double c0 = o.z() - plane(o.x(), o.y());
    const double c1 = d.z() - plane_gx * d.x() - plane_gy * d.y();
    if (c1 >= 0.0 || c0 <= relief) return kInf;  // going up (w.r.t. the plane), or underground
    const double t_lo = (c0 - relief) / -c1, t_hi = std::min((c0 + relief) / -c1, t_limit);
    if (t_lo >= t_limit) return kInf;
    const int steps = std::clamp(static_cast<int>(std::ceil((t_hi - t_lo) / 0.25)), 1, 256);
    double a = t_lo, fa = above(o, d, a, nullptr);
    for (int s = 1; s <= steps; ++s) {
      const double b = s == steps ? t_hi : t_lo + (t_hi - t_lo) * s / steps;
      const double fb = above(o, d, b, nullptr);
      if (fa > 0.0 && fb <= 0.0) {  // bracketed: refine
        double lo = a, hi = b;
        double t = lo - fa * (hi - lo) / (fb - fa);
        for (int it = 0; it < 50; ++it) {
          double df = 0.0;
          const double f = above(o, d, t, &df);
          if (std::abs(f) < 1e-10 || hi - lo < 1e-12) break;
          if (f > 0.0) {
            lo = t;
          } else {
            hi = t;
          }
          double next = df != 0.0 ? t - f / df : 0.5 * (lo + hi);
          if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
          t = next;
        }
        return t < t_limit ? t : kInf;
      }
      a = b;
      fa = fb;
    }
    return kInf;
  }

  /// Nearest hit of the unit ray o + t d in (0, t_limit), or kInf.
  double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_limit) const {
    double best = std::min(t_limit, ground_hit(o, d, t_limit));
    // Walk the 2-D grid cells the ray's footprint crosses (Amanatides-Woo), starting where the
    // ray enters the grid.
    const double gx1 = x0 + nx * kCellSize, gy1 = y0 + ny * kCellSize;
    double t_in = 0.0, t_out = best;
    const double lo[2] = {x0, y0}, hi[2] = {gx1, gy1};
    for (int a = 0; a < 2; ++a) {
      if (d[a] == 0.0) {
        if (o[a] < lo[a] || o[a] >= hi[a]) return best < t_limit ? best : kInf;
        continue;
      }
      double t1 = (lo[a] - o[a]) / d[a], t2 = (hi[a] - o[a]) / d[a];
      if (t1 > t2) std::swap(t1, t2);
      t_in = std::max(t_in, t1);
      t_out = std::min(t_out, t2);
    }
    if (t_in < t_out) {
      const double sx = o.x() + t_in * d.x(), sy = o.y() + t_in * d.y();
      int ix = std::clamp(static_cast<int>(std::floor((sx - x0) / kCellSize)), 0, nx - 1);
      int iy = std::clamp(static_cast<int>(std::floor((sy - y0) / kCellSize)), 0, ny - 1);
      const int step_x = d.x() > 0.0 ? 1 : -1, step_y = d.y() > 0.0 ? 1 : -1;
      const double delta_x = d.x() != 0.0 ? kCellSize / std::abs(d.x()) : kInf;
      const double delta_y = d.y() != 0.0 ? kCellSize / std::abs(d.y()) : kInf;
      double next_x = d.x() != 0.0 ? (x0 + (ix + (d.x() > 0.0)) * kCellSize - o.x()) / d.x() : kInf;
      double next_y = d.y() != 0.0 ? (y0 + (iy + (d.y() > 0.0)) * kCellSize - o.y()) / d.y() : kInf;
      while (true) {
        const std::size_t cell = static_cast<std::size_t>(iy) * nx + ix;
        for (std::uint32_t k = cell_start[cell]; k < cell_start[cell + 1]; ++k) {
          best = intersect(primitives[cell_items[k]], o, d, best);
        }
        const double t_exit = std::min(next_x, next_y);
        if (best <= t_exit || t_exit >= t_out) break;
        if (d.z() > 0.0 && o.z() + t_exit * d.z() > top_z) break;  // above everything
        if (next_x < next_y) {
          ix += step_x;
          next_x += delta_x;
        } else {
          iy += step_y;
          next_y += delta_y;
        }
        if (ix < 0 || ix >= nx || iy < 0 || iy >= ny) break;
      }
    }
    return best < t_limit ? best : kInf;
  }

  // ---- Construction -------------------------------------------------------------------------

  /// Lowest ground height under the axis-aligned footprint (plane corners minus the relief).
  double base_z(double min_x, double min_y, double max_x, double max_y) const {
    return std::min({plane(min_x, min_y), plane(min_x, max_y), plane(max_x, min_y),
                     plane(max_x, max_y)}) -
           relief - 0.5;
  }

  void add(Primitive p) {
    switch (p.shape) {
      case Shape::kBox: {
        const double ex = std::abs(p.cos_yaw) * p.half.x() + std::abs(p.sin_yaw) * p.half.y();
        const double ey = std::abs(p.sin_yaw) * p.half.x() + std::abs(p.cos_yaw) * p.half.y();
        p.min_x = p.center.x() - ex;
        p.max_x = p.center.x() + ex;
        p.min_y = p.center.y() - ey;
        p.max_y = p.center.y() + ey;
        p.max_z = p.center.z() + p.half.z();
        break;
      }
      case Shape::kCylinder:
        p.min_x = p.center.x() - p.radius;
        p.max_x = p.center.x() + p.radius;
        p.min_y = p.center.y() - p.radius;
        p.max_y = p.center.y() + p.radius;
        p.max_z = p.z1;
        break;
      case Shape::kSphere:
        p.min_x = p.center.x() - p.radius;
        p.max_x = p.center.x() + p.radius;
        p.min_y = p.center.y() - p.radius;
        p.max_y = p.center.y() + p.radius;
        p.max_z = p.center.z() + p.radius;
        break;
    }
    top_z = std::max(top_z, p.max_z);
    primitives.push_back(p);
  }

  /// An axis-aligned box from its corner ranges (x, y) and z range.
  void add_box(double xa, double xb, double ya, double yb, double za, double zb) {
    Primitive p;
    p.shape = Shape::kBox;
    p.center = {0.5 * (xa + xb), 0.5 * (ya + yb), 0.5 * (za + zb)};
    p.half = {0.5 * std::abs(xb - xa), 0.5 * std::abs(yb - ya), 0.5 * std::abs(zb - za)};
    add(p);
  }

  /// A box standing on the ground: centre (x, y), size, yaw, bottom `lift` above the ground.
  void add_yawed_box(double x, double y, double length, double width, double height, double yaw,
                     double lift) {
    Primitive p;
    p.shape = Shape::kBox;
    const double r = 0.5 * std::hypot(length, width);
    const double z0 = lift > 0.0 ? this->height(x, y) + lift : base_z(x - r, y - r, x + r, y + r);
    const double z1 = this->height(x, y) + lift + height;
    p.center = {x, y, 0.5 * (z0 + z1)};
    p.half = {0.5 * length, 0.5 * width, 0.5 * (z1 - z0)};
    p.cos_yaw = std::cos(yaw);
    p.sin_yaw = std::sin(yaw);
    add(p);
  }

  void add_cylinder(double x, double y, double radius, double height) {
    Primitive p;
    p.shape = Shape::kCylinder;
    p.center = {x, y, 0.0};
    p.radius = radius;
    p.z0 = base_z(x - radius, y - radius, x + radius, y + radius);
    p.z1 = this->height(x, y) + height;
    add(p);
  }

  void add_sphere(double x, double y, double z, double radius) {
    Primitive p;
    p.shape = Shape::kSphere;
    p.center = {x, y, z};
    p.radius = radius;
    add(p);
  }

  /// A row of buildings along the line p0 + s u, s in [0, length], standing behind it (on the
  /// side opposite n = (u.y, -u.x), which points into the street), with sidewalk objects in
  /// front of it within `band` metres (the street side beyond `band` stays empty).
  /// `clutter_margin` keeps sidewalk objects away from the row's ends (street crossings).
  void add_row(Random& rng, const Eigen::Vector2d& p0, const Eigen::Vector2d& u, double length,
               double max_depth, double band, double clutter_margin) {
    const Eigen::Vector2d n(u.y(), -u.x());
    auto at = [&](double s, double off) -> Eigen::Vector2d { return p0 + s * u + off * n; };
    auto box = [&](double s0, double s1, double off0, double off1, double za, double zb_rel,
                   bool on_ground) {
      const Eigen::Vector2d a = at(s0, off0), b = at(s1, off1);
      const double xa = std::min(a.x(), b.x()), xb = std::max(a.x(), b.x());
      const double ya = std::min(a.y(), b.y()), yb = std::max(a.y(), b.y());
      const double g = this->height(0.5 * (xa + xb), 0.5 * (ya + yb));
      const double z0 = on_ground ? base_z(xa, ya, xb, yb) : g + za;
      add_box(xa, xb, ya, yb, z0, g + zb_rel);
    };
    // Buildings: lots of random width with varied setback, depth and height, sometimes an
    // alley between them, and facade detail (bays, balconies, porches, pillars).
    double s = 0.0;
    while (s < length - 2.0) {
      const double width = std::min(rng.uniform(7.0, 20.0), length - s);
      const double setback = rng.chance(0.4) ? 0.0 : rng.uniform(0.3, 2.0);
      const double depth = rng.uniform(std::min(6.0, max_depth), max_depth);
      const double height =
          rng.uniform(0.0, 1.0) < 0.3 ? rng.uniform(4.0, 8.0) : rng.uniform(8.0, 26.0);
      box(s, s + width, -setback - depth, -setback, 0.0, height, true);
      const int details = static_cast<int>(rng.uniform(0.0, 4.0));
      for (int k = 0; k < details; ++k) {
        const double w = rng.uniform(1.0, std::min(4.0, width * 0.5));
        const double s0 = s + rng.uniform(0.0, width - w);
        const double out = rng.uniform(0.3, 1.2);
        if (rng.chance(0.5)) {  // porch / pillar / bay from the ground
          const double h = rng.uniform(2.5, std::min(6.0, height));
          box(s0, s0 + w, -setback - 0.5, -setback + out, 0.0, h, true);
        } else {  // balcony
          const double z = rng.uniform(3.0, std::max(3.5, height - 2.0));
          box(s0, s0 + w, -setback - 0.5, -setback + out, z, z + rng.uniform(0.8, 2.5), false);
        }
      }
      s += width;
      if (rng.chance(0.2)) s += rng.uniform(2.0, 5.0);
    }
    // Curb-side objects, walked along the row so they do not overlap: poles, street lights,
    // trees, parked cars.
    const double curb = band - 0.2;
    s = clutter_margin + rng.uniform(0.0, 4.0);
    while (s < length - clutter_margin) {
      const double pick = rng.uniform();
      if (pick < 0.3) {  // pole, sometimes a street light with an arm over the street
        const double r = rng.uniform(0.08, 0.2), h = rng.uniform(3.5, 9.0);
        const Eigen::Vector2d c = at(s, curb - r);
        add_cylinder(c.x(), c.y(), r, h);
        if (h > 6.0 && rng.chance(0.6)) {
          const double arm = rng.uniform(1.0, 2.5);
          box(s - 0.08, s + 0.08, curb - r, curb - r + arm, h - 0.3, h - 0.1, false);
        }
        s += rng.uniform(5.0, 12.0);
      } else if (pick < 0.55) {  // tree: trunk and a canopy of a few spheres
        const double r = rng.uniform(0.12, 0.3), h = rng.uniform(2.6, 4.0);
        const Eigen::Vector2d c = at(s, curb - r - 0.3);
        add_cylinder(c.x(), c.y(), r, h);
        const int blobs = 1 + static_cast<int>(rng.uniform(0.0, 3.0));
        const double g = this->height(c.x(), c.y());
        for (int k = 0; k < blobs; ++k) {
          const double cr = rng.uniform(1.0, 2.0);
          const Eigen::Vector2d q = c + rng.uniform(-0.8, 0.8) * u + rng.uniform(-0.8, 0.0) * n;
          add_sphere(q.x(), q.y(), g + h + cr * rng.uniform(0.5, 0.9), cr);
        }
        s += rng.uniform(6.0, 14.0);
      } else if (pick < 0.85 && band >= 2.2) {  // parked car: body and cabin
        const double len = rng.uniform(3.8, 4.8), wid = rng.uniform(1.7, 1.9);
        const Eigen::Vector2d c = at(s + 0.5 * len, curb - 0.5 * wid);
        const double yaw = std::atan2(u.y(), u.x()) + rng.uniform(-0.05, 0.05);
        add_yawed_box(c.x(), c.y(), len, wid, rng.uniform(0.9, 1.1), yaw, 0.0);
        const Eigen::Vector2d cab = at(s + 0.5 * len + rng.uniform(-0.4, 0.2), curb - 0.5 * wid);
        add_yawed_box(cab.x(), cab.y(), 0.5 * len, wid - 0.1, rng.uniform(0.4, 0.6), yaw,
                      rng.uniform(0.9, 1.1) - 0.05);
        s += len + rng.uniform(0.8, 6.0);
      } else {
        s += rng.uniform(2.0, 8.0);
      }
    }
    // Facade-side clutter: bushes (clusters of spheres) and small boxes (bins, benches, kiosks)
    // at random yaw.
    s = rng.uniform(0.0, 3.0);
    while (s < length) {
      const double off = rng.uniform(0.3, std::min(1.6, band - 1.0));
      const Eigen::Vector2d c = at(s, off);
      if (rng.chance(0.6)) {
        const int blobs = 2 + static_cast<int>(rng.uniform(0.0, 5.0));
        const double g = this->height(c.x(), c.y());
        for (int k = 0; k < blobs; ++k) {
          const double r = rng.uniform(0.25, 0.7);
          const Eigen::Vector2d q = c + rng.uniform(-1.0, 1.0) * u + rng.uniform(-0.3, 0.3) * n;
          add_sphere(q.x(), q.y(), g + r * rng.uniform(0.2, 1.2), r);
        }
      } else {
        const double a = rng.uniform(0.4, 1.5), b = rng.uniform(0.4, 1.0);
        add_yawed_box(c.x(), c.y(), a, b, rng.uniform(0.5, 1.8), rng.uniform(0.0, kPi), 0.0);
      }
      s += rng.uniform(3.0, 12.0);
    }
  }

  void build_grid() {
    double min_x = kInf, min_y = kInf, max_x = -kInf, max_y = -kInf;
    for (const Primitive& p : primitives) {
      min_x = std::min(min_x, p.min_x);
      min_y = std::min(min_y, p.min_y);
      max_x = std::max(max_x, p.max_x);
      max_y = std::max(max_y, p.max_y);
    }
    x0 = min_x - 1.0;
    y0 = min_y - 1.0;
    nx = static_cast<int>(std::ceil((max_x + 1.0 - x0) / kCellSize));
    ny = static_cast<int>(std::ceil((max_y + 1.0 - y0) / kCellSize));
    auto cell_range = [&](const Primitive& p, int* i0, int* i1, int* j0, int* j1) {
      *i0 = std::clamp(static_cast<int>(std::floor((p.min_x - x0) / kCellSize)), 0, nx - 1);
      *i1 = std::clamp(static_cast<int>(std::floor((p.max_x - x0) / kCellSize)), 0, nx - 1);
      *j0 = std::clamp(static_cast<int>(std::floor((p.min_y - y0) / kCellSize)), 0, ny - 1);
      *j1 = std::clamp(static_cast<int>(std::floor((p.max_y - y0) / kCellSize)), 0, ny - 1);
    };
    const std::size_t cells = static_cast<std::size_t>(nx) * ny;
    std::vector<std::uint32_t> count(cells + 1, 0);
    for (const Primitive& p : primitives) {
      int i0, i1, j0, j1;
      cell_range(p, &i0, &i1, &j0, &j1);
      for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i) ++count[static_cast<std::size_t>(j) * nx + i + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) count[c + 1] += count[c];
    cell_start = count;
    cell_items.resize(cell_start.back());
    for (std::uint32_t k = 0; k < primitives.size(); ++k) {
      int i0, i1, j0, j1;
      cell_range(primitives[k], &i0, &i1, &j0, &j1);
      for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i)
          cell_items[count[static_cast<std::size_t>(j) * nx + i]++] = k;
    }
  }
};

SyntheticWorld::SyntheticWorld(const SyntheticWorldOptions& options) : options_(options) {
  validate(options);
  auto scene = std::make_shared<Scene>();
  Random rng(options.seed);
  // Ground: the plane tilts by ground_slope towards a random direction; three waves with
  // random directions, wavelengths of 4..20 m, amplitudes summing to ground_roughness.
  const double tilt = rng.uniform(0.0, 2.0 * kPi);
  scene->plane_gx = std::tan(options.ground_slope) * std::cos(tilt);
  scene->plane_gy = std::tan(options.ground_slope) * std::sin(tilt);
  const double weights[3] = {0.5, 0.3, 0.2};
  for (int k = 0; k < 3; ++k) {
    const double dir = rng.uniform(0.0, 2.0 * kPi), wavelength = rng.uniform(4.0, 20.0);
    scene->kx[k] = 2.0 * kPi / wavelength * std::cos(dir);
    scene->ky[k] = 2.0 * kPi / wavelength * std::sin(dir);
    scene->phase[k] = rng.uniform(0.0, 2.0 * kPi);
    scene->amp[k] = weights[k] * options.ground_roughness;
  }
  scene->relief = options.ground_roughness * (1.0 + 1e-9) + 1e-12;

  const double B = options.block_size, W = options.street_width;
  const double band = 0.5 * W - kLaneClearance;  // sidewalk objects stay within this
  const double depth = std::min(14.0, 0.5 * B - 1.0);
  for (int j = 0; j < options.blocks_y; ++j) {
    for (int i = 0; i < options.blocks_x; ++i) {
      const double x = i * (B + W), y = j * (B + W);
      const std::array<Eigen::Vector2d, 4> corner = {
          Eigen::Vector2d(x, y), Eigen::Vector2d(x + B, y), Eigen::Vector2d(x + B, y + B),
          Eigen::Vector2d(x, y + B)};
      for (int e = 0; e < 4; ++e) {
        const Eigen::Vector2d u = (corner[(e + 1) % 4] - corner[e]) / B;
        scene->add_row(rng, corner[e], u, B, depth, band, 2.0);
      }
    }
  }
  // The outer ring, facing the outer streets.
  const double X = options.blocks_x * B + (options.blocks_x - 1) * W;
  const double Y = options.blocks_y * B + (options.blocks_y - 1) * W;
  const std::array<Eigen::Vector2d, 4> ring = {Eigen::Vector2d(X + W, -W), Eigen::Vector2d(-W, -W),
                                               Eigen::Vector2d(-W, Y + W),
                                               Eigen::Vector2d(X + W, Y + W)};
  for (int e = 0; e < 4; ++e) {
    const Eigen::Vector2d d = ring[(e + 1) % 4] - ring[e];
    scene->add_row(rng, ring[e], d / d.norm(), d.norm(), 12.0, band, 2.0);
  }
  scene->build_grid();

  // Sensor ray directions.
  const int beams = options.beams;
  for (int b = 0; b < beams; ++b) {
    const double el_deg =
        beams == 1 ? 0.5 * (options.min_elevation_deg + options.max_elevation_deg)
                   : options.min_elevation_deg +
                         (options.max_elevation_deg - options.min_elevation_deg) * b / (beams - 1);
    const double el = el_deg * kPi / 180.0;
    scene->cos_el.push_back(std::cos(el));
    scene->sin_el.push_back(std::sin(el));
  }
  for (int a = 0; a < options.azimuth_steps; ++a) {
    const double az = 2.0 * kPi * a / options.azimuth_steps;
    scene->cos_az.push_back(std::cos(az));
    scene->sin_az.push_back(std::sin(az));
  }
  scene_ = std::move(scene);
}

double SyntheticWorld::ground_height(double x, double y) const { return scene_->height(x, y); }

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

std::vector<Eigen::Isometry3d> SyntheticWorld::trajectory(
    const SyntheticTrajectoryOptions& options) const {
  auto require_t = [](bool ok, const std::string& field, const std::string& problem) {
    if (!ok) throw Error("SyntheticTrajectoryOptions." + field + ": " + problem);
  };
  const double B = options_.block_size, W = options_.street_width;
  require_t(options.frames >= 2, "frames", "must be >= 2, got " + std::to_string(options.frames));
  require_t(options.laps >= 1, "laps", "must be >= 1, got " + std::to_string(options.laps));
  require_t(
      std::isfinite(options.lap_offset) && options.lap_offset >= 0.0 && options.lap_offset <= 1.5,
      "lap_offset", "must be finite and in [0, 1.5] m, got " + std::to_string(options.lap_offset));
  require_t(std::isfinite(options.corner_radius) && options.corner_radius > options.lap_offset &&
                options.corner_radius < 0.5 * (B + W),
            "corner_radius",
            "must be finite, > lap_offset and < (block_size + street_width) / 2, got " +
                std::to_string(options.corner_radius));
  require_t(std::isfinite(options.lap_yaw_deg) && std::abs(options.lap_yaw_deg) <= 10.0,
            "lap_yaw_deg",
            "must be finite with |.| <= 10 deg, got " + std::to_string(options.lap_yaw_deg));

  require_t(options.circuit_blocks_x >= 1 && options.circuit_blocks_x <= options_.blocks_x,
            "circuit_blocks_x",
            "must be in [1, blocks_x = " + std::to_string(options_.blocks_x) + "], got " +
                std::to_string(options.circuit_blocks_x));
  require_t(options.circuit_blocks_y >= 1 && options.circuit_blocks_y <= options_.blocks_y,
            "circuit_blocks_y",
            "must be in [1, blocks_y = " + std::to_string(options_.blocks_y) + "], got " +
                std::to_string(options.circuit_blocks_y));

  // The centre-line rectangle through the streets around the circuit's blocks: straights of
  // n (B + W) - 2 r between the rounded corners (one block: B + W - 2 r on every side).
  const double span_x = options.circuit_blocks_x * (B + W),
               span_y = options.circuit_blocks_y * (B + W);
  // (Written so that one block gives exactly the centre (B / 2, B / 2) of block (0, 0).)
  const Eigen::Vector2d center(0.5 * B + 0.5 * (options.circuit_blocks_x - 1) * (B + W),
                               0.5 * B + 0.5 * (options.circuit_blocks_y - 1) * (B + W));
  const std::array<double, 2> straight = {span_x - 2.0 * options.corner_radius,
                                          span_y - 2.0 * options.corner_radius};
  // Unit normal of the ground plane: sensor z axis.
  const Eigen::Vector3d up =
      Eigen::Vector3d(-scene_->plane_gx, -scene_->plane_gy, 1.0).normalized();
  std::vector<Eigen::Isometry3d> poses;
  poses.reserve(options.frames);
  for (int k = 0; k < options.frames; ++k) {
    const double lap_pos = static_cast<double>(k) * options.laps / options.frames;
    const int lap = static_cast<int>(std::floor(lap_pos));
    const double fraction = lap_pos - lap;
    const double factor = std::array<double, 3>{0.0, 1.0, -1.0}[lap % 3];
    const double offset = options.lap_offset * factor;
    const double half_y = 0.5 * span_y + offset, radius = options.corner_radius + offset;
    const double length = 2.0 * (straight[0] + straight[1]) + 2.0 * kPi * radius;
    // Arc length from the start of the bottom straight; frame 0 sits at its middle.
    double s = std::fmod(fraction * length + 0.5 * straight[0], length);
    Eigen::Vector2d p(center.x() - 0.5 * straight[0], center.y() - half_y);
    double heading = 0.0;
    for (int q = 0; q < 4; ++q) {
      const double side = straight[static_cast<std::size_t>(q % 2)];
      const Eigen::Vector2d dir(std::cos(heading), std::sin(heading));
      const Eigen::Vector2d left(-dir.y(), dir.x());
      if (s <= side) {
        p += s * dir;
        break;
      }
      s -= side;
      const Eigen::Vector2d arc_center = p + side * dir + radius * left;
      const double arc = 0.5 * kPi * radius;
      if (s <= arc || q == 3) {
        const double phi = std::min(s, arc) / radius;
        p = arc_center +
            radius * Eigen::Vector2d(std::sin(heading + phi), -std::cos(heading + phi));
        heading += phi;
        break;
      }
      s -= arc;
      p = arc_center + radius * dir;
      heading += 0.5 * kPi;
    }
    const double yaw = heading + factor * options.lap_yaw_deg * kPi / 180.0;
    const Eigen::Vector3d forward(std::cos(yaw), std::sin(yaw), 0.0);
    const Eigen::Vector3d x_axis = (forward - forward.dot(up) * up).normalized();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = x_axis;
    T.linear().col(1) = up.cross(x_axis);
    T.linear().col(2) = up;
    T.translation() =
        Eigen::Vector3d(p.x(), p.y(), scene_->height(p.x(), p.y()) + options_.sensor_height);
    poses.push_back(T);
  }
  return poses;
}

std::uint64_t synthetic_frame_noise_seed(std::uint64_t seed, std::size_t frame) {
  return splitmix64(seed ^ splitmix64(0x5eed0000ULL + frame));
}

SyntheticSequence make_synthetic_sequence(const SyntheticWorld& world,
                                          const SyntheticTrajectoryOptions& options) {
  SyntheticSequence sequence;
  sequence.T_world_frame = world.trajectory(options);
  sequence.scans.resize(sequence.T_world_frame.size());
  tbb::parallel_for(std::size_t{0}, sequence.scans.size(), [&](std::size_t k) {
    sequence.scans[k] =
        world.scan(sequence.T_world_frame[k], synthetic_frame_noise_seed(world.options().seed, k));
  });
  return sequence;
}

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
  std::vector<Eigen::Isometry3d> out(T_world_frame.begin(), T_world_frame.end());
  if (out.empty() || (options.translation_sigma == 0.0 && options.rotation_sigma_deg == 0.0)) {
    return out;
  }
  Random rng(options.seed);
  const double rotation_sigma = options.rotation_sigma_deg * kPi / 180.0;
  for (std::size_t k = 1; k < out.size(); ++k) {
    const Eigen::Isometry3d relative = T_world_frame[k - 1].inverse() * T_world_frame[k];
    const double distance = relative.translation().norm();
    se3::Vector6d xi;
    for (int i = 0; i < 3; ++i) xi[i] = rotation_sigma * distance * rng.normal();
    for (int i = 3; i < 6; ++i) xi[i] = options.translation_sigma * distance * rng.normal();
    out[k] = out[k - 1] * relative * se3::exp(xi);
  }
  return out;
}

namespace {

void write_kitti_poses(const std::filesystem::path& path,
                       std::span<const Eigen::Isometry3d> T_world_frame) {
  std::string text;
  for (const Eigen::Isometry3d& T : T_world_frame) {
    const Eigen::Matrix4d M = T.matrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        char number[40];
        std::snprintf(number, sizeof(number), "%.9g", M(r, c));
        if (r + c > 0) text += ' ';
        text += number;
      }
    }
    text += '\n';
  }
  write_file_atomically(path, [&](std::ostream& out) { out << text; });
}

std::filesystem::path frame_file(const std::filesystem::path& dir, std::size_t k) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06zu.bin", k);
  return dir / name;
}

void create_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir.string() + ": cannot create the directory (" + ec.message() + ")");
}

}  // namespace

void write_synthetic_sequence(const std::filesystem::path& dir, const SyntheticSequence& sequence) {
  if (sequence.scans.size() != sequence.T_world_frame.size()) {
    throw Error("write_synthetic_sequence: " + std::to_string(sequence.scans.size()) +
                " scans but " + std::to_string(sequence.T_world_frame.size()) + " poses");
  }
  create_folder(dir);
  for (std::size_t k = 0; k < sequence.scans.size(); ++k) {
    write_kitti_bin(frame_file(dir, k), sequence.scans[k], KittiFormat::kXyzi);
  }
  write_kitti_poses(dir / "poses.txt", sequence.T_world_frame);
}

std::size_t write_synthetic_drive(const std::filesystem::path& dir, const SyntheticWorld& world,
                                  const SyntheticTrajectoryOptions& options,
                                  const std::function<void(std::size_t, std::size_t)>& progress) {
  const std::vector<Eigen::Isometry3d> poses = world.trajectory(options);
  create_folder(dir);
  std::atomic<std::size_t> points{0}, done{0};
  tbb::parallel_for(std::size_t{0}, poses.size(), [&](std::size_t k) {
    const PointCloud scan =
        world.scan(poses[k], synthetic_frame_noise_seed(world.options().seed, k));
    write_kitti_bin(frame_file(dir, k), scan, KittiFormat::kXyzi);
    points += scan.size();
    if (progress) progress(done.fetch_add(1) + 1, poses.size());
  });
  write_kitti_poses(dir / "poses.txt", poses);
  return points.load();
}

}  // namespace carat
