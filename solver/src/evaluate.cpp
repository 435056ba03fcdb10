#include "carat/solver/evaluate.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "source_runs.hpp"

namespace carat {
namespace {

/// Pointers to the values of a block's variables, in the block's order.
std::vector<const double*> values_of(const Problem& problem, const Problem::BlockEntry& entry) {
  std::vector<const double*> params;
  for (VariableId v : entry.variables) params.push_back(problem.value(v).data());
  return params;
}

}  // namespace

ProblemEvaluation evaluate_problem(const Problem& problem, int num_threads) {
  ProblemEvaluation out;
  // Tangent offsets of the free variables.
  std::vector<int> offset(static_cast<std::size_t>(problem.num_variables()), -1);
  int size = 0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    if (problem.is_constant(VariableId{v})) continue;
    offset[static_cast<std::size_t>(v)] = size;
    size += problem.manifold(VariableId{v}).tangent_size();
  }
  const auto blocks = problem.blocks();
  std::vector<double> cost(blocks.size(), 0.0);
  std::vector<Eigen::VectorXd> block_gradient(blocks.size());
  tbb::task_arena arena(std::clamp(num_threads, 1, tbb::info::default_concurrency()));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t i) {
      const auto& entry = blocks[i];
      const std::vector<const double*> params = values_of(problem, entry);
      const int r = entry.block->reduced_dim();
      const int D = entry.block->tangent_dim();
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(r, r);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(r);
      const double sq = entry.block->accumulate(params, H, b);
      Eigen::VectorXd g = b;
      if (r != D) {
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> A(r, D);
        entry.block->reduced_map(params, A.data());
        g = A.transpose() * b;
      }
      if (entry.loss) {
        const LossValue lv = entry.loss->evaluate(sq);
        cost[i] = 0.5 * lv.rho;
        g *= lv.rho1;
      } else {
        cost[i] = 0.5 * sq;
      }
      block_gradient[i] = std::move(g);
    });
  });
  out.gradient = Eigen::VectorXd::Zero(size);
  for (std::size_t i = 0; i < blocks.size(); ++i) {  // fixed order: thread-count independent
    out.cost += cost[i];
    int local = 0;
    for (VariableId v : blocks[i].variables) {
      const int t = problem.manifold(v).tangent_size();
      const int o = offset[static_cast<std::size_t>(v.index)];
      if (o >= 0) out.gradient.segment(o, t) += block_gradient[i].segment(local, t);
      local += t;
    }
  }
  if (const auto& source = problem.block_source()) {
    // Its records, after the own blocks: the cost, and b added to the free variables.
    std::size_t next = 0;
    source->linearize(
        problem.all_values(), [&](std::size_t first, std::span<const double> records) {
          internal::check_run_start(first, next, "records");
          for (std::size_t at = 0; at < records.size(); ++next) {
            if (next >= source->num_blocks())
              throw Error("block source: records beyond its blocks");
            int D = 0;
            for (VariableId v : source->variables(next)) D += problem.manifold(v).tangent_size();
            const std::size_t record = linearization_record_size(D);
            if (at + record > records.size())
              throw Error("block source: a run of records ends inside a block's");
            const double* b = records.data() + at + record - 1 - static_cast<std::size_t>(D);
            out.cost += records[at + record - 1];
            int local = 0;
            for (VariableId v : source->variables(next)) {
              const int t = problem.manifold(v).tangent_size();
              const int o = offset[static_cast<std::size_t>(v.index)];
              if (o >= 0)
                out.gradient.segment(o, t) += Eigen::Map<const Eigen::VectorXd>(b + local, t);
              local += t;
            }
            at += record;
          }
        });
    internal::check_runs_complete(next, source->num_blocks(), "records");
  }
  out.gradient_max_norm = size > 0 ? out.gradient.cwiseAbs().maxCoeff() : 0.0;
  out.finite = std::isfinite(out.cost) && out.gradient.allFinite();
  return out;
}

double evaluate_cost(const Problem& problem, int num_threads) {
  const auto blocks = problem.blocks();
  std::vector<double> cost(blocks.size(), 0.0);
  tbb::task_arena arena(std::clamp(num_threads, 1, tbb::info::default_concurrency()));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, blocks.size(), [&](std::size_t i) {
      const auto& entry = blocks[i];
      const double sq = entry.block->squared_norm(values_of(problem, entry));
      cost[i] = 0.5 * (entry.loss ? entry.loss->evaluate(sq).rho : sq);
    });
  });
  double total = 0.0;
  for (double c : cost) total += c;  // fixed order: thread-count independent
  if (const auto& source = problem.block_source())
    total = internal::add_source_costs(*source, problem.all_values(), total);
  return total;
}

}  // namespace carat
