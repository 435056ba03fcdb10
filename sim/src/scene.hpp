#pragma once

// The scene behind SyntheticWorld: ground parameters, primitives, a 2-D grid over them and the
// sensor's ray directions; built in city.cpp, ray cast in scene.cpp.

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include "carat/sim/world.hpp"
#include "primitive.hpp"
#include "random.hpp"

namespace carat {
namespace sim_detail {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kInf = std::numeric_limits<double>::infinity();
/// Metres either side of a street centre line kept empty.
inline constexpr double kLaneClearance = 3.0;
/// Metres, edge of a cell of the 2-D acceleration grid.
inline constexpr double kCellSize = 4.0;

}  // namespace sim_detail

/// The scene: ground parameters, primitives and a 2-D uniform grid over them.
struct SyntheticWorld::Scene {
  // Ground: z = plane_gx * x + plane_gy * y + sum_k amp_k sin(kx_k x + ky_k y + phase_k).
  double plane_gx = 0.0, plane_gy = 0.0;
  std::array<double, 3> amp{}, kx{}, ky{}, phase{};
  double relief = 0.0;  // bound of |relief|, sum of |amp_k|

  std::vector<sim_detail::Primitive> primitives;
  double top_z = -sim_detail::kInf;  // highest point of any primitive

  // Grid: cells of kCellSize, cell (i, j) covers [x0 + i s, x0 + (i + 1) s) x [...]; the
  // primitives overlapping cell c are cell_items[cell_start[c] .. cell_start[c + 1]).
  double x0 = 0.0, y0 = 0.0;
  int nx = 0, ny = 0;
  std::vector<std::uint32_t> cell_start, cell_items;

  // Ray directions of the sensor.
  std::vector<double> cos_el, sin_el, cos_az, sin_az;

  /// Ground height z at (x, y), metres: the plane plus the relief.
  double height(double x, double y) const {
    double z = plane_gx * x + plane_gy * y;
    for (int k = 0; k < 3; ++k) z += amp[k] * std::sin(kx[k] * x + ky[k] * y + phase[k]);
    return z;
  }
  /// Height of the tilted plane alone at (x, y), metres.
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
  double ground_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_limit) const;

  /// Nearest hit of the unit ray o + t d in (0, t_limit), or kInf.
  double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_limit) const;

  // ---- Construction -------------------------------------------------------------------------

  /// Lowest ground height under the axis-aligned footprint (plane corners minus the relief).
  double base_z(double min_x, double min_y, double max_x, double max_y) const;

  /// Adds a primitive with its bounds filled in.
  void add(sim_detail::Primitive p);

  /// An axis-aligned box from its corner ranges (x, y) and z range.
  void add_box(double xa, double xb, double ya, double yb, double za, double zb);

  /// A box standing on the ground: centre (x, y), size, yaw, bottom `lift` above the ground.
  void add_yawed_box(double x, double y, double length, double width, double height, double yaw,
                     double lift);

  /// A vertical cylinder standing on the ground: axis at (x, y), radius, height above ground.
  void add_cylinder(double x, double y, double radius, double height);

  /// A sphere of centre (x, y, z), world frame, metres.
  void add_sphere(double x, double y, double z, double radius);

  /// A row of buildings along the line p0 + s u, s in [0, length], standing behind it (on the
  /// side opposite n = (u.y, -u.x), which points into the street), with sidewalk objects in
  /// front of it within `band` metres (the street side beyond `band` stays empty).
  /// `clutter_margin` keeps sidewalk objects away from the row's ends (street crossings).
  void add_row(sim_detail::Random& rng, const Eigen::Vector2d& p0, const Eigen::Vector2d& u,
               double length, double max_depth, double band, double clutter_margin);

  /// Fills the 2-D grid over the primitives (after the last add).
  void build_grid();
};

}  // namespace carat
