// Ray casting of the synthetic scene: the ground height field and the primitives on a 2-D grid.
#include "scene.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace carat {
namespace {

using sim_detail::intersect;
using sim_detail::kCellSize;
using sim_detail::kInf;
using sim_detail::kLaneClearance;
using sim_detail::kPi;
using sim_detail::Primitive;
using sim_detail::Random;
using sim_detail::Shape;

}  // namespace

double SyntheticWorld::Scene::ground_hit(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                         double t_limit) const {
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

double SyntheticWorld::Scene::cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                   double t_limit) const {
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

void SyntheticWorld::Scene::build_grid() {
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
      for (int i = i0; i <= i1; ++i) cell_items[count[static_cast<std::size_t>(j) * nx + i]++] = k;
  }
}

}  // namespace carat
