#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/sim/world.hpp"

namespace carat {
namespace {

constexpr double kPi = std::numbers::pi;

}  // namespace

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
  const Eigen::Vector3d up = ground_normal();
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
        Eigen::Vector3d(p.x(), p.y(), ground_height(p.x(), p.y()) + options_.sensor_height);
    poses.push_back(T);
  }
  return poses;
}

}  // namespace carat
