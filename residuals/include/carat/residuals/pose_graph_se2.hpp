#pragma once

/// A 2D pose graph (planar vertices T_world_vertex, SE(2) relative-pose edges) and its
/// least-squares problem.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "carat/residuals/pose_graph.hpp"

namespace carat {

/// Vertices and edges of an SE(2) pose graph, as read from or written to g2o.
struct PoseGraphSE2 {
  /// One planar pose.
  struct Vertex {
    std::int64_t id = 0;                                               ///< file id
    Eigen::Isometry2d T_world_vertex = Eigen::Isometry2d::Identity();  ///< pose in the world (m)
  };
  /// One planar relative-pose measurement between two vertices.
  struct Edge {
    std::int64_t from = 0;                                        ///< id of vertex i
    std::int64_t to = 0;                                          ///< id of vertex j
    Eigen::Isometry2d T_from_to = Eigen::Isometry2d::Identity();  ///< measured T_i_j (m, rad)
    Eigen::Matrix3d information = Eigen::Matrix3d::Identity();    ///< order x, y, theta
  };
  std::vector<Vertex> vertices;     ///< in file order
  std::vector<Edge> edges;          ///< in file order
  std::vector<std::int64_t> fixed;  ///< ids of vertices held constant (g2o FIX records)

  /// Index of a vertex id in `vertices`, or -1.
  std::int64_t index_of(std::int64_t id) const;
};

/// Builds the problem (one SE(2) variable per vertex, one RelativePoseSE2Block per edge); throws
/// carat::Error if an edge names a missing vertex or joins a vertex to itself, an information
/// matrix is not positive definite, or (unless allow_unanchored) some vertices are not connected
/// through edges to a constant vertex.
PoseGraphProblem build_pose_graph_problem(const PoseGraphSE2& graph,
                                          const PoseGraphProblemOptions& options = {});

/// Copies the problem's current planar poses back into the graph's vertices.
void update_vertices(const PoseGraphProblem& solved, PoseGraphSE2* graph);

/// Initial poses from odometry: the vertices of `graph` are replaced by one per id named by an
/// edge, the smallest id at the origin and each next id k + 1 at T_world_k * T_k_(k+1) of the
/// first edge k -> k + 1. Throws carat::Error (prefixed by `name`) naming the ids that no
/// chain of such edges reaches, or if the graph has no edges.
void compose_odometry(PoseGraphSE2* graph, const std::string& name);

}  // namespace carat
