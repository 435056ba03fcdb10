#include "block_evaluator.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "huge_pages.hpp"
#include "source_runs.hpp"

namespace carat::internal {
namespace {

bool finite(const double* x, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i])) return false;
  }
  return true;
}

/// Which row of a block is not finite, for the message: its residual, else its Jacobian row.
std::string first_bad_row(const ResidualBlock& block, ParameterPointers params) {
  const int n = block.num_rows();
  const int r = block.reduced_dim();
  constexpr int kChunk = 256;
  std::vector<int> rows;
  std::vector<double> residuals, jacobian;
  try {
    for (int begin = 0; begin < n; begin += kChunk) {
      const int count = std::min(kChunk, n - begin);
      rows.resize(static_cast<std::size_t>(count));
      for (int k = 0; k < count; ++k) rows[static_cast<std::size_t>(k)] = begin + k;
      residuals.assign(static_cast<std::size_t>(count), 0.0);
      jacobian.assign(static_cast<std::size_t>(count) * static_cast<std::size_t>(r), 0.0);
      evaluate_rows_checked(block, params, rows, residuals.data(), jacobian.data());
      for (int k = 0; k < count; ++k) {
        const double value = residuals[static_cast<std::size_t>(k)];
        if (!std::isfinite(value)) {
          return "row " + std::to_string(begin + k) + " is not finite (residual " +
                 std::to_string(value) + ")";
        }
        if (!finite(jacobian.data() + static_cast<std::size_t>(k) * r,
                    static_cast<std::size_t>(r))) {
          return "the Jacobian of row " + std::to_string(begin + k) + " is not finite";
        }
      }
    }
  } catch (const std::exception& e) {
    return std::string("evaluating its rows failed: ") + e.what();
  }
  return "its sums overflow (every row is finite)";
}

}  // namespace

void record_bad_block(std::atomic<std::size_t>& first_bad, std::size_t i) {
  std::size_t seen = first_bad.load(std::memory_order_relaxed);
  while (i < seen && !first_bad.compare_exchange_weak(seen, i)) {
  }
}

BlockEvaluator::BlockEvaluator(const Problem& problem) : problem_(problem) {
  const auto blocks = problem.blocks();
  dims_.reserve(blocks.size());
  std::size_t num_params = 0;
  for (const auto& entry : blocks) {
    dims_.push_back(entry.block->tangent_dim());
    num_params += entry.variables.size();
  }
  param_offsets_.reserve(num_params);
  param_begin_.reserve(blocks.size() + 1);
  param_begin_.push_back(0);
  for (const auto& entry : blocks) {
    for (VariableId v : entry.variables) param_offsets_.push_back(problem.value_offset(v));
    param_begin_.push_back(param_offsets_.size());
  }
  block_cost_.resize(blocks.size());
}

void BlockEvaluator::bind(int which, const double* values) {
  values_[which] = values;
  auto& ptrs = pointers_[which];
  ptrs.resize(param_offsets_.size());
  for (std::size_t k = 0; k < param_offsets_.size(); ++k) ptrs[k] = values + param_offsets_[k];
}

void BlockEvaluator::allocate(BlockLinearizations* out, std::size_t run_blocks) const {
  const auto blocks = problem_.blocks();
  out->h_offset.resize(blocks.size());
  out->b_offset.resize(blocks.size());
  out->dim.resize(blocks.size());
  out->cost.assign(blocks.size(), 0.0);
  run_blocks = std::max<std::size_t>(run_blocks, 1);
  std::size_t h = 0;
  std::size_t b = 0;
  std::size_t run_h = 0;  // the largest run's
  std::size_t run_b = 0;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const int D = blocks[i].block->tangent_dim();
    out->dim[i] = D;
    out->h_offset[i] = h;
    out->b_offset[i] = b;
    h += static_cast<std::size_t>(D) * static_cast<std::size_t>(D + 1) / 2;
    b += static_cast<std::size_t>(D);
    const std::size_t first = i - i % run_blocks;
    run_h = std::max(run_h, h - out->h_offset[first]);
    run_b = std::max(run_b, b - out->b_offset[first]);
  }
  out->h.assign(run_h, 0.0);  // huge pages (see huge_pages.hpp)
  out->b.assign(run_b, 0.0);
}

bool BlockEvaluator::evaluate_block(std::size_t i, int which, BlockScratch& s, double* packed_h,
                                    double* b_out, double* cost) const {
  // A block that throws (a user's functor, a prepare() hook, a loss) is a bad block: the caller
  // names it, and describe_bad_block() repeats the evaluation to report what it threw.
  try {
    return evaluate_block_unguarded(i, which, s, packed_h, b_out, cost);
  } catch (...) {
    *cost = std::numeric_limits<double>::quiet_NaN();
    return false;
  }
}

bool BlockEvaluator::evaluate_block_unguarded(std::size_t i, int which, BlockScratch& s,
                                              double* packed_h, double* b_out, double* cost) const {
  const auto& entry = problem_.blocks()[i];
  const ResidualBlock& block = *entry.block;
  const auto& ptrs = pointers_[which];
  const ParameterPointers params(ptrs.data() + param_begin_[i],
                                 param_begin_[i + 1] - param_begin_[i]);
  const int D = dims_[i];
  const int r = block.reduced_dim();
  s.H_r.setZero(r, r);
  s.b_r.setZero(r);
  const double sq = block.accumulate(params, s.H_r, s.b_r);
  Eigen::Map<Eigen::VectorXd> b(b_out, D);
  if (r == D) {
    b = s.b_r;
  } else {
    s.A.resize(r, D);
    block.reduced_map(params, s.A.data());
    s.H.noalias() = s.A.transpose() * s.H_r * s.A;
    s.H_r.swap(s.H);
    b.noalias() = s.A.transpose() * s.b_r;
  }
  Eigen::MatrixXd& H = s.H_r;  // D x D now
  if (entry.loss) {
    const LossValue lv = entry.loss->evaluate(sq);
    const double second = lv.rho1 + 2.0 * sq * lv.rho2;
    if (lv.rho2 != 0.0 && second > 0.0) {
      H = lv.rho1 * H + (2.0 * lv.rho2) * (b * b.transpose());
    } else {
      H *= lv.rho1;
    }
    b *= lv.rho1;
    *cost = 0.5 * lv.rho;
  } else {
    *cost = 0.5 * sq;
  }
  // The lower triangle, packed by columns.
  bool ok = std::isfinite(*cost) && b.allFinite();
  for (int c = 0; c < D; ++c) {
    const double* column = H.data() + static_cast<std::size_t>(c) * static_cast<std::size_t>(D);
    for (int row = c; row < D; ++row) {
      *packed_h++ = column[row];
      ok = ok && std::isfinite(column[row]);
    }
  }
  return ok;
}

bool BlockEvaluator::evaluate_rows(std::size_t i, int which, int n, double* out,
                                   double* cost) const {
  static constexpr int kRows[] = {0, 1, 2, 3, 4, 5, 6, 7};
  const auto& ptrs = pointers_[which];
  const ParameterPointers params(ptrs.data() + param_begin_[i],
                                 param_begin_[i + 1] - param_begin_[i]);
  const auto count = static_cast<std::size_t>(n) * static_cast<std::size_t>(dims_[i] + 1);
  double* residuals = out + static_cast<std::size_t>(n) * static_cast<std::size_t>(dims_[i]);
  try {
    problem_.blocks()[i].block->evaluate_rows(
        params, std::span<const int>(kRows, static_cast<std::size_t>(n)), residuals, out);
  } catch (...) {
    *cost = std::numeric_limits<double>::quiet_NaN();
    return false;
  }
  double sum = 0.0;
  bool ok = true;
  for (std::size_t k = 0; k < count; ++k) ok = ok && std::isfinite(out[k]);
  for (int k = 0; k < n; ++k) sum += residuals[k] * residuals[k];
  *cost = 0.5 * sum;
  return ok;
}

std::string BlockEvaluator::describe_bad_block(std::size_t i, int which) const {
  const auto& ptrs = pointers_[which];
  const ParameterPointers params(ptrs.data() + param_begin_[i],
                                 param_begin_[i + 1] - param_begin_[i]);
  const ResidualBlock& block = *problem_.blocks()[i].block;
  return "residual block " + std::to_string(i) +
         (block.name().empty() ? std::string() : " ('" + block.name() + "')") + ": " +
         first_bad_row(block, params);
}

bool BlockEvaluator::linearize(int which, BlockLinearizations* out, std::string* error) const {
  return linearize_run(which, 0, problem_.blocks().size(), out, error);
}

bool BlockEvaluator::linearize_run(int which, std::size_t first, std::size_t last,
                                   BlockLinearizations* out, std::string* error) const {
  if (first >= last) return true;
  tbb::enumerable_thread_specific<BlockScratch> scratch;
  const std::size_t h_base = out->h_offset[first];
  const std::size_t b_base = out->b_offset[first];
  // The first block (lowest index) whose H, b or cost is not finite; none: last.
  std::atomic<std::size_t> first_bad{last};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(first, last, 8),
      [&](const tbb::blocked_range<std::size_t>& range) {
        BlockScratch& s = scratch.local();
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          if (!evaluate_block(i, which, s, out->h.data() + (out->h_offset[i] - h_base),
                              out->b.data() + (out->b_offset[i] - b_base), &out->cost[i])) {
            record_bad_block(first_bad, i);
          }
        }
      });
  const std::size_t bad = first_bad.load();
  if (bad < last) {
    *error = describe_bad_block(bad, which);
    return false;
  }
  return true;
}

double BlockEvaluator::cost(int which) const {
  double total = 0.0;
  for (double c : own_costs(which)) total += c;
  if (const auto& source = problem_.block_source())
    total = add_source_costs(*source, values(which), total);
  return total;
}

const std::vector<double>& BlockEvaluator::own_costs(int which) const {
  const auto blocks = problem_.blocks();
  const auto& ptrs = pointers_[which];
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, blocks.size(), 16),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i) {
                        const auto& entry = blocks[i];
                        const ParameterPointers params(ptrs.data() + param_begin_[i],
                                                       param_begin_[i + 1] - param_begin_[i]);
                        // A block that throws at a trial point makes its cost NaN: the
                        // step is rejected, as for a functor that returns false.
                        try {
                          const double sq = entry.block->squared_norm(params);
                          block_cost_[i] = 0.5 * (entry.loss ? entry.loss->evaluate(sq).rho : sq);
                        } catch (...) {
                          block_cost_[i] = std::numeric_limits<double>::quiet_NaN();
                        }
                      }
                    });
  return block_cost_;
}

}  // namespace carat::internal
