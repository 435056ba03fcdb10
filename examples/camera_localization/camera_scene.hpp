#pragma once

// A synthetic camera-localization problem (shared by the example and bench/ceres): a fixed 3-D
// map of points along a street, a camera driving through it, thousands of 2-D to 3-D matches
// per frame (pinhole, 0.5 px noise), odometry between consecutive frames, and a start perturbed
// from the truth. What carat and Ceres both solve: every frame's pose T_world_camera.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "carat/solver/lie_functions.hpp"
#include "carat/solver/se3.hpp"

namespace camera_scene {

/// One match: a map point (world frame, metres) and where the frame saw it (pixels, centred).
struct Observation {
  Eigen::Vector3d point_world;
  Eigen::Vector2d pixel;
};

/// The pinhole projection error of a map point for the pose T_world_camera, in pixels.
struct Reprojection {
  double focal = 500.0;  ///< focal length, pixels
  template <typename T>
  bool operator()(const Observation& o, const T* T_world_camera, T* residuals) const {
    const auto pose = carat::lie::Pose<T>::from_storage(T_world_camera);
    const Eigen::Matrix<T, 3, 1> p = pose.inverse().act(o.point_world.cast<T>());
    if (!(carat::lie::value_of(p.z()) > 0.1)) return false;  // at or behind the camera
    residuals[0] = T(focal) * p.x() / p.z() - T(o.pixel.x());
    residuals[1] = T(focal) * p.y() / p.z() - T(o.pixel.y());
    return true;
  }
};

/// The scene: truth, start, matches per frame, odometry between consecutive frames.
struct Scene {
  std::vector<Eigen::Isometry3d> T_world_camera_truth;
  std::vector<Eigen::Isometry3d> T_world_camera_start;
  std::vector<std::vector<Observation>> observations;  ///< per frame
  std::vector<Eigen::Isometry3d> odometry;             ///< T_k_k+1, measured (noisy)
  double odometry_sigma_m = 0.02;                      ///< its noise per axis, metres
  double odometry_sigma_rad = 0.002;                   ///< its noise per axis, radians
};

/// `frames` cameras 1 m apart along x (looking along the street, z forward), `per_frame`
/// matches each; the start is the truth moved by about `start_m` and `start_deg` per frame.
inline Scene make_scene(int frames = 20, int per_frame = 3000, double start_m = 0.1,
                        double start_deg = 1.0, std::uint64_t seed = 1) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Scene scene;
  // The camera looks along +x (the street): camera z = world x, camera x = -world y,
  // camera y = -world z.
  Eigen::Matrix3d R_world_camera;
  R_world_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  for (int k = 0; k < frames; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() =
        Eigen::AngleAxisd(0.02 * std::sin(0.3 * k), Eigen::Vector3d::UnitZ()) * R_world_camera;
    T.translation() = Eigen::Vector3d(1.0 * k, 0.3 * std::sin(0.2 * k), 1.5);
    scene.T_world_camera_truth.push_back(T);
    carat::se3::Vector6d xi;
    for (int a = 0; a < 3; ++a) xi[a] = start_deg * M_PI / 180.0 * n(rng) / std::sqrt(3.0);
    for (int a = 3; a < 6; ++a) xi[a] = start_m * n(rng) / std::sqrt(3.0);
    scene.T_world_camera_start.push_back(T * carat::se3::exp(xi));
  }
  const double focal = Reprojection{}.focal;
  for (int k = 0; k < frames; ++k) {
    const Eigen::Isometry3d T_camera_world = scene.T_world_camera_truth[k].inverse();
    std::vector<Observation> seen;
    while (static_cast<int>(seen.size()) < per_frame) {
      // Facades 6 m to either side, ground and clutter, 3 to 40 m ahead.
      const double ahead = scene.T_world_camera_truth[k].translation().x() + 3.0 + 37.0 * u(rng);
      const double side = u(rng) < 0.5 ? -6.0 : 6.0;
      const double kind = u(rng);
      Eigen::Vector3d p;
      if (kind < 0.6) {
        p = {ahead, side + 0.05 * n(rng), 10.0 * u(rng)};
      } else if (kind < 0.85) {
        p = {ahead, 12.0 * (u(rng) - 0.5), 0.02 * n(rng)};
      } else {
        p = {ahead, 8.0 * (u(rng) - 0.5), 3.0 * u(rng)};
      }
      const Eigen::Vector3d c = T_camera_world * p;
      if (c.z() < 1.0) continue;
      const Eigen::Vector2d pixel(focal * c.x() / c.z(), focal * c.y() / c.z());
      if (std::abs(pixel.x()) > 640.0 || std::abs(pixel.y()) > 360.0) continue;
      seen.push_back({p, pixel + 0.5 * Eigen::Vector2d(n(rng), n(rng))});
    }
    scene.observations.push_back(std::move(seen));
  }
  for (int k = 0; k + 1 < frames; ++k) {
    carat::se3::Vector6d xi;
    for (int a = 0; a < 3; ++a) xi[a] = scene.odometry_sigma_rad * n(rng);
    for (int a = 3; a < 6; ++a) xi[a] = scene.odometry_sigma_m * n(rng);
    scene.odometry.push_back(scene.T_world_camera_truth[k].inverse() *
                             scene.T_world_camera_truth[k + 1] * carat::se3::exp(xi));
  }
  return scene;
}

}  // namespace camera_scene
