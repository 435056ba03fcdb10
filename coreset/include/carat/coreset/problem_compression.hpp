#pragma once

/// Compressing a whole problem: every selected block replaced by its exact coreset at the
/// problem's current values, in parallel, with the replaced blocks kept in the report. Solving to
/// the full problem's optimum with compressed blocks: compressed_solve.hpp (included here).

#include <cstddef>
#include <functional>
#include <memory>
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
  /// With compression.target_rows 0, each block keeps max(its minimum M, this) rows: more rows
  /// than the minimum r(r+1)/2 + r + 2 of a block of small r make a better subsample away from
  /// the point (solve_recompressed() uses 64), for a coreset that costs little more.
  int min_target_rows = 0;
  int num_threads = 1;  ///< blocks are compressed in parallel; results do not depend on it
  /// Optional filter: compress block `id` only if it returns true.
  std::function<bool(ResidualBlockId, const ResidualBlock&)> select;
};

/// A block compress_problem() replaced, and the block it was.
struct ReplacedBlock {
  ResidualBlockId id;                             ///< the block's id in the problem
  std::shared_ptr<const ResidualBlock> original;  ///< the block before compression
};

/// What compress_problem() did.
struct ProblemCompressionReport {
  int compressed_blocks = 0;     ///< blocks replaced by their coreset
  std::size_t rows_before = 0;   ///< rows of all blocks before
  std::size_t rows_after = 0;    ///< rows of all blocks after
  std::size_t bytes_before = 0;  ///< memory_bytes() of all blocks before
  std::size_t bytes_after = 0;   ///< memory_bytes() of all blocks after
  double seconds = 0.0;          ///< wall time
  /// The blocks replaced, so that the full problem stays at hand (restore_blocks(), or a copy of
  /// the problem with them put back to evaluate its full cost). Holding this report keeps the
  /// original blocks alive; drop it to release their memory.
  std::vector<ReplacedBlock> replaced;
};

/// Replaces every selected block of `problem` by its exact coreset at the problem's current
/// values (compress()), in parallel. Throws carat::Error as compress() does, naming the block.
ProblemCompressionReport compress_problem(Problem& problem,
                                          const ProblemCompressionOptions& options = {});

/// Puts the blocks `report` replaced back into `problem` (the full problem again, at whatever
/// values it holds now). Throws carat::Error if a block id no longer exists.
void restore_blocks(Problem& problem, const ProblemCompressionReport& report);

}  // namespace carat

// solve_recompressed() and its settings, for code that includes this header for them.
#include "carat/coreset/compressed_solve.hpp"
