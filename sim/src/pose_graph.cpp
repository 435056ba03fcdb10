#include "carat/sim/pose_graph.hpp"

#include <cmath>
#include <random>
#include <string>

#include "carat/base/error.hpp"
#include "carat/solver/se3.hpp"

namespace carat {
namespace {

/// Pose at arc length s along a rounded rectangle (corners are quarter circles), with a gentle
/// height profile so that the graph is truly 3D.
Eigen::Isometry3d circuit_pose(double s, double length, double width, double radius) {
  const double a = length - 2.0 * radius;
  const double b = width - 2.0 * radius;
  const double arc = 0.5 * M_PI * radius;
  const double perimeter = 2.0 * a + 2.0 * b + 4.0 * arc;
  s = std::fmod(s, perimeter);
  if (s < 0) s += perimeter;
  const double segments[8] = {a, arc, b, arc, a, arc, b, arc};
  double heading = 0.0;
  Eigen::Vector2d p(radius, 0.0);
  for (int k = 0; k < 8; ++k) {
    const double len = std::min(s, segments[k]);
    if (k % 2 == 0) {
      p += len * Eigen::Vector2d(std::cos(heading), std::sin(heading));
    } else {
      const double dtheta = len / radius;
      const Eigen::Vector2d center =
          p + radius * Eigen::Vector2d(-std::sin(heading), std::cos(heading));
      heading += dtheta;
      p = center + radius * Eigen::Vector2d(std::sin(heading), -std::cos(heading));
    }
    s -= len;
    if (s <= 0.0) break;
  }
  const double z = 1.5 * std::sin(2.0 * M_PI * p.x() / length) * std::sin(M_PI * p.y() / width);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.x(), p.y(), z);
  return T;
}

}  // namespace

SyntheticPoseGraph make_synthetic_pose_graph(const SyntheticPoseGraphOptions& o) {
  if (o.poses_per_lap < 8)
    throw Error("synthetic pose graph: poses_per_lap must be >= 8, got " +
                std::to_string(o.poses_per_lap));
  if (o.laps < 1)
    throw Error("synthetic pose graph: laps must be >= 1, got " + std::to_string(o.laps));
  if (!(o.block_length_m > 0.0) || !(o.block_width_m > 0.0))
    throw Error("synthetic pose graph: block size must be > 0");
  if (!(o.translation_sigma_m > 0.0) || !(o.rotation_sigma_rad > 0.0))
    throw Error("synthetic pose graph: noise sigmas must be > 0");
  if (o.loop_closure_stride < 1)
    throw Error("synthetic pose graph: loop_closure_stride must be >= 1");

  SyntheticPoseGraph out;
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double radius = 0.2 * std::min(o.block_length_m, o.block_width_m);
  const double a = o.block_length_m - 2.0 * radius;
  const double b = o.block_width_m - 2.0 * radius;
  const double perimeter = 2.0 * a + 2.0 * b + 2.0 * M_PI * radius;
  const int n = o.poses_per_lap * o.laps;
  for (int k = 0; k < n; ++k) {
    // Later laps drift sideways by up to 1 m so that revisits are near, not identical.
    Eigen::Isometry3d T =
        circuit_pose(perimeter * k / o.poses_per_lap, o.block_length_m, o.block_width_m, radius);
    T.translation() += T.linear() * Eigen::Vector3d(0.0, 0.5 * (k / o.poses_per_lap), 0.0);
    out.T_world_truth.push_back(T);
  }

  se3::Matrix6d information = se3::Matrix6d::Zero();
  information.diagonal().head<3>().setConstant(1.0 /
                                               (o.translation_sigma_m * o.translation_sigma_m));
  information.diagonal().tail<3>().setConstant(1.0 / (o.rotation_sigma_rad * o.rotation_sigma_rad));
  const auto noisy = [&](const Eigen::Isometry3d& T) {
    se3::Vector6d xi;
    for (int i = 0; i < 3; ++i) xi[i] = o.rotation_sigma_rad * normal(rng);
    for (int i = 3; i < 6; ++i) xi[i] = o.translation_sigma_m * normal(rng);
    return T * se3::exp(xi);
  };
  const auto add_edge = [&](int i, int j) {
    PoseGraph::Edge e;
    e.from = i;
    e.to = j;
    e.T_from_to = noisy(out.T_world_truth[static_cast<std::size_t>(i)].inverse() *
                        out.T_world_truth[static_cast<std::size_t>(j)]);
    e.information = information;
    out.graph.edges.push_back(e);
  };
  for (int k = 0; k + 1 < n; ++k) add_edge(k, k + 1);
  for (int k = o.poses_per_lap; k < n; k += o.loop_closure_stride) {
    for (int lap = 1; lap * o.poses_per_lap <= k; ++lap) add_edge(k - lap * o.poses_per_lap, k);
  }
  // Initial guess: the first pose at its true value, then composed noisy odometry.
  Eigen::Isometry3d T = out.T_world_truth.front();
  for (int k = 0; k < n; ++k) {
    if (k > 0) T = T * out.graph.edges[static_cast<std::size_t>(k - 1)].T_from_to;
    out.graph.vertices.push_back({k, T});
  }
  out.graph.fixed.push_back(0);
  return out;
}

double position_rmse(const PoseGraph& graph, const std::vector<Eigen::Isometry3d>& truth) {
  if (graph.vertices.size() != truth.size() || truth.empty()) {
    throw Error("position_rmse: " + std::to_string(graph.vertices.size()) + " vertices but " +
                std::to_string(truth.size()) + " ground-truth poses");
  }
  double sum = 0.0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    sum += (graph.vertices[i].T_world_vertex.translation() - truth[i].translation()).squaredNorm();
  }
  return std::sqrt(sum / static_cast<double>(truth.size()));
}

}  // namespace carat
