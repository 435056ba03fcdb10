#include "carat/sim/world.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "carat/solver/error.hpp"
#include "primitive.hpp"
#include "random.hpp"

namespace carat {
namespace {

using sim_detail::intersect;
using sim_detail::Primitive;
using sim_detail::Random;
using sim_detail::Shape;

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kLaneClearance = 3.0;  // metres either side of a street centre line kept empty
constexpr double kCellSize = 4.0;       // metres, edge of a cell of the 2-D acceleration grid

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
