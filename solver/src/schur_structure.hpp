#pragma once

// Internal: the symbolic structure of the Schur complement, built once per problem. The free
// variables split into eliminated ones ("points": no residual block connects two of them) and
// the rest ("cameras"). The structure says which blocks touch which variables (each block's
// contributions to V, W, A and the gradient), where every variable sits in the system, the
// edges (point, camera) that W is stored for, the pairs of cameras that share a block of the
// reduced system S = A - W V^-1 W^T, and S's lower-triangular pattern. It holds no values: the
// assembled blocks are SchurValues, laid out by it.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "carat/solver/problem.hpp"
#include "huge_pages.hpp"

namespace carat::internal {

/// One char per variable: 1 where `eliminate` marks it and it is not constant (the variables a
/// Schur complement eliminates).
std::vector<char> free_marked(const Problem& problem, const std::vector<char>& eliminate);

/// Throws carat::Error naming the block and the two variables when a residual block connects
/// two free variables marked in `eliminate` (one char per variable; the eliminated variables
/// must not share a block).
void check_eliminable_group(const Problem& problem, const std::vector<char>& eliminate);

/// Which fixed-size kernels the numeric passes use: every camera and point of one size, or not.
enum class SchurKernel {
  kDynamic,        ///< sizes read per variable
  kCamera9Point3,  ///< every camera 9-dimensional, every point 3-dimensional (BAL)
  kCamera6Point3,  ///< every camera 6-dimensional, every point 3-dimensional
};

/// The symbolic structure (see the file comment). Plain data, read by the linearization, the
/// eliminator and the system; every list is in a fixed order, so sums over it are deterministic.
struct SchurStructure {
  /// eliminate[v] != 0 marks variable v for elimination (constant variables are skipped).
  /// Throws carat::Error when a block connects two marked variables.
  SchurStructure(const Problem& problem, const std::vector<char>& eliminate);

  /// A pair of cameras (row i >= column j) of S.
  struct Pair {
    int row_cam;                 ///< camera i
    std::int64_t row_in_column;  ///< offset of the row block below the diagonal block in the CSC
    std::size_t h_offset;        ///< start of the undamped A block (di x dj, column-major)
    std::size_t contrib_begin, contrib_end;  ///< A's contributions from blocks
  };
  /// A block's contribution to a pair (or an edge): its block and local tangent offsets.
  struct Contribution {
    std::int32_t block;
    std::int16_t row_local;
    std::int16_t col_local;
  };

  /// Most cameras per task forming S and reducing the right-hand side: a point's W is read once
  /// per group holding one of its cameras, so larger groups read it less often (ring 100 × 20,000
  /// formed S in 79 ms with 32 against 98 ms with 8); fewer than that when the threads need more
  /// groups (group_cameras).
  static constexpr std::size_t kMaxGroupCameras = 32;
  /// Cameras per group (each group's sums are the same whatever the grouping: a block of S is
  /// summed in point order within the group holding its column).
  std::size_t group_cameras = kMaxGroupCameras;

  /// Number of cameras (variables kept).
  std::size_t num_cameras() const { return cam_dim.size(); }
  /// Number of points (variables eliminated).
  std::size_t num_points() const { return pt_dim.size(); }
  /// Tangent size of residual block `block`.
  int block_dim(std::int32_t block) const { return block_dims[static_cast<std::size_t>(block)]; }
  /// Number of groups of group_cameras consecutive cameras.
  std::size_t num_groups() const { return group_points_begin.size() - 1; }
  /// Cameras [first, end) of group g.
  std::pair<std::size_t, std::size_t> group_range(std::size_t g) const {
    return {g * group_cameras, std::min(cam_dim.size(), (g + 1) * group_cameras)};
  }

  int n = 0;                    ///< size of the whole system
  int ns = 0;                   ///< size of the reduced system (the cameras' dimensions)
  std::vector<int> var_offset;  ///< system offset per variable, -1 for constant ones
  SchurKernel kernel = SchurKernel::kDynamic;
  /// Every block with a point touches at most one camera: its camera part is one diagonal block,
  /// summed while the points are linearized (see SchurLinearization).
  bool fused = true;
  std::vector<int> block_dims;  ///< tangent size per residual block

  // Cameras: dimension, offset in the system. Points: dimension, offset in the system, offset
  // of V / L^-1 storage.
  std::vector<int> cam_dim, cam_offset;
  std::vector<int> pt_dim, pt_offset;
  std::vector<std::size_t> pt_v_offset;
  // Edges (point, camera) in point-major order, each point's by camera index; W's offset each.
  std::vector<std::size_t> pt_edge_begin;
  std::vector<int> edge_cam, edge_pt;
  std::vector<std::size_t> edge_w_offset;
  // Each camera's edges, by point index.
  std::vector<std::size_t> cam_edge_begin;
  std::vector<std::size_t> cam_edges;

  // Camera pairs of S, grouped by column j, rows ascending (the diagonal first), and A's
  // contributions from blocks per pair.
  std::vector<std::size_t> column_pair_begin;
  std::vector<Pair> pairs;
  std::vector<Contribution> pair_contribs;
  // Per group of cameras: the points its cameras see (ascending); the most values of one
  // group's stacked S blocks, and of one point's Y = W L^-T.
  std::vector<std::size_t> group_points_begin, group_points;
  std::size_t max_group_values = 0;
  std::size_t max_point_y = 0;
  // W's contributions per edge (row_local: camera, col_local: point) and the index in
  // pt_contribs of each one's block.
  std::vector<std::size_t> edge_contrib_begin;
  std::vector<Contribution> edge_contribs;
  std::vector<std::uint32_t> edge_contrib_source;
  // V's and the points' gradient contributions per point (block, point's local offset), blocks
  // ascending; the cameras' gradient contributions per camera.
  std::vector<std::size_t> pt_contrib_begin;
  std::vector<std::pair<std::int32_t, std::int16_t>> pt_contribs;
  std::vector<std::size_t> cam_grad_begin;
  std::vector<std::pair<std::int32_t, std::int16_t>> cam_grad;

  // S's lower triangle in compressed columns, cameras in system order: per scalar column of
  // camera j, the diagonal block's rows from the diagonal down, then the blocks below it.
  std::vector<std::int64_t> colptr, rows;

  std::size_t a_size = 0, w_size = 0, v_size = 0;  ///< values of A, W and V (SchurValues)
};

/// The undamped assembled blocks of H = [A W; W^T V]: A per camera pair, W per edge, V per
/// point (column-major each), laid out by a SchurStructure and zeroed when made (their pages
/// are touched while the system is set up, not in the first assembly). The large ones on huge
/// pages (see huge_pages.hpp).
struct SchurValues {
  explicit SchurValues(const SchurStructure& structure)
      : a(structure.a_size, 0.0), w(structure.w_size, 0.0), v(structure.v_size, 0.0) {}

  std::vector<double> a;
  HugeVector<double> w, v;
};

}  // namespace carat::internal
