#include "carat/residuals/pose_graph.hpp"

#include <string>
#include <unordered_map>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/relative_pose_block.hpp"

namespace carat {

std::int64_t PoseGraph::index_of(std::int64_t id) const {
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    if (vertices[i].id == id) return static_cast<std::int64_t>(i);
  }
  return -1;
}

namespace {

/// Throws unless every vertex is connected through edges to a constant vertex: a component
/// without one can move freely as a whole (its gauge is not fixed).
void check_anchored(const PoseGraph& graph, const PoseGraphProblem& built) {
  const std::size_t n = graph.vertices.size();
  std::vector<std::size_t> parent(n);
  for (std::size_t i = 0; i < n; ++i) parent[i] = i;
  const auto find = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::unordered_map<std::int64_t, std::size_t> index;
  for (std::size_t i = 0; i < n; ++i) index.emplace(graph.vertices[i].id, i);
  for (const auto& edge : graph.edges) parent[find(index.at(edge.from))] = find(index.at(edge.to));
  std::vector<char> anchored(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    if (built.problem.is_constant(built.vertex_variables[i])) anchored[find(i)] = 1;
  std::size_t free = 0, components = 0;
  std::int64_t example = 0;
  std::vector<char> counted(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t root = find(i);
    if (anchored[root]) continue;
    if (free++ == 0) example = graph.vertices[i].id;
    if (!counted[root]) {
      counted[root] = 1;
      ++components;
    }
  }
  if (free > 0) {
    throw Error(
        "pose graph: " + std::to_string(free) + " vertices in " + std::to_string(components) +
        " disconnected part(s) are not linked to a fixed vertex (e.g. vertex " +
        std::to_string(example) + "), so their poses are undetermined; add edges or FIX records");
  }
}

}  // namespace

PoseGraphProblem build_pose_graph_problem(const PoseGraph& graph,
                                          const PoseGraphProblemOptions& options) {
  PoseGraphProblem out;
  std::unordered_map<std::int64_t, VariableId> by_id;
  for (const auto& vertex : graph.vertices) {
    const VariableId v = out.problem.add_se3(vertex.T_world_vertex);
    if (!by_id.emplace(vertex.id, v).second) {
      throw Error("pose graph: vertex id " + std::to_string(vertex.id) + " appears twice");
    }
    out.vertex_variables.push_back(v);
  }
  for (std::size_t e = 0; e < graph.edges.size(); ++e) {
    const auto& edge = graph.edges[e];
    const auto from = by_id.find(edge.from);
    const auto to = by_id.find(edge.to);
    if (from == by_id.end() || to == by_id.end()) {
      throw Error("pose graph: edge " + std::to_string(e) + " (" + std::to_string(edge.from) +
                  " -> " + std::to_string(edge.to) + ") names a missing vertex " +
                  std::to_string(from == by_id.end() ? edge.from : edge.to));
    }
    if (edge.from == edge.to) {
      throw Error("pose graph: edge " + std::to_string(e) + " joins vertex " +
                  std::to_string(edge.from) + " to itself");
    }
    auto block = std::make_shared<RelativePoseBlock>(edge.T_from_to, edge.information);
    out.problem.add_residual_block(block, {from->second, to->second}, options.loss);
  }
  for (std::int64_t id : graph.fixed) {
    const auto it = by_id.find(id);
    if (it == by_id.end()) {
      throw Error("pose graph: FIX names a missing vertex " + std::to_string(id));
    }
    out.problem.set_constant(it->second);
  }
  if (graph.fixed.empty() && options.fix_first_vertex && !out.vertex_variables.empty()) {
    out.problem.set_constant(out.vertex_variables.front());
  }
  if (!options.allow_unanchored) check_anchored(graph, out);
  return out;
}

void update_vertices(const PoseGraphProblem& solved, PoseGraph* graph) {
  if (graph->vertices.size() != solved.vertex_variables.size()) {
    throw Error("update_vertices: the graph has " + std::to_string(graph->vertices.size()) +
                " vertices but the problem " + std::to_string(solved.vertex_variables.size()));
  }
  for (std::size_t i = 0; i < graph->vertices.size(); ++i) {
    graph->vertices[i].T_world_vertex = solved.problem.se3(solved.vertex_variables[i]);
  }
}

}  // namespace carat
