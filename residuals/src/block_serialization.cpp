#include "carat/residuals/block_serialization.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/coreset/compressed_block.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"

namespace carat {
namespace internal {

/// Reads and writes the private state of the blocks that have a byte form.
class BlockCodec {
 public:
  enum Tag : std::uint8_t {
    kGicp = 1,                // GicpBlock: correspondences or single rows
    kCompressedFolded = 2,    // CompressedBlock whose weights live in its inner block
    kCompressedSelected = 3,  // CompressedBlock: inner block, row indices, weights
    kLossless = 4,            // LosslessRegistrationBlock
  };

  static bool leaf(const ResidualBlock& block) {
    return dynamic_cast<const GicpBlock*>(&block) ||
           dynamic_cast<const LosslessRegistrationBlock*>(&block);
  }

  static void write(const ResidualBlock& block, ByteWriter& out) {
    if (const auto* gicp = dynamic_cast<const GicpBlock*>(&block)) {
      out.put(kGicp);
      out.put(static_cast<std::uint64_t>(gicp->points_.size()));
      out.put(static_cast<std::uint64_t>(gicp->rows_.size()));
      out.put_array(std::span<const GicpBlock::Point>(gicp->points_));
      out.put_array(std::span<const GicpBlock::Row>(gicp->rows_));
      return;
    }
    if (const auto* lossless = dynamic_cast<const LosslessRegistrationBlock*>(&block)) {
      out.put(kLossless);
      const PoseEmbedding& e = lossless->embedding_;
      out.put_array(std::span<const double>(e.R_target_source_reference.data(), 9));
      out.put_array(std::span<const double>(e.t_target_source_reference.data(), 3));
      out.put_array(std::span<const double>(e.source_centre.data(), 3));
      out.put(static_cast<std::uint8_t>(lossless->rank_));
      out.put_array(std::span<const std::uint8_t>(lossless->order_));
      out.put_array(std::span<const double>(
          lossless->upper_.data(),
          static_cast<std::size_t>(LosslessRegistrationBlock::row_offset(lossless->rank_))));
      out.put(static_cast<std::uint64_t>(lossless->original_rows_));
      return;
    }
    if (const auto* compressed = dynamic_cast<const CompressedBlock*>(&block)) {
      if (!leaf(compressed->inner()))
        throw Error("write_block: a CompressedBlock over this inner block has no byte form");
      if (compressed->folded()) {
        out.put(kCompressedFolded);
        write(compressed->inner(), out);
        return;
      }
      out.put(kCompressedSelected);
      write(compressed->inner(), out);
      out.put(static_cast<std::uint64_t>(compressed->selected_rows().size()));
      out.put_array(compressed->selected_rows());
      out.put_array(compressed->weights());
      return;
    }
    throw Error(
        "write_block: this block type has no byte form (GicpBlock, LosslessRegistrationBlock and "
        "CompressedBlock over them have)");
  }

  static std::shared_ptr<const ResidualBlock> read(ByteReader& in, bool inner) {
    const auto tag = in.get<std::uint8_t>();
    switch (tag) {
      case kGicp:
        return read_gicp(in);
      case kLossless:
        return read_lossless(in);
      case kCompressedFolded:
      case kCompressedSelected: {
        if (inner) in.garbled("a compressed block inside a compressed block");
        std::shared_ptr<const ResidualBlock> rows = read(in, true);
        if (tag == kCompressedFolded) return std::make_shared<const CompressedBlock>(rows);
        const auto count = in.get<std::uint64_t>();
        if (count == 0 || count > in.remaining() / (sizeof(int) + sizeof(double)))
          in.garbled("selected row count " + std::to_string(count));
        std::vector<int> indices = in.get_array<int>(static_cast<std::size_t>(count));
        std::vector<double> weights = in.get_array<double>(static_cast<std::size_t>(count));
        try {
          return std::make_shared<const CompressedBlock>(rows, std::move(indices),
                                                         std::move(weights));
        } catch (const Error& e) {
          in.garbled(e.what());
        }
      }
      default:
        in.garbled("unknown block tag " + std::to_string(tag));
    }
  }

 private:
  template <typename T>
  static bool finite(const std::vector<T>& items) {
    return std::all_of(items.begin(), items.end(), [](const T& item) {
      const auto* v = reinterpret_cast<const double*>(&item);
      return std::all_of(v, v + sizeof(T) / sizeof(double),
                         [](double x) { return std::isfinite(x); });
    });
  }

  static std::shared_ptr<const ResidualBlock> read_gicp(ByteReader& in) {
    static_assert(sizeof(GicpBlock::Point) == 12 * sizeof(double));
    static_assert(sizeof(GicpBlock::Row) == 7 * sizeof(double));
    const auto points = in.get<std::uint64_t>();
    const auto rows = in.get<std::uint64_t>();
    if ((points == 0) == (rows == 0))
      in.garbled("a GICP block holds " + std::to_string(points) + " correspondences and " +
                 std::to_string(rows) + " rows (one of the two, not both)");
    auto block = std::shared_ptr<GicpBlock>(new GicpBlock());
    block->points_ = in.get_array<GicpBlock::Point>(static_cast<std::size_t>(points));
    block->rows_ = in.get_array<GicpBlock::Row>(static_cast<std::size_t>(rows));
    if (block->num_rows() <= 0 || !finite(block->points_) || !finite(block->rows_))
      in.garbled("a GICP block with a non-finite value or too many rows");
    return block;
  }

  static std::shared_ptr<const ResidualBlock> read_lossless(ByteReader& in) {
    auto block = std::shared_ptr<LosslessRegistrationBlock>(new LosslessRegistrationBlock());
    PoseEmbedding& e = block->embedding_;
    const std::vector<double> pose = in.get_array<double>(15);
    std::copy(pose.begin(), pose.begin() + 9, e.R_target_source_reference.data());
    std::copy(pose.begin() + 9, pose.begin() + 12, e.t_target_source_reference.data());
    std::copy(pose.begin() + 12, pose.end(), e.source_centre.data());
    const int rank = in.get<std::uint8_t>();
    if (rank < 1 || rank > 13) in.garbled("lossless block of rank " + std::to_string(rank));
    block->rank_ = rank;
    const std::vector<std::uint8_t> order = in.get_array<std::uint8_t>(13);
    std::array<bool, 13> seen{};
    for (std::size_t j = 0; j < 13; ++j) {
      if (order[j] >= 13 || seen[order[j]]) in.garbled("a pivot order that is not a permutation");
      seen[order[j]] = true;
      block->order_[j] = order[j];
    }
    const std::vector<double> upper =
        in.get_array<double>(static_cast<std::size_t>(LosslessRegistrationBlock::row_offset(rank)));
    std::copy(upper.begin(), upper.end(), block->upper_.begin());
    block->original_rows_ = static_cast<std::size_t>(in.get<std::uint64_t>());
    if (!finite(pose) || !finite(upper)) in.garbled("a lossless block with a non-finite value");
    return block;
  }
};

}  // namespace internal

bool has_byte_form(const ResidualBlock& block) {
  if (internal::BlockCodec::leaf(block)) return true;
  const auto* compressed = dynamic_cast<const CompressedBlock*>(&block);
  return compressed && internal::BlockCodec::leaf(compressed->inner());
}

void write_block(const ResidualBlock& block, ByteWriter& out) {
  internal::BlockCodec::write(block, out);
}

std::shared_ptr<const ResidualBlock> read_block(ByteReader& in) {
  return internal::BlockCodec::read(in, false);
}

}  // namespace carat
