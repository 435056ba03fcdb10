#include "linear_system.hpp"

#include <algorithm>
#include <map>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/machine_memory.hpp"
#include "carat/base/stopwatch.hpp"
#include "fill_estimate.hpp"
#include "schur_system.hpp"
#include "sparse_system.hpp"

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

namespace {

/// Bytes the whole system's factorization would hold (matrix values and row indices, factor).
double whole_system_bytes(const FillEstimate& fill) {
  return 16.0 * fill.matrix_entries + 8.0 * fill.factor_entries;
}

/// The block graph of the free variables (the whole system), or of the kept variables alone
/// after eliminating `eliminate` (the Schur complement's reduced system: two kept variables share
/// a block when a residual block or an eliminated variable joins them). *eliminated_bytes gets
/// what the elimination itself holds: each (kept, eliminated) pair's block and each eliminated
/// variable's diagonal block and its inverse factor.
BlockGraph block_graph(const Problem& problem, const std::vector<char>* eliminate,
                       double* eliminated_bytes) {
  const auto n = static_cast<std::size_t>(problem.num_variables());
  std::vector<int> node(n, -1), dim(n, 0);
  BlockGraph graph;
  for (std::size_t v = 0; v < n; ++v) {
    const VariableId id{static_cast<std::int32_t>(v)};
    dim[v] = problem.manifold(id).tangent_size();
    if (problem.is_constant(id) || (eliminate && (*eliminate)[v])) continue;
    node[v] = static_cast<int>(graph.dims.size());
    graph.dims.push_back(dim[v]);
  }
  graph.neighbours.resize(graph.dims.size());
  // Per eliminated variable, the kept variables its blocks touch.
  std::vector<std::vector<int>> kept_of(eliminate ? n : 0);
  double eliminated = 0.0;
  for (const auto& entry : problem.blocks()) {
    int point = -1;
    for (const VariableId a : entry.variables) {
      const auto i = static_cast<std::size_t>(a.index);
      if (eliminate && (*eliminate)[i]) point = a.index;
      if (node[i] < 0) continue;
      for (const VariableId b : entry.variables) {
        const int j = node[static_cast<std::size_t>(b.index)];
        if (j >= 0 && j != node[i])
          graph.neighbours[static_cast<std::size_t>(node[i])].push_back(j);
      }
    }
    if (point < 0) continue;
    for (const VariableId a : entry.variables) {
      const int i = node[static_cast<std::size_t>(a.index)];
      if (i >= 0) kept_of[static_cast<std::size_t>(point)].push_back(i);
    }
  }
  for (std::size_t p = 0; p < kept_of.size(); ++p) {
    std::vector<int>& kept = kept_of[p];
    if (!(*eliminate)[p]) continue;
    std::sort(kept.begin(), kept.end());
    kept.erase(std::unique(kept.begin(), kept.end()), kept.end());
    const double dp = dim[p];
    eliminated += 16.0 * dp * dp;
    for (const int i : kept) {
      eliminated += 8.0 * dp * graph.dims[static_cast<std::size_t>(i)];
      std::vector<int>& list = graph.neighbours[static_cast<std::size_t>(i)];
      list.insert(list.end(), kept.begin(), kept.end());
    }
    // Deduplicate as the lists grow, so that a variable seen with many others stays one list.
    for (const int i : kept) {
      std::vector<int>& list = graph.neighbours[static_cast<std::size_t>(i)];
      if (list.size() > 4 * graph.dims.size()) {
        std::sort(list.begin(), list.end());
        list.erase(std::unique(list.begin(), list.end()), list.end());
      }
    }
  }
  for (std::size_t i = 0; i < graph.neighbours.size(); ++i) {
    std::vector<int>& list = graph.neighbours[i];
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    list.erase(std::remove(list.begin(), list.end(), static_cast<int>(i)), list.end());
  }
  if (eliminated_bytes) *eliminated_bytes = eliminated;
  return graph;
}

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
                            " may be used (SolverOptions::max_linear_system_bytes, "
                            "or 80 % of the memory available)";
  // Counting the factor stops once it alone exceeds the cap (the estimate then exceeds it too).
  const double stop_after = cap / 8.0;
  const auto whole_bytes = [&] {
    return whole_system_bytes(estimate_fill(block_graph(problem, nullptr, nullptr), stop_after));
  };
  const auto schur_bytes = [&](const std::vector<char>& eliminate) {
    double eliminated = 0.0;
    const BlockGraph reduced = block_graph(problem, &eliminate, &eliminated);
    return whole_system_bytes(estimate_fill(reduced, stop_after)) + eliminated;
  };
  const auto refuse = [&](const std::string& what, double bytes, const std::string& other) {
    throw Error("linear solver: " + what + " needs about " + format_bytes(bytes) +
                " (matrix and factor); " + limit + other);
  };
  if (options.linear_solver == LinearSolver::kCholesky) {
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
  if (options.linear_solver == LinearSolver::kSchur || problem.has_eliminable()) {
    if (!problem.has_eliminable() && group_dims == 0) {
      throw Error(
          "linear solver schur: no variables to eliminate (mark them with "
          "Problem::set_eliminable(); every group of free variables of one tangent size has a "
          "residual block connecting two of its members)");
    }
    if (options.linear_solver == LinearSolver::kSchur) {
      const double bytes = schur_bytes(eliminate);
      if (bytes > cap) refuse("the Schur complement", bytes, "; try the whole system (cholesky)");
      return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
    }
  }
  // Auto: the Schur complement when a group can be eliminated (marked, or most of the system)
  // and its reduced system fits: dense reduced systems (cameras that share points with most
  // others) can take far more than the whole system, which then is the one to factorize.
  const bool schur_candidate =
      problem.has_eliminable() ||
      (group_dims > 0 && 2 * group_dims > total_dims && group_dims < total_dims);
  const double whole = whole_bytes();
  if (schur_candidate) {
    const double schur = schur_bytes(eliminate);
    if (schur <= cap && (schur <= kSchurMemoryMargin * whole || whole > cap)) {
      return std::make_unique<SchurSystem>(problem, eliminate, options.ordering);
    }
    if (whole > cap) {
      throw Error("linear solver auto: neither system fits: the Schur complement needs about " +
                  format_bytes(schur) + " and sparse Cholesky of the whole system about " +
                  format_bytes(whole) + " (matrix and factor); " + limit);
    }
  }
  if (whole > cap) refuse("sparse Cholesky of the whole system", whole, "");
  return std::make_unique<SparseSystem>(problem, options.ordering);
}

}  // namespace carat::internal
