#pragma once

// Internal: what one built factor adds to the stats of the factors it joins.

#include <cstddef>

#include "carat/base/field_count.hpp"
#include "carat/registration/global_registration.hpp"

namespace carat::internal {

/// Adds `factor` (its block present) to *stats: one factor, its correspondences, kept rows,
/// bytes and CPU times.
inline void count_factor(const RegistrationFactor& factor, RegistrationFactorStats* stats) {
  static_assert(field_count<RegistrationFactorStats>() == 8, "count_factor: count the new field");
  stats->num_factors += 1;
  stats->num_correspondences += factor.correspondences;
  stats->num_rows += static_cast<std::size_t>(factor.block->num_rows());
  stats->correspondence_bytes += factor.correspondence_bytes;
  stats->residual_bytes += factor.block->memory_bytes();
  stats->correspondence_s += factor.correspondence_s;
  stats->compression_s += factor.compression_s;
  stats->minimum_s += factor.minimum_s;
}

}  // namespace carat::internal
