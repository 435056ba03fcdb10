#pragma once

// A synthetic camera-calibration problem (shared by the example, tests and bench/ceres): one
// camera's intrinsics [fx, fy, cx, cy, k1, k2], shared by every view, and one pose
// T_world_camera per view; each view sees thousands of known 3-D points of a calibration rig
// (two rows per point: the reprojection error in pixels, 0.5 px noise, optionally a share of
// outliers). The start is off in the intrinsics and in every pose. What carat and Ceres both
// solve: the intrinsics and every view's pose.

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "carat/solver/lie_functions.hpp"
#include "carat/solver/se3.hpp"

namespace calibration_scene {

/// One observation: a rig point (world frame, metres) and where the view saw it (pixels).
struct Observation {
  Eigen::Vector3d point_world;
  Eigen::Vector2d pixel;
};

/// The camera model: p = R^T (X - t) for T_world_camera = (R, t), x = p.xy / p.z,
/// d = 1 + k1 |x|^2 + k2 |x|^4, pixel = (fx d x_0 + cx, fy d x_1 + cy). False behind the camera.
template <typename T>
bool project(const T* K, const carat::lie::Pose<T>& T_camera_world, const Observation& o,
             T* residuals) {
  const Eigen::Matrix<T, 3, 1> p = T_camera_world.act(o.point_world);
  if (!(carat::lie::value_of(p.z()) > 0.1)) return false;
  const T x = p.x() / p.z(), y = p.y() / p.z();
  const T r2 = x * x + y * y;
  const T d = T(1.0) + r2 * (K[4] + K[5] * r2);
  residuals[0] = K[0] * d * x + K[2] - o.pixel.x();
  residuals[1] = K[1] * d * y + K[3] - o.pixel.y();
  return true;
}

/// The reprojection error as a new user writes it first: everything per observation (the pose's
/// quaternion turned into a rotation and inverted for every row).
struct Reprojection {
  template <typename T>
  bool operator()(const Observation& o, const T* K, const T* T_world_camera, T* residuals) const {
    const auto T_camera_world = carat::lie::Pose<T>::from_storage(T_world_camera).inverse();
    return project(K, T_camera_world, o, residuals);
  }
};

/// The same error with the per-view work done once per evaluation (AutoDiffBlock's prepare()):
/// the rotation is built and inverted once, then each observation costs a few multiplications.
struct PreparedReprojection {
  /// What prepare() computes once per evaluation.
  template <typename T>
  struct View {
    const T* K;                          ///< the intrinsics (valid during the evaluation)
    carat::lie::Pose<T> T_camera_world;  ///< the view's pose, inverted
  };
  template <typename T>
  View<T> prepare(const T* K, const T* T_world_camera) const {
    return {K, carat::lie::Pose<T>::from_storage(T_world_camera).inverse()};
  }
  template <typename T>
  bool operator()(const Observation& o, const View<T>& view, T* residuals) const {
    return project(view.K, view.T_camera_world, o, residuals);
  }
};

/// Intrinsics [fx, fy, cx, cy, k1, k2] (pixels; k1, k2 unitless).
using Intrinsics = std::array<double, 6>;

/// The scene: truth, start, observations per view.
struct Scene {
  Intrinsics K_truth{800.0, 790.0, 640.0, 480.0, -0.2, 0.05};
  Intrinsics K_start{};
  std::vector<Eigen::Isometry3d> T_world_camera_truth;
  std::vector<Eigen::Isometry3d> T_world_camera_start;
  std::vector<std::vector<Observation>> observations;  ///< per view
  std::vector<std::vector<char>> outlier;              ///< per view and observation
};

/// Settings of make_scene().
struct SceneOptions {
  int views = 25;                   ///< views (groups)
  int per_view = 2500;              ///< observations per view (two rows each)
  double noise_px = 0.5;            ///< pixel noise (standard deviation per axis)
  double outlier_share = 0.0;       ///< share of observations displaced by outlier_px
  double outlier_px = 15.0;         ///< displacement of an outlier, pixels
  double start_m = 0.05;            ///< start: pose translation error per view, metres
  double start_deg = 1.0;           ///< start: pose rotation error per view, degrees
  double start_focal_share = 0.05;  ///< start: focal lengths off by this share
  double start_center_px = 15.0;    ///< start: principal point off by this, pixels
  std::uint64_t seed = 1;           ///< seed of everything drawn
};

/// Views 3.5-5 m from a rig of points in [-1, 1]^3 m, looking at it from a cone of directions;
/// the start perturbs the intrinsics (distortion starts at 0) and every pose.
inline Scene make_scene(const SceneOptions& options = {}) {
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> n;
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Scene scene;
  for (int v = 0; v < options.views; ++v) {
    const double azimuth = 2.0 * M_PI * (v + 0.3 * u(rng)) / options.views;
    const double elevation = 0.3 + 0.4 * u(rng);
    const double distance = 3.5 + 1.5 * u(rng);
    const Eigen::Vector3d center(distance * std::cos(elevation) * std::cos(azimuth),
                                 distance * std::cos(elevation) * std::sin(azimuth),
                                 distance * std::sin(elevation));
    // z looks at the rig's centre, x stays horizontal.
    const Eigen::Vector3d z = (-center).normalized();
    const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() << x, y, z;
    T.translation() = center;
    scene.T_world_camera_truth.push_back(T);
    carat::se3::Vector6d xi;
    for (int a = 0; a < 3; ++a) xi[a] = options.start_deg * M_PI / 180.0 * n(rng) / std::sqrt(3.0);
    for (int a = 3; a < 6; ++a) xi[a] = options.start_m * n(rng) / std::sqrt(3.0);
    scene.T_world_camera_start.push_back(T * carat::se3::exp(xi));
  }
  const Intrinsics& K = scene.K_truth;
  for (int v = 0; v < options.views; ++v) {
    const Eigen::Isometry3d& T_world_camera =
        scene.T_world_camera_truth[static_cast<std::size_t>(v)];
    carat::lie::Pose<double> T_camera_world;
    T_camera_world.R = T_world_camera.linear().transpose();
    T_camera_world.t = -T_camera_world.R * T_world_camera.translation();
    std::vector<Observation> seen;
    std::vector<char> outlier;
    while (static_cast<int>(seen.size()) < options.per_view) {
      Observation o{Eigen::Vector3d(2.0 * u(rng) - 1.0, 2.0 * u(rng) - 1.0, 2.0 * u(rng) - 1.0),
                    Eigen::Vector2d::Zero()};
      double r[2];
      if (!project(K.data(), T_camera_world, o, r)) continue;
      const Eigen::Vector2d pixel(r[0], r[1]);  // o.pixel is 0: the residual is the pixel
      if (pixel.x() < 0.0 || pixel.x() > 1280.0 || pixel.y() < 0.0 || pixel.y() > 960.0) continue;
      o.pixel = pixel + options.noise_px * Eigen::Vector2d(n(rng), n(rng));
      const bool bad = u(rng) < options.outlier_share;
      if (bad) {
        const double angle = 2.0 * M_PI * u(rng);
        o.pixel += options.outlier_px * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      }
      seen.push_back(o);
      outlier.push_back(bad ? 1 : 0);
    }
    scene.observations.push_back(std::move(seen));
    scene.outlier.push_back(std::move(outlier));
  }
  scene.K_start = {K[0] * (1.0 + options.start_focal_share),
                   K[1] * (1.0 + options.start_focal_share),
                   K[2] + options.start_center_px,
                   K[3] - options.start_center_px,
                   0.0,
                   0.0};
  return scene;
}

}  // namespace calibration_scene
