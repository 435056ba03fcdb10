#pragma once

// Internal: reading a block source's runs (block_source.hpp) in block order, with the checks
// every reader makes.

#include <cstddef>
#include <span>
#include <string>

#include "carat/base/error.hpp"
#include "carat/solver/block_source.hpp"

namespace carat::internal {

/// Throws unless a run of `what` (e.g. "records") starts at block `next`, the one expected.
inline void check_run_start(std::size_t first, std::size_t next, const char* what) {
  if (first != next) {
    throw Error(std::string("block source: ") + what + " of block " + std::to_string(first) +
                " arrived where block " + std::to_string(next) + " was expected");
  }
}

/// Throws unless the runs of `what` covered all `blocks` blocks (`seen` of them).
inline void check_runs_complete(std::size_t seen, std::size_t blocks, const char* what) {
  if (seen != blocks) {
    throw Error(std::string("block source: ") + what + " of " + std::to_string(seen) + " of its " +
                std::to_string(blocks) + " blocks");
  }
}

/// `total` plus the source's costs at `values`, added in block order.
inline double add_source_costs(BlockSource& source, std::span<const double> values, double total) {
  std::size_t next = 0;
  source.costs(values, [&](std::size_t first, std::span<const double> costs) {
    check_run_start(first, next, "the cost");
    for (const double c : costs) total += c;
    next += costs.size();
  });
  check_runs_complete(next, source.num_blocks(), "costs");
  return total;
}

}  // namespace carat::internal
