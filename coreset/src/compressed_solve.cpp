#include "carat/coreset/compressed_solve.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/solve.hpp"
#include "shuffle.hpp"

namespace carat {
namespace {

constexpr std::array<std::pair<CompressionMode, const char*>, 5> kModes{{
    {CompressionMode::kSurrogate, "surrogate"},
    {CompressionMode::kRecompress, "recompress"},
    {CompressionMode::kOnce, "once"},
    {CompressionMode::kAuto, "auto"},
    {CompressionMode::kFull, "full"},
}};

using Values = std::vector<double>;

Values values_of(const Problem& problem) {
  return {problem.all_values().begin(), problem.all_values().end()};
}

/// One solve_recompressed() call: the stages every mode is made of, with their time and counts
/// kept in the summary.
class CompressedSolver {
 public:
  CompressedSolver(Problem& problem, const RecompressedSolveOptions& options)
      : problem_(problem), options_(options) {
    threads_ = std::max(1, options.compression.num_threads);
    inner_ = options.inner;
    inner_.num_threads = threads_;
    summary_.mode = options.mode;
    summary_.full_rows = problem.num_residual_rows();
  }

  RecompressedSolveSummary run();

 private:
  /// The problem compressed at `values`, and its evaluation there (the full problem's cost and
  /// gradient: the coreset keeps every block's b and c).
  struct Compressed {
    Problem problem;
    ProblemEvaluation model;
  };
  Compressed compress_at(const Values& values);
  /// The full cost at `values` from residuals alone.
  double full_cost_at(const Values& values);
  /// Solves `work` (a compressed problem, or a sampled one when not `compressed`) with the inner
  /// options, at most `iterations`.
  SolverSummary solve_compressed(Problem& work, int iterations, bool compressed = true);
  /// Full iterations from the problem's current values; returns the summary.
  SolverSummary solve_full(const SolverOptions& options);
  RecompressedSolveSummary finish(TerminationType type, std::string message);

  /// kSurrogate's sampled start (see compressed_solve.hpp): solves the problem with its large
  /// blocks sampled and moves the problem to the result when that lowers the full cost. False
  /// (nothing done) when sampling would keep more than a quarter of the rows.
  bool run_sampled_start();

  RecompressedSolveSummary run_once();
  RecompressedSolveSummary run_surrogate();
  /// Compressions while the compressed solve beats a full step, then full iterations.
  RecompressedSolveSummary run_compressions();
  RecompressedSolveSummary run_recompress();
  /// The full solve, switching to run_compressions() where its Gauss-Newton model fails.
  RecompressedSolveSummary run_full_then_compressions();
  /// Full iterations to finish a mode that ends at the full optimum.
  RecompressedSolveSummary finish_with_full(std::string why);

  Problem& problem_;
  const RecompressedSolveOptions& options_;
  /// The values before a sampled start the full solve has not judged yet (empty otherwise).
  Values sampled_from_;
  bool aborted_ = false;  ///< the caller's callback stopped the sampled solve
  SolverOptions inner_;
  int threads_ = 1;
  RecompressedSolveSummary summary_;
  Stopwatch total_time_;
};

CompressedSolver::Compressed CompressedSolver::compress_at(const Values& values) {
  Compressed out{problem_, {}};
  out.problem.set_all_values(values);
  Stopwatch stage;
  const ProblemCompressionReport report = compress_problem(out.problem, options_.compression);
  summary_.compression_s += stage.elapsed_s();
  summary_.compressed_rows = report.rows_after;
  ++summary_.recompressions;
  stage.restart();
  out.model = evaluate_problem(out.problem, threads_);
  summary_.full_evaluation_s += stage.elapsed_s();
  return out;
}

double CompressedSolver::full_cost_at(const Values& values) {
  const Stopwatch stage;
  problem_.set_all_values(values);
  const double cost = evaluate_cost(problem_, threads_);
  summary_.full_evaluation_s += stage.elapsed_s();
  return cost;
}

SolverSummary CompressedSolver::solve_compressed(Problem& work, int iterations, bool compressed) {
  SolverOptions options = inner_;
  options.max_iterations = std::min(options.max_iterations, iterations);
  const Stopwatch stage;
  SolverSummary solved = solve(options, work);
  summary_.inner_solve_s += stage.elapsed_s();
  summary_.inner_iterations += solved.num_iterations;
  if (compressed) summary_.compressed_final_cost = solved.final_cost;
  return solved;
}

SolverSummary CompressedSolver::solve_full(const SolverOptions& options) {
  const Stopwatch stage;
  SolverSummary solved = solve(options, problem_);
  summary_.full_solve_s += stage.elapsed_s();
  summary_.full_iterations += solved.num_iterations;
  return solved;
}

RecompressedSolveSummary CompressedSolver::finish(TerminationType type, std::string message) {
  summary_.termination = type;
  summary_.message = std::move(message);
  summary_.total_s = total_time_.elapsed_s();
  return summary_;
}

RecompressedSolveSummary CompressedSolver::finish_with_full(std::string why) {
  const SolverSummary full = solve_full(inner_);
  summary_.final_cost = full.final_cost;
  if (!full.iterations.empty()) {
    summary_.final_gradient_max_norm = full.iterations.back().gradient_max_norm;
  }
  return finish(full.termination, why + "; full iterations: " + full.message);
}

RecompressedSolveSummary CompressedSolver::run_once() {
  const Values start = values_of(problem_);
  Compressed work = compress_at(start);
  summary_.initial_cost = work.model.cost;
  summary_.compressed_initial_cost = work.model.cost;
  const SolverSummary solved = solve_compressed(work.problem, inner_.max_iterations);
  const Values result = values_of(work.problem);
  summary_.final_cost = full_cost_at(result);
  summary_.records.push_back({work.model.cost, work.model.gradient_max_norm, solved.final_cost,
                              summary_.final_cost, 0.0, solved.num_iterations,
                              summary_.compressed_rows});
  if (solved.termination == TerminationType::kFailure) {
    summary_.final_cost = full_cost_at(start);
    return finish(TerminationType::kFailure, "the compressed solve failed: " + solved.message);
  }
  if (solved.termination == TerminationType::kUserAbort) {  // where the compressed solve stopped
    return finish(TerminationType::kUserAbort, "the iteration callback asked to stop");
  }
  return finish(solved.termination,
                "one compression, solved (not the full optimum): " + solved.message);
}

bool CompressedSolver::run_sampled_start() {
  // Blocks held outside the problem would be evaluated whole in the sampled problem too.
  if (problem_.block_source()) return false;
  const Stopwatch stage;
  const auto blocks = problem_.blocks();
  const ProblemCompressionOptions& compression = options_.compression;
  // Which blocks are sampled, to how many rows; the rest stay whole (those compress_problem()
  // would leave, those with a loss per row group, whose groups a row sample would split, and
  // those of too few rows to gain from it).
  std::vector<int> targets(blocks.size(), 0);
  // Blocks that state their whole cost function in fewer rows (ResidualBlock::exact_form())
  // enter the sampled problem in that form: exact at every point, so no sample is needed.
  std::vector<std::shared_ptr<const ResidualBlock>> exact(blocks.size());
  // Blocks that stay whole whatever their form or sample (compression.select asked once, here):
  // when they alone (with one row for every other block) hold more than a quarter of the rows,
  // no form is worth building.
  std::vector<char> whole_anyway(blocks.size(), 0);
  std::size_t least_rows = 0;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const ResidualBlock& block = *blocks[k].block;
    whole_anyway[k] = (compression.select &&
                       !compression.select(ResidualBlockId{static_cast<std::int32_t>(k)}, block)) ||
                      block.group_loss() != nullptr || block.num_rows() <= compression.min_rows;
    least_rows += whole_anyway[k] ? static_cast<std::size_t>(block.num_rows()) : 1;
  }
  if (least_rows > summary_.full_rows / 4) {
    summary_.compression_s += stage.elapsed_s();
    return false;
  }
  if (options_.exact_forms) {  // one pass over each block's data: on compression's threads
    std::vector<std::string> errors(blocks.size());
    tbb::task_arena arena(std::clamp(compression.num_threads, 1, tbb::info::default_concurrency()));
    arena.execute([&] {
      tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t k) {
        if (whole_anyway[k]) return;
        const ResidualBlock& block = *blocks[k].block;
        std::vector<const double*> params;
        for (VariableId v : blocks[k].variables) params.push_back(problem_.value(v).data());
        try {
          exact[k] = block.exact_form(params);
        } catch (const Error&) {  // a form that cannot be built (e.g. from non-finite data)
          exact[k] = nullptr;     // leaves the block to sampling, and the full solve to report
        } catch (const std::exception& e) {  // anything else is the block's error
          errors[k] = std::string("its exact_form() threw: ") + e.what();
          return;
        }
        if (!exact[k]) return;
        const auto dims = block.tangent_dims();
        const auto form_dims = exact[k]->tangent_dims();
        if (!std::equal(dims.begin(), dims.end(), form_dims.begin(), form_dims.end())) {
          errors[k] = "its exact_form() has variables of other tangent sizes than the block's";
        } else if (exact[k]->num_rows() < 1 || exact[k]->group_loss() != nullptr) {
          errors[k] = "its exact_form() has no rows or a loss per row group";
        }
        if (exact[k]->num_rows() >= block.num_rows()) exact[k] = nullptr;  // nothing to gain
      });
    });
    for (std::size_t k = 0; k < blocks.size(); ++k) {
      if (errors[k].empty()) continue;
      const std::string& name = blocks[k].block->name();
      throw Error("solve_recompressed: residual block " + std::to_string(k) +
                  (name.empty() ? std::string() : " ('" + name + "')") + ": " + errors[k]);
    }
  }
  std::size_t rows = 0;
  bool any = false;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const ResidualBlock& block = *blocks[k].block;
    const int n = block.num_rows();
    if (exact[k]) {
      rows += static_cast<std::size_t>(exact[k]->num_rows());
      ++summary_.exact_form_blocks;
      any = true;
      continue;
    }
    // In 64 bits (a large factor or reduced dimension would overflow an int), at most n.
    const std::int64_t target = std::min<std::int64_t>(
        n, std::max({std::int64_t{options_.sampled_rows_factor} *
                         minimum_coreset_rows(block.reduced_dim()),
                     std::int64_t{compression.min_target_rows},
                     static_cast<std::int64_t>(
                         std::ceil(options_.sampled_rows_share * static_cast<double>(n)))}));
    const bool whole = whole_anyway[k] || n <= 2 * target;
    if (!whole) {
      targets[k] = static_cast<int>(target);
      any = true;
    }
    rows += static_cast<std::size_t>(whole ? n : target);
  }
  if (!any || rows > summary_.full_rows / 4) {
    summary_.exact_form_blocks = 0;
    summary_.compression_s += stage.elapsed_s();
    return false;
  }
  Problem sampled = problem_;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    if (exact[k]) {
      sampled.replace_residual_block(ResidualBlockId{static_cast<std::int32_t>(k)},
                                     std::move(exact[k]));
      continue;
    }
    if (targets[k] == 0) continue;
    // Floyd's draw of the rows, not compress_random()'s permutation of all of them.
    const int n = blocks[k].block->num_rows();
    std::vector<int> rows_kept =
        internal::seeded_sample(n, targets[k], compression.compression.seed + k);
    std::vector<double> weights(rows_kept.size(),
                                static_cast<double>(n) / static_cast<double>(targets[k]));
    sampled.replace_residual_block(
        ResidualBlockId{static_cast<std::int32_t>(k)},
        compress_rows(blocks[k].block, std::move(rows_kept), std::move(weights)));
  }
  summary_.compression_s += stage.elapsed_s();
  summary_.sampled_start = true;
  summary_.sampled_rows = rows;
  const Values start = values_of(problem_);
  const SolverSummary solved = solve_compressed(sampled, inner_.max_iterations, false);
  if (solved.termination == TerminationType::kUserAbort) {  // the caller's callback said stop
    problem_.set_all_values(start);
    aborted_ = true;
    return true;
  }
  summary_.initial_cost = full_cost_at(start);
  // A failed sampled solve, or a start whose cost is not finite (the full solve reports that),
  // leaves the start as it is.
  if (solved.termination == TerminationType::kFailure || !std::isfinite(summary_.initial_cost)) {
    summary_.sampled_start_cost = std::numeric_limits<double>::infinity();
    problem_.set_all_values(start);
    return true;
  }
  // The full solve starts at the sampled solution; its first linearization gives the full cost
  // there, and a start that does not lower it is abandoned for this one (no pass of its own).
  problem_.set_all_values(values_of(sampled));
  sampled_from_ = start;
  return true;
}

RecompressedSolveSummary CompressedSolver::run_surrogate() {
  if (!options_.sampled_start || !run_sampled_start()) return run_compressions();
  if (aborted_) {
    return finish(TerminationType::kUserAbort,
                  "the iteration callback asked to stop (in the sampled start)");
  }
  const double initial = summary_.initial_cost;
  RecompressedSolveSummary out = run_full_then_compressions();
  out.initial_cost = initial;
  const bool kept = out.sampled_start_cost < initial;
  out.message = "sampled start (full cost " + message_number(initial) + " -> " +
                message_number(out.sampled_start_cost) +
                (kept ? "), then " : ", not kept), then ") + out.message;
  return out;
}

RecompressedSolveSummary CompressedSolver::run_compressions() {
  Values x = values_of(problem_);
  double cost = 0.0;
  for (int outer = 0; outer < options_.max_recompressions; ++outer) {
    Compressed work = compress_at(x);
    if (outer == 0) {
      summary_.initial_cost = work.model.cost;
      summary_.compressed_initial_cost = work.model.cost;
    }
    cost = work.model.cost;
    if (!work.model.finite) return finish(TerminationType::kFailure, "the full cost is not finite");
    if (work.model.gradient_max_norm <= options_.gradient_tolerance) {
      problem_.set_all_values(x);
      summary_.final_cost = cost;
      summary_.final_gradient_max_norm = work.model.gradient_max_norm;
      return finish(TerminationType::kConvergence,
                    "full gradient tolerance reached: max |gradient| = " +
                        message_number(work.model.gradient_max_norm));
    }
    // The surrogate's result, and one full step from the same compression.
    Problem stepped = work.problem;
    const SolverSummary step = solve_compressed(stepped, 1);
    const SolverSummary solved = solve_compressed(work.problem, inner_.max_iterations);
    if (solved.termination == TerminationType::kFailure) {
      return finish(TerminationType::kFailure, "the compressed solve failed: " + solved.message);
    }
    if (solved.termination == TerminationType::kUserAbort) {
      problem_.set_all_values(x);
      summary_.final_cost = cost;
      return finish(TerminationType::kUserAbort, "the iteration callback asked to stop");
    }
    const Values by_surrogate = values_of(work.problem);
    const Values by_step = values_of(stepped);
    const double surrogate_cost = full_cost_at(by_surrogate);
    // A step the compressed problem rejected did not move: its cost is known.
    const double step_cost = step.termination == TerminationType::kFailure
                                 ? std::numeric_limits<double>::infinity()
                             : by_step == x ? cost
                                            : full_cost_at(by_step);
    summary_.records.push_back({cost, work.model.gradient_max_norm, solved.final_cost,
                                surrogate_cost, step_cost, solved.num_iterations,
                                summary_.compressed_rows});
    const bool surrogate_better = surrogate_cost < step_cost;
    const double best = std::min(surrogate_cost, step_cost);
    if (!(best < cost)) {  // neither lowered the full cost: full iterations from here
      problem_.set_all_values(x);
      return finish_with_full("no compressed step lowered the full cost");
    }
    x = surrogate_better ? by_surrogate : by_step;
    problem_.set_all_values(x);
    // The surrogate pays while it goes clearly beyond one full step of the same model.
    // (A decrease within the full solve's function tolerance is convergence, not a gain.)
    const double step_decrease = cost - step_cost;
    const double extra = step_cost - surrogate_cost;
    const double meaningful = inner_.function_tolerance * cost;
    if (!(surrogate_better && std::isfinite(step_cost) && extra > meaningful &&
          extra >= options_.surrogate_gain * step_decrease)) {
      return finish_with_full("compressed solves no longer beat a full step after " +
                              std::to_string(summary_.recompressions) + " compressions");
    }
  }
  return finish_with_full("maximum number of compressions reached (" +
                          std::to_string(options_.max_recompressions) + ")");
}

RecompressedSolveSummary CompressedSolver::run_recompress() {
  Values accepted = values_of(problem_);
  Compressed work = compress_at(accepted);
  summary_.initial_cost = work.model.cost;
  summary_.compressed_initial_cost = work.model.cost;
  ProblemEvaluation full = work.model;
  const auto done = [&](TerminationType type, std::string message) {
    problem_.set_all_values(accepted);
    summary_.final_cost = full.cost;
    summary_.final_gradient_max_norm = full.gradient_max_norm;
    return finish(type, std::move(message));
  };
  if (!full.finite) return done(TerminationType::kFailure, "the initial full cost is not finite");
  if (full.gradient_max_norm <= options_.gradient_tolerance) {
    return done(TerminationType::kConvergence, "full gradient tolerance reached at the start");
  }
  int iterations = inner_.max_iterations;
  for (;;) {
    const SolverSummary solved = solve_compressed(work.problem, iterations);
    if (solved.termination == TerminationType::kFailure) {
      return done(TerminationType::kFailure, "the compressed solve failed: " + solved.message);
    }
    if (solved.termination == TerminationType::kUserAbort) {  // the last accepted point stays
      return done(TerminationType::kUserAbort, "the iteration callback asked to stop");
    }
    if (summary_.recompressions >= options_.max_recompressions) {
      accepted = values_of(work.problem);
      full.cost = full_cost_at(accepted);
      full.gradient_max_norm = -1.0;
      return done(TerminationType::kNoConvergence, "maximum number of compressions reached (" +
                                                       std::to_string(options_.max_recompressions) +
                                                       ")");
    }
    const Values candidate = values_of(work.problem);
    Compressed next = compress_at(candidate);
    summary_.records.push_back({next.model.cost, next.model.gradient_max_norm, solved.final_cost,
                                next.model.cost, 0.0, solved.num_iterations,
                                summary_.compressed_rows});
    if (!next.model.finite || !(next.model.cost <= full.cost)) {
      // A rise within the rounding of the cost (a sum of many terms): nothing left to gain.
      const double rounding = 1e3 * std::numeric_limits<double>::epsilon() * full.cost;
      if (next.model.finite && next.model.cost - full.cost <= rounding) {
        return done(TerminationType::kConvergence,
                    "the full cost no longer decreases beyond its rounding");
      }
      // The compressed problem led away from the full optimum: keep the last accepted point. One
      // step of the compressed problem is one step of the full problem's model, so retry with
      // one inner iteration before giving up.
      if (iterations > 1) {
        iterations = 1;
        work = compress_at(accepted);
        continue;
      }
      return done(TerminationType::kNoConvergence,
                  "a compressed step did not lower the full cost (" +
                      message_number(next.model.cost) + " after " + message_number(full.cost) +
                      ")");
    }
    const double change = full.cost - next.model.cost;
    full = next.model;
    work = std::move(next);
    accepted = candidate;
    iterations = inner_.max_iterations;
    if (full.gradient_max_norm <= options_.gradient_tolerance) {
      return done(TerminationType::kConvergence,
                  "full gradient tolerance reached: max |gradient| = " +
                      message_number(full.gradient_max_norm));
    }
    if (change <= options_.function_tolerance * std::max(full.cost, 1e-300)) {
      return done(TerminationType::kConvergence,
                  "full function tolerance reached: |cost change| / cost = " +
                      message_number(full.cost > 0.0 ? change / full.cost : 0.0));
    }
  }
}

RecompressedSolveSummary CompressedSolver::run_full_then_compressions() {
  SolverOptions options = inner_;
  const int switch_at = options_.switch_iteration;
  bool switch_now = false;
  bool back_to_start = false;
  bool judged = false;
  const IterationCallback user = inner_.iteration_callback;
  options.iteration_callback = [&](const IterationSummary& row) {
    // From a sampled start: its full cost is the first row's; keep it only if below the start's.
    if (row.iteration == 0 && !sampled_from_.empty()) {
      judged = true;
      summary_.sampled_start_cost = row.cost;
      if (!(row.cost < summary_.initial_cost)) {
        back_to_start = true;
        return CallbackResult::kAbort;
      }
    }
    if (user && user(row) == CallbackResult::kAbort) return CallbackResult::kAbort;
    // The Gauss-Newton model fails where the solve stands (a step rejected, or accepted with a
    // gain ratio far below 1 while the cost still falls fast): a nonlinear stretch, which
    // compressed solves cross with a few passes over the rows.
    const bool rejected = !row.step_is_successful;
    const bool poor = row.step_is_successful && row.cost > 0.0 &&
                      row.cost_change > options_.switch_decrease * (row.cost + row.cost_change) &&
                      row.relative_decrease < options_.switch_gain_ratio;
    if (row.iteration >= switch_at && (rejected || poor)) {
      switch_now = true;
      return CallbackResult::kAbort;
    }
    return CallbackResult::kContinue;
  };
  const bool sampled = !sampled_from_.empty();
  SolverSummary full;
  try {
    full = solve_full(options);
  } catch (...) {  // leave the problem at the caller's values, not at the sampled start
    if (sampled) problem_.set_all_values(sampled_from_);
    sampled_from_.clear();
    throw;
  }
  // The sampled start raised the full cost, or could not be evaluated (the solve failed before
  // its first row): solve from the start instead.
  if (sampled && !judged) summary_.sampled_start_cost = std::numeric_limits<double>::infinity();
  if (back_to_start || (sampled && !judged)) {
    problem_.set_all_values(sampled_from_);
    sampled_from_.clear();
    return run_full_then_compressions();
  }
  sampled_from_.clear();
  if (!sampled) summary_.initial_cost = full.initial_cost;
  // A solve that ended by itself (its last row may be a step too small to take) stays as it is.
  if (!switch_now || full.termination != TerminationType::kUserAbort) {
    summary_.final_cost = full.final_cost;
    if (!full.iterations.empty()) {
      summary_.final_gradient_max_norm = full.iterations.back().gradient_max_norm;
    }
    return finish(full.termination, "full solve: " + full.message);
  }
  summary_.switched_to_compression = true;
  const double initial = summary_.initial_cost;
  RecompressedSolveSummary out = run_compressions();
  out.initial_cost = initial;
  return out;
}

RecompressedSolveSummary CompressedSolver::run() {
  switch (options_.mode) {
    case CompressionMode::kOnce:
      return run_once();
    case CompressionMode::kRecompress:
      return run_recompress();
    case CompressionMode::kAuto:
      return run_full_then_compressions();
    case CompressionMode::kFull: {
      const SolverSummary full = solve_full(inner_);
      summary_.initial_cost = full.initial_cost;
      summary_.final_cost = full.final_cost;
      if (!full.iterations.empty()) {
        summary_.final_gradient_max_norm = full.iterations.back().gradient_max_norm;
      }
      return finish(full.termination, "full solve: " + full.message);
    }
    case CompressionMode::kSurrogate:
      break;
  }
  return run_surrogate();
}

}  // namespace

const char* to_string(CompressionMode mode) {
  for (const auto& [m, name] : kModes) {
    if (m == mode) return name;
  }
  return "unknown";
}

CompressionMode parse_compression_mode(std::string_view name) {
  for (const auto& [m, text] : kModes) {
    if (name == text) return m;
  }
  throw Error("unknown compression mode '" + std::string(name) +
              "' (expected surrogate, recompress, once, auto or full)");
}

bool RecompressedSolveOptions::validate(std::string* error) const {
  std::string why;
  if (!inner.validate(&why)) {
    *error = "inner options: " + why;
    return false;
  }
  if (max_recompressions < 1) {
    *error = "max_recompressions must be >= 1, got " + std::to_string(max_recompressions);
    return false;
  }
  if (!(function_tolerance >= 0.0) || !(gradient_tolerance >= 0.0)) {
    *error = "tolerances must be >= 0";
    return false;
  }
  if (sampled_rows_factor < 1) {
    *error = "sampled_rows_factor must be >= 1, got " + std::to_string(sampled_rows_factor);
    return false;
  }
  if (!(sampled_rows_share >= 0.0 && sampled_rows_share <= 1.0)) {
    *error = "sampled_rows_share must be in [0, 1], got " + message_number(sampled_rows_share);
    return false;
  }
  if (!(surrogate_gain >= 0.0) || !std::isfinite(surrogate_gain)) {
    *error = "surrogate_gain must be finite and >= 0, got " + message_number(surrogate_gain);
    return false;
  }
  if (switch_iteration < 1 || !(switch_decrease >= 0.0) || !(switch_gain_ratio >= 0.0)) {
    *error = "switch_iteration must be >= 1 and switch_decrease, switch_gain_ratio >= 0";
    return false;
  }
  return true;
}

std::string RecompressedSolveSummary::brief_report() const {
  return std::string("compressed solve (") + to_string(mode) +
         (switched_to_compression ? ", switched to compression" : "") + "): full cost " +
         message_number(initial_cost) + " -> " + message_number(final_cost) +
         (recompressions > 0 ? " (compressed " + message_number(compressed_initial_cost) + " -> " +
                                   message_number(compressed_final_cost) + ")"
                             : std::string()) +
         (sampled_start
              ? ", sampled start on " + std::to_string(sampled_rows) + " rows" +
                    (exact_form_blocks > 0
                         ? " (" + std::to_string(exact_form_blocks) +
                               (exact_form_blocks == 1 ? " block" : " blocks") + " in exact form)"
                         : std::string())
              : std::string()) +
         ", " + std::to_string(recompressions) + " compressions, " +
         std::to_string(inner_iterations) + " compressed and " + std::to_string(full_iterations) +
         " full iterations, " + std::to_string(full_rows) + " -> " +
         std::to_string(compressed_rows) + " rows, " + to_string(termination) + " (" + message +
         "), " + message_number(total_s) + " s";
}

RecompressedSolveSummary solve_recompressed(Problem& problem,
                                            const RecompressedSolveOptions& options) {
  std::string why;
  if (!options.validate(&why)) throw Error("solve_recompressed: " + why);
  CompressedSolver solver(problem, options);
  return solver.run();
}

}  // namespace carat
