#pragma once

/// Compressing residual blocks: exactly (Caratheodory coreset) or by uniform random sampling
/// (the baseline the paper compares against). Both return a CompressedBlock that holds only
/// the data of the selected rows when the block supports extract_rows().

#include <cstdint>
#include <memory>

#include "carat/coreset/compressed_block.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// Settings of compress().
struct CompressionOptions {
  int target_rows = 0;     ///< M; 0: the minimum r(r+1)/2 + r + 2 for the block's reduced dim r
  int clusters = 0;        ///< K clusters per level; 0: default_coreset_clusters(r)
  std::uint64_t seed = 1;  ///< seed of the shuffle
  bool exact_size = true;  ///< exactly M rows (when the block has more than M)
};

/// Exact compression at `values`: the weighted rows reproduce J_r^T J_r, J_r^T e and e^T e of
/// the block (and so its full H, b, c through the block's reduced map) to rounding. A block
/// with at most M rows comes back whole, every weight 1. Throws carat::Error for bad options or
/// non-finite rows.
std::shared_ptr<CompressedBlock> compress(std::shared_ptr<const ResidualBlock> block,
                                          ParameterPointers values,
                                          const CompressionOptions& options = {});

/// The block kept at `rows` (ascending, distinct, in range) with `weights` (finite, > 0; a
/// weight w counts its row w times): the rows' data extracted where the block can
/// (extract_weighted_rows(), else extract_rows()), else the whole block with the row indices.
/// What compress() and compress_random() return, for rows chosen by other means. Throws
/// carat::Error naming the first row or weight that does not fit.
std::shared_ptr<CompressedBlock> compress_rows(std::shared_ptr<const ResidualBlock> block,
                                               std::vector<int> rows, std::vector<double> weights);

/// Settings of compress_random().
struct RandomSamplingOptions {
  int target_rows = 29;    ///< M rows to keep (a multiple of group_size)
  int group_size = 1;      ///< rows that are kept or dropped together (3 for a GICP point)
  std::uint64_t seed = 1;  ///< seed of the draw
};

/// Uniform random sampling without replacement of M / group_size groups of group_size
/// consecutive rows; every kept row gets weight N / M. Throws carat::Error if the block's rows
/// are not a whole number of groups or M is not a positive multiple of the group size.
std::shared_ptr<CompressedBlock> compress_random(std::shared_ptr<const ResidualBlock> block,
                                                 const RandomSamplingOptions& options = {});

}  // namespace carat
