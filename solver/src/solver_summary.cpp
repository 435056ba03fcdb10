#include "carat/solver/solver_summary.hpp"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "carat/base/field_count.hpp"

namespace carat {
namespace {

std::string format(const char* fmt, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

}  // namespace

const char* to_string(TerminationType type) {
  switch (type) {
    case TerminationType::kConvergence:
      return "CONVERGENCE";
    case TerminationType::kNoConvergence:
      return "NO_CONVERGENCE";
    case TerminationType::kUserAbort:
      return "USER_ABORT";
    case TerminationType::kFailure:
      return "FAILURE";
  }
  return "UNKNOWN";
}

std::string SolverSummary::brief_report() const {
  if (iterations.empty() && termination == TerminationType::kFailure) {
    // Nothing was evaluated (invalid options, a block that failed at the start): no costs.
    return format("carat %s: %s (%s), %.3f s", method.c_str(), to_string(termination),
                  message.c_str(), time.total_s);
  }
  return format("carat %s: cost %.6e -> %.6e, %d iterations (%d accepted), %s, %.3f s",
                method.c_str(), initial_cost, final_cost, num_iterations, num_successful_steps,
                to_string(termination), time.total_s);
}

std::string SolverSummary::iteration_table() const {
  std::string out =
      "iter      cost      cost_change  |gradient|   |step|    tr_ratio  tr_radius  iter_time  "
      "total_time\n";
  for (const auto& it : iterations) {
    const char* note = "";
    if (it.linear_solver_failed) {
      note = "  (not positive definite)";
    } else if (it.iteration > 0 && !it.step_is_successful) {
      note = "  (rejected)";
    } else if (it.reused_factorization && it.accelerated) {
      note = "  (reused factorization, accelerated)";
    } else if (it.reused_factorization) {
      note = "  (reused factorization)";
    } else if (it.accelerated) {
      note = "  (accelerated)";
    }
    // A value that is not a number is shown as "-", never as "nan" or "-nan".
    const auto cell = [](const char* fmt, double value, int width) {
      return std::isfinite(value) ? format(fmt, value) : format("%*s", width, "-");
    };
    out += format("%4d", it.iteration) + " " + cell("% 8.6e", it.cost, 13) + " " +
           cell("% 3.2e", it.cost_change, 9) + " " + cell("% 3.2e", it.gradient_max_norm, 9) + " " +
           cell("% 3.2e", it.step_norm, 9) + " " + cell("% 3.2e", it.relative_decrease, 9) + " " +
           cell("% 3.2e", it.trust_region_radius, 9) + " " +
           cell("% 4.2e", it.iteration_time_s, 9) + " " + cell("% 4.2e", it.cumulative_time_s, 9) +
           note + "\n";
  }
  return out;
}

std::string SolverSummary::full_report() const {
  std::string out = iteration_table();
  out += "\nSolver summary\n";
  out += format("  %-28s %d (%d free)\n", "variables", num_variables, num_free_variables);
  out += format("  %-28s %d\n", "tangent parameters", num_tangent_parameters);
  out += format("  %-28s %d\n", "residual blocks", num_residual_blocks);
  out += format("  %-28s %zu\n", "residual rows", num_residual_rows);
  out += format("  %-28s %zu\n", "residual block bytes", residual_memory_bytes);
  out += format("  %-28s %s\n", "method", method.c_str());
  out += format("  %-28s %s\n", "linear solver", linear_solver.c_str());
  out += format("  %-28s %zu / %zu\n", "nonzeros H (upper) / L", hessian_nonzeros, factor_nonzeros);
  const int factorizations = num_iterations - num_reused_factorizations;
  if (factor_flops > 0.0 && factorizations > 0 && time.numeric_s > 0.0) {
    out += format("  %-28s %.3e (%.2f GFLOP/s over %d)\n", "flops per factorization", factor_flops,
                  factor_flops * factorizations / time.numeric_s * 1e-9, factorizations);
  }
  out += format("  %-28s %d\n", "threads", num_threads);
  out += format("  %-28s %.9e\n", "initial cost", initial_cost);
  out += format("  %-28s %.9e\n", "final cost", final_cost);
  out += format("  %-28s %.9e\n", "change", initial_cost - final_cost);
  out += format("  %-28s %d (%d accepted, %d rejected, %d not positive definite)\n", "iterations",
                num_iterations, num_successful_steps, num_unsuccessful_steps,
                num_linear_solver_failures);
  out += format("  %-28s %d kept, %d refused\n", "steps on a reused factor",
                num_reused_factorizations, num_refused_reuses);
  out += format("  %-28s %d\n", "accelerated steps", num_accelerated_steps);
  out += "\nTime (seconds)\n";
  out += format("  %-28s %.6f\n", "symbolic analysis", time.symbolic_s);
  out += format("  %-28s %.6f\n", "linearization", time.linearize_s);
  out += format("  %-28s %.6f\n", "cost evaluation", time.cost_s);
  out += format("  %-28s %.6f\n", "assembly", time.assembly_s);
  out += format("  %-28s %.6f\n", "numeric factorization", time.numeric_s);
  out += format("  %-28s %.6f\n", "triangular solves", time.solve_s);
  if (time.schur_s > 0.0) out += format("  %-28s %.6f\n", "schur elimination", time.schur_s);
  out += format("  %-28s %.6f\n", "total", time.total_s);
  out += format("\nTermination: %s (%s)\n", to_string(termination), message.c_str());
  return out;
}

std::string SolverSummary::to_json() const {
  nlohmann::json j;
  j["termination"] = to_string(termination);
  j["message"] = message;
  j["initial_cost"] = initial_cost;
  j["final_cost"] = final_cost;
  j["iterations"] = num_iterations;
  j["successful_steps"] = num_successful_steps;
  j["unsuccessful_steps"] = num_unsuccessful_steps;
  j["reused_factorizations"] = num_reused_factorizations;
  j["refused_reuses"] = num_refused_reuses;
  j["accelerated_steps"] = num_accelerated_steps;
  j["linear_solver_failures"] = num_linear_solver_failures;
  j["variables"] = num_variables;
  j["free_variables"] = num_free_variables;
  j["tangent_parameters"] = num_tangent_parameters;
  j["residual_blocks"] = num_residual_blocks;
  j["residual_rows"] = num_residual_rows;
  j["hessian_nonzeros"] = hessian_nonzeros;
  j["factor_nonzeros"] = factor_nonzeros;
  j["factor_flops"] = factor_flops;
  j["residual_memory_bytes"] = residual_memory_bytes;
  j["threads"] = num_threads;
  j["method"] = method;
  j["linear_solver"] = linear_solver;
  j["trust_region_growth"] = trust_region_growth;
  j["time_s"] = time.total_s;
  j["time_breakdown"] = {{"symbolic_s", time.symbolic_s}, {"linearize_s", time.linearize_s},
                         {"cost_s", time.cost_s},         {"assembly_s", time.assembly_s},
                         {"numeric_s", time.numeric_s},   {"solve_s", time.solve_s},
                         {"schur_s", time.schur_s},       {"total_s", time.total_s}};
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& it : iterations) {
    rows.push_back({{"iteration", it.iteration},
                    {"cost", it.cost},
                    {"cost_change", it.cost_change},
                    {"gradient_max_norm", it.gradient_max_norm},
                    {"step_norm", it.step_norm},
                    {"relative_decrease", it.relative_decrease},
                    {"trust_region_radius", it.trust_region_radius},
                    {"step_is_successful", it.step_is_successful},
                    {"linear_solver_failed", it.linear_solver_failed},
                    {"reused_factorization", it.reused_factorization},
                    {"accelerated", it.accelerated},
                    {"iteration_time_s", it.iteration_time_s},
                    {"cumulative_time_s", it.cumulative_time_s}});
  }
  j["iteration_rows"] = rows;
  return j.dump();
}

// merge_later_solve() is written for these members: a new one must be merged there (or left as
// `later`'s on purpose), and the count here raised.
static_assert(field_count<SolverSummary>() == 26, "merge_later_solve: merge the new field");
static_assert(field_count<TimeBreakdown>() == 8, "merge_later_solve: sum the new stage time");
static_assert(field_count<IterationSummary>() == 13, "merge_later_solve: continue the new field");

void merge_later_solve(SolverSummary& total, const SolverSummary& later) {
  if (total.num_iterations == 0 && total.iterations.empty()) {
    total = later;
    return;
  }
  // The end state and what describes the problem and the setup: the later solve's.
  const double initial_cost = total.initial_cost;
  const int iterations = total.num_iterations + later.num_iterations;
  const int successful = total.num_successful_steps + later.num_successful_steps;
  const int unsuccessful = total.num_unsuccessful_steps + later.num_unsuccessful_steps;
  const int reused = total.num_reused_factorizations + later.num_reused_factorizations;
  const int refused = total.num_refused_reuses + later.num_refused_reuses;
  const int accelerated = total.num_accelerated_steps + later.num_accelerated_steps;
  const int failures = total.num_linear_solver_failures + later.num_linear_solver_failures;
  TimeBreakdown time = total.time;
  time.linearize_s += later.time.linearize_s;
  time.cost_s += later.time.cost_s;
  time.assembly_s += later.time.assembly_s;
  time.symbolic_s += later.time.symbolic_s;
  time.numeric_s += later.time.numeric_s;
  time.solve_s += later.time.solve_s;
  time.schur_s += later.time.schur_s;
  time.total_s += later.time.total_s;
  std::vector<IterationSummary> rows = std::move(total.iterations);
  // Rows go on from the last one's number and cumulative time.
  const int first_number = rows.empty() ? 0 : rows.back().iteration + 1;
  const double elapsed_s = rows.empty() ? 0.0 : rows.back().cumulative_time_s;
  rows.reserve(rows.size() + later.iterations.size());
  for (IterationSummary row : later.iterations) {
    row.iteration += first_number;
    row.cumulative_time_s += elapsed_s;
    rows.push_back(row);
  }
  total = later;
  total.initial_cost = initial_cost;
  total.num_iterations = iterations;
  total.num_successful_steps = successful;
  total.num_unsuccessful_steps = unsuccessful;
  total.num_reused_factorizations = reused;
  total.num_refused_reuses = refused;
  total.num_accelerated_steps = accelerated;
  total.num_linear_solver_failures = failures;
  total.time = time;
  total.iterations = std::move(rows);
}

}  // namespace carat
