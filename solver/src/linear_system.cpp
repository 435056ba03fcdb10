#include "linear_system.hpp"

#include <algorithm>
#include <map>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/machine_memory.hpp"
#include "carat/base/stopwatch.hpp"
#include "schur_structure.hpp"
#include "schur_system.hpp"
#include "sparse_system.hpp"
#include "system_memory.hpp"

namespace carat::internal {
namespace {

/// kAuto keeps the Schur complement while its estimate is at most this many times the whole
/// system's: it is usually the faster of the two when both fit (bundle adjustment).
constexpr double kSchurMemoryMargin = 2.0;

/// The free variables marked eliminable; throws if a block connects two of them.
std::vector<char> marked_group(const Problem& problem) {
  std::vector<char> eliminate(static_cast<std::size_t>(problem.num_variables()), 0);
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    eliminate[static_cast<std::size_t>(v)] = problem.is_eliminable(id) && !problem.is_constant(id);
  }
  check_eliminable_group(problem, eliminate);
  return eliminate;
}

/// With nothing marked: among the groups of free variables of equal tangent size, those no
/// block connects two members of; the one with the most tangent dimensions (empty if none).
std::vector<char> detected_group(const Problem& problem, int* group_dims) {
  std::map<int, int> dims_of_size;  // tangent size -> total dimensions of its free variables
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    if (problem.is_constant(id)) continue;
    const int d = problem.manifold(id).tangent_size();
    dims_of_size[d] += d;
  }
  for (const auto& entry : problem.blocks()) {
    std::map<int, int> count;
    for (VariableId v : entry.variables) {
      if (problem.is_constant(v)) continue;
      const int d = problem.manifold(v).tangent_size();
      if (++count[d] == 2) dims_of_size.erase(d);
    }
  }
  int best_size = 0;
  *group_dims = 0;
  for (const auto& [size, dims] : dims_of_size) {
    if (dims > *group_dims) {
      *group_dims = dims;
      best_size = size;
    }
  }
  std::vector<char> eliminate(static_cast<std::size_t>(problem.num_variables()), 0);
  if (best_size == 0) return eliminate;
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    eliminate[static_cast<std::size_t>(v)] =
        !problem.is_constant(id) && problem.manifold(id).tangent_size() == best_size;
  }
  return eliminate;
}

}  // namespace

LinearizeReport LinearSystem::linearize(const BlockEvaluator& evaluator, int which,
                                        Eigen::VectorXd* gradient) {
  LinearizeReport report;
  Stopwatch t0;
  if (storage_.dim.empty()) evaluator.allocate(&storage_);
  const bool ok = evaluator.linearize(which, &storage_, &report.error);
  report.time.linearize_s = t0.elapsed_s();
  if (!ok) return report;
  t0.restart();
  assemble(storage_, gradient);
  report.time.assembly_s = t0.elapsed_s();
  finish_linearize(evaluator, which, gradient, &report);
  return report;
}

void LinearSystem::finish_linearize(const BlockEvaluator& evaluator, int which,
                                    Eigen::VectorXd* gradient, LinearizeReport* report) {
  for (const double c : storage_.cost) report->cost += c;
  if (const auto& source = evaluator.problem().block_source()) {
    const Stopwatch t0;
    const bool added = add_source_blocks(*source, evaluator.values(which),
                                         evaluator.problem().blocks().size(), gradient, report);
    report->time.linearize_s += t0.elapsed_s();
    if (!added) return;
  }
  report->ok = true;
}

bool LinearSystem::add_source_blocks(BlockSource&, std::span<const double>, std::size_t,
                                     Eigen::VectorXd*, LinearizeReport*) {
  throw Error(
      "linear solver: a problem with a block source needs sparse Cholesky of the whole "
      "system (linear_solver cholesky or auto)");
}

namespace {

/// The memory the linear system may take: the option, else 80 % of what the machine has.
double memory_cap(const SolverOptions& options) {
  if (options.max_linear_system_bytes > 0.0) return options.max_linear_system_bytes;
  return 0.8 * static_cast<double>(available_memory_bytes());
}

}  // namespace

std::unique_ptr<LinearSystem> make_linear_system(const Problem& problem,
                                                 const SolverOptions& options) {
  const double cap = memory_cap(options);
  const std::string limit = format_bytes(cap) +
                            " may be used (SolverOptions::max_linear_system_bytes, or 80 % of "
                            "the memory available)";
  // Whether the whole system fits: a dense factor's size when even that fits, else the estimate.
  const auto whole_bytes = [&] {
    const double bound = whole_system_bound(problem);
    return bound <= cap ? bound : whole_system_bytes(problem, cap);
  };
  const auto refuse = [&](const std::string& what, double bytes, const std::string& other) {
    throw Error("linear solver: " + what + " needs about " + format_bytes(bytes) +
                " (matrix and factor); " + limit + other);
  };
  if (options.linear_solver == LinearSolver::kCholesky || problem.block_source()) {
    if (options.linear_solver == LinearSolver::kSchur) {
      throw Error(
          "linear solver schur: a problem with a block source is solved as the whole "
          "sparse system (use cholesky or auto)");
    }
    const double bytes = whole_bytes();
    if (bytes > cap) refuse("sparse Cholesky of the whole system", bytes, "");
    return std::make_unique<SparseSystem>(problem, options.ordering);
  }
  std::vector<char> eliminate;
  int group_dims = 0;
  if (problem.has_eliminable()) {
    eliminate = marked_group(problem);
  } else {
    eliminate = detected_group(problem, &group_dims);
  }
  int total_dims = 0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    if (!problem.is_constant(id)) total_dims += problem.manifold(id).tangent_size();
  }
  if (options.linear_solver == LinearSolver::kSchur) {
    if (!problem.has_eliminable() && group_dims == 0) {
      throw Error(
          "linear solver schur: no variables to eliminate (mark them with "
          "Problem::set_eliminable(); every group of free variables of one tangent size has a "
          "residual block connecting two of its members)");
    }
    const double bytes = schur_system_bytes(problem, eliminate, cap).bytes;
    if (bytes > cap) refuse("the Schur complement", bytes, "; try the whole system (cholesky)");
    return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
  }
  // Auto: the Schur complement when a group can be eliminated (marked, or most of the system)
  // and it fits in at most kSchurMemoryMargin times the whole system's memory. A reduced system
  // made dense by points that most cameras share can take far more than the whole system, which
  // then is the one to factorize.
  const bool schur_candidate =
      problem.has_eliminable() ||
      (group_dims > 0 && 2 * group_dims > total_dims && group_dims < total_dims);
  if (schur_candidate) {
    const SchurMemory schur = schur_system_bytes(problem, eliminate, cap);
    // The whole system's own estimate is needed only when its lower bound does not settle it.
    if (schur.bytes <= cap && schur.bytes <= kSchurMemoryMargin * schur.whole_lower_bound) {
      return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
    }
    const double whole = whole_system_bytes(problem, cap);
    if (schur.bytes <= cap && (schur.bytes <= kSchurMemoryMargin * whole || whole > cap)) {
      return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
    }
    if (whole > cap) {
      throw Error("linear solver auto: neither system fits: the Schur complement needs about " +
                  format_bytes(schur.bytes) + " and sparse Cholesky of the whole system about " +
                  format_bytes(whole) + " (matrix and factor); " + limit);
    }
    return std::make_unique<SparseSystem>(problem, options.ordering);
  }
  const double whole = whole_bytes();
  if (whole > cap) refuse("sparse Cholesky of the whole system", whole, "");
  return std::make_unique<SparseSystem>(problem, options.ordering);
}

}  // namespace carat::internal
