#pragma once

/// A compact byte form of the residual blocks that registration factors keep: GICP blocks (whole
/// correspondences or single weighted rows), compressed blocks over them (exact coresets) and
/// lossless registration blocks. A block read back holds the same numbers as the one written,
/// so its rows, squared norm and normal equations are equal bit for bit. The bytes are for
/// processes of one job (the machine's own byte order); a reader refuses truncated input and
/// values no writer produces.

#include <memory>

#include "carat/base/byte_stream.hpp"
#include "carat/solver/residual_block.hpp"

namespace carat {

/// True when write_block() has a byte form for `block`: a GicpBlock, a
/// LosslessRegistrationBlock, or a CompressedBlock whose inner block is one of those two.
bool has_byte_form(const ResidualBlock& block);

/// Appends `block` to `out`: a GicpBlock takes 96 bytes per correspondence or 56 per single row,
/// a LosslessRegistrationBlock at most 870 bytes, a CompressedBlock its inner block's bytes and
/// 12 per selected row, each plus a few bytes of tags and counts. Throws carat::Error for a
/// block without a byte form (has_byte_form()).
void write_block(const ResidualBlock& block, ByteWriter& out);

/// The next block written by write_block(). Throws carat::Error naming the reader's input for
/// truncated bytes, an unknown tag, counts or indices out of range, non-finite values, weights
/// that are not positive, or a pivot order that is not a permutation.
std::shared_ptr<const ResidualBlock> read_block(ByteReader& in);

}  // namespace carat
