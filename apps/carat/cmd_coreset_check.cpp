// carat coreset-check --rows N --target M [--clusters K] [--dim D] [--trials T] [--seed S]
//                     [--scale X] [--json]
// The paper's numerical validation (Sec. IV-A): random J (N x D) and e, T trials; exactness of
// the coreset against the full rows, its time, and the time of forming H, b, c once with Eigen
// (J^T J, J^T e, e^T e) on the same data in the same run.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/base/statistics.hpp"
#include "carat/coreset/quadratic_model.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/coreset/row_coreset_cost.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "coreset_timing.hpp"

namespace carat::cli {
namespace {

struct CoresetCheckArgs {
  long rows = 30000;
  int target = 0;
  int clusters = 0;
  int dim = 6;
  int trials = 10;
  std::uint64_t seed = 1;
  double scale = 1.0;
  bool inexact_size = false;
  bool json = false;
};

/// Floating-point operations per second assumed for the work estimate (a conservative core).
constexpr double kOperationsPerSecond = 2e9;

/// Refuses, before any work, option combinations the coreset cannot take and sizes this machine
/// cannot hold.
void check_options(const CoresetCheckArgs& args) {
  const int lifted = (args.dim + 1) * (args.dim + 2) / 2;  // L = D(D+1)/2 + D + 1
  const int minimum = minimum_coreset_rows(args.dim);
  if (args.target != 0 && args.target < minimum) {
    throw UsageError("--target " + std::to_string(args.target) + " is below the minimum of " +
                     std::to_string(minimum) + " rows for --dim " + std::to_string(args.dim) +
                     " (D(D+1)/2 + D + 2; 0 selects it)");
  }
  if (args.clusters != 0 && args.clusters < lifted + 2) {
    throw UsageError("--clusters " + std::to_string(args.clusters) + " is too few for --dim " +
                     std::to_string(args.dim) + ": at least " + std::to_string(lifted + 2) +
                     " clusters are needed (D(D+1)/2 + D + 3; 0 selects the default " +
                     std::to_string(default_coreset_clusters(args.dim)) + ")");
  }
  // J twice (row-major, and the column-major copy of the reference), e, and what the coreset
  // holds: its chunk sums, the rows it lifts (L numbers each) and its eliminations' tableaus.
  RowCoresetOptions options;
  options.target_rows = args.target;
  options.clusters = args.clusters;
  const RowCoresetCost cost = estimate_row_coreset(args.rows, args.dim, options);
  const double bytes = static_cast<double>(args.rows) * (16.0 * args.dim + 32.0) + cost.bytes;
  const double available = static_cast<double>(available_memory_bytes());
  if (bytes > 0.8 * available) {
    throw UsageError("--rows " + std::to_string(args.rows) + " --dim " + std::to_string(args.dim) +
                     " needs about " + format_bytes(bytes) + " of memory (J twice and e, and the " +
                     "coreset's scratch: " + std::to_string(cost.lifted_rows) + " rows lifted to " +
                     std::to_string(cost.lifted_dim) + " numbers each); " +
                     format_bytes(available) + " are available");
  }
  // The work: each level eliminates in a K-point set of dimension L (about K L^2 operations).
  const double seconds = static_cast<double>(args.trials) * cost.operations / kOperationsPerSecond;
  if (seconds > 600.0) {
    char minutes[32];
    std::snprintf(minutes, sizeof(minutes), "%.0f", seconds / 60.0);
    throw UsageError("--rows " + std::to_string(args.rows) + " --dim " + std::to_string(args.dim) +
                     " --clusters " + std::to_string(cost.clusters) + " --trials " +
                     std::to_string(args.trials) + " would take about " + minutes + " minutes (" +
                     std::to_string(static_cast<long>(cost.levels)) +
                     " levels per trial, each an elimination of " + std::to_string(cost.clusters) +
                     " points in " + std::to_string(lifted) +
                     " dimensions); use more --clusters (e.g. " + std::to_string(2 * (lifted + 1)) +
                     "), fewer rows or a smaller --dim");
  }
}

int run_coreset_check(const CoresetCheckArgs& args) {
  check_options(args);
  RowCoresetOptions options;
  options.target_rows = args.target;
  options.clusters = args.clusters;
  options.exact_size = !args.inexact_size;
  RandomRowSource source(args.seed, args.scale);
  std::vector<double> times, reference_times;
  QuadraticModelError worst;
  long rows_min = args.rows, rows_max = 0;
  RowMajorMatrix J;
  Eigen::VectorXd e;
  for (int t = 0; t < args.trials; ++t) {
    source.draw(args.rows, args.dim, &J, &e);
    options.seed = args.seed + static_cast<std::uint64_t>(t);
    const CoresetTrial trial = time_coreset_trial(J, e, {&options, 1}, t);
    times.push_back(trial.coreset_ms[0]);
    reference_times.push_back(trial.reference_ms);
    const RowCoreset& coreset = trial.coresets[0];
    const QuadraticModelError err =
        relative_error(quadratic_model(J, e), quadratic_model(J, e, coreset.rows, coreset.weights));
    worst.H = std::max(worst.H, err.H);
    worst.b = std::max(worst.b, err.b);
    worst.c = std::max(worst.c, err.c);
    rows_min = std::min<long>(rows_min, static_cast<long>(coreset.rows.size()));
    rows_max = std::max<long>(rows_max, static_cast<long>(coreset.rows.size()));
  }
  const double ms = median(times);
  const double reference_ms = median(reference_times);
  const int target = args.target == 0 ? minimum_coreset_rows(args.dim) : args.target;
  const int clusters = args.clusters == 0 ? default_coreset_clusters(args.dim) : args.clusters;
  if (args.json) {
    nlohmann::json j;
    j["rows"] = args.rows;
    j["dim"] = args.dim;
    j["target"] = target;
    j["clusters"] = clusters;
    j["trials"] = args.trials;
    j["seed"] = args.seed;
    j["scale"] = args.scale;
    j["exact_size"] = !args.inexact_size;
    j["rows_out_min"] = rows_min;
    j["rows_out_max"] = rows_max;
    j["max_rel_error_H"] = worst.H;
    j["max_rel_error_b"] = worst.b;
    j["max_rel_error_c"] = worst.c;
    j["median_ms"] = ms;
    j["reference_median_ms"] = reference_ms;
    j["ratio_to_reference"] = ms / reference_ms;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("coreset of %ld x %d rows -> target %d (K = %d), %d trials\n", args.rows, args.dim,
                target, clusters, args.trials);
    std::printf("  rows out           %ld .. %ld\n", rows_min, rows_max);
    std::printf("  max rel. error     H %.3e   b %.3e   c %.3e\n", worst.H, worst.b, worst.c);
    std::printf("  median time        %.3f ms (Eigen H, b, c once: %.3f ms; ratio %.2f)\n", ms,
                reference_ms, ms / reference_ms);
  }
  return 0;
}

}  // namespace

void register_coreset_check(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<CoresetCheckArgs>();
  CLI::App* cmd = app.add_subcommand("coreset-check",
                                     "Check exactness and speed of the coreset on random rows");
  cmd->add_option("--rows", args->rows, "rows N")
      ->check(integer_in(1, 100000000))
      ->capture_default_str();
  cmd->add_option("--target", args->target, "target rows M (0: the minimum, D(D+1)/2 + D + 2)")
      ->check(integer_in(0, 100000000))
      ->capture_default_str();
  cmd->add_option("--clusters", args->clusters,
                  "clusters K per level (0: the default max(64, 2 (L + 1)), L = D(D+1)/2 + D + 1)")
      ->check(integer_in(0, 100000))
      ->capture_default_str();
  cmd->add_option("--dim", args->dim, "Jacobian columns D")
      ->check(integer_in(1, 64))
      ->capture_default_str();
  cmd->add_option("--trials", args->trials, "random trials")
      ->check(integer_in(1, 100000))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "random seed")->check(seed_value())->capture_default_str();
  cmd->add_option("--scale", args->scale, "scale of the random data")
      ->check(real_in(1e-100, 1e100))
      ->capture_default_str();
  cmd->add_flag("--inexact-size", args->inexact_size, "allow fewer than --target rows");
  cmd->add_flag("--json", args->json, "print one JSON object");
  registry.add(cmd, [args] { return run_coreset_check(*args); });
}

}  // namespace carat::cli
