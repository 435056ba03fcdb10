// A pose graph: a vehicle drives a city block twice; odometry and loop-closure edges with noise,
// the drifting odometry as the start (or a g2o file given as the first argument). Builds the
// problem from the graph (the first vertex held constant), solves it with Levenberg-Marquardt on
// CHOLMOD and prints the iteration table, or one JSON object with --json. Exits 1 unless the solve
// converges and (for the synthetic graph) the positions end closer to the truth than the start.
#include "carat/residuals/pose_graph.hpp"

#include <cstdio>
#include <cstring>
#include <memory>
#include <string>

#include "carat/base/error.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/sim/pose_graph.hpp"
#include "carat/solver/solve.hpp"

int main(int argc, char** argv) {
  bool json = false;
  std::string file;
  for (int k = 1; k < argc; ++k) {
    if (std::strcmp(argv[k], "--json") == 0) {
      json = true;
    } else {
      file = argv[k];
    }
  }
  try {
    carat::SyntheticPoseGraph synthetic;
    carat::PoseGraph graph;
    if (file.empty()) {
      synthetic = carat::make_synthetic_pose_graph();
      graph = synthetic.graph;
    } else {
      graph = carat::read_g2o(file);
    }
    const double start_rmse =
        file.empty() ? carat::position_rmse(graph, synthetic.T_world_truth) : 0.0;
    carat::PoseGraphProblem built = carat::build_pose_graph_problem(graph);
    const carat::SolverSummary summary = carat::solve(carat::SolverOptions{}, built.problem);
    carat::update_vertices(built, &graph);
    const double end_rmse =
        file.empty() ? carat::position_rmse(graph, synthetic.T_world_truth) : 0.0;
    const bool ok = summary.termination == carat::TerminationType::kConvergence &&
                    summary.final_cost < summary.initial_cost &&
                    (!file.empty() || end_rmse < start_rmse);
    if (json) {
      std::printf(
          "{\n  \"vertices\": %zu,\n  \"edges\": %zu,\n  \"initial_cost\": %.9g,\n"
          "  \"final_cost\": %.9g,\n  \"iterations\": %d,\n  \"termination\": \"%s\",\n"
          "  \"time_s\": %.6f,\n  \"start_position_rmse_m\": %.6f,\n"
          "  \"final_position_rmse_m\": %.6f,\n  \"ok\": %s\n}\n",
          graph.vertices.size(), graph.edges.size(), summary.initial_cost, summary.final_cost,
          summary.num_iterations, carat::to_string(summary.termination), summary.time.total_s,
          start_rmse, end_rmse, ok ? "true" : "false");
    } else {
      std::printf("%zu vertices, %zu edges\n\n%s\n%s\n", graph.vertices.size(), graph.edges.size(),
                  summary.full_report().c_str(), summary.brief_report().c_str());
      if (file.empty()) {
        std::printf("position RMSE against the truth: %.4f m at the start, %.4f m solved\n",
                    start_rmse, end_rmse);
      }
      std::printf("%s\n", ok ? "ok" : "FAILED");
    }
    return ok ? 0 : 1;
  } catch (const carat::Error& e) {
    std::fprintf(stderr, "pose_graph: %s\n", e.what());
    return 1;
  }
}
