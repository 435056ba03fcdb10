#pragma once

/// A seeded synthetic SE(3) pose graph: a vehicle drives a rectangular city-block circuit
/// several times; odometry edges between consecutive poses and loop-closure edges between
/// poses at the same place on different laps carry Gaussian noise, and the initial guess is
/// the composed (drifting) odometry.

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "carat/residuals/pose_graph.hpp"

namespace carat {

/// Shape and noise of the synthetic pose graph.
struct SyntheticPoseGraphOptions {
  int poses_per_lap = 200;            ///< poses along one circuit (>= 8)
  int laps = 2;                       ///< times the circuit is driven (>= 1)
  double block_length_m = 80.0;       ///< long side of the circuit, metres
  double block_width_m = 50.0;        ///< short side of the circuit, metres
  double translation_sigma_m = 0.05;  ///< odometry/loop noise per axis, metres
  double rotation_sigma_rad = 0.005;  ///< odometry/loop noise per axis, radians
  int loop_closure_stride = 5;        ///< a loop closure every this many poses on laps >= 2
  std::uint64_t seed = 1;             ///< random seed (same seed, same graph)
};

/// The graph (vertices hold the drifting initial guess) and the ground truth.
struct SyntheticPoseGraph {
  PoseGraph graph;                               ///< noisy measurements, odometry initial guess
  std::vector<Eigen::Isometry3d> T_world_truth;  ///< ground-truth pose of every vertex
};

/// Generates the graph; throws carat::Error for out-of-range options.
SyntheticPoseGraph make_synthetic_pose_graph(const SyntheticPoseGraphOptions& options = {});

/// RMSE of vertex positions against `truth` (same order), metres, without any alignment
/// (the first vertex is the gauge and sits at its true pose).
double position_rmse(const PoseGraph& graph, const std::vector<Eigen::Isometry3d>& truth);

}  // namespace carat
