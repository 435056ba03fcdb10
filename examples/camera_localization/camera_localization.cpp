// Camera localization against a fixed 3-D map: 20 frames, 3,000 2-D to 3-D matches each (one
// AutoDiffBlock per frame over its pose, 6,000 rows), odometry between consecutive frames
// (relative-pose blocks), a start 0.1 m / 1 degree off. A problem far from LiDAR whose blocks
// have thousands of rows over one pose each: the coreset keeps 29 rows per frame. Solved
//   full          every row;
//   compressed    each frame's block replaced by its 29-row coreset at the start, then solved;
//   recompressed  compressed again at each result until the full problem's tests hold.
// Prints a table, or one JSON object with --json (per method: full_cost, time_s, pose errors);
// exits 1 if the recompressed solve misses the full optimum by more than 1e-9 (relative cost).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "camera_scene.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/coreset/problem_compression.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/solve.hpp"

namespace {

carat::Problem make_problem(const camera_scene::Scene& scene, std::vector<carat::VariableId>* ids) {
  carat::Problem problem;
  ids->clear();
  for (const auto& T : scene.T_world_camera_start) ids->push_back(problem.add_se3(T));
  for (std::size_t k = 0; k < ids->size(); ++k) {
    problem.add_residual_block(carat::make_autodiff_block<2, carat::Se3Variable>(
                                   camera_scene::Reprojection{}, scene.observations[k]),
                               {(*ids)[k]});
  }
  // Translation rows first, as RelativePoseBlock (and g2o, and Ceres's pose_graph_3d) take them.
  carat::se3::Matrix6d information = carat::se3::Matrix6d::Zero();
  for (int a = 0; a < 3; ++a) {
    information(a, a) = 1.0 / (scene.odometry_sigma_m * scene.odometry_sigma_m);
    information(3 + a, 3 + a) = 1.0 / (scene.odometry_sigma_rad * scene.odometry_sigma_rad);
  }
  for (std::size_t k = 0; k + 1 < ids->size(); ++k) {
    problem.add_residual_block(
        std::make_shared<carat::RelativePoseBlock>(scene.odometry[k], information),
        {(*ids)[k], (*ids)[k + 1]});
  }
  return problem;
}

struct Result {
  std::string name;
  double full_cost = 0.0;
  double time_s = 0.0;
  int iterations = 0;
  std::size_t rows = 0;
  double translation_rmse_m = 0.0;
  double rotation_rmse_deg = 0.0;
};

void pose_errors(const carat::Problem& problem, const std::vector<carat::VariableId>& ids,
                 const camera_scene::Scene& scene, Result* r) {
  double t2 = 0.0, a2 = 0.0;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const carat::se3::Vector6d e =
        carat::se3::log(scene.T_world_camera_truth[k].inverse() * problem.se3(ids[k]));
    a2 += e.head<3>().squaredNorm();
    t2 += e.tail<3>().squaredNorm();
  }
  r->translation_rmse_m = std::sqrt(t2 / static_cast<double>(ids.size()));
  r->rotation_rmse_deg = std::sqrt(a2 / static_cast<double>(ids.size())) * 180.0 / M_PI;
}

}  // namespace

int main(int argc, char** argv) {
  const bool json = argc > 1 && std::strcmp(argv[1], "--json") == 0;
  const camera_scene::Scene scene = camera_scene::make_scene();
  carat::SolverOptions options;
  options.function_tolerance = 1e-12;
  options.gradient_tolerance = 1e-10;
  options.max_iterations = 100;
  std::vector<carat::VariableId> ids;
  std::vector<Result> results;
  {
    carat::Problem problem = make_problem(scene, &ids);
    const carat::Stopwatch stopwatch;
    const carat::SolverSummary s = carat::solve(options, problem);
    Result r{"full", carat::evaluate_problem(problem).cost, stopwatch.elapsed_s(), s.num_iterations,
             problem.num_residual_rows()};
    pose_errors(problem, ids, scene, &r);
    results.push_back(r);
  }
  {
    carat::Problem problem = make_problem(scene, &ids);
    const carat::Stopwatch stopwatch;
    carat::compress_problem(problem);
    const carat::SolverSummary s = carat::solve(options, problem);
    const double seconds = stopwatch.elapsed_s();
    carat::Problem judged = make_problem(scene, &ids);
    judged.set_all_values(problem.all_values());
    Result r{"compressed", carat::evaluate_problem(judged).cost, seconds, s.num_iterations,
             problem.num_residual_rows()};
    pose_errors(problem, ids, scene, &r);
    results.push_back(r);
  }
  {
    carat::Problem problem = make_problem(scene, &ids);
    carat::RecompressedSolveOptions recompressed;
    recompressed.inner = options;
    const carat::Stopwatch stopwatch;
    const carat::RecompressedSolveSummary s = carat::solve_recompressed(problem, recompressed);
    // Rows of the compressed problems, or of the sampled start's.
    Result r{"recompressed", s.final_cost, stopwatch.elapsed_s(), s.inner_iterations,
             s.compressed_rows > 0 ? s.compressed_rows : s.sampled_rows};
    pose_errors(problem, ids, scene, &r);
    results.push_back(r);
  }
  const double optimum = results[0].full_cost;
  const bool ok = std::abs(results[2].full_cost - optimum) <= 1e-9 * optimum;
  if (json) {
    std::printf("{\n  \"frames\": %zu,\n  \"matches_per_frame\": %zu,\n  \"methods\": {\n",
                scene.observations.size(), scene.observations[0].size());
    for (std::size_t k = 0; k < results.size(); ++k) {
      const Result& r = results[k];
      std::printf(
          "    \"%s\": {\"full_cost\": %.15g, \"full_cost_vs_full\": %.6e, \"time_s\": "
          "%.6g, \"iterations\": %d, \"rows\": %zu, \"translation_rmse_m\": %.6g, "
          "\"rotation_rmse_deg\": %.6g}%s\n",
          r.name.c_str(), r.full_cost, r.full_cost / optimum - 1.0, r.time_s, r.iterations, r.rows,
          r.translation_rmse_m, r.rotation_rmse_deg, k + 1 < results.size() ? "," : "");
    }
    std::printf("  },\n  \"recompressed_reaches_the_full_optimum\": %s\n}\n",
                ok ? "true" : "false");
  } else {
    std::printf("camera localization: %zu frames, %zu matches each, odometry between them\n\n",
                scene.observations.size(), scene.observations[0].size());
    std::printf("%-13s %16s %12s %10s %6s %8s %12s %12s\n", "method", "full cost", "vs full",
                "time [s]", "iters", "rows", "trans [m]", "rot [deg]");
    for (const Result& r : results) {
      std::printf("%-13s %16.6f %+12.3e %10.4f %6d %8zu %12.3e %12.3e\n", r.name.c_str(),
                  r.full_cost, r.full_cost / optimum - 1.0, r.time_s, r.iterations, r.rows,
                  r.translation_rmse_m, r.rotation_rmse_deg);
    }
    std::printf("\nrecompressed %s the full optimum\n", ok ? "reaches" : "MISSES");
  }
  return ok ? 0 : 1;
}
