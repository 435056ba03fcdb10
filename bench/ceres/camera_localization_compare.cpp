// Side-by-side on a problem far from LiDAR: camera localization against a fixed 3-D map
// (examples/camera_localization/camera_scene.hpp: frames of thousands of 2-D to 3-D matches
// each, odometry between consecutive frames, a start 0.1 m / 1 degree off), solved in the same
// run by
//   ceres          Ceres 2.1's standard setup: one AutoDiffCostFunction<Reprojection, 2, 7> per
//                  match on a pose block [qx qy qz qw tx ty tz] with ProductManifold<
//                  EigenQuaternionManifold, EuclideanManifold<3>>, the relative-pose cost of its
//                  pose_graph_3d example for the odometry, default solver options (LM,
//                  SPARSE_NORMAL_CHOLESKY), 1 thread;
//   carat_full     carat with one AutoDiffBlock per frame (the same functor), 1 thread;
//   carat_compressed    each frame's block compressed once to its 29-row coreset;
//   carat_recompressed  compressed again at each result until the full problem's tests hold.
// Every method's result is judged by the same full cost (1/2 sum of squares, Ceres's convention).
//
// Usage: camera_localization_compare [--frames F] [--matches N] [--repeat R]; one JSON object.
#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "../../examples/camera_localization/camera_scene.hpp"
#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/coreset/problem_compression.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/solve.hpp"

namespace {

/// The reprojection error for Ceres: the same functor as carat's, one match per cost function.
struct CeresReprojection {
  explicit CeresReprojection(camera_scene::Observation o) : observation(std::move(o)) {}
  template <typename T>
  bool operator()(const T* pose, T* residuals) const {
    return camera_scene::Reprojection{}(observation, pose, residuals);
  }
  camera_scene::Observation observation;
};

/// Ceres's pose-graph residual on [q, t] storage: [R_a^T (t_b - t_a) - t_ab; 2 vec(q_ab^-1
/// q_a^-1 q_b)], whitened (translation first, as in its pose_graph_3d example): the same
/// function as carat's RelativePoseBlock.
struct CeresRelativePose {
  CeresRelativePose(const Eigen::Isometry3d& T_ab, const Eigen::Matrix<double, 6, 6>& sqrt_info)
      : t_ab(T_ab.translation()), q_ab(T_ab.linear()), sqrt_information(sqrt_info) {}
  template <typename T>
  bool operator()(const T* a, const T* b, T* residuals) const {
    const Eigen::Quaternion<T> q_a(a[3], a[0], a[1], a[2]), q_b(b[3], b[0], b[1], b[2]);
    const Eigen::Matrix<T, 3, 1> t_a(a[4], a[5], a[6]), t_b(b[4], b[5], b[6]);
    const Eigen::Quaternion<T> q_ab_estimated = q_a.conjugate() * q_b;
    const Eigen::Matrix<T, 3, 1> t_ab_estimated = q_a.conjugate() * (t_b - t_a);
    const Eigen::Quaternion<T> delta = q_ab.template cast<T>().conjugate() * q_ab_estimated;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residuals);
    r.template head<3>() = t_ab_estimated - t_ab.template cast<T>();
    r.template tail<3>() = T(2.0) * delta.vec();
    r.applyOnTheLeft(sqrt_information.template cast<T>());
    return true;
  }
  Eigen::Vector3d t_ab;
  Eigen::Quaterniond q_ab;
  Eigen::Matrix<double, 6, 6> sqrt_information;
};

/// The odometry's information, translation rows first (RelativePoseBlock's and Ceres's order).
carat::se3::Matrix6d odometry_information(const camera_scene::Scene& scene) {
  carat::se3::Matrix6d information = carat::se3::Matrix6d::Zero();
  for (int k = 0; k < 3; ++k) {
    information(k, k) = 1.0 / (scene.odometry_sigma_m * scene.odometry_sigma_m);
    information(3 + k, 3 + k) = 1.0 / (scene.odometry_sigma_rad * scene.odometry_sigma_rad);
  }
  return information;
}

/// The carat problem; its full cost is the yardstick for every method.
carat::Problem carat_problem(const camera_scene::Scene& scene,
                             const std::vector<Eigen::Isometry3d>& poses) {
  carat::Problem problem;
  std::vector<carat::VariableId> ids;
  for (const auto& T : poses) ids.push_back(problem.add_se3(T));
  for (std::size_t k = 0; k < ids.size(); ++k) {
    problem.add_residual_block(carat::make_autodiff_block<2, carat::Se3Variable>(
                                   camera_scene::Reprojection{}, scene.observations[k]),
                               {ids[k]});
  }
  const carat::se3::Matrix6d information = odometry_information(scene);
  for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
    problem.add_residual_block(
        std::make_shared<carat::RelativePoseBlock>(scene.odometry[k], information),
        {ids[k], ids[k + 1]});
  }
  return problem;
}

std::vector<Eigen::Isometry3d> poses_of(const carat::Problem& problem) {
  std::vector<Eigen::Isometry3d> out;
  for (int v = 0; v < problem.num_variables(); ++v)
    out.push_back(problem.se3(carat::VariableId{v}));
  return out;
}

nlohmann::json judge(const camera_scene::Scene& scene, const std::vector<Eigen::Isometry3d>& poses,
                     double seconds, int iterations) {
  const carat::Problem full = carat_problem(scene, poses);
  double t2 = 0.0, a2 = 0.0;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const carat::se3::Vector6d e =
        carat::se3::log(scene.T_world_camera_truth[k].inverse() * poses[k]);
    a2 += e.head<3>().squaredNorm();
    t2 += e.tail<3>().squaredNorm();
  }
  return {{"full_cost", carat::evaluate_problem(full).cost},
          {"time_s", seconds},
          {"iterations", iterations},
          {"translation_rmse_m", std::sqrt(t2 / static_cast<double>(poses.size()))},
          {"rotation_rmse_deg", std::sqrt(a2 / static_cast<double>(poses.size())) * 180.0 / M_PI}};
}

nlohmann::json run_ceres(const camera_scene::Scene& scene) {
  std::vector<std::array<double, 7>> poses(scene.T_world_camera_start.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    carat::se3::to_storage(scene.T_world_camera_start[k], poses[k].data());
  }
  ceres::Problem problem;
  using PoseManifold =
      ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>;
  for (auto& pose : poses) problem.AddParameterBlock(pose.data(), 7, new PoseManifold);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    for (const auto& o : scene.observations[k]) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<CeresReprojection, 2, 7>(new CeresReprojection(o)),
          nullptr, poses[k].data());
    }
  }
  const Eigen::Matrix<double, 6, 6> sqrt_information =
      odometry_information(scene).llt().matrixU();  // the same whitening as RelativePoseBlock
  for (std::size_t k = 0; k + 1 < poses.size(); ++k) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CeresRelativePose, 6, 7, 7>(
                                 new CeresRelativePose(scene.odometry[k], sqrt_information)),
                             nullptr, poses[k].data(), poses[k + 1].data());
  }
  ceres::Solver::Options options;
  options.num_threads = 1;
  options.max_num_iterations = 100;
  ceres::Solver::Summary summary;
  const carat::Stopwatch stopwatch;
  ceres::Solve(options, &problem, &summary);
  const double seconds = stopwatch.elapsed_s();
  std::vector<Eigen::Isometry3d> out;
  for (const auto& pose : poses) out.push_back(carat::se3::from_storage(pose.data()));
  nlohmann::json j = judge(scene, out, seconds, static_cast<int>(summary.iterations.size()) - 1);
  j["own_final_cost"] = summary.final_cost;
  j["linear_solver"] = ceres::LinearSolverTypeToString(summary.linear_solver_type_used);
  return j;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  int frames = 20, matches = 3000, repeat = 1;
  for (int k = 1; k + 1 < argc; k += 2) {
    if (std::strcmp(argv[k], "--frames") == 0) frames = std::atoi(argv[k + 1]);
    if (std::strcmp(argv[k], "--matches") == 0) matches = std::atoi(argv[k + 1]);
    if (std::strcmp(argv[k], "--repeat") == 0) repeat = std::atoi(argv[k + 1]);
  }
  const camera_scene::Scene scene = camera_scene::make_scene(frames, matches);
  carat::SolverOptions options;
  options.num_threads = 1;
  options.max_iterations = 100;
  for (int r = 0; r < repeat; ++r) {
    nlohmann::json out;
    out["frames"] = frames;
    out["matches_per_frame"] = matches;
    out["ceres"] = run_ceres(scene);
    {
      carat::Problem problem = carat_problem(scene, scene.T_world_camera_start);
      const carat::Stopwatch stopwatch;
      const carat::SolverSummary s = carat::solve(options, problem);
      out["carat_full"] = judge(scene, poses_of(problem), stopwatch.elapsed_s(), s.num_iterations);
    }
    {
      carat::Problem problem = carat_problem(scene, scene.T_world_camera_start);
      const carat::Stopwatch stopwatch;
      carat::compress_problem(problem);
      const carat::SolverSummary s = carat::solve(options, problem);
      out["carat_compressed"] =
          judge(scene, poses_of(problem), stopwatch.elapsed_s(), s.num_iterations);
    }
    {
      carat::Problem problem = carat_problem(scene, scene.T_world_camera_start);
      carat::RecompressedSolveOptions recompressed;
      recompressed.inner = options;
      const carat::Stopwatch stopwatch;
      const carat::RecompressedSolveSummary s = carat::solve_recompressed(problem, recompressed);
      out["carat_recompressed"] =
          judge(scene, poses_of(problem), stopwatch.elapsed_s(), s.inner_iterations);
      out["carat_recompressed"]["recompressions"] = s.recompressions;
    }
    const double ceres_time = out["ceres"]["time_s"];
    const double ceres_cost = out["ceres"]["full_cost"];
    for (const char* method : {"carat_full", "carat_compressed", "carat_recompressed"}) {
      out[method]["time_vs_ceres"] = out[method]["time_s"].get<double>() / ceres_time;
      out[method]["cost_vs_ceres"] = out[method]["full_cost"].get<double>() / ceres_cost - 1.0;
    }
    std::printf("%s\n", out.dump(2).c_str());
  }
  return 0;
}
