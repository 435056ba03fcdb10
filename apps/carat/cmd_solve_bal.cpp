// carat solve-bal FILE [--out FILE] [--linear-solver auto|schur|cholesky] [--max-iterations N]
//                      [--threads T] [--loss none|huber|cauchy] [--loss-scale S]
//                      [--trust-region-growth G] [--no-factor-reuse] [--anderson-memory M]
//                      [--lm-start auto|gauss_newton|trust_region]
//                      [--covariance FILE [--covariance-gauge error|pseudo-inverse]] [--json]
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/io/bal_io.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/solve.hpp"
#include "carat/solver/solver_options.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "covariance_output.hpp"

namespace carat::cli {
namespace {

struct SolveBalArgs {
  std::string input;
  std::string output;
  std::string linear_solver = "auto";
  int max_iterations = 50;
  int threads = 1;
  std::string loss = "none";
  double loss_scale = 1.0;
  double trust_region_growth = SolverOptions{}.max_trust_region_growth;
  std::string lm_start = to_string(SolverOptions{}.lm_start);
  bool no_factor_reuse = false;
  int anderson_memory = SolverOptions{}.anderson_memory;
  std::string camera_steps = "centre";
  CovarianceRequest covariance;
  bool json = false;
};

int run_solve_bal(const CLI::App& command, const SolveBalArgs& args) {
  const Stopwatch total;
  const LossKind loss = parse_loss_kind(args.loss);
  refuse_unused(command, "--loss-scale", loss != LossKind::kNone, "to --loss none (set --loss)");
  if (!args.output.empty()) check_output_file("--out", args.output, {{"FILE", args.input}});
  check_covariance_request(command, args.covariance, {{"FILE", args.input}}, "--out", args.output);

  Stopwatch stage;
  BalProblem bal = read_bal(args.input);
  const double read_s = stage.elapsed_s();
  const std::size_t behind = count_points_behind_cameras(bal);

  stage.restart();
  Problem problem;
  const BalVariables variables =
      add_bal_problem(bal, &problem, make_loss(loss, args.loss_scale),
                      args.camera_steps == "centre" ? BalCameraTangent::kAboutCentre
                                                    : BalCameraTangent::kParameters);
  const double build_s = stage.elapsed_s();

  SolverOptions options;
  options.linear_solver = parse_linear_solver(args.linear_solver);
  options.max_iterations = args.max_iterations;
  options.num_threads = args.threads;
  options.max_trust_region_growth = args.trust_region_growth;
  options.reuse_factorization = !args.no_factor_reuse;
  options.anderson_memory = args.anderson_memory;
  options.lm_start = parse_lm_start(args.lm_start);
  const SolverSummary summary = solve(options, problem);
  if (summary.termination == TerminationType::kFailure) {
    throw Error(args.input + ": the solve failed: " + summary.message);
  }

  stage.restart();
  std::unique_ptr<OutputFile> out;
  if (!args.output.empty()) {
    update_bal_problem(problem, variables, &bal);
    out = std::make_unique<OutputFile>(args.output);
    write_bal(out->stream(), bal);
  }
  const double write_s = stage.elapsed_s();

  // The cameras' covariances (the points are eliminated: the reduced system's factor gives them).
  std::unique_ptr<OutputFile> covariance_out;
  double covariance_s = 0.0;
  int gauge_dimension = 0;
  CovarianceTimes covariance_times;
  if (!args.covariance.path.empty()) {
    stage.restart();
    Covariance::Options covariance_settings = covariance_options(args.covariance, args.threads);
    covariance_settings.linear_solver = options.linear_solver;
    const Covariance covariance = [&] {
      try {
        return Covariance(problem, covariance_settings);
      } catch (const Error& e) {
        throw Error(args.input + ": " + e.what());
      }
    }();
    gauge_dimension = covariance.gauge_dimension();
    covariance_times = covariance.time();
    covariance_out = std::make_unique<OutputFile>(args.covariance.path);
    for (std::size_t c = 0; c < variables.cameras.size(); ++c) {
      write_covariance_line(covariance_out->stream(), static_cast<std::int64_t>(c),
                            covariance.block(variables.cameras[c]));
    }
    covariance_s = stage.elapsed_s();
  }

  if (args.json) {
    nlohmann::json j = nlohmann::json::parse(summary.to_json());
    j["input"] = args.input;
    j["cameras"] = bal.cameras.size();
    j["points"] = bal.points.size();
    j["observations"] = bal.observations.size();
    j["points_behind_cameras"] = behind;
    j["camera_steps"] = args.camera_steps;
    j["solve_time_s"] = summary.time.total_s;
    j["time_breakdown"]["read_s"] = read_s;
    j["time_breakdown"]["build_s"] = build_s;
    j["time_breakdown"]["write_s"] = write_s;
    j["time_s"] = total.elapsed_s();
    if (!args.output.empty()) j["output"] = args.output;
    if (covariance_out) {
      j["covariance"] = args.covariance.path;
      j["covariance_s"] = covariance_s;
      j["covariance_gauge_dimension"] = gauge_dimension;
      j["covariance_breakdown"] = {{"linearize_s", covariance_times.linearize_s},
                                   {"factorize_s", covariance_times.factorize_s},
                                   {"inverse_s", covariance_times.inverse_s}};
    }
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("%s: %zu cameras, %zu points, %zu observations", args.input.c_str(),
                bal.cameras.size(), bal.points.size(), bal.observations.size());
    if (behind > 0) std::printf(" (%zu observations of points behind their camera)", behind);
    std::printf("\n\n%s\n%s\n", summary.full_report().c_str(), summary.brief_report().c_str());
    std::printf("read %.3f s, build %.3f s, solve %.3f s, total %.3f s\n", read_s, build_s,
                summary.time.total_s, total.elapsed_s());
    if (!args.output.empty()) std::printf("wrote %s\n", args.output.c_str());
    if (covariance_out) {
      std::printf("wrote %s (covariances of the cameras, %.3f s", args.covariance.path.c_str(),
                  covariance_s);
      if (gauge_dimension > 0) {
        std::printf("; %d free directions removed: the pseudo-inverse", gauge_dimension);
      }
      std::printf(")\n");
    }
  }
  flush_standard_output();  // the report is out: now the problem goes into place
  if (out) out->commit();
  if (covariance_out) covariance_out->commit();
  return 0;
}

}  // namespace

void register_solve_bal(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<SolveBalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "solve-bal", "Bundle adjustment of a BAL problem (Snavely camera model, Schur complement)");
  cmd->add_option("file", args->input, "BAL file to read")->check(path_value())->required();
  cmd->add_option("--out", args->output, "write the solved problem here (BAL; never the input)")
      ->check(path_value());
  cmd->add_option("--linear-solver", args->linear_solver,
                  "schur (eliminate the points), cholesky (whole system) or auto")
      ->check(CLI::IsMember({"auto", "schur", "cholesky"}))
      ->capture_default_str();
  cmd->add_option("--max-iterations", args->max_iterations, "iteration limit")
      ->check(integer_in(0, 1000000))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads for linearization and elimination")
      ->check(integer_in(1, 1024))
      ->capture_default_str();
  cmd->add_option("--loss", args->loss, "robust loss on every observation")
      ->check(CLI::IsMember({"none", "huber", "cauchy"}))
      ->capture_default_str();
  cmd->add_option("--loss-scale", args->loss_scale, "scale of the robust loss (pixels)")
      ->check(real_in(1e-6, 1e6))
      ->capture_default_str();
  cmd->add_option("--lm-start", args->lm_start,
                  "how LM begins: gauss_newton (undamped steps while they keep their gain), "
                  "trust_region (Ceres's start) or auto (gauss_newton)")
      ->check(CLI::IsMember({"auto", "gauss_newton", "trust_region"}))
      ->capture_default_str();
  cmd->add_option("--trust-region-growth", args->trust_region_growth,
                  "most the LM radius grows after one step (0: automatic, 3 with the Schur "
                  "complement, 10 without)")
      ->check(zero_or_real_in(1.0, 1e6, "automatic"))
      ->capture_default_str();
  cmd->add_flag("--no-factor-reuse", args->no_factor_reuse,
                "factorize afresh every iteration (no steps on an earlier factorization)");
  cmd->add_option("--anderson-memory", args->anderson_memory,
                  "steps Anderson's method combines in a slow tail (0: off; docs/cli.md)")
      ->check(integer_in(0, 64))
      ->capture_default_str();
  cmd->add_option("--camera-steps", args->camera_steps,
                  "how a camera steps: centre (rotation about its centre, and the centre; fewer "
                  "iterations far from the world origin) or parameters (added to its nine "
                  "numbers, as Ceres's bundle_adjuster); the covariances are in these tangents")
      ->check(CLI::IsMember({"centre", "parameters"}))
      ->capture_default_str();
  add_covariance_options(cmd, &args->covariance, "every camera (by its index)", "pseudo-inverse");
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args, cmd] { return run_solve_bal(*cmd, *args); });
}

}  // namespace carat::cli
