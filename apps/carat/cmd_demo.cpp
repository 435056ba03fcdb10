// carat demo: builds a synthetic city-block pose graph (driven twice, noisy odometry and loop
// closures), optimizes it and reports the solve and the trajectory error before and after.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/synthetic_pose_graph.hpp"
#include "carat/solver/error.hpp"
#include "carat/solver/solve.hpp"
#include "commands.hpp"

namespace carat::cli {
namespace {

struct DemoArgs {
  int frames = 400;
  std::uint64_t seed = 1;
  int threads = 2;
  bool json = false;
};

int run_demo(const DemoArgs& args) {
  SyntheticPoseGraphOptions world;
  world.laps = 2;
  world.poses_per_lap = std::max(8, args.frames / world.laps);
  world.seed = args.seed;
  SyntheticPoseGraph synthetic = make_synthetic_pose_graph(world);
  const double rmse_before = position_rmse(synthetic.graph, synthetic.T_world_truth);

  PoseGraphProblem built = build_pose_graph_problem(synthetic.graph);
  SolverOptions options;
  options.num_threads = args.threads;
  options.max_iterations = 100;
  const SolverSummary summary = solve(options, built.problem);
  if (summary.termination == TerminationType::kFailure) {
    throw Error("demo: the solve failed: " + summary.message);
  }
  update_vertices(built, &synthetic.graph);
  const double rmse_after = position_rmse(synthetic.graph, synthetic.T_world_truth);

  if (args.json) {
    nlohmann::json j;
    j["frames"] = synthetic.graph.vertices.size();
    j["factors"] = synthetic.graph.edges.size();
    j["seed"] = args.seed;
    j["position_rmse_initial_m"] = rmse_before;
    j["position_rmse_final_m"] = rmse_after;
    j["solver"] = nlohmann::json::parse(summary.to_json());
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("carat demo: synthetic city-block pose graph, %d laps, seed %llu\n", world.laps,
              static_cast<unsigned long long>(args.seed));
  std::printf("  %zu poses, %zu relative-pose factors (odometry + loop closures)\n\n",
              synthetic.graph.vertices.size(), synthetic.graph.edges.size());
  std::printf("%s\n", summary.full_report().c_str());
  std::printf("Trajectory error against ground truth (position RMSE)\n");
  std::printf("  odometry (initial guess)   %9.4f m\n", rmse_before);
  std::printf("  optimized                  %9.4f m\n", rmse_after);
  return 0;
}

}  // namespace

void register_demo(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand("demo", "Run the main job on the built-in synthetic world");
  cmd->add_option("--frames", args->frames, "number of poses")
      ->check(CLI::Range(16, 1000000))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "random seed")->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args] { return run_demo(*args); });
}

}  // namespace carat::cli
