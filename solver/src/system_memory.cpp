#include "system_memory.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>

#include "block_variables.hpp"
#include "fill_estimate.hpp"
#include "schur_structure.hpp"

namespace carat::internal {
namespace {

/// Bytes of a factorization with `fill`: the matrix's values and row indices, the factor.
double factorization_bytes(const FillEstimate& fill) {
  return 16.0 * fill.matrix_entries + 8.0 * fill.factor_entries;
}

/// Node of each variable in a graph of the free variables that `keep` accepts (-1 elsewhere),
/// and the nodes' tangent sizes.
std::vector<int> number_nodes(const Problem& problem, const std::vector<char>* eliminate,
                              std::vector<int>* dims) {
  std::vector<int> node(static_cast<std::size_t>(problem.num_variables()), -1);
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    if (problem.is_constant(id) || (eliminate && (*eliminate)[static_cast<std::size_t>(v)])) {
      continue;
    }
    node[static_cast<std::size_t>(v)] = static_cast<int>(dims->size());
    dims->push_back(problem.manifold(id).tangent_size());
  }
  return node;
}

/// Sorts each list and drops repeats and the node itself.
void tidy(BlockGraph* graph) {
  for (std::size_t i = 0; i < graph->neighbours.size(); ++i) {
    std::vector<int>& list = graph->neighbours[i];
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    list.erase(std::remove(list.begin(), list.end(), static_cast<int>(i)), list.end());
  }
}

}  // namespace

double whole_system_bytes(const Problem& problem, double cap) {
  BlockGraph graph;
  const std::vector<int> node = number_nodes(problem, nullptr, &graph.dims);
  graph.neighbours.resize(graph.dims.size());
  for_each_block_variables(problem, [&](std::span<const VariableId> variables) {
    for (const VariableId a : variables) {
      const int i = node[static_cast<std::size_t>(a.index)];
      if (i < 0) continue;
      for (const VariableId b : variables) {
        const int j = node[static_cast<std::size_t>(b.index)];
        if (j >= 0 && j != i) graph.neighbours[static_cast<std::size_t>(i)].push_back(j);
      }
    }
  });
  tidy(&graph);
  return factorization_bytes(estimate_fill(graph, cap / 8.0));
}

double whole_system_bound(const Problem& problem) {
  double n = 0.0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    if (!problem.is_constant(id)) n += problem.manifold(id).tangent_size();
  }
  return 24.0 * n * (n + 1.0) / 2.0;
}

SchurMemory schur_system_bytes(const Problem& problem, const std::vector<char>& eliminate,
                               double cap) {
  BlockGraph graph;
  const std::vector<int> node = number_nodes(problem, &eliminate, &graph.dims);
  const std::size_t kept = graph.dims.size();
  graph.neighbours.resize(kept);
  // (eliminated variable, kept node) of every block with an eliminated variable; kept nodes
  // that share a block directly.
  const auto num_vars = static_cast<std::size_t>(problem.num_variables());
  const std::vector<char> eliminated = free_marked(problem, eliminate);
  std::vector<std::pair<int, int>> found;
  found.reserve(problem.blocks().size());
  for (const auto& entry : problem.blocks()) {
    int point = -1;
    for (const VariableId a : entry.variables) {
      if (eliminated[static_cast<std::size_t>(a.index)]) point = a.index;
    }
    for (const VariableId a : entry.variables) {
      const int i = node[static_cast<std::size_t>(a.index)];
      if (i < 0) continue;
      if (point >= 0) found.emplace_back(point, i);
      for (const VariableId b : entry.variables) {
        const int j = node[static_cast<std::size_t>(b.index)];
        if (j >= 0 && j != i) graph.neighbours[static_cast<std::size_t>(i)].push_back(j);
      }
    }
  }
  // Sorted and without repeats: by eliminated variable (a counting sort), then each one's few
  // kept nodes.
  std::vector<std::pair<int, int>> links(found.size());
  {
    std::vector<std::size_t> start(num_vars + 1, 0);
    for (const auto& [point, i] : found) ++start[static_cast<std::size_t>(point) + 1];
    for (std::size_t v = 0; v < num_vars; ++v) start[v + 1] += start[v];
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (const auto& link : found) links[fill[static_cast<std::size_t>(link.first)]++] = link;
    std::size_t kept_links = 0;
    for (std::size_t v = 0; v < num_vars; ++v) {
      const auto first = links.begin() + static_cast<std::ptrdiff_t>(start[v]);
      const auto last = links.begin() + static_cast<std::ptrdiff_t>(start[v + 1]);
      std::sort(first, last);
      const auto end = std::unique(first, last);
      for (auto link = first; link != end; ++link) links[kept_links++] = *link;
    }
    links.resize(kept_links);
  }
  // What the elimination holds, and the whole system's matrix (a lower bound of its bytes).
  SchurMemory out;
  double whole_entries = 0.0;
  for (int v = 0; v < problem.num_variables(); ++v) {
    const VariableId id{v};
    if (problem.is_constant(id)) continue;
    const double d = problem.manifold(id).tangent_size();
    whole_entries += d * (d + 1.0) / 2.0;
    if (eliminate[static_cast<std::size_t>(v)]) out.bytes += 16.0 * d * d;
  }
  // Each kept node's eliminated variables, then the kept nodes each of those joins: the reduced
  // system's blocks, found with one mark per node (no pair is listed twice).
  std::vector<std::vector<std::size_t>> points_of_node(kept);
  for (std::size_t k = 0; k < links.size();) {
    std::size_t end = k;
    while (end < links.size() && links[end].first == links[k].first) ++end;
    const double dp = problem.manifold(VariableId{links[k].first}).tangent_size();
    for (std::size_t q = k; q < end; ++q) {
      const double dc = graph.dims[static_cast<std::size_t>(links[q].second)];
      out.bytes += 8.0 * dp * dc;
      whole_entries += dp * dc;
      points_of_node[static_cast<std::size_t>(links[q].second)].push_back(k);
    }
    k = end;
  }
  std::vector<std::size_t> mark(kept, SIZE_MAX);
  for (std::size_t i = 0; i < kept; ++i) {
    std::vector<int>& list = graph.neighbours[i];
    for (const int j : list) mark[static_cast<std::size_t>(j)] = i;
    for (const std::size_t first : points_of_node[i]) {
      for (std::size_t q = first; q < links.size() && links[q].first == links[first].first; ++q) {
        const auto j = static_cast<std::size_t>(links[q].second);
        if (j == i || mark[j] == i) continue;
        mark[j] = i;
        list.push_back(static_cast<int>(j));
      }
    }
  }
  tidy(&graph);
  out.bytes += factorization_bytes(estimate_fill(graph, cap / 8.0));
  out.whole_lower_bound = 24.0 * whole_entries;
  return out;
}

}  // namespace carat::internal
