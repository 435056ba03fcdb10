#pragma once

/// A 3D pose graph (vertices T_world_vertex, relative-pose edges) and its least-squares problem.

#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <vector>

#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/se3.hpp"

namespace carat {

/// Vertices and edges of an SE(3) pose graph, as read from or written to g2o.
struct PoseGraph {
  /// One pose.
  struct Vertex {
    std::int64_t id = 0;                                               ///< file id
    Eigen::Isometry3d T_world_vertex = Eigen::Isometry3d::Identity();  ///< pose in the world
  };
  /// One relative-pose measurement between two vertices.
  struct Edge {
    std::int64_t from = 0;                                        ///< id of vertex i
    std::int64_t to = 0;                                          ///< id of vertex j
    Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();  ///< measured T_i_j
    se3::Matrix6d information = se3::Matrix6d::Identity();        ///< translation first
  };
  std::vector<Vertex> vertices;     ///< in file order
  std::vector<Edge> edges;          ///< in file order
  std::vector<std::int64_t> fixed;  ///< ids of vertices held constant (g2o FIX records)

  /// Index of a vertex id in `vertices`, or -1.
  std::int64_t index_of(std::int64_t id) const;
};

/// How a pose graph becomes a Problem.
struct PoseGraphProblemOptions {
  std::shared_ptr<const LossFunction> loss;  ///< robust loss on every edge (null: none)
  bool fix_first_vertex = true;   ///< hold the first vertex constant when no FIX record exists
  bool allow_unanchored = false;  ///< accept parts of the graph not linked to a fixed vertex
};

/// A Problem built from a PoseGraph with the variable of each vertex.
struct PoseGraphProblem {
  Problem problem;                           ///< one SE(3) variable per vertex, one block per edge
  std::vector<VariableId> vertex_variables;  ///< parallel to PoseGraph::vertices
};

/// Builds the problem; throws carat::Error if an edge names a missing vertex or joins a vertex
/// to itself, an information matrix is not positive definite, or (unless allow_unanchored)
/// some vertices are not connected through edges to a constant vertex.
PoseGraphProblem build_pose_graph_problem(const PoseGraph& graph,
                                          const PoseGraphProblemOptions& options = {});

/// Copies the problem's current poses back into the graph's vertices.
void update_vertices(const PoseGraphProblem& solved, PoseGraph* graph);

}  // namespace carat
