// The C++ reference of examples/python/curve_fit_vs_scipy.py: the curve fit y = exp(m x + c)
// over the observations of a file, as one AutoDiffBlock of a row per observation, solved from
// (m, c) = (0, 0) with the tolerances given (the Python example passes its own). Prints one JSON
// object: the wall seconds of building the problem plus solving it (best of --repeat runs), the
// solver's own seconds, the final cost, iterations and (m, c). --mode: 'full' (carat::solve) or
// a carat::CompressionMode of solve_recompressed ('auto', 'surrogate', ...).
//
//   curve_fit_autodiff DATA [--mode M] [--repeat N] [--function-tolerance F]
//                           [--gradient-tolerance G] [--parameter-tolerance P]
//
// DATA holds n pairs (x, y) as little-endian float64, x0 y0 x1 y1 ...
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/coreset/compressed_solve.hpp"
#include "carat/solver/autodiff_block.hpp"
#include "carat/solver/solve.hpp"

namespace {

/// One observation (x, y): residual y - exp(m x + c).
struct ExponentialResidual {
  template <typename T>
  bool operator()(const Eigen::Vector2d& xy, const T* mc, T* residual) const {
    using std::exp;
    residual[0] = T(xy.y()) - exp(mc[0] * xy.x() + mc[1]);
    return true;
  }
};

int usage(const char* message) {
  std::fprintf(stderr, "curve_fit_autodiff: %s\n", message);
  std::fprintf(stderr,
               "usage: curve_fit_autodiff DATA [--mode M] [--repeat N] [--function-tolerance F] "
               "[--gradient-tolerance G] [--parameter-tolerance P]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  if (argc < 2) return usage("missing DATA");
  int repeat = 1;
  std::string mode = "full";
  carat::SolverOptions options;
  options.max_iterations = 200;
  for (int k = 2; k < argc; ++k) {
    const std::string flag = argv[k];
    if (k + 1 >= argc) return usage(("missing the value of " + flag).c_str());
    const char* value = argv[++k];
    if (flag == "--mode") {
      mode = value;
    } else if (flag == "--repeat") {
      repeat = std::max(1, std::atoi(value));
    } else if (flag == "--function-tolerance") {
      options.function_tolerance = std::atof(value);
    } else if (flag == "--gradient-tolerance") {
      options.gradient_tolerance = std::atof(value);
    } else if (flag == "--parameter-tolerance") {
      options.parameter_tolerance = std::atof(value);
    } else {
      return usage(("unknown option " + flag).c_str());
    }
  }
  carat::RecompressedSolveOptions compressed;
  if (mode != "full") {
    try {
      compressed.mode = carat::parse_compression_mode(mode);
    } catch (const carat::Error& e) {
      return usage(e.what());
    }
  }
  std::ifstream in(argv[1], std::ios::binary | std::ios::ate);
  if (!in) return usage("cannot read DATA");
  const auto bytes = static_cast<std::size_t>(in.tellg());
  if (bytes == 0 || bytes % (2 * sizeof(double)) != 0) {
    return usage("DATA is not a whole number of (x, y) float64 pairs");
  }
  std::vector<Eigen::Vector2d> data(bytes / (2 * sizeof(double)));
  in.seekg(0);
  in.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(bytes));

  double best_s = 1e300;
  double solve_s = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
  carat::TerminationType termination = carat::TerminationType::kFailure;
  Eigen::Vector2d mc = Eigen::Vector2d::Zero();
  for (int run = 0; run < repeat; ++run) {
    const carat::Stopwatch time;
    carat::Problem problem;
    const carat::VariableId v = problem.add_euclidean(Eigen::Vector2d::Zero());
    problem.add_residual_block(
        carat::make_autodiff_block<1, carat::VariableSize<2>>(ExponentialResidual{}, data), {v});
    if (mode == "full") {
      const carat::SolverSummary summary = carat::solve(options, problem);
      solve_s = summary.time.total_s;
      final_cost = summary.final_cost;
      iterations = summary.num_iterations;
      termination = summary.termination;
    } else {
      compressed.inner = options;
      compressed.function_tolerance = options.function_tolerance;
      compressed.gradient_tolerance = options.gradient_tolerance;
      const carat::RecompressedSolveSummary summary =
          carat::solve_recompressed(problem, compressed);
      solve_s = summary.total_s;
      final_cost = summary.final_cost;
      iterations = summary.inner_iterations + summary.full_iterations;
      termination = summary.termination;
    }
    best_s = std::min(best_s, time.elapsed_s());
    mc = Eigen::Map<const Eigen::Vector2d>(problem.value(v).data());
  }
  std::printf(
      "{\"rows\": %zu, \"time_s\": %.6f, \"solve_s\": %.6f, \"final_cost\": %.17g, "
      "\"iterations\": %d, \"termination\": \"%s\", \"m\": %.17g, \"c\": %.17g}\n",
      data.size(), best_s, solve_s, final_cost, iterations, carat::to_string(termination), mc.x(),
      mc.y());
  return termination == carat::TerminationType::kFailure ? 1 : 0;
}
