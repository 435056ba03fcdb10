// carat solve-g2o FILE [--out FILE] [--max-iterations N] [--threads T] [--method lm|gn]
//                      [--loss none|huber|cauchy] [--loss-scale S] [--no-factor-reuse]
//                      [--anderson-memory M]
//                      [--trust-region-growth G] [--lm-start auto|gauss_newton|trust_region]
//                      [--repair-information]
//                      [--covariance FILE [--covariance-gauge error|pseudo-inverse]] [--json]
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <type_traits>
#include <variant>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/residuals/io/g2o_io.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/residuals/pose_graph_se2.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/solve.hpp"
#include "carat/solver/solver_options.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "covariance_output.hpp"

namespace carat::cli {
namespace {

struct SolveG2oArgs {
  std::string input;
  std::string output;
  int max_iterations = 100;
  int threads = 1;
  std::string method = "lm";
  std::string ordering = "auto";
  std::string loss = "none";
  double loss_scale = 1.0;
  bool no_factor_reuse = false;
  int anderson_memory = SolverOptions{}.anderson_memory;
  bool repair_information = false;
  double trust_region_growth = SolverOptions{}.max_trust_region_growth;
  std::string lm_start = to_string(SolverOptions{}.lm_start);
  CovarianceRequest covariance;
  bool json = false;
};

/// Solves a graph of either dimension (PoseGraph or PoseGraphSE2), prints the report and writes
/// --out.
template <typename Graph>
int solve_graph(const SolveG2oArgs& args, Method method, LossKind loss,
                const G2oReadReport& read_report, Graph& graph) {
  constexpr int kDimension = std::is_same_v<Graph, PoseGraphSE2> ? 2 : 3;
  PoseGraphProblemOptions problem_options;
  problem_options.loss = make_loss(loss, args.loss_scale);
  PoseGraphProblem built;
  try {
    built = build_pose_graph_problem(graph, problem_options);
  } catch (const Error& e) {
    throw Error(args.input + ": " + e.what());
  }

  SolverOptions options;
  options.max_iterations = args.max_iterations;
  options.num_threads = args.threads;
  options.method = method;
  options.ordering = parse_ordering(args.ordering);
  options.reuse_factorization = !args.no_factor_reuse;
  options.anderson_memory = args.anderson_memory;
  options.lm_start = parse_lm_start(args.lm_start);
  options.max_trust_region_growth = args.trust_region_growth;
  const SolverSummary summary = solve(options, built.problem);
  if (summary.termination == TerminationType::kFailure) {
    throw Error(args.input + ": the solve failed: " + summary.message);
  }
  std::unique_ptr<OutputFile> out;
  if (!args.output.empty()) {
    update_vertices(built, &graph);
    out = std::make_unique<OutputFile>(args.output);
    write_g2o(out->stream(), graph);
  }
  std::unique_ptr<OutputFile> covariance_out;
  double covariance_s = 0.0;
  if (!args.covariance.path.empty()) {
    const Stopwatch covariance_time;
    Covariance covariance = [&] {
      try {
        return Covariance(built.problem, covariance_options(args.covariance, args.threads));
      } catch (const Error& e) {
        throw Error(args.input + ": " + e.what());
      }
    }();
    covariance_out = std::make_unique<OutputFile>(args.covariance.path);
    for (std::size_t i = 0; i < graph.vertices.size(); ++i) {
      const VariableId v = built.vertex_variables[i];
      if (built.problem.is_constant(v)) continue;
      write_covariance_line(covariance_out->stream(), graph.vertices[i].id, covariance.block(v));
    }
    covariance_s = covariance_time.elapsed_s();
  }
  if (args.json) {
    nlohmann::json j = nlohmann::json::parse(summary.to_json());
    j["input"] = args.input;
    j["vertices"] = graph.vertices.size();
    j["edges"] = graph.edges.size();
    j["dimension"] = kDimension;
    j["repaired_information"] = read_report.repaired_lines.size();
    if (!args.output.empty()) j["output"] = args.output;
    if (covariance_out) {
      j["covariance"] = args.covariance.path;
      j["covariance_s"] = covariance_s;
    }
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("%s: %dD graph, %zu vertices, %zu edges", args.input.c_str(), kDimension,
                graph.vertices.size(), graph.edges.size());
    if (!read_report.repaired_lines.empty()) {
      std::printf(" (%zu information matrices replaced by the nearest positive-definite one)",
                  read_report.repaired_lines.size());
    }
    std::printf("\n\n");
    std::printf("%s\n%s\n", summary.full_report().c_str(), summary.brief_report().c_str());
    if (!args.output.empty()) std::printf("wrote %s\n", args.output.c_str());
    if (covariance_out) {
      std::printf("wrote %s (covariances of the free vertices, %.3f s)\n",
                  args.covariance.path.c_str(), covariance_s);
    }
  }
  flush_standard_output();  // the report is out: now the graph goes into place
  if (out) out->commit();
  if (covariance_out) covariance_out->commit();
  return 0;
}

int run_solve_g2o(const CLI::App& command, const SolveG2oArgs& args) {
  const Method method = parse_method(args.method);
  const LossKind loss = parse_loss_kind(args.loss);
  refuse_unused(command, "--loss-scale", loss != LossKind::kNone, "to --loss none (set --loss)");
  const bool lm = method == Method::kLevenbergMarquardt;
  refuse_unused(command, "--trust-region-growth", lm, "to --method gn");
  refuse_unused(command, "--no-factor-reuse", lm, "to --method gn");
  refuse_unused(command, "--anderson-memory", lm, "to --method gn");
  refuse_unused(command, "--lm-start", lm, "to --method gn");
  if (!args.output.empty()) check_output_file("--out", args.output, {{"FILE", args.input}});
  check_covariance_request(command, args.covariance, {{"FILE", args.input}}, "--out", args.output);
  G2oReadOptions read_options;
  if (args.repair_information) read_options.information = InformationRepair::kNearest;
  G2oReadReport read_report;
  G2oGraph any = read_g2o_any(args.input, read_options, &read_report);
  return std::visit(
      [&](auto& graph) { return solve_graph(args, method, loss, read_report, graph); }, any);
}

}  // namespace

void register_solve_g2o(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<SolveG2oArgs>();
  CLI::App* cmd = app.add_subcommand(
      "solve-g2o",
      "Optimize a 3D or 2D g2o pose graph (VERTEX_SE3:QUAT / EDGE_SE3:QUAT or VERTEX_SE2 / "
      "EDGE_SE2)");
  cmd->add_option("file", args->input, "g2o file to read")->check(path_value())->required();
  cmd->add_option("--out", args->output, "write the optimized graph here (g2o; never the input)")
      ->check(path_value());
  cmd->add_option("--max-iterations", args->max_iterations, "iteration limit")
      ->check(integer_in(0, 1000000))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads for linearization")
      ->check(integer_in(1, 1024))
      ->capture_default_str();
  cmd->add_option("--method", args->method, "lm (Levenberg-Marquardt) or gn (Gauss-Newton)")
      ->check(CLI::IsMember({"lm", "gn"}))
      ->capture_default_str();
  cmd->add_option("--ordering", args->ordering, "fill-reducing ordering of the variables")
      ->check(CLI::IsMember({"auto", "amd", "metis"}))
      ->capture_default_str();
  cmd->add_option("--loss", args->loss, "robust loss on every edge")
      ->check(CLI::IsMember({"none", "huber", "cauchy"}))
      ->capture_default_str();
  cmd->add_option("--loss-scale", args->loss_scale, "scale of the robust loss (whitened units)")
      ->check(real_in(1e-6, 1e6))
      ->capture_default_str();
  cmd->add_flag("--no-factor-reuse", args->no_factor_reuse,
                "factorize afresh every iteration (no steps on an earlier factorization)");
  cmd->add_option("--anderson-memory", args->anderson_memory,
                  "steps Anderson's method combines in a slow tail (0: off; docs/cli.md)")
      ->check(integer_in(0, 64))
      ->capture_default_str();
  cmd->add_option("--lm-start", args->lm_start,
                  "how LM begins: gauss_newton (undamped steps while they keep their gain), "
                  "trust_region (Ceres's start) or auto (gauss_newton)")
      ->check(CLI::IsMember({"auto", "gauss_newton", "trust_region"}))
      ->capture_default_str();
  cmd->add_option("--trust-region-growth", args->trust_region_growth,
                  "most the LM radius grows after one step (0: automatic, 10 here; Ceres: 3)")
      ->check(zero_or_real_in(1.0, 1e6, "automatic"))
      ->capture_default_str();
  cmd->add_flag("--repair-information", args->repair_information,
                "replace an information matrix that is not positive definite by the nearest one "
                "(eigenvalues raised to 1e-9 of the largest) instead of failing");
  add_covariance_options(cmd, &args->covariance, "every free vertex (by its g2o id)", "error");
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args, cmd] { return run_solve_g2o(*cmd, *args); });
}

}  // namespace carat::cli
