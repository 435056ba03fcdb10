#pragma once

// Internal: the Schur complement's assembly of H = [A W; W^T V] and the gradient into
// SchurValues, from per-block H and b (assemble()) or, fused, evaluating the blocks as it goes
// (linearize()). The points are taken a chunk at a time, in fixed chunks (a function of the
// problem alone): per point, V and its gradient, and W per edge. Fused (every block with a point
// touches at most one camera; SchurStructure::fused), each chunk also sums its blocks' camera
// parts into one slot per camera it touches (a diagonal block and a gradient), and the cameras
// gather their slots in chunk order: every sum has a fixed order, so results are bit-identical
// for any number of threads. A block of a few rows without a loss is scattered straight from
// its Jacobian rows ("direct", schur_kernels.hpp).

#include <Eigen/Core>
#include <cstddef>
#include <utility>
#include <vector>

#include "block_evaluator.hpp"
#include "block_linearizations.hpp"
#include "carat/solver/problem.hpp"
#include "linearize_report.hpp"
#include "schur_structure.hpp"

namespace carat::internal {

class SchurLinearization {
 public:
  /// Plans the chunks of `structure` (built from `problem`), whose assemblies go to `values`;
  /// both must outlive this object.
  SchurLinearization(const Problem& problem, const SchurStructure& structure, SchurValues& values);

  /// Gathers blocks' H and b (every block's) into the values and the gradient.
  void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient);

  /// Fused only (SchurStructure::fused): evaluates every block at the evaluator's buffer
  /// `which` and assembles the values and the gradient; the blocks with a point a piece of
  /// points at a time, scattered while in cache, without per-block storage.
  LinearizeReport linearize(const BlockEvaluator& evaluator, int which, Eigen::VectorXd* gradient);

 private:
  void plan_chunks();
  void plan_direct_blocks(const Problem& problem);
  void plan_other_blocks(const Problem& problem);
  void zero_slots(std::size_t k);
  /// The points [p0, p1) of chunk k: V, their gradients, W per edge and, fused, the chunk's
  /// slots; h_of(q) / b_of(q): packed H (or, direct, Jacobian rows) and b of the block of
  /// structure point contribution q.
  template <typename HOf, typename BOf>
  void scatter_chunk(std::size_t k, std::size_t p0, std::size_t p1, double* gradient,
                     const HOf& h_of, const BOf& b_of, bool use_direct);
  template <int DC, int DP, typename HOf, typename BOf>
  void scatter_chunk_sized(std::size_t k, std::size_t p0, std::size_t p1, double* gradient,
                           const HOf& h_of, const BOf& b_of, bool use_direct);
  void gather_cameras(const BlockLinearizations& blocks, double* gradient);
  std::size_t num_point_chunks() const {
    return (s_.num_points() + chunk_points_ - 1) / chunk_points_;
  }
  /// Points [first, end) of chunk k.
  std::pair<std::size_t, std::size_t> chunk_range(std::size_t k) const {
    return {k * chunk_points_, std::min(s_.num_points(), (k + 1) * chunk_points_)};
  }
  /// Number of pieces of chunk k (linearize() evaluates and scatters a piece at a time).
  std::size_t num_pieces(std::size_t k) const {
    const auto [p0, p1] = chunk_range(k);
    return (p1 - p0 + kPiecePoints - 1) / kPiecePoints;
  }
  /// Points [first, end) of piece j of chunk k.
  std::pair<std::size_t, std::size_t> piece_range(std::size_t k, std::size_t j) const {
    const auto [p0, p1] = chunk_range(k);
    return {std::min(p1, p0 + j * kPiecePoints), std::min(p1, p0 + (j + 1) * kPiecePoints)};
  }

  static constexpr int kDirectRows = 4;             // most rows of a direct block
  static constexpr std::size_t kPiecePoints = 256;  // points evaluated, then scattered, together
  static constexpr std::size_t kEdgesPerSlot = 64;  // edges per camera slot (see plan_chunks())
  static constexpr std::size_t kNoEdge = ~std::size_t{0};

  const SchurStructure& s_;
  SchurValues& values_;
  std::size_t chunk_points_ = 1024;  // points per chunk (see plan_chunks())

  // Fused: per chunk of points, one slot (dc x dc diagonal block, then dc gradient) per camera
  // its points are seen by; each edge's slot; each camera's slots in chunk order; where each
  // block with a point goes in a piece's buffer; the blocks without a point.
  std::vector<std::size_t> edge_slot_;
  std::vector<std::size_t> cam_slot_begin_, cam_slots_;
  std::vector<std::size_t> chunk_slot_begin_;  // chunk k's slots: [begin[k], begin[k + 1])
  std::vector<double> slots_;
  std::vector<std::size_t> pt_contrib_h_local_, pt_contrib_b_local_;  // in its piece's buffer
  // Direct blocks (see plan_direct_blocks()), per point contribution: flag, rows, camera offset
  // in the block, edge.
  std::vector<char> direct_;
  std::vector<int> direct_rows_;
  std::vector<int> direct_cam_local_;
  std::vector<std::size_t> direct_edge_;
  // Edges whose one contribution is a direct block: it writes W (not zeroed before).
  std::vector<char> edge_assigned_;
  std::vector<char> chunk_standard_;  // per chunk: all its blocks take the standard 9 / 3 path
  std::size_t chunk_h_size_ = 0, chunk_b_size_ = 0;
  std::vector<std::size_t> other_blocks_;  // blocks without a point
  BlockLinearizations other_;              // their H and b (the others' entries unused)
  std::vector<double> chunk_cost_;
};

}  // namespace carat::internal
