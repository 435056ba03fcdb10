#include "linear_system.hpp"

#include <map>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "schur_system.hpp"
#include "sparse_system.hpp"

namespace carat::internal {
namespace {

/// The free variables marked eliminable; throws if a block connects two of them.
std::vector<char> marked_group(const Problem& problem) {
  std::vector<char> eliminate(static_cast<std::size_t>(problem.num_variables()), 0);
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    eliminate[static_cast<std::size_t>(v)] = problem.is_eliminable(id) && !problem.is_constant(id);
  }
  const auto blocks = problem.blocks();
  for (std::size_t bi = 0; bi < blocks.size(); ++bi) {
    int first = -1;
    for (VariableId v : blocks[bi].variables) {
      if (!eliminate[static_cast<std::size_t>(v.index)]) continue;
      if (first >= 0) {
        throw Error("Schur complement: residual block " + std::to_string(bi) +
                    " connects two eliminable variables (" + std::to_string(first) + " and " +
                    std::to_string(v.index) + "); the eliminated variables must not share a block");
      }
      first = v.index;
    }
  }
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

bool LinearSystem::linearize(const BlockEvaluator& evaluator, int which, Eigen::VectorXd* gradient,
                             double* cost, double* linearize_s, double* assembly_s,
                             std::string* error) {
  Stopwatch t0;
  if (storage_.dim.empty()) evaluator.allocate(&storage_);
  if (!evaluator.linearize(which, &storage_, error)) {
    *linearize_s += t0.elapsed_s();
    return false;
  }
  *linearize_s += t0.elapsed_s();
  t0.restart();
  assemble(storage_, gradient);
  *assembly_s += t0.elapsed_s();
  *cost = 0.0;
  for (const double c : storage_.cost) *cost += c;
  return true;
}

std::unique_ptr<LinearSystem> make_linear_system(const Problem& problem,
                                                 const SolverOptions& options) {
  if (options.linear_solver == LinearSolver::kCholesky) {
    return std::make_unique<SparseSystem>(problem, options.ordering);
  }
  if (problem.has_eliminable()) {
    return std::make_unique<SchurSystem>(problem, marked_group(problem), options.ordering);
  }
  int group_dims = 0;
  std::vector<char> eliminate = detected_group(problem, &group_dims);
  int total_dims = 0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    if (!problem.is_constant(id)) total_dims += problem.manifold(id).tangent_size();
  }
  if (options.linear_solver == LinearSolver::kSchur) {
    if (group_dims == 0) {
      throw Error(
          "linear solver schur: no variables to eliminate (mark them with "
          "Problem::set_eliminable(); every group of free variables of one tangent size has a "
          "residual block connecting two of its members)");
    }
    return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
  }
  // Auto: eliminate when the group is most of the system and something is left to reduce to.
  if (group_dims > 0 && 2 * group_dims > total_dims && group_dims < total_dims) {
    return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
  }
  return std::make_unique<SparseSystem>(problem, options.ordering);
}

}  // namespace carat::internal
