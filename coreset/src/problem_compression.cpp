#include "carat/coreset/problem_compression.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/solver/evaluate.hpp"
#include "carat/solver/solve.hpp"

namespace carat {
ProblemCompressionReport compress_problem(Problem& problem,
                                          const ProblemCompressionOptions& options) {
  const Stopwatch total_time;
  ProblemCompressionReport report;
  const auto blocks = problem.blocks();
  std::vector<std::shared_ptr<CompressedBlock>> compressed(blocks.size());
  std::vector<std::string> errors(blocks.size());
  tbb::task_arena arena(std::clamp(options.num_threads, 1, tbb::info::default_concurrency()));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t k) {
      const auto& entry = blocks[k];
      const ResidualBlockId id{static_cast<std::int32_t>(k)};
      if (options.select && !options.select(id, *entry.block)) return;
      const int r = entry.block->reduced_dim();
      const int target = options.compression.target_rows > 0 ? options.compression.target_rows
                                                             : r * (r + 1) / 2 + r + 2;
      const int floor = options.min_rows > 0 ? options.min_rows : target;
      if (entry.block->num_rows() <= floor) return;
      std::vector<const double*> params;
      for (VariableId v : entry.variables) params.push_back(problem.value(v).data());
      CompressionOptions compression = options.compression;
      compression.seed = options.compression.seed + k;
      try {
        compressed[k] = compress(entry.block, params, compression);
      } catch (const std::exception& e) {
        errors[k] = e.what();
      }
    });
  });
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    if (!errors[k].empty()) {
      throw Error("compress_problem: residual block " + std::to_string(k) + ": " + errors[k]);
    }
  }
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const auto& block = blocks[k].block;
    report.rows_before += static_cast<std::size_t>(block->num_rows());
    report.bytes_before += block->memory_bytes();
    if (compressed[k]) {
      ++report.compressed_blocks;
      problem.replace_residual_block(ResidualBlockId{static_cast<std::int32_t>(k)}, compressed[k]);
    }
    const auto& now = problem.blocks()[k].block;
    report.rows_after += static_cast<std::size_t>(now->num_rows());
    report.bytes_after += now->memory_bytes();
  }
  report.seconds = total_time.elapsed_s();
  return report;
}

std::string RecompressedSolveSummary::brief_report() const {
  return "recompressed solve: full cost " + message_number(initial_cost) + " -> " +
         message_number(final_cost) + " (max |gradient| " +
         message_number(final_gradient_max_norm) + "), " + std::to_string(recompressions) +
         " compressions, " + std::to_string(inner_iterations) + " inner iterations, " +
         std::to_string(full_rows) + " -> " + std::to_string(compressed_rows) + " rows, " +
         to_string(termination) + " (" + message + "), " + message_number(total_s) + " s";
}

RecompressedSolveSummary solve_recompressed(Problem& problem,
                                            const RecompressedSolveOptions& options) {
  const Stopwatch total_time;
  RecompressedSolveSummary summary;
  std::string why;
  if (!options.inner.validate(&why)) throw Error("solve_recompressed: inner options: " + why);
  if (options.max_recompressions < 1) {
    throw Error("solve_recompressed: max_recompressions must be >= 1, got " +
                std::to_string(options.max_recompressions));
  }
  if (!(options.function_tolerance >= 0.0) || !(options.gradient_tolerance >= 0.0)) {
    throw Error("solve_recompressed: tolerances must be >= 0");
  }
  const int threads = std::max(1, options.compression.num_threads);
  summary.full_rows = problem.num_residual_rows();
  const auto finish = [&](TerminationType type, std::string message) {
    // The reported cost is the full problem's, evaluated once more at the returned point.
    const Stopwatch evaluation_time;
    const ProblemEvaluation final = evaluate_problem(problem, threads);
    summary.full_evaluation_s += evaluation_time.elapsed_s();
    summary.final_cost = final.cost;
    summary.final_gradient_max_norm = final.gradient_max_norm;
    summary.termination = type;
    summary.message = std::move(message);
    summary.total_s = total_time.elapsed_s();
    return summary;
  };
  // A compression at a point is also the full problem's cost and gradient there: the coreset
  // reproduces every block's b and c exactly, so evaluating the compressed copy (a few rows per
  // block) replaces a pass over all rows.
  const auto compressed_at = [&](const std::vector<double>& values, Problem* work,
                                 ProblemEvaluation* model) {
    *work = problem;
    work->set_all_values(values);
    Stopwatch stage;
    const ProblemCompressionReport report = compress_problem(*work, options.compression);
    summary.compression_s += stage.elapsed_s();
    summary.compressed_rows = report.rows_after;
    ++summary.recompressions;
    stage.restart();
    *model = evaluate_problem(*work, threads);
    summary.full_evaluation_s += stage.elapsed_s();
  };
  std::vector<double> accepted(problem.all_values().begin(), problem.all_values().end());
  Problem work;
  ProblemEvaluation full;
  compressed_at(accepted, &work, &full);
  summary.initial_cost = full.cost;
  if (!full.finite) return finish(TerminationType::kFailure, "the initial full cost is not finite");
  if (full.gradient_max_norm <= options.gradient_tolerance) {
    return finish(TerminationType::kConvergence, "full gradient tolerance reached at the start");
  }
  SolverOptions inner = options.inner;
  inner.num_threads = threads;
  for (;;) {
    Problem solved_work = work;
    const Stopwatch solve_time;
    const SolverSummary solved = solve(inner, solved_work);
    summary.inner_solve_s += solve_time.elapsed_s();
    summary.inner_iterations += solved.num_iterations;
    if (solved.termination == TerminationType::kFailure) {
      return finish(TerminationType::kFailure, "the compressed solve failed: " + solved.message);
    }
    if (summary.recompressions >= options.max_recompressions) {
      problem.set_all_values(solved_work.all_values());
      return finish(TerminationType::kNoConvergence,
                    "maximum number of compressions reached (" +
                        std::to_string(options.max_recompressions) + ")");
    }
    const std::vector<double> candidate(solved_work.all_values().begin(),
                                        solved_work.all_values().end());
    Problem next_work;
    ProblemEvaluation next;
    compressed_at(candidate, &next_work, &next);
    summary.records.push_back({next.cost, next.gradient_max_norm, solved.final_cost,
                               solved.num_iterations, summary.compressed_rows});
    if (!next.finite || !(next.cost <= full.cost)) {
      // A rise within the rounding of the cost (a sum of many terms): nothing left to gain.
      const double rounding = 1e3 * std::numeric_limits<double>::epsilon() * full.cost;
      if (next.finite && next.cost - full.cost <= rounding) {
        return finish(TerminationType::kConvergence,
                      "the full cost no longer decreases beyond its rounding");
      }
      // The compressed problem led away from the full optimum: keep the last accepted point. One
      // step of the compressed problem is one step of the full problem's model, so retry with
      // one inner iteration before giving up.
      if (inner.max_iterations > 1) {
        inner.max_iterations = 1;
        continue;
      }
      return finish(TerminationType::kNoConvergence,
                    "a compressed step did not lower the full cost (" + message_number(next.cost) +
                        " after " + message_number(full.cost) + ")");
    }
    const double change = full.cost - next.cost;
    full = next;
    work = std::move(next_work);
    accepted = candidate;
    problem.set_all_values(accepted);
    inner.max_iterations = options.inner.max_iterations;
    if (full.gradient_max_norm <= options.gradient_tolerance) {
      return finish(TerminationType::kConvergence,
                    "full gradient tolerance reached: max |gradient| = " +
                        message_number(full.gradient_max_norm));
    }
    if (change <= options.function_tolerance * std::max(full.cost, 1e-300)) {
      return finish(TerminationType::kConvergence,
                    "full function tolerance reached: |cost change| / cost = " +
                        message_number(full.cost > 0.0 ? change / full.cost : 0.0));
    }
  }
}

}  // namespace carat
