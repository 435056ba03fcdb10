#include "carat/residuals/pose_graph.hpp"

#include <string>
#include <unordered_map>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/residuals/relative_pose_block.hpp"
#include "pose_graph_build.hpp"

namespace carat {

std::int64_t PoseGraph::index_of(std::int64_t id) const {
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    if (vertices[i].id == id) return static_cast<std::int64_t>(i);
  }
  return -1;
}

PoseGraphProblem build_pose_graph_problem(const PoseGraph& graph,
                                          const PoseGraphProblemOptions& options) {
  return build_graph_problem(
      graph, options,
      [](Problem& problem, const PoseGraph::Vertex& vertex) {
        return problem.add_se3(vertex.T_world_vertex);
      },
      [](const PoseGraph::Edge& edge) {
        return std::make_shared<RelativePoseBlock>(edge.T_from_to, edge.information);
      });
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
