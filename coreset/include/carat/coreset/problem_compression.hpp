#pragma once

/// Compressing a whole problem, and solving it to the full problem's optimum with compressed
/// blocks. An exact coreset reproduces a block's H, b and c at the point it was built for, not
/// away from it: solving a compressed problem stops near, not at, the full optimum (the further
/// the solve moves, the further off). solve_recompressed() alternates: compress every block at
/// the current point, solve the compressed problem, judge the result on the full problem (its
/// cost and gradient), and compress again there, until the full problem's own convergence tests
/// hold. At that point the compressed gradient equals the full one, so the optimum is the full
/// problem's.

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "carat/coreset/compress.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat {

/// Which blocks compress_problem() compresses, and how.
struct ProblemCompressionOptions {
  CompressionOptions compression;  ///< M, clusters; block k uses seed compression.seed + k
  /// Blocks with at most this many rows stay as they are (0: those with at most M rows, for
  /// which a coreset would be the block itself).
  int min_rows = 0;
  int num_threads = 1;  ///< blocks are compressed in parallel; results do not depend on it
  /// Optional filter: compress block `id` only if it returns true.
  std::function<bool(ResidualBlockId, const ResidualBlock&)> select;
};

/// What compress_problem() did.
struct ProblemCompressionReport {
  int compressed_blocks = 0;     ///< blocks replaced by their coreset
  std::size_t rows_before = 0;   ///< rows of all blocks before
  std::size_t rows_after = 0;    ///< rows of all blocks after
  std::size_t bytes_before = 0;  ///< memory_bytes() of all blocks before
  std::size_t bytes_after = 0;   ///< memory_bytes() of all blocks after
  double seconds = 0.0;          ///< wall time
};

/// Replaces every selected block of `problem` by its exact coreset at the problem's current
/// values (compress()), in parallel. Throws carat::Error as compress() does, naming the block.
ProblemCompressionReport compress_problem(Problem& problem,
                                          const ProblemCompressionOptions& options = {});

/// Settings of solve_recompressed().
struct RecompressedSolveOptions {
  ProblemCompressionOptions compression;  ///< what to compress (num_threads is also the solve's)
  SolverOptions inner;                    ///< the solves of the compressed problems
  int max_recompressions = 20;            ///< compressions (outer iterations) at most
  /// Stop when the full cost changes by less than this, relatively, between compressions.
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-10;  ///< stop when the full max |gradient| is below this
};

/// One outer iteration of solve_recompressed(): a solve of the compressed problem, judged at the
/// compression of its result.
struct RecompressionRecord {
  double full_cost = 0.0;               ///< full cost at the solve's result (from its coreset)
  double full_gradient_max_norm = 0.0;  ///< full max |gradient| there (from its coreset)
  double compressed_final_cost = 0.0;   ///< the compressed problem's own final cost
  int inner_iterations = 0;             ///< iterations of the compressed solve
  std::size_t compressed_rows = 0;      ///< rows of the compressed problem
};

/// What solve_recompressed() did. Costs are the full problem's.
struct RecompressedSolveSummary {
  TerminationType termination = TerminationType::kFailure;  ///< why it stopped
  std::string message;                                      ///< the reason in words
  double initial_cost = 0.0;                                ///< full cost at the start
  double final_cost = 0.0;                                  ///< full cost of the returned point
  double final_gradient_max_norm = 0.0;                     ///< full max |gradient| there
  int recompressions = 0;                    ///< compressions done (outer iterations)
  int inner_iterations = 0;                  ///< iterations of all compressed solves
  std::size_t full_rows = 0;                 ///< rows of the full problem
  std::size_t compressed_rows = 0;           ///< rows of the (last) compressed problem
  double compression_s = 0.0;                ///< time compressing
  double inner_solve_s = 0.0;                ///< time solving compressed problems
  double full_evaluation_s = 0.0;            ///< time evaluating the full problem
  double total_s = 0.0;                      ///< whole call
  std::vector<RecompressionRecord> records;  ///< one per outer iteration
  /// One line: costs, compressions, inner iterations, termination, time.
  std::string brief_report() const;
};

/// Minimizes the full problem's cost with compressed copies of it (see the file comment) and
/// writes the result into `problem` (whose blocks are not changed). The compression at a solve's
/// result also judges it: a coreset keeps each block's b and c exactly, so the compressed copy's
/// cost and gradient are the full problem's there, without a pass over all rows; the final cost
/// is the full problem's, evaluated once at the end. Each outer iteration is accepted only if it
/// lowers the full cost; otherwise the solve retries with one inner iteration, then stops at the
/// last accepted point. Does not throw for numerical trouble (reported as termination); throws
/// carat::Error for invalid options or a block compress() refuses.
RecompressedSolveSummary solve_recompressed(Problem& problem,
                                            const RecompressedSolveOptions& options = {});

}  // namespace carat
