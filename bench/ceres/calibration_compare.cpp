// Side-by-side on a problem class carat does not ship: camera calibration against a 3-D rig
// (examples/calibration/calibration_scene.hpp: intrinsics [fx fy cx cy k1 k2] shared by every
// view, one SE(3) pose per view, thousands of two-row observations per view), a user's own
// templated functor in both solvers, 1 thread, solved in the same run by
//   ceres_per_view    Ceres 2.1 with carat's block layout: one AutoDiffCostFunction<.., DYNAMIC,
//                     6, 7> per view whose functor loops over the view's observations (the pose
//                     inverted once per call), pose block [qx qy qz qw tx ty tz] with
//                     ProductManifold<EigenQuaternionManifold, EuclideanManifold<3>>, default
//                     solver options (LM, SPARSE_NORMAL_CHOLESKY);
//   ceres_per_obs     Ceres's usual layout: one AutoDiffCostFunction<.., 2, 6, 7> per observation;
//   carat_full        one AutoDiffBlock per view, the functor as a new user writes it (the pose
//                     turned into a rotation for every observation), default options;
//   carat_prepared    the same functor with prepare() (the pose once per evaluation);
//   carat_compressed  carat_prepared's blocks compressed once, then solved (not the optimum);
//   carat_recompressed  solve_recompressed() with its default options (CompressionMode::
//                     kSurrogate: the full optimum);
//   carat_auto        solve_recompressed() with CompressionMode::kAuto.
// With --outliers S a share S of the observations is displaced by 15 px: Ceres gets a HuberLoss
// (1 px) per observation (ceres_per_obs only: a per-view cost function cannot weight single
// observations), carat a group loss per observation (with_group_loss()) in carat_prepared,
// carat_compressed and carat_recompressed.
// Every result is judged by the same full cost (1/2 sum rho, Ceres's convention, evaluated by
// carat on the full problem) and by its intrinsics' distance from the truth. A tight full solve
// (function tolerance 1e-12) gives the optimum's cost for `cost_vs_optimum`.
//
// Usage: calibration_compare [--views G] [--per-view N] [--outliers S] [--repeat R]
//        [--skip-per-obs] [--only TEXT]; one JSON object per repeat (--only: the methods whose
//        names contain TEXT).
#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "../../examples/calibration/calibration_scene.hpp"
#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/coreset/problem_compression.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/solve.hpp"

namespace {

using calibration_scene::Observation;
using calibration_scene::Scene;

/// One view's observations for Ceres: the pose inverted once per call, then every observation.
struct CeresViewReprojection {
  const std::vector<Observation>* observations;
  template <typename T>
  bool operator()(const T* K, const T* T_world_camera, T* residuals) const {
    const auto T_camera_world = carat::lie::Pose<T>::from_storage(T_world_camera).inverse();
    for (std::size_t k = 0; k < observations->size(); ++k) {
      if (!calibration_scene::project(K, T_camera_world, (*observations)[k], residuals + 2 * k)) {
        return false;
      }
    }
    return true;
  }
};

/// One observation for Ceres (its usual layout).
struct CeresObservationReprojection {
  Observation observation;
  template <typename T>
  bool operator()(const T* K, const T* T_world_camera, T* residuals) const {
    return calibration_scene::Reprojection{}(observation, K, T_world_camera, residuals);
  }
};

struct Options {
  calibration_scene::SceneOptions scene;
  int repeat = 1;
  bool per_obs = true;
  std::string only;  ///< run only the methods whose names contain this
};

/// The carat problem over `functor`; with `huber` > 0 each observation gets a HuberLoss.
template <typename Functor>
carat::Problem carat_problem(const Scene& scene, const calibration_scene::Intrinsics& K,
                             const std::vector<Eigen::Isometry3d>& poses, double huber) {
  carat::Problem problem;
  const carat::VariableId k = problem.add_euclidean(Eigen::Map<const Eigen::VectorXd>(K.data(), 6));
  for (std::size_t v = 0; v < poses.size(); ++v) {
    const carat::VariableId pose = problem.add_se3(poses[v]);
    auto block = carat::make_autodiff_block<2, carat::VariableSize<6>, carat::Se3Variable>(
        Functor{}, scene.observations[v], {}, "view " + std::to_string(v));
    if (huber > 0.0) {
      problem.add_residual_block(block->with_group_loss(std::make_shared<carat::HuberLoss>(huber)),
                                 {k, pose});
    } else {
      problem.add_residual_block(block, {k, pose});
    }
  }
  return problem;
}

calibration_scene::Intrinsics intrinsics_of(const carat::Problem& p) {
  calibration_scene::Intrinsics K{};
  const auto v = p.value(carat::VariableId{0});
  for (int i = 0; i < 6; ++i) K[static_cast<std::size_t>(i)] = v[static_cast<std::size_t>(i)];
  return K;
}

std::vector<Eigen::Isometry3d> poses_of(const carat::Problem& p) {
  std::vector<Eigen::Isometry3d> out;
  for (int v = 1; v < p.num_variables(); ++v) out.push_back(p.se3(carat::VariableId{v}));
  return out;
}

/// The judge: the full cost (with the loss when there is one) and the intrinsics' errors.
nlohmann::json judge(const Scene& scene, const calibration_scene::Intrinsics& K,
                     const std::vector<Eigen::Isometry3d>& poses, double huber, double seconds,
                     int iterations) {
  const carat::Problem full =
      carat_problem<calibration_scene::PreparedReprojection>(scene, K, poses, huber);
  const double dcx = K[2] - scene.K_truth[2], dcy = K[3] - scene.K_truth[3];
  return {{"full_cost", carat::evaluate_problem(full).cost},
          {"time_s", seconds},
          {"iterations", iterations},
          {"principal_point_error_px", std::hypot(dcx, dcy)},
          {"focal_error_px", std::hypot(K[0] - scene.K_truth[0], K[1] - scene.K_truth[1])},
          {"intrinsics", K}};
}

nlohmann::json run_ceres(const Scene& scene, bool per_view, double huber) {
  calibration_scene::Intrinsics K = scene.K_start;
  std::vector<std::array<double, 7>> poses(scene.T_world_camera_start.size());
  for (std::size_t v = 0; v < poses.size(); ++v) {
    carat::se3::to_storage(scene.T_world_camera_start[v], poses[v].data());
  }
  ceres::Problem problem;
  using PoseManifold =
      ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>;
  problem.AddParameterBlock(K.data(), 6);
  for (auto& pose : poses) problem.AddParameterBlock(pose.data(), 7, new PoseManifold);
  for (std::size_t v = 0; v < poses.size(); ++v) {
    const auto& observations = scene.observations[v];
    if (per_view) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<CeresViewReprojection, ceres::DYNAMIC, 6, 7>(
              new CeresViewReprojection{&observations}, static_cast<int>(2 * observations.size())),
          nullptr, K.data(), poses[v].data());
    } else {
      for (const auto& o : observations) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<CeresObservationReprojection, 2, 6, 7>(
                new CeresObservationReprojection{o}),
            huber > 0.0 ? new ceres::HuberLoss(huber) : nullptr, K.data(), poses[v].data());
      }
    }
  }
  ceres::Solver::Options options;
  options.num_threads = 1;
  options.max_num_iterations = 100;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  const carat::Stopwatch stopwatch;
  ceres::Solve(options, &problem, &summary);
  const double seconds = stopwatch.elapsed_s();
  std::vector<Eigen::Isometry3d> out;
  for (const auto& pose : poses) out.push_back(carat::se3::from_storage(pose.data()));
  nlohmann::json j =
      judge(scene, K, out, huber, seconds, static_cast<int>(summary.iterations.size()) - 1);
  j["own_final_cost"] = summary.final_cost;
  j["linear_solver"] = ceres::LinearSolverTypeToString(summary.linear_solver_type_used);
  j["residual_only_s"] = summary.residual_evaluation_time_in_seconds;
  j["jacobian_s"] = summary.jacobian_evaluation_time_in_seconds;
  j["linear_solver_s"] = summary.linear_solver_time_in_seconds;
  return j;
}

template <typename Functor>
nlohmann::json run_carat_full(const Scene& scene, double huber, const carat::SolverOptions& o) {
  carat::Problem p =
      carat_problem<Functor>(scene, scene.K_start, scene.T_world_camera_start, huber);
  const carat::Stopwatch stopwatch;
  const carat::SolverSummary s = carat::solve(o, p);
  nlohmann::json j =
      judge(scene, intrinsics_of(p), poses_of(p), huber, stopwatch.elapsed_s(), s.num_iterations);
  j["cost_s"] = s.time.cost_s;
  for (const auto& row : s.iterations) j["costs"].push_back(row.cost);
  j["linearize_s"] = s.time.linearize_s;
  return j;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  Options options;
  for (int k = 1; k < argc; ++k) {
    const std::string arg = argv[k];
    const bool has_value = k + 1 < argc;
    if (arg == "--views" && has_value) {
      options.scene.views = std::atoi(argv[++k]);
    } else if (arg == "--per-view" && has_value) {
      options.scene.per_view = std::atoi(argv[++k]);
    } else if (arg == "--outliers" && has_value) {
      options.scene.outlier_share = std::atof(argv[++k]);
    } else if (arg == "--repeat" && has_value) {
      options.repeat = std::atoi(argv[++k]);
    } else if (arg == "--only" && has_value) {
      options.only = argv[++k];
    } else if (arg == "--skip-per-obs") {
      options.per_obs = false;
    } else {
      std::fprintf(stderr,
                   "usage: calibration_compare [--views G] [--per-view N] [--outliers S] "
                   "[--repeat R] [--skip-per-obs] [--only TEXT]\n");
      return 2;
    }
  }
  const Scene scene = calibration_scene::make_scene(options.scene);
  const double huber = options.scene.outlier_share > 0.0 ? 1.0 : 0.0;
  carat::SolverOptions solver;
  solver.num_threads = 1;
  solver.max_iterations = 100;
  // The optimum, for cost_vs_optimum: a tight full solve.
  double optimum = 0.0;
  {
    carat::SolverOptions tight = solver;
    tight.function_tolerance = 1e-14;
    tight.gradient_tolerance = 1e-12;
    tight.parameter_tolerance = 1e-14;
    carat::Problem p = carat_problem<calibration_scene::PreparedReprojection>(
        scene, scene.K_start, scene.T_world_camera_start, huber);
    carat::solve(tight, p);
    optimum = carat::evaluate_problem(p).cost;
  }
  for (int r = 0; r < options.repeat; ++r) {
    nlohmann::json out;
    out["views"] = options.scene.views;
    out["per_view"] = options.scene.per_view;
    out["outlier_share"] = options.scene.outlier_share;
    out["optimum_cost"] = optimum;
    const auto wanted = [&](const char* name) {
      return std::string(name).find(options.only) != std::string::npos;
    };
    if (huber == 0.0 && wanted("ceres_per_view"))
      out["ceres_per_view"] = run_ceres(scene, true, 0.0);
    if (options.per_obs && wanted("ceres_per_obs")) {
      out["ceres_per_obs"] = run_ceres(scene, false, huber);
    }
    if (wanted("carat_full")) {
      out["carat_full"] = run_carat_full<calibration_scene::Reprojection>(scene, huber, solver);
    }
    if (wanted("carat_prepared")) {
      out["carat_prepared"] =
          run_carat_full<calibration_scene::PreparedReprojection>(scene, huber, solver);
    }
    if (wanted("carat_compressed")) {
      carat::Problem p = carat_problem<calibration_scene::PreparedReprojection>(
          scene, scene.K_start, scene.T_world_camera_start, huber);
      const carat::Stopwatch stopwatch;
      carat::compress_problem(p);
      const carat::SolverSummary s = carat::solve(solver, p);
      out["carat_compressed"] = judge(scene, intrinsics_of(p), poses_of(p), huber,
                                      stopwatch.elapsed_s(), s.num_iterations);
    }
    if (wanted("carat_auto")) {
      carat::Problem p = carat_problem<calibration_scene::PreparedReprojection>(
          scene, scene.K_start, scene.T_world_camera_start, huber);
      carat::RecompressedSolveOptions automatic;
      automatic.inner = solver;
      automatic.mode = carat::CompressionMode::kAuto;
      const carat::Stopwatch stopwatch;
      const carat::RecompressedSolveSummary s = carat::solve_recompressed(p, automatic);
      out["carat_auto"] = judge(scene, intrinsics_of(p), poses_of(p), huber, stopwatch.elapsed_s(),
                                s.full_iterations + s.inner_iterations);
      out["carat_auto"]["switched_to_compression"] = s.switched_to_compression;
    }
    if (wanted("carat_recompressed")) {
      carat::Problem p = carat_problem<calibration_scene::PreparedReprojection>(
          scene, scene.K_start, scene.T_world_camera_start, huber);
      carat::RecompressedSolveOptions recompressed;
      recompressed.inner = solver;
      const carat::Stopwatch stopwatch;
      const carat::RecompressedSolveSummary s = carat::solve_recompressed(p, recompressed);
      out["carat_recompressed"] = judge(scene, intrinsics_of(p), poses_of(p), huber,
                                        stopwatch.elapsed_s(), s.inner_iterations);
      out["carat_recompressed"]["recompressions"] = s.recompressions;
      for (const auto& record : s.records) {
        out["carat_recompressed"]["records"].push_back(
            {record.full_cost, record.full_gradient_max_norm, record.compressed_final_cost,
             record.inner_iterations});
      }
      out["carat_recompressed"]["split_s"] = {s.compression_s, s.inner_solve_s,
                                              s.full_evaluation_s};
      out["carat_recompressed"]["termination"] = carat::to_string(s.termination);
    }
    for (auto& [name, method] : out.items()) {
      if (!method.is_object() || !method.contains("full_cost")) continue;
      method["cost_vs_optimum"] = method["full_cost"].get<double>() / optimum - 1.0;
      for (const char* reference :
           {"ceres_per_view", "ceres_per_obs", "carat_full", "carat_prepared"}) {
        if (out.contains(reference)) {
          method[std::string("time_vs_") + reference] =
              method["time_s"].get<double>() / out[reference]["time_s"].get<double>();
        }
      }
    }
    std::printf("%s\n", out.dump(2).c_str());
  }
  return 0;
}
