#include "carat/coreset/problem_compression.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <memory>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"

namespace carat {
ProblemCompressionReport compress_problem(Problem& problem,
                                          const ProblemCompressionOptions& options) {
  const Stopwatch total_time;
  ProblemCompressionReport report;
  const auto blocks = problem.blocks();
  std::vector<std::shared_ptr<CompressedBlock>> compressed(blocks.size());
  std::vector<std::string> errors(blocks.size());
  tbb::task_arena arena(std::clamp(options.num_threads, 1, tbb::info::default_concurrency()));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t k) {
      const auto& entry = blocks[k];
      const ResidualBlockId id{static_cast<std::int32_t>(k)};
      if (options.select && !options.select(id, *entry.block)) return;
      const int r = entry.block->reduced_dim();
      const int target = options.compression.target_rows > 0
                             ? options.compression.target_rows
                             : std::max(r * (r + 1) / 2 + r + 2, options.min_target_rows);
      const int floor = options.min_rows > 0 ? options.min_rows : target;
      if (entry.block->num_rows() <= floor) return;
      std::vector<const double*> params;
      for (VariableId v : entry.variables) params.push_back(problem.value(v).data());
      CompressionOptions compression = options.compression;
      compression.seed = options.compression.seed + k;
      compression.target_rows = target;
      try {
        compressed[k] = compress(entry.block, params, compression);
      } catch (const std::exception& e) {
        errors[k] = e.what();
      }
    });
  });
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    if (!errors[k].empty()) {
      const std::string& name = blocks[k].block->name();
      throw Error("compress_problem: residual block " + std::to_string(k) +
                  (name.empty() ? std::string() : " ('" + name + "')") + ": " + errors[k]);
    }
  }
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const auto& block = blocks[k].block;
    report.rows_before += static_cast<std::size_t>(block->num_rows());
    report.bytes_before += block->memory_bytes();
    if (compressed[k]) {
      ++report.compressed_blocks;
      report.replaced.push_back({ResidualBlockId{static_cast<std::int32_t>(k)}, block});
      problem.replace_residual_block(ResidualBlockId{static_cast<std::int32_t>(k)}, compressed[k]);
    }
    const auto& now = problem.blocks()[k].block;
    report.rows_after += static_cast<std::size_t>(now->num_rows());
    report.bytes_after += now->memory_bytes();
  }
  report.seconds = total_time.elapsed_s();
  return report;
}

void restore_blocks(Problem& problem, const ProblemCompressionReport& report) {
  for (const ReplacedBlock& r : report.replaced) {
    if (r.id.index < 0 || r.id.index >= problem.num_residual_blocks()) {
      throw Error("restore_blocks: residual block " + std::to_string(r.id.index) +
                  " does not exist (" + std::to_string(problem.num_residual_blocks()) + " blocks)");
    }
    problem.replace_residual_block(r.id, r.original);
  }
}

}  // namespace carat
