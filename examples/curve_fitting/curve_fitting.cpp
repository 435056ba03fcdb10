// Curve fitting, y = exp(m x + c), with a residual written once as a templated functor and
// differentiated automatically; the 10,000-row block solved three ways:
//   full          every row, Levenberg-Marquardt to convergence;
//   compressed    the block replaced by its 7-row exact coreset at the start, then solved: the
//                 coreset is exact only where it was built, so this stops near, not at, the
//                 optimum;
//   recompressed  compress, solve, judge on the full problem, compress again there, until the
//                 full problem's convergence tests hold: the full optimum.
// Prints a table, or one JSON object with --json; exits 1 if the recompressed solve misses the
// full optimum by more than 1e-9 (relative cost).
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "carat/base/stopwatch.hpp"
#include "carat/coreset/problem_compression.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/solve.hpp"

namespace {

/// One observation (x, y): residual y - exp(m x + c), written once for doubles and duals.
struct ExponentialResidual {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, T* residual) const {
    using std::exp;
    residual[0] = T(xy.y()) - exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};

std::vector<Eigen::Vector2d> observations(int n) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::vector<Eigen::Vector2d> data;
  for (int k = 0; k < n; ++k) {
    const double x = 5.0 * k / n;
    data.emplace_back(x, std::exp(0.3 * x + 0.1) + noise(rng));  // truth: m = 0.3, c = 0.1
  }
  return data;
}

carat::Problem make_problem(const std::vector<Eigen::Vector2d>& data) {
  carat::Problem problem;
  const carat::VariableId mc = problem.add_euclidean(Eigen::Vector2d(0.0, 0.0));
  problem.add_residual_block(
      carat::make_autodiff_block<1, carat::VariableSize<2>>(ExponentialResidual{}, data), {mc});
  return problem;
}

struct Result {
  std::string name;
  double m = 0.0, c = 0.0;
  double full_cost = 0.0;  // 1/2 sum of squares over all 10,000 rows at the estimate
  int iterations = 0;
  double time_s = 0.0;
  std::size_t rows = 0;  // rows the solve worked with
};

}  // namespace

int main(int argc, char** argv) {
  const bool json = argc > 1 && std::strcmp(argv[1], "--json") == 0;
  const std::vector<Eigen::Vector2d> data = observations(10000);
  carat::SolverOptions options;
  options.function_tolerance = 1e-15;
  options.gradient_tolerance = 1e-12;
  options.parameter_tolerance = 1e-14;
  options.max_iterations = 200;
  const auto estimate = [](const carat::Problem& p) {
    return Eigen::Vector2d(p.value(carat::VariableId{0})[0], p.value(carat::VariableId{0})[1]);
  };
  std::vector<Result> results;

  {  // full
    carat::Problem problem = make_problem(data);
    const carat::Stopwatch stopwatch;
    const carat::SolverSummary summary = carat::solve(options, problem);
    const double s = stopwatch.elapsed_s();
    results.push_back({"full", estimate(problem)[0], estimate(problem)[1],
                       carat::evaluate_problem(problem).cost, summary.num_iterations, s,
                       problem.num_residual_rows()});
  }
  {  // compressed once, at the start
    carat::Problem problem = make_problem(data);
    const carat::Stopwatch stopwatch;
    carat::compress_problem(problem);
    const carat::SolverSummary summary = carat::solve(options, problem);
    const double s = stopwatch.elapsed_s();
    carat::Problem judged = make_problem(data);  // the full rows, at the compressed estimate
    judged.set_all_values(problem.all_values());
    results.push_back({"compressed", estimate(problem)[0], estimate(problem)[1],
                       carat::evaluate_problem(judged).cost, summary.num_iterations, s,
                       problem.num_residual_rows()});
  }
  {  // recompressed until the full optimum
    carat::Problem problem = make_problem(data);
    carat::RecompressedSolveOptions recompressed;
    recompressed.inner = options;
    const carat::Stopwatch stopwatch;
    const carat::RecompressedSolveSummary summary =
        carat::solve_recompressed(problem, recompressed);
    const double s = stopwatch.elapsed_s();
    results.push_back(
        {"recompressed", estimate(problem)[0], estimate(problem)[1], summary.final_cost,
         summary.inner_iterations, s,
         // rows of the compressed problems, or of the sampled start's
         summary.compressed_rows > 0 ? summary.compressed_rows : summary.sampled_rows});
  }

  const double optimum = results[0].full_cost;
  const bool ok = std::abs(results[2].full_cost - optimum) <= 1e-9 * optimum;
  if (json) {
    std::printf("{\n  \"rows\": %zu,\n  \"methods\": {\n", data.size());
    for (std::size_t k = 0; k < results.size(); ++k) {
      const Result& r = results[k];
      std::printf(
          "    \"%s\": {\"m\": %.12g, \"c\": %.12g, \"full_cost\": %.15g, "
          "\"full_cost_vs_full\": %.6e, \"iterations\": %d, \"rows\": %zu, "
          "\"time_s\": %.6g}%s\n",
          r.name.c_str(), r.m, r.c, r.full_cost, r.full_cost / optimum - 1.0, r.iterations, r.rows,
          r.time_s, k + 1 < results.size() ? "," : "");
    }
    std::printf("  },\n  \"recompressed_reaches_the_full_optimum\": %s\n}\n",
                ok ? "true" : "false");
  } else {
    std::printf("y = exp(m x + c) over %zu observations (truth m = 0.3, c = 0.1)\n\n", data.size());
    std::printf("%-13s %10s %10s %16s %12s %6s %10s %8s\n", "method", "m", "c", "full cost",
                "vs full", "iters", "time [s]", "rows");
    for (const Result& r : results) {
      std::printf("%-13s %10.6f %10.6f %16.9f %+12.3e %6d %10.6f %8zu\n", r.name.c_str(), r.m, r.c,
                  r.full_cost, r.full_cost / optimum - 1.0, r.iterations, r.time_s, r.rows);
    }
    std::printf("\nrecompressed %s the full optimum\n", ok ? "reaches" : "MISSES");
  }
  return ok ? 0 : 1;
}
