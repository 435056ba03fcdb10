#include "carat/solver/block_source.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "block_evaluator.hpp"
#include "carat/base/error.hpp"
#include "carat/solver/problem.hpp"

namespace carat {

struct BlockLinearizer::Impl {
  Impl(const Problem& p, int threads, std::size_t run)
      : problem(p),
        evaluator(p),
        arena(std::clamp(threads, 1, tbb::info::default_concurrency())),
        run_blocks(run) {}
  const Problem& problem;
  internal::BlockEvaluator evaluator;
  tbb::task_arena arena;
  std::size_t run_blocks;
  std::vector<std::size_t> record_offset;  // per block, into all records; then the total
  std::vector<double> records;             // one run's

  /// Points the evaluator at `values`, checking their size.
  void bind(std::span<const double> values, const char* who) {
    if (values.size() != problem.all_values().size()) {
      throw Error(std::string("BlockLinearizer::") + who + ": " + std::to_string(values.size()) +
                  " values for a problem of " + std::to_string(problem.all_values().size()));
    }
    evaluator.bind(0, values.data());
  }
};

BlockLinearizer::BlockLinearizer(const Problem& problem, int num_threads, std::size_t run_blocks)
    : impl_(std::make_unique<Impl>(problem, num_threads, std::max<std::size_t>(run_blocks, 1))) {
  if (problem.block_source())
    throw Error("BlockLinearizer: the problem has a block source of its own");
  std::size_t at = 0;
  for (const auto& entry : problem.blocks()) {
    impl_->record_offset.push_back(at);
    at += linearization_record_size(entry.block->tangent_dim());
  }
  impl_->record_offset.push_back(at);
}

BlockLinearizer::~BlockLinearizer() = default;

void BlockLinearizer::linearize(std::span<const double> values, const BlockRecordSink& sink) {
  Impl& s = *impl_;
  s.bind(values, "linearize");
  const std::size_t n = s.record_offset.size() - 1;
  tbb::enumerable_thread_specific<internal::BlockScratch> scratch;
  for (std::size_t first = 0; first < n; first += s.run_blocks) {
    const std::size_t last = std::min(n, first + s.run_blocks);
    const std::size_t base = s.record_offset[first];
    s.records.resize(s.record_offset[last] - base);
    s.arena.execute([&] {
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(first, last, 8),
          [&](const tbb::blocked_range<std::size_t>& range) {
            internal::BlockScratch& local = scratch.local();
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
              double* record = s.records.data() + (s.record_offset[i] - base);
              const std::size_t size = s.record_offset[i + 1] - s.record_offset[i];
              const auto D = static_cast<std::size_t>(s.problem.blocks()[i].block->tangent_dim());
              double* cost = record + size - 1;
              if (!s.evaluator.evaluate_block(i, 0, local, record, record + D * (D + 1) / 2,
                                              cost)) {
                *cost = std::numeric_limits<double>::quiet_NaN();
              }
            }
          });
    });
    sink(first, s.records);
  }
}

void BlockLinearizer::costs(std::span<const double> values, const BlockRecordSink& sink) {
  Impl& s = *impl_;
  s.bind(values, "costs");
  const std::vector<double>* costs = nullptr;
  s.arena.execute([&] { costs = &s.evaluator.own_costs(0); });
  const std::span<const double> all(*costs);
  for (std::size_t first = 0; first < all.size(); first += s.run_blocks)
    sink(first, all.subspan(first, std::min(s.run_blocks, all.size() - first)));
}

}  // namespace carat
