// Solves the public 3D and 2D pose graphs in ../shared/data/posegraph with carat (LM, 1 thread)
// and the synthetic city-block graph (always available). Real files are skipped when absent;
// cubicle's indefinite information matrices are repaired (nearest positive definite).
//
//   ./build/bench/posegraph_bench [--benchmark_filter=sphere]
// Counters: final_cost, iterations, numeric_s (factorization time per solve), factor_nnz.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <string>
#include <variant>

#include "carat/base/blas_kernels.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/sim/pose_graph.hpp"
#include "carat/solver/solve.hpp"

namespace {

template <typename Graph>
void solve_graph(benchmark::State& state, const Graph& graph, carat::Ordering ordering) {
  carat::SolverSummary summary;
  for (auto _ : state) {
    state.PauseTiming();
    carat::PoseGraphProblem built = carat::build_pose_graph_problem(graph);
    carat::SolverOptions options;
    options.max_iterations = 200;
    options.ordering = ordering;
    state.ResumeTiming();
    summary = carat::solve(options, built.problem);
  }
  state.counters["final_cost"] = summary.final_cost;
  state.counters["iterations"] = summary.num_iterations;
  state.counters["numeric_s"] = summary.time.numeric_s;
  state.counters["factor_nnz"] = static_cast<double>(summary.factor_nonzeros);
}

void register_file(const std::string& name, const carat::G2oReadOptions& read_options = {}) {
  const std::filesystem::path path =
      std::filesystem::path(CARAT_DATA_DIR) / "posegraph" / (name + ".g2o");
  if (!std::filesystem::exists(path)) return;  // real data absent: skip cleanly
  const auto graph = std::make_shared<carat::G2oGraph>(carat::read_g2o_any(path, read_options));
  for (const auto& [label, ordering] :
       {std::pair{"auto", carat::Ordering::kAuto}, std::pair{"amd", carat::Ordering::kAmd},
        std::pair{"metis", carat::Ordering::kMetis}}) {
    benchmark::RegisterBenchmark(
        ("posegraph/" + name + "/" + label).c_str(),
        [graph, ordering = ordering](benchmark::State& state) {
          std::visit([&](const auto& g) { solve_graph(state, g, ordering); }, *graph);
        })
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  }
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  carat::SyntheticPoseGraphOptions options;
  options.poses_per_lap = 1000;
  const auto synthetic =
      std::make_shared<carat::PoseGraph>(carat::make_synthetic_pose_graph(options).graph);
  benchmark::RegisterBenchmark("posegraph/synthetic_city_2000/auto",
                               [synthetic](benchmark::State& state) {
                                 solve_graph(state, *synthetic, carat::Ordering::kAuto);
                               })
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  for (const char* name : {"sphere2500", "parking-garage", "torus3D", "intel", "manhattan"}) {
    register_file(name);
  }
  // cubicle.g2o carries indefinite information blocks (e.g. line 5753): solved with each
  // replaced by the nearest positive-definite matrix, as `solve-g2o --repair-information` does.
  carat::G2oReadOptions repair;
  repair.information = carat::InformationRepair::kNearest;
  register_file("cubicle", repair);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
