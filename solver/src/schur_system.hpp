#pragma once

// Internal: the Schur complement. The free variables split into eliminated ones ("points": no
// residual block connects two of them, so their part of H is block diagonal) and the rest
// ("cameras"). With H = [A B; B^T C] and C block diagonal, each iteration forms the reduced
// system S = A - B C^-1 B^T (damping added to A and C first, as on the whole system), factorizes
// S with CHOLMOD (supernodal; symbolic analysis once) and recovers the points by
// back-substitution. Every sum is gathered per destination in a fixed order, so results are
// bit-identical for any number of threads.

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "carat/solver/problem.hpp"
#include "carat/solver/solver_options.hpp"
#include "cholmod_session.hpp"
#include "huge_pages.hpp"
#include "linear_system.hpp"

namespace carat::internal {

class SchurSystem final : public LinearSystem {
 public:
  /// eliminate[v] != 0 marks variable v for elimination (it must be free, and no block may
  /// connect two marked variables; the constructor throws carat::Error otherwise).
  SchurSystem(const Problem& problem, const std::vector<char>& eliminate, Ordering ordering);
  ~SchurSystem() override;
  SchurSystem(const SchurSystem&) = delete;
  SchurSystem& operator=(const SchurSystem&) = delete;

  std::size_t hessian_nonzeros() const override { return rows_.size(); }
  std::size_t factor_nonzeros() const override { return factor_nnz_; }
  void assemble(const BlockLinearizations& blocks, Eigen::VectorXd* gradient) override;
  /// Fused (every block with an eliminated variable touches at most one kept variable): the
  /// blocks with a point are evaluated a chunk of points at a time and scattered while in
  /// cache, without per-block storage; otherwise as LinearSystem::linearize().
  bool linearize(const BlockEvaluator& evaluator, int which, Eigen::VectorXd* gradient,
                 double* cost, double* linearize_s, double* assembly_s,
                 std::string* error) override;
  Eigen::VectorXd diagonal() const override;
  bool factorize(const Eigen::VectorXd& damping) override;
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd* y) const override;
  void solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) override;
  double take_elimination_seconds() override;
  double automatic_trust_region_growth() const override { return 3.0; }
  bool reuses_factorization() const override { return false; }

  /// Size of the reduced system (tangent dimensions of the variables not eliminated).
  int reduced_size() const { return ns_; }
  /// Number of eliminated variables.
  int num_eliminated() const { return static_cast<int>(pt_dim_.size()); }

  // What the covariance reads after factorize() (see covariance.hpp): the factor of S, and per
  // eliminated variable p its V's inverse factor and its blocks W with the kept variables.

  /// The reduced system's CHOLMOD session; after factorize(), its factor is of S.
  CholmodSession& reduced_cholmod() { return *cholmod_; }
  /// The eliminated variable whose tangent starts at system offset `offset`; -1 if none does.
  int eliminated_at(int offset) const;
  /// System offset of eliminated variable p.
  int eliminated_offset(std::size_t p) const { return pt_offset_[p]; }
  /// Tangent size of eliminated variable p.
  int eliminated_dim(std::size_t p) const { return pt_dim_[p]; }
  /// L^-1 (column-major, lower) with L L^T = V_p + damping of the last factorize().
  const double* eliminated_l_inverse(std::size_t p) const {
    return l_inverse_.data() + pt_v_offset_[p];
  }
  /// Edges of eliminated variable p: [first, end) (kept variables sharing a block with it).
  std::pair<std::size_t, std::size_t> eliminated_edges(std::size_t p) const {
    return {pt_edge_begin_[p], pt_edge_begin_[p + 1]};
  }
  /// System offset of edge e's kept variable.
  int edge_offset(std::size_t e) const {
    return cam_offset_[static_cast<std::size_t>(edge_cam_[e])];
  }
  /// Tangent size of edge e's kept variable.
  int edge_dim(std::size_t e) const { return cam_dim_[static_cast<std::size_t>(edge_cam_[e])]; }
  /// W = H(kept, eliminated) of edge e: edge_dim(e) x eliminated_dim(p), column-major.
  const double* edge_w(std::size_t e) const { return w_.data() + edge_w_offset_[e]; }
  /// V_p = H(p, p) of the last assembly (undamped; column-major).
  const double* eliminated_v(std::size_t p) const { return v_.data() + pt_v_offset_[p]; }
  /// S's lower triangle in compressed columns (kept variables in system order) as the last
  /// factorize() formed it, damping included: column pointers, rows, values.
  const std::vector<std::int64_t>& reduced_colptr() const { return colptr_; }
  /// See reduced_colptr().
  const std::vector<std::int64_t>& reduced_rows() const { return rows_; }
  /// See reduced_colptr().
  const std::vector<double>& reduced_values() const { return values_; }

 private:
  template <int DC, int DP>
  bool eliminate_points(const Eigen::VectorXd& damping);
  template <int DC, int DP>
  void form_reduced_system(const Eigen::VectorXd& damping);
  template <int DC, int DP>
  void reduce_rhs(const Eigen::VectorXd& rhs, double* reduced);
  template <int DC, int DP>
  void back_substitute(const Eigen::VectorXd& rhs, const double* x_cameras, double* x) const;

  void plan_chunks(const Problem& problem);
  void zero_slots(std::size_t k);
  template <typename HOf, typename BOf>
  void scatter_chunk(std::size_t k, std::size_t p0, std::size_t p1, double* gradient,
                     const HOf& h_of, const BOf& b_of, bool use_direct);
  template <int DC, int DP, typename HOf, typename BOf>
  void scatter_chunk_sized(std::size_t k, std::size_t p0, std::size_t p1, double* gradient,
                           const HOf& h_of, const BOf& b_of, bool use_direct);
  void gather_cameras(const BlockLinearizations& blocks, double* gradient);
  int block_dim(std::int32_t block) const { return block_dims_[static_cast<std::size_t>(block)]; }
  std::size_t num_point_chunks() const {
    return (pt_dim_.size() + chunk_points_ - 1) / chunk_points_;
  }
  /// Points [first, end) of chunk k.
  std::pair<std::size_t, std::size_t> chunk_range(std::size_t k) const {
    return {k * chunk_points_, std::min(pt_dim_.size(), (k + 1) * chunk_points_)};
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
  /// Cameras [first, end) of group g (form_reduced_system(), reduce_rhs()).
  std::pair<std::size_t, std::size_t> group_range(std::size_t g) const {
    return {g * kGroupCameras, std::min(cam_dim_.size(), (g + 1) * kGroupCameras)};
  }

  std::size_t chunk_points_ = 1024;                 // points per chunk (see plan_chunks())
  static constexpr int kDirectRows = 4;             // most rows of a direct block
  static constexpr std::size_t kPiecePoints = 256;  // points evaluated, then scattered, together
  static constexpr std::size_t kEdgesPerSlot = 64;  // edges per camera slot (see plan_chunks())
  static constexpr std::size_t kGroupCameras = 8;   // cameras per task forming S
  static constexpr std::size_t kNoEdge = ~std::size_t{0};

  int ns_ = 0;
  bool fused_ = true;
  std::vector<int> block_dims_;  // D per residual block      // reduced size
  int kernel_ = 0;               // 0: dynamic sizes, 1: cameras 9 / points 3, 2: 6 / 3
  std::size_t factor_nnz_ = 0;
  double elimination_s_ = 0.0;

  // Cameras (variables kept): dimension, offset in the system.
  std::vector<int> cam_dim_, cam_offset_;
  // Points (eliminated): dimension, offset in the system, offset of V / V^-1 storage.
  std::vector<int> pt_dim_, pt_offset_;
  std::vector<std::size_t> pt_v_offset_;
  // Edges (point, camera) in point-major order; each point's edges by camera index.
  std::vector<std::size_t> pt_edge_begin_;
  std::vector<int> edge_cam_, edge_pt_;
  std::vector<std::size_t> edge_w_offset_;
  // Each camera's edges, by point index (for the reduced right-hand side).
  std::vector<std::size_t> cam_edge_begin_;
  std::vector<std::size_t> cam_edges_;

  // Camera pairs (row i >= column j) of S, grouped by column j, rows ascending.
  struct Pair {
    int row_cam;
    std::int64_t row_in_column;  // offset of the row block below the diagonal block in the CSC
    std::size_t h_offset;        // start of the undamped A block (di x dj, column-major)
    std::size_t contrib_begin, contrib_end;  // A's contributions from blocks
  };
  std::vector<std::size_t> column_pair_begin_;
  std::vector<Pair> pairs_;
  struct Contribution {
    std::int32_t block;
    std::int16_t row_local;
    std::int16_t col_local;
  };
  std::vector<Contribution> pair_contribs_;
  // Groups of cameras for forming S (see the constructor).
  std::vector<std::size_t> group_points_begin_, group_points_;
  std::size_t max_group_values_ = 0;
  std::size_t max_point_y_ = 0;  // largest Y of one point's edges (values)
  std::vector<std::size_t> edge_contrib_begin_;
  std::vector<Contribution> edge_contribs_;         // row_local: camera, col_local: point
  std::vector<std::uint32_t> edge_contrib_source_;  // its block's index in pt_contribs_
  std::vector<std::size_t> pt_contrib_begin_;
  std::vector<std::pair<std::int32_t, std::int16_t>> pt_contribs_;  // V and g of points
  std::vector<std::size_t> cam_grad_begin_;
  std::vector<std::pair<std::int32_t, std::int16_t>> cam_grad_;

  // Fused: per chunk of points, one slot (dc x dc diagonal block, then dc gradient) per camera
  // its points are seen by; each edge's slot; each camera's slots in chunk order; where each
  // block with a point goes in a chunk's buffer; the blocks without a point.
  std::vector<std::size_t> edge_slot_;
  std::vector<std::size_t> cam_slot_begin_, cam_slots_;
  std::vector<std::size_t> chunk_slot_begin_;  // chunk k's slots: [begin[k], begin[k + 1])
  std::vector<double> slots_;
  std::vector<std::size_t> pt_contrib_h_local_, pt_contrib_b_local_;  // in its piece's buffer
  // Direct blocks (see plan_chunks()): flag, rows, camera offset in the block, edge.
  std::vector<char> direct_;
  std::vector<int> direct_rows_;
  std::vector<int> direct_cam_local_;
  std::vector<std::size_t> direct_edge_;
  // Edges whose one contribution is a direct block: it writes W (not zeroed before).
  std::vector<char> edge_assigned_;
  std::vector<char> chunk_standard_;  // per chunk: all its blocks take the standard 9 / 3 path
  std::size_t chunk_h_size_ = 0, chunk_b_size_ = 0;
  std::vector<std::size_t> other_blocks_;
  std::vector<double> chunk_cost_;

  // Values: undamped A blocks, W per edge (dc x dp), V per point; the factorization's
  // L^-1 (V + damping = L L^T; Y = W L^-T is formed where needed, not stored); z: V^-1 rhs of
  // the points in the last solve. solve() reads W, so it needs the assembly the factorization
  // was made from: this system does not reuse factorizations.
  // The large ones on huge pages (see huge_pages.hpp): fewer page faults on first touch.
  std::vector<double> a_, z_;
  HugeVector<double> w_, v_, l_inverse_;

  // Reduced system: lower-triangular CSC in camera order (CHOLMOD orders it).
  std::vector<std::int64_t> colptr_, rows_;
  std::vector<double> values_;
  std::unique_ptr<CholmodSession> cholmod_;  // S is a header over colptr_, rows_, values_
  std::vector<double> x_cameras_;            // the reduced solve's solution
};

}  // namespace carat::internal
