#pragma once

/// Solving a problem to the full problem's optimum with compressed blocks. An exact coreset
/// reproduces a block's H, b and c at the point it was built for, not away from it, and its few
/// rows carry weights of N / M: away from that point the compressed problem is a subsample whose
/// curvature errors are amplified, so solving it stops near, not at, the full optimum. What it
/// does well is the nonlinear part of a solve: its rows are real rows, so one compressed solve
/// can cover what takes a Gauss-Newton model several steps.
///
/// solve_recompressed() uses that in one of these modes (CompressionMode):
/// - kSurrogate (the default): first a sampled start. Every block of many rows is replaced by a
///   uniform random sample of its rows (sampled_rows_factor times its coreset's minimum,
///   compression.min_target_rows or sampled_rows_share of its rows, whichever is most), each
///   weighted N / M: an unbiased estimate of the block's cost at every point, where a coreset is
///   exact at one only. Blocks with a loss per row group stay whole (a row sample would split
///   their groups), and blocks with an exact form (ResidualBlock::exact_form(): registration
///   blocks' lossless rows) enter in that form, so that a problem of such blocks is solved
///   exactly in its few rows. The sampled problem is solved, and the full solve starts at its
///   result, kept when its first linearization finds the full cost lowered (else the full solve
///   starts again from the start; a start of non-finite cost is never left). The full solve
///   switches to compressed solves where its Gauss-Newton model fails (kAuto's rule): each
///   compression is solved (the surrogate) beside one Levenberg-Marquardt step from the same
///   compression (exact H and b there, so the full problem's step), both judged on the full cost;
///   while the surrogate beats the step clearly it compresses again at its result, else it finishes
///   with full iterations. Ends at the full optimum. Without blocks worth sampling (sampling would
///   keep more than a quarter of the rows), with blocks held outside the problem
///   (Problem::set_block_source()), or with sampled_start off, it starts with the compressions.
/// - kRecompress: compress again at every result until the full problem's tests hold; between
///   compressions only compressed blocks are evaluated (for memory rather than time). Ends at the
///   full optimum.
/// - kOnce: compress once and solve (the paper's trade: fast, not the full optimum).
/// - kAuto: a full solve that switches to compressed solves (kSurrogate's rounds) when its
///   Gauss-Newton model fails (a step rejected, or a poor gain ratio while far from converged: a
///   nonlinear region, where compression pays); otherwise the full solve, at no cost over it.
/// - kFull: no compression (the reference).
///
/// When it pays, measured (docs/benchmarks.md, "Compressed solves"): a full solve spends most of
/// its iterations getting near the optimum and its last two in the region where Gauss-Newton
/// converges fast. The sampled start covers the first part with passes over a few hundred rows
/// per block, so that kSurrogate takes about the full solve's last two iterations plus one
/// residual pass: 0.45-0.59 x the full solve from 4-5 iterations up, 0.74 x at 3 (0.48 x on a
/// registration graph of exact forms, at 3, where one full iteration confirms). An exact
/// compression costs one pass over the rows plus the coreset (more than a full iteration for
/// blocks of 12 unknowns), so it pays only where the model fails for a stretch.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "carat/coreset/problem_compression.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat {

/// How solve_recompressed() uses compression (see the file comment).
enum class CompressionMode {
  kSurrogate,   ///< a sampled start, then a full solve switching to compressed solves as kAuto
  kRecompress,  ///< compress again at every result until the full tests hold
  kOnce,        ///< one compression, solved: fast, not the full optimum
  kAuto,        ///< the full solve, switching to compressed solves in a nonlinear stretch
  kFull,        ///< no compression
};

/// Name of a mode: "surrogate", "recompress", "once", "auto" or "full".
const char* to_string(CompressionMode mode);
/// Parses a mode's name; throws carat::Error listing them otherwise.
CompressionMode parse_compression_mode(std::string_view name);

/// Settings of solve_recompressed().
struct RecompressedSolveOptions {
  /// What to compress (num_threads is also the solves'). By default every block keeps at least
  /// 64 rows (min_target_rows): for blocks of small r (the curve fit's 2, a pose's 6) a larger
  /// subsample's solve lands closer to the optimum, which saves full iterations.
  ProblemCompressionOptions compression = [] {
    ProblemCompressionOptions defaults;
    defaults.min_target_rows = 64;
    return defaults;
  }();
  /// Every solve inside: of sampled and compressed problems, and the full iterations that
  /// finish kSurrogate and make kAuto and kFull (their stop tests are the full solve's). Its
  /// iteration_callback sees the rows of each of these solves (each counting from 0; a sampled
  /// or compressed solve's costs are its own problem's); kAbort ends solve_recompressed().
  SolverOptions inner;
  CompressionMode mode = CompressionMode::kSurrogate;  ///< how compression is used
  int max_recompressions = 20;                         ///< compressions at most
  /// kRecompress: stop when the full cost changes by less than this, relatively, between
  /// compressions.
  double function_tolerance = 1e-12;
  /// kSurrogate and kRecompress: stop when the full max |gradient| at a compression is below this.
  double gradient_tolerance = 1e-10;
  /// kSurrogate: compress again only while the surrogate's result lowers the full cost beyond one
  /// full step's by at least this share of that step's decrease; else finish with full
  /// iterations.
  double surrogate_gain = 0.5;
  /// kAuto and kSurrogate's full solve: from this iteration on, the full solve switches to
  /// compressed solves when the Gauss-Newton model fails where it stands: a step rejected, or
  /// one accepted with a gain ratio below switch_gain_ratio while it lowered the cost by more
  /// than switch_decrease (relatively). Where the model holds, the full solve converges in a
  /// few steps and compression would not pay.
  int switch_iteration = 1;
  double switch_decrease = 1e-3;    ///< kAuto and kSurrogate: see switch_iteration
  double switch_gain_ratio = 0.25;  ///< kAuto and kSurrogate: see switch_iteration
  /// kSurrogate: start from the solution of a uniformly sampled problem (see the file comment).
  bool sampled_start = true;
  /// kSurrogate's sampled start: rows kept per block, the largest of this multiple of the
  /// block's minimum coreset rows r(r+1)/2 + r + 2, compression.min_target_rows (64 by
  /// default) and sampled_rows_share of its rows; blocks of at most twice that many rows, and
  /// blocks compression.select leaves out, are kept whole.
  int sampled_rows_factor = 4;
  double sampled_rows_share = 1.0 / 256.0;  ///< kSurrogate: see sampled_rows_factor; in [0, 1]
  /// kSurrogate's sampled start: a block that has an exact form (ResidualBlock::exact_form(),
  /// e.g. registration blocks' lossless rows) enters the sampled problem in it, not sampled; a
  /// form that throws carat::Error leaves the block to sampling, and one over other tangent
  /// sizes, without rows or with a group loss is a carat::Error naming the block.
  bool exact_forms = true;

  /// True if every setting is in range; otherwise false with a message in *error.
  bool validate(std::string* error) const;
};

/// One compression of solve_recompressed() and what became of it.
struct RecompressionRecord {
  double full_cost = 0.0;               ///< full cost at the compression point (from its coreset)
  double full_gradient_max_norm = 0.0;  ///< full max |gradient| there (from its coreset)
  double compressed_final_cost = 0.0;   ///< the compressed problem's own cost after its solve
  double full_cost_after = 0.0;         ///< the full cost at that solve's result (kSurrogate)
  double full_cost_after_step = 0.0;    ///< kSurrogate: the full cost after one full step instead
  int inner_iterations = 0;             ///< iterations of the compressed solve
  std::size_t compressed_rows = 0;      ///< rows of the compressed problem
};

/// What solve_recompressed() did. initial_cost and final_cost are the full problem's (every
/// mode); the compressed problem's own costs are beside them.
struct RecompressedSolveSummary {
  TerminationType termination = TerminationType::kFailure;  ///< why it stopped
  std::string message;                                      ///< the reason in words
  CompressionMode mode = CompressionMode::kSurrogate;       ///< the mode asked for
  /// kAuto and kSurrogate: whether the full solve switched to compressed solves.
  bool switched_to_compression = false;
  double initial_cost = 0.0;              ///< full cost at the start
  double final_cost = 0.0;                ///< full cost of the returned point
  double final_gradient_max_norm = -1.0;  ///< full max |gradient| there; -1 when not evaluated
  double compressed_initial_cost = 0.0;   ///< the first compressed problem's cost at its start
  double compressed_final_cost = 0.0;     ///< the last compressed problem's cost after its solve
  int recompressions = 0;                 ///< compressions done
  int inner_iterations = 0;               ///< iterations of all compressed and sampled solves
  int full_iterations = 0;          ///< iterations of full solves (kSurrogate's finish, kAuto)
  std::size_t full_rows = 0;        ///< rows of the full problem
  std::size_t compressed_rows = 0;  ///< rows of the (last) compressed problem
  double compression_s = 0.0;       ///< time compressing (and sampling)
  double inner_solve_s = 0.0;       ///< time solving compressed and sampled problems
  double full_evaluation_s = 0.0;   ///< time evaluating full costs
  double full_solve_s = 0.0;        ///< time in full iterations
  double total_s = 0.0;             ///< whole call
  std::vector<RecompressionRecord> records;  ///< one per compression
  /// kSurrogate: whether the sampled start ran, its problem's rows, and the full cost at its
  /// solution (kept when below initial_cost; infinity when the sampled solve failed or that
  /// cost is not finite; 0 when it did not run).
  bool sampled_start = false;
  std::size_t sampled_rows = 0;     ///< rows of the sampled problem (0 when it did not run)
  double sampled_start_cost = 0.0;  ///< full cost at the sample's solution (see sampled_start)
  int exact_form_blocks = 0;  ///< blocks in the sampled problem in their exact form (exact_forms)
  /// One line: mode, full and compressed costs, compressions, iterations, termination, time.
  std::string brief_report() const;
};

/// Minimizes the full problem's cost as `options.mode` says (see the file comment) and writes the
/// result into `problem`, whose blocks are not changed. Does not throw for numerical trouble
/// (reported as termination); throws carat::Error for invalid options or a block compress()
/// refuses, naming the block.
RecompressedSolveSummary solve_recompressed(Problem& problem,
                                            const RecompressedSolveOptions& options = {});

}  // namespace carat
