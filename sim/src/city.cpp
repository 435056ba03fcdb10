// The procedural city of SyntheticWorld: ground, building rows with facade detail, poles, trees,
// parked cars and bushes, all drawn from the seed, and the sensor's ray directions.
#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "scene.hpp"

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

double SyntheticWorld::Scene::base_z(double min_x, double min_y, double max_x, double max_y) const {
  return std::min(
             {plane(min_x, min_y), plane(min_x, max_y), plane(max_x, min_y), plane(max_x, max_y)}) -
         relief - 0.5;
}

void SyntheticWorld::Scene::add(Primitive p) {
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

void SyntheticWorld::Scene::add_box(double xa, double xb, double ya, double yb, double za,
                                    double zb) {
  Primitive p;
  p.shape = Shape::kBox;
  p.center = {0.5 * (xa + xb), 0.5 * (ya + yb), 0.5 * (za + zb)};
  p.half = {0.5 * std::abs(xb - xa), 0.5 * std::abs(yb - ya), 0.5 * std::abs(zb - za)};
  add(p);
}

void SyntheticWorld::Scene::add_yawed_box(double x, double y, double length, double width,
                                          double height, double yaw, double lift) {
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

void SyntheticWorld::Scene::add_cylinder(double x, double y, double radius, double height) {
  Primitive p;
  p.shape = Shape::kCylinder;
  p.center = {x, y, 0.0};
  p.radius = radius;
  p.z0 = base_z(x - radius, y - radius, x + radius, y + radius);
  p.z1 = this->height(x, y) + height;
  add(p);
}

void SyntheticWorld::Scene::add_sphere(double x, double y, double z, double radius) {
  Primitive p;
  p.shape = Shape::kSphere;
  p.center = {x, y, z};
  p.radius = radius;
  add(p);
}

void SyntheticWorld::Scene::add_row(Random& rng, const Eigen::Vector2d& p0,
                                    const Eigen::Vector2d& u, double length, double max_depth,
                                    double band, double clutter_margin) {
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

}  // namespace carat
