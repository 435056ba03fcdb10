#include "carat/coreset/compress.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <span>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "shuffle.hpp"

namespace carat {
namespace {

std::string label(const ResidualBlock& block) {
  return block.name().empty() ? std::string("the block") : "block '" + block.name() + "'";
}

/// Keeps only the selected rows' data when the block can extract them, with the weights folded
/// into the rows when the block can do that too.
std::shared_ptr<CompressedBlock> make_compressed(std::shared_ptr<const ResidualBlock> block,
                                                 std::vector<int> rows,
                                                 std::vector<double> weights) {
  if (std::unique_ptr<ResidualBlock> weighted = block->extract_weighted_rows(rows, weights)) {
    return std::make_shared<CompressedBlock>(
        std::shared_ptr<const ResidualBlock>(std::move(weighted)));
  }
  if (std::unique_ptr<ResidualBlock> extracted = block->extract_rows(rows)) {
    std::vector<int> local(rows.size());
    std::iota(local.begin(), local.end(), 0);
    return std::make_shared<CompressedBlock>(
        std::shared_ptr<const ResidualBlock>(std::move(extracted)), std::move(local),
        std::move(weights));
  }
  return std::make_shared<CompressedBlock>(std::move(block), std::move(rows), std::move(weights));
}

/// The coreset of a block with a group loss: its rows were weighted by sqrt(rho'(s_g)) at
/// `values`; the compressed block holds the plain rows with those weights frozen into the coreset
/// weights, and sum_g rho(s_g) - sum_g rho'(s_g) s_g as a constant, so that its H, b and c at
/// `values` are the robust block's (and it is plain least squares elsewhere). `weighted_sum` is
/// the sum of the weighted rows' squares.
std::shared_ptr<CompressedBlock> freeze_group_loss(const ResidualBlock& block,
                                                   ParameterPointers values, RowCoreset coreset,
                                                   double weighted_sum) {
  std::vector<double> loss_weights(coreset.rows.size());
  std::unique_ptr<ResidualBlock> plain =
      block.extract_rows_without_loss(values, coreset.rows, loss_weights.data());
  if (!plain) {
    throw Error("compress: " + label(block) +
                " has a group loss but cannot extract its rows without it "
                "(extract_rows_without_loss() returned null)");
  }
  std::vector<int> local;
  std::vector<double> weights;
  for (std::size_t k = 0; k < coreset.rows.size(); ++k) {
    const double w = coreset.weights[k] * loss_weights[k];
    if (w > 0.0) {  // a row the loss gives no weight adds nothing
      local.push_back(static_cast<int>(k));
      weights.push_back(w);
    }
  }
  const double robust_sum = block.squared_norm(values);
  if (local.empty()) {  // every selected row has weight 0: keep one row at weight 1 with no say
    throw Error("compress: " + label(block) + ": the group loss gives every row weight 0");
  }
  return std::make_shared<CompressedBlock>(std::shared_ptr<const ResidualBlock>(std::move(plain)),
                                           std::move(local), std::move(weights),
                                           robust_sum - weighted_sum);
}

}  // namespace

std::shared_ptr<CompressedBlock> compress(std::shared_ptr<const ResidualBlock> block,
                                          ParameterPointers values,
                                          const CompressionOptions& options) {
  if (!block) throw Error("compress: block is null");
  if (values.size() != block->tangent_dims().size()) {
    throw Error("compress: the block has " + std::to_string(block->tangent_dims().size()) +
                " variables but " + std::to_string(values.size()) + " values were given");
  }
  const int n = block->num_rows();
  const int r = block->reduced_dim();
  // Per-thread scratch that only grows, up to kMaxReusedBytes: compressing thousands of factors
  // in a row, or one large block again and again (solve_recompressed()), would otherwise map and
  // fault in fresh pages on every call. A larger block gets scratch of its own, not zero-filled.
  constexpr std::size_t kMaxReusedBytes = std::size_t{64} << 20;
  // A block's evaluate_rows() may run parallel work whose scheduler starts another compress()
  // on this thread; the flag keeps that nested call off the buffers in use.
  thread_local std::vector<double> reused_jacobian, reused_residuals;
  thread_local std::vector<int> reused_indices;
  thread_local bool in_use = false;
  const auto size = static_cast<std::size_t>(n);
  const std::size_t jacobian_size = size * static_cast<std::size_t>(r);
  // The buffers kept only grow: reuse them while all three together stay within the limit.
  const std::size_t kept_bytes = std::max(reused_jacobian.size(), jacobian_size) * sizeof(double) +
                                 std::max(reused_residuals.size(), size) * sizeof(double) +
                                 std::max(reused_indices.size(), size) * sizeof(int);
  const bool reuse = kept_bytes <= kMaxReusedBytes && !in_use;
  struct Claim {
    bool* flag;
    ~Claim() {
      if (flag) *flag = false;
    }
  } claim{reuse ? &in_use : nullptr};
  std::unique_ptr<double[]> local_jacobian, local_residuals;
  std::unique_ptr<int[]> local_indices;
  double* jacobian_buffer = nullptr;
  double* residual_buffer = nullptr;
  int* all = nullptr;
  if (reuse) {
    in_use = true;
    if (reused_jacobian.size() < jacobian_size) reused_jacobian.resize(jacobian_size);
    if (reused_residuals.size() < size) reused_residuals.resize(size);
    if (reused_indices.size() < size) {
      const std::size_t old = reused_indices.size();
      reused_indices.resize(size);
      std::iota(reused_indices.begin() + static_cast<std::ptrdiff_t>(old), reused_indices.end(),
                static_cast<int>(old));
    }
    jacobian_buffer = reused_jacobian.data();
    residual_buffer = reused_residuals.data();
    all = reused_indices.data();
  } else {
    local_jacobian = std::make_unique_for_overwrite<double[]>(jacobian_size);
    local_residuals = std::make_unique_for_overwrite<double[]>(size);
    local_indices = std::make_unique_for_overwrite<int[]>(size);
    std::iota(local_indices.get(), local_indices.get() + size, 0);
    jacobian_buffer = local_jacobian.get();
    residual_buffer = local_residuals.get();
    all = local_indices.get();
  }
  block->evaluate_rows(values, std::span<const int>(all, size), residual_buffer, jacobian_buffer);
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> J(
      jacobian_buffer, n, r);
  const Eigen::Map<const Eigen::VectorXd> e(residual_buffer, n);
  RowCoresetOptions row_options;
  row_options.target_rows = options.target_rows;
  row_options.clusters = options.clusters;
  row_options.seed = options.seed;
  row_options.exact_size = options.exact_size;
  RowCoreset coreset = select_coreset_rows(J, e, row_options);
  if (block->group_loss()) {
    return freeze_group_loss(*block, values, std::move(coreset), e.squaredNorm());
  }
  return make_compressed(std::move(block), std::move(coreset.rows), std::move(coreset.weights));
}

std::shared_ptr<CompressedBlock> compress_rows(std::shared_ptr<const ResidualBlock> block,
                                               std::vector<int> rows, std::vector<double> weights) {
  if (!block) throw Error("compress_rows: block is null");
  if (block->group_loss()) {
    throw Error("compress_rows: " + label(*block) +
                " has a loss per row group, which a choice of rows would split; compress() "
                "freezes it exactly");
  }
  if (rows.empty()) throw Error("compress_rows: no rows");
  if (rows.size() != weights.size()) {
    throw Error("compress_rows: " + std::to_string(rows.size()) + " rows but " +
                std::to_string(weights.size()) + " weights");
  }
  const int n = block->num_rows();
  for (std::size_t k = 0; k < rows.size(); ++k) {
    if (rows[k] < 0 || rows[k] >= n) {
      throw Error("compress_rows: row " + std::to_string(rows[k]) + " is out of range (" +
                  label(*block) + " has " + std::to_string(n) + " rows)");
    }
    if (k > 0 && rows[k] <= rows[k - 1]) {
      throw Error("compress_rows: rows must ascend without repeats; row " +
                  std::to_string(rows[k]) + " follows " + std::to_string(rows[k - 1]));
    }
    if (!std::isfinite(weights[k]) || !(weights[k] > 0.0)) {
      throw Error("compress_rows: the weight of row " + std::to_string(rows[k]) + " is " +
                  message_number(weights[k]) + "; weights must be finite and > 0");
    }
  }
  return make_compressed(std::move(block), std::move(rows), std::move(weights));
}

std::shared_ptr<CompressedBlock> compress_random(std::shared_ptr<const ResidualBlock> block,
                                                 const RandomSamplingOptions& options) {
  if (!block) throw Error("compress_random: block is null");
  const int n = block->num_rows();
  const int g = options.group_size;
  if (g < 1) throw Error("compress_random: group size must be >= 1, got " + std::to_string(g));
  if (n % g != 0) {
    throw Error("compress_random: the block's " + std::to_string(n) +
                " rows are not a whole number of groups of " + std::to_string(g));
  }
  if (options.target_rows < g || options.target_rows % g != 0) {
    throw Error("compress_random: target of " + std::to_string(options.target_rows) +
                " rows must be a positive multiple of the group size " + std::to_string(g));
  }
  std::vector<int> rows;
  std::vector<double> weights;
  if (options.target_rows >= n) {
    rows.resize(static_cast<std::size_t>(n));
    std::iota(rows.begin(), rows.end(), 0);
    weights.assign(rows.size(), 1.0);
  } else {
    const int groups = n / g;
    const int keep = options.target_rows / g;
    std::vector<int> order = internal::seeded_permutation(groups, options.seed);
    order.resize(static_cast<std::size_t>(keep));
    std::sort(order.begin(), order.end());
    const double weight = static_cast<double>(n) / static_cast<double>(options.target_rows);
    for (int group : order) {
      for (int k = 0; k < g; ++k) rows.push_back(group * g + k);
    }
    weights.assign(rows.size(), weight);
  }
  return make_compressed(std::move(block), std::move(rows), std::move(weights));
}

}  // namespace carat
