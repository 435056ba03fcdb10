// When a compressed solve beats solving the full problem, and when it does not: the same built
// problem solved by solve_recompressed() in each CompressionMode, every mode with the solver's
// default options (1 thread) and judged by its full-data cost against the optimum (a tight
// full solve):
//   BM_Solve/<problem>/0   kFull: the full problem, Levenberg-Marquardt (the reference);
//   BM_Solve/<problem>/1   kSurrogate (the default): a sampled start, then full iterations that
//                          switch to compressed solves where the model fails (the full optimum);
//   BM_Solve/<problem>/2   kRecompress: compress again at every result (the full optimum);
//   BM_Solve/<problem>/3   kOnce: one compression, solved (not the full optimum);
//   BM_Solve/<problem>/4   kAuto: the full solve, switching to kSurrogate in a long nonlinear
//                          stretch.
// Problems: 0 the curve fit y = exp(m x + c) (10^6 rows, 2 unknowns, from (0, 0)); 1 camera
// localization (20 frames x 3,000 matches, start 0.1 m / 1 degree off); 2 the same from 0.5 m /
// 5 degrees; 3 a dense LiDAR registration graph (synthetic world, 40 frames, full GICP factors,
// drift start); 4 camera calibration (examples/calibration: intrinsics shared by 100 views of
// 10,000 observations, one autodiff block per view with prepare(), no loss). Counters:
// compressed and full iterations, compressions, rows of the sampled start, cost_vs_optimum.
// Environment: CARAT_BENCH_EXACT_FORMS=0 samples blocks that have an exact form too;
// CARAT_BENCH_DRIFT=s scales problem 3's drift by s; CARAT_BENCH_VERBOSE=1 prints the stages.
//
//   ./build/bench/recompression_bench
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <utility>

#include "../examples/calibration/calibration_scene.hpp"
#include "../examples/camera_localization/camera_scene.hpp"
#include "../tests/curve_fit_problem.hpp"
#include "benchmark_main.hpp"
#include "carat/coreset/problem_compression.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "carat/sim/drift.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/solve.hpp"

namespace {

carat::Problem curve_problem() {
  const std::vector<Eigen::Vector2d> data = carat::test::curve_data(1000000, 1);
  carat::Problem problem;
  const carat::VariableId mc = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  problem.add_residual_block(
      carat::make_autodiff_block<1, carat::VariableSize<2>>(carat::test::ExpResidual{}, data),
      {mc});
  return problem;
}

carat::Problem camera_problem(double start_m, double start_deg) {
  const camera_scene::Scene scene = camera_scene::make_scene(20, 3000, start_m, start_deg);
  carat::Problem problem;
  std::vector<carat::VariableId> ids;
  for (const auto& T : scene.T_world_camera_start) ids.push_back(problem.add_se3(T));
  for (std::size_t k = 0; k < ids.size(); ++k) {
    problem.add_residual_block(carat::make_autodiff_block<2, carat::Se3Variable>(
                                   camera_scene::Reprojection{}, scene.observations[k]),
                               {ids[k]});
  }
  carat::se3::Matrix6d information = carat::se3::Matrix6d::Zero();
  for (int a = 0; a < 3; ++a) {
    information(a, a) = 1.0 / (scene.odometry_sigma_m * scene.odometry_sigma_m);
    information(3 + a, 3 + a) = 1.0 / (scene.odometry_sigma_rad * scene.odometry_sigma_rad);
  }
  for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
    problem.add_residual_block(
        std::make_shared<carat::RelativePoseBlock>(scene.odometry[k], information),
        {ids[k], ids[k + 1]});
  }
  return problem;
}

carat::Problem registration_problem() {
  carat::SyntheticWorldOptions world_options;
  world_options.seed = 7;
  const carat::SyntheticWorld world(world_options);
  carat::SyntheticTrajectoryOptions drive;
  drive.frames = 40;
  drive.laps = 2;
  const carat::SyntheticSequence sequence = carat::make_synthetic_sequence(world, drive);
  std::vector<std::shared_ptr<const carat::Frame>> frames;
  for (const auto& scan : sequence.scans) {
    frames.push_back(carat::preprocess_frame(scan, carat::PreprocessOptions{}, "frame"));
  }
  carat::DriftOptions drift;
  drift.seed = 3;
  // CARAT_BENCH_DRIFT=s scales the drift (4: 0.02 m / 0.1 degrees per frame, 4 full iterations).
  const char* scale = std::getenv("CARAT_BENCH_DRIFT");
  const double s = scale && *scale ? std::atof(scale) : 1.0;
  drift.translation_sigma = 0.005 * s;
  drift.rotation_sigma_deg = 0.03 * s;
  const auto initial = carat::apply_drift(sequence.T_world_frame, drift);
  carat::FrameStore store(std::move(frames));
  const auto pairs = carat::build_dense_graph(store, initial);
  carat::GlobalRegistrationOptions options;
  options.sampling = carat::ResidualSampling::kFull;
  return carat::build_registration_problem(store, pairs, initial, options).problem;
}

carat::Problem calibration_problem() {
  calibration_scene::SceneOptions options;
  options.views = 100;
  options.per_view = 10000;
  const calibration_scene::Scene scene = calibration_scene::make_scene(options);
  carat::Problem problem;
  const carat::VariableId K =
      problem.add_euclidean(Eigen::Map<const Eigen::VectorXd>(scene.K_start.data(), 6));
  for (std::size_t v = 0; v < scene.observations.size(); ++v) {
    problem.add_residual_block(
        carat::make_autodiff_block<2, carat::VariableSize<6>, carat::Se3Variable>(
            calibration_scene::PreparedReprojection{}, scene.observations[v]),
        {K, problem.add_se3(scene.T_world_camera_start[v])});
  }
  return problem;
}

const carat::Problem& problem(int which) {
  static const carat::Problem curve = curve_problem();
  static const carat::Problem camera = camera_problem(0.1, 1.0);
  static const carat::Problem camera_far = camera_problem(0.5, 5.0);
  static const carat::Problem registration = registration_problem();
  static const carat::Problem calibration = calibration_problem();
  switch (which) {
    case 0:
      return curve;
    case 1:
      return camera;
    case 2:
      return camera_far;
    case 3:
      return registration;
    default:
      return calibration;
  }
}

carat::SolverOptions tight() {
  carat::SolverOptions options;
  options.function_tolerance = 1e-12;
  options.gradient_tolerance = 1e-10;
  options.max_iterations = 200;
  return options;
}

/// The full optimum's cost, once per problem.
double optimum(int which) {
  static std::array<double, 5> costs{-1.0, -1.0, -1.0, -1.0, -1.0};
  auto& c = costs[static_cast<std::size_t>(which)];
  if (c < 0.0) {
    carat::Problem p = problem(which);
    carat::solve(tight(), p);
    c = carat::evaluate_problem(p).cost;
  }
  return c;
}

void BM_Solve(benchmark::State& state) {
  const int which = static_cast<int>(state.range(0));
  constexpr carat::CompressionMode kModes[] = {
      carat::CompressionMode::kFull, carat::CompressionMode::kSurrogate,
      carat::CompressionMode::kRecompress, carat::CompressionMode::kOnce,
      carat::CompressionMode::kAuto};
  const double best = optimum(which);
  carat::RecompressedSolveSummary s;
  for (auto _ : state) {
    carat::Problem p = problem(which);  // shares the blocks: a cheap copy of values
    carat::RecompressedSolveOptions options;
    options.mode = kModes[state.range(1)];
    if (const char* m = std::getenv("CARAT_BENCH_M")) {
      options.compression.compression.target_rows = std::atoi(m);
    }
    if (const char* e = std::getenv("CARAT_BENCH_EXACT_FORMS"); e && *e == '0') {
      options.exact_forms = false;
    }
    s = carat::solve_recompressed(p, options);
  }
  if (std::getenv("CARAT_BENCH_VERBOSE") && state.range(1) == 0) {
    carat::Problem p = problem(which);
    const carat::SolverSummary full = carat::solve(carat::SolverOptions{}, p);
    for (const auto& row : full.iterations) {
      std::fprintf(stderr, "  full iteration %d: cost %.12g (%.3e over the optimum), ratio %.3f\n",
                   row.iteration, row.cost, row.cost / best - 1.0, row.relative_decrease);
    }
  }
  if (std::getenv("CARAT_BENCH_VERBOSE")) {
    std::fprintf(
        stderr, "%s\n  compress %.4f s, compressed solves %.4f s, full costs %.4f s, full %.4f s\n",
        s.brief_report().c_str(), s.compression_s, s.inner_solve_s, s.full_evaluation_s,
        s.full_solve_s);
    for (const auto& r : s.records) {
      std::fprintf(
          stderr, "  at %.12g: compressed -> %.12g, full after surrogate %.12g, after step %.12g\n",
          r.full_cost, r.compressed_final_cost, r.full_cost_after, r.full_cost_after_step);
    }
  }
  state.counters["compressed_iterations"] = s.inner_iterations;
  state.counters["full_iterations"] = s.full_iterations;
  state.counters["compressions"] = s.recompressions;
  state.counters["sampled_rows"] = static_cast<double>(s.sampled_rows);
  state.counters["cost_vs_optimum"] = s.final_cost / best - 1.0;
}

}  // namespace

BENCHMARK(BM_Solve)
    ->ArgsProduct({{0, 1, 2, 3, 4}, {0, 1, 2, 3, 4}})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

CARAT_BENCHMARK_MAIN()
