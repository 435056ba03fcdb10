#pragma once

// The problem of a pose graph of either dimension: one variable per vertex, one block per edge,
// constant vertices, and the check that every vertex is anchored.

#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/pose_graph.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"

namespace carat {

/// Throws unless every vertex is connected through edges to a constant vertex: a component
/// without one can move freely as a whole (its gauge is not fixed).
template <typename Graph>
void check_anchored(const Graph& graph, const PoseGraphProblem& built) {
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

/// What keeps a measurement or pose from being rigid, or nullptr (either dimension).
inline const char* rigid_problem_of(const Eigen::Isometry3d& T) {
  return se3::rigid_transform_problem(T);
}
/// What keeps a measurement or pose from being rigid, or nullptr (either dimension).
inline const char* rigid_problem_of(const Eigen::Isometry2d& T) {
  return se2::rigid_transform_problem(T);
}

/// Builds the problem of `graph`: add_vertex(problem, vertex) adds a vertex's variable,
/// make_block(edge) makes an edge's residual block.
template <typename Graph, typename AddVertex, typename MakeBlock>
PoseGraphProblem build_graph_problem(const Graph& graph, const PoseGraphProblemOptions& options,
                                     AddVertex add_vertex, MakeBlock make_block) {
  PoseGraphProblem out;
  std::unordered_map<std::int64_t, VariableId> by_id;
  for (const auto& vertex : graph.vertices) {
    if (const char* problem = rigid_problem_of(vertex.T_world_vertex)) {
      throw Error("pose graph: vertex " + std::to_string(vertex.id) + ": the pose " + problem);
    }
    const VariableId v = add_vertex(out.problem, vertex);
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
    if (const char* problem = rigid_problem_of(edge.T_from_to)) {
      throw Error("pose graph: edge " + std::to_string(e) + " (" + std::to_string(edge.from) +
                  " -> " + std::to_string(edge.to) + "): the measurement " + problem);
    }
    if (edge.from == edge.to) {
      throw Error("pose graph: edge " + std::to_string(e) + " joins vertex " +
                  std::to_string(edge.from) + " to itself");
    }
    out.problem.add_residual_block(make_block(edge), {from->second, to->second}, options.loss);
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

}  // namespace carat
