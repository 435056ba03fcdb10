#include "carat/residuals/pose_graph_se2.hpp"

#include <algorithm>
#include <map>
#include <set>
#include <string>

#include "carat/base/error.hpp"
#include "carat/residuals/relative_pose_se2_block.hpp"
#include "pose_graph_build.hpp"

namespace carat {

std::int64_t PoseGraphSE2::index_of(std::int64_t id) const {
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    if (vertices[i].id == id) return static_cast<std::int64_t>(i);
  }
  return -1;
}

PoseGraphProblem build_pose_graph_problem(const PoseGraphSE2& graph,
                                          const PoseGraphProblemOptions& options) {
  return build_graph_problem(
      graph, options,
      [](Problem& problem, const PoseGraphSE2::Vertex& vertex) {
        return problem.add_se2(vertex.T_world_vertex);
      },
      [](const PoseGraphSE2::Edge& edge) {
        return std::make_shared<RelativePoseSE2Block>(edge.T_from_to, edge.information);
      });
}

void update_vertices(const PoseGraphProblem& solved, PoseGraphSE2* graph) {
  if (graph->vertices.size() != solved.vertex_variables.size()) {
    throw Error("update_vertices: the graph has " + std::to_string(graph->vertices.size()) +
                " vertices but the problem " + std::to_string(solved.vertex_variables.size()));
  }
  for (std::size_t i = 0; i < graph->vertices.size(); ++i) {
    graph->vertices[i].T_world_vertex = solved.problem.se2(solved.vertex_variables[i]);
  }
}

void compose_odometry(PoseGraphSE2* graph, const std::string& name) {
  if (graph->edges.empty()) throw Error(name + ": no edges to compose initial poses from");
  std::set<std::int64_t> ids;
  std::map<std::int64_t, const PoseGraphSE2::Edge*> odometry;  // first edge k -> k + 1 by k
  for (const auto& edge : graph->edges) {
    ids.insert(edge.from);
    ids.insert(edge.to);
    if (edge.from < edge.to && edge.from + 1 == edge.to) odometry.emplace(edge.from, &edge);
  }
  std::vector<PoseGraphSE2::Vertex> vertices;
  std::vector<std::int64_t> unreached;
  Eigen::Isometry2d T_world_k = Eigen::Isometry2d::Identity();
  bool chained = true;
  std::int64_t previous = *ids.begin();
  for (const std::int64_t id : ids) {
    if (id != *ids.begin()) {
      const auto step = odometry.find(previous);
      chained = chained && previous + 1 == id && step != odometry.end();
      if (chained) T_world_k = T_world_k * step->second->T_from_to;
    }
    previous = id;
    if (!chained) {
      unreached.push_back(id);
      continue;
    }
    vertices.push_back({id, T_world_k});
  }
  if (!unreached.empty()) {
    std::string list;
    const std::size_t shown = std::min<std::size_t>(unreached.size(), 5);
    for (std::size_t k = 0; k < shown; ++k) list += (k ? ", " : "") + std::to_string(unreached[k]);
    if (shown < unreached.size()) list += ", ...";
    throw Error(name + ": no VERTEX_SE2 records, and " + std::to_string(unreached.size()) +
                " vertex id(s) (" + list + ") are not reached from vertex " +
                std::to_string(*ids.begin()) +
                " through odometry edges k -> k+1, so they have no initial pose");
  }
  graph->vertices = std::move(vertices);
}

}  // namespace carat
