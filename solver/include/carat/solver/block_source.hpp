#pragma once

/// Residual blocks held outside a Problem, e.g. by other processes: the problem knows only each
/// block's variables, and every linearization or cost evaluation of solve() asks the source for
/// the blocks' results and adds them to its system as they arrive, in block order. The solver
/// thus holds no per-block data for them, and, as it adds each result in the order it would
/// add a block of its own, a source whose results are those of BlockLinearizer gives the same
/// solve, bit for bit, as the same blocks added to the problem after its own blocks.
///
/// A linearization record of a block of tangent dimension D (the sum of its variables' tangent
/// sizes) holds D (D + 1) / 2 + D + 1 doubles: H = J^T J (robust loss applied as solve() does)
/// as its lower triangle packed by columns (column c holds rows c..D-1), then b = J^T r, then
/// the cost 1/2 rho(|r|^2). A cost record is the cost alone.

#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "carat/solver/variable_id.hpp"

namespace carat {

class Problem;

/// Receives records of consecutive blocks: the first block's index in the source and the records
/// (of as many blocks as they hold).
using BlockRecordSink = std::function<void(std::size_t first, std::span<const double> records)>;

/// Doubles of a linearization record of a block of tangent dimension D.
inline std::size_t linearization_record_size(int D) {
  const auto d = static_cast<std::size_t>(D);
  return d * (d + 1) / 2 + d + 1;
}

/// Blocks whose linearizations and costs come from elsewhere (Problem::set_block_source()).
class BlockSource {
 public:
  virtual ~BlockSource() = default;

  /// Number of blocks.
  virtual std::size_t num_blocks() const = 0;

  /// The variables of block k, in its parameter order (ids of the problem the source is set on).
  virtual std::span<const VariableId> variables(std::size_t k) const = 0;

  /// Linearizes every block at `values` (the problem's all_values() layout) and passes the
  /// linearization records to `sink` in block order, in one or more runs. May throw (the solve
  /// then throws the same); a result that is not finite fails the solve naming the block.
  virtual void linearize(std::span<const double> values, const BlockRecordSink& sink) = 0;

  /// The cost of every block at `values`, passed to `sink` in block order (one double a block).
  virtual void costs(std::span<const double> values, const BlockRecordSink& sink) = 0;

  /// Scalar residual rows over all blocks, for reports (0 when unknown).
  virtual std::size_t num_residual_rows() const { return 0; }
};

/// Evaluates a problem's own residual blocks as solve() does, into records (the serving side of
/// a BlockSource): the results are bit for bit those solve() adds for the same blocks.
class BlockLinearizer {
 public:
  /// For `problem`'s blocks (the problem must outlive this), with `num_threads` threads (>= 1),
  /// passing records in runs of at most `run_blocks` blocks (>= 1). Throws carat::Error for a
  /// problem with a block source of its own.
  BlockLinearizer(const Problem& problem, int num_threads, std::size_t run_blocks = 4096);
  ~BlockLinearizer();
  BlockLinearizer(const BlockLinearizer&) = delete;
  BlockLinearizer& operator=(const BlockLinearizer&) = delete;

  /// Linearizes every block at `values` (all_values() layout) and passes the records to `sink`
  /// in block order, one run at a time (memory: one run's records). A block that throws, or
  /// whose result is not finite, gets a record with a NaN cost, on which solve() fails naming
  /// it. Throws carat::Error for a wrong number of values.
  void linearize(std::span<const double> values, const BlockRecordSink& sink);

  /// The cost of every block at `values`, passed to `sink` in block order in runs (NaN for a
  /// block that threw).
  void costs(std::span<const double> values, const BlockRecordSink& sink);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace carat
