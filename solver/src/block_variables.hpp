#pragma once

// Internal: the variables of every block a solve adds, the problem's own blocks first, then its
// block source's (block_source.hpp), for the code that lays out the system.

#include <cstddef>
#include <span>

#include "carat/solver/problem.hpp"

namespace carat::internal {

/// Calls visit(variables) for every block in block order: own blocks, then the source's.
template <class Visit>
void for_each_block_variables(const Problem& problem, Visit&& visit) {
  for (const auto& entry : problem.blocks()) visit(std::span<const VariableId>(entry.variables));
  if (const auto& source = problem.block_source()) {
    for (std::size_t k = 0; k < source->num_blocks(); ++k) visit(source->variables(k));
  }
}

}  // namespace carat::internal
