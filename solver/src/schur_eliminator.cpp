#include "schur_eliminator.hpp"

#include <cholmod.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>

#include "carat/base/multiversion.hpp"
#include "carat/base/stopwatch.hpp"

namespace carat::internal {
namespace {

template <int R, int C>
using MapMatrix = Eigen::Map<Eigen::Matrix<double, R, C>>;
template <int R, int C>
using ConstMapMatrix = Eigen::Map<const Eigen::Matrix<double, R, C>>;
template <int R>
using MapVector = Eigen::Map<Eigen::Matrix<double, R, 1>>;
template <int R>
using ConstMapVector = Eigen::Map<const Eigen::Matrix<double, R, 1>>;

std::size_t at(int k) { return static_cast<std::size_t>(k); }

/// L^-1 (3 x 3, column-major, lower; the upper part zero) for V + diag(d) = L L^T, V symmetric
/// 3 x 3 column-major; false if V + diag(d) is not positive definite (or not finite).
inline bool inverse_cholesky_3(const double* V, const double* d, double* L_inverse) {
  const double a = V[0] + d[0];
  if (!(a > 0.0)) return false;
  const double l00 = std::sqrt(a);
  const double l10 = V[1] / l00;
  const double l20 = V[2] / l00;
  const double b = V[4] + d[1] - l10 * l10;
  if (!(b > 0.0)) return false;
  const double l11 = std::sqrt(b);
  const double l21 = (V[5] - l20 * l10) / l11;
  const double c = V[8] + d[2] - l20 * l20 - l21 * l21;
  if (!(c > 0.0)) return false;
  const double l22 = std::sqrt(c);
  const double i00 = 1.0 / l00, i11 = 1.0 / l11, i22 = 1.0 / l22;
  const double i10 = -l10 * i00 * i11;
  const double i21 = -l21 * i11 * i22;
  const double i20 = -(l20 * i00 + l21 * i10) * i22;
  L_inverse[0] = i00;
  L_inverse[1] = i10;
  L_inverse[2] = i20;
  L_inverse[3] = 0.0;
  L_inverse[4] = i11;
  L_inverse[5] = i21;
  L_inverse[6] = 0.0;
  L_inverse[7] = 0.0;
  L_inverse[8] = i22;
  return std::isfinite(i20) && std::isfinite(i21) && std::isfinite(i10);
}

/// What one column of S needs from the system (see SchurEliminator::form_reduced_system()).
struct GroupInput {
  const std::size_t* points_begin;  // the points the group's cameras see, ascending
  const std::size_t* points_end;
  int first_camera;  // the group: cameras [first_camera, end_camera)
  int end_camera;
  std::size_t num_cameras;
  const int* edge_cam;
  const std::size_t* edge_y_offset;
  const std::size_t* pt_edge_begin;
  const int* cam_dim;
  const int* pt_dim;
  const double* w;          // W per edge (edge_y_offset)
  const double* l_inverse;  // L^-1 per point (pt_v_offset)
  const std::size_t* pt_v_offset;
  double* y;                      // scratch: Y = W L^-T of one point's edges
  const std::size_t* row_offset;  // [(j - first_camera) * num_cameras + i]: block (i, j) in stack
  double* stack;                  // the group's columns of S blocks (stack_index() per block)
  // The right-hand side reduced alongside (null: not asked): u = L^-1 rhs per point (at
  // pt_offset - ns), and the cameras' reduced values, rhs_camera to start with (cam_offset).
  const double* u;
  const int* pt_offset;
  int ns;
  const int* cam_offset;
  double* reduced_rhs;
};

/// r (dc) -= Y (dc x dp, column-major) u (dp): W V^-1 rhs_point = Y (L^-1 rhs_point), edge by
/// edge.
template <int DC, int DP>
[[gnu::always_inline]] inline void subtract_y_u(double* __restrict r, const double* __restrict Y,
                                                const double* __restrict u, int dc, int dp) {
  const int DI = DC == Eigen::Dynamic ? dc : DC;
  const int DPP = DP == Eigen::Dynamic ? dp : DP;
  for (int k = 0; k < DPP; ++k) {
    const double uk = u[k];
    const double* column = Y + k * DI;
    for (int i = 0; i < DI; ++i) r[i] -= column[i] * uk;
  }
}

/// S (di x dj, column-major) -= Y1 (di x dp) Y2^T (dj x dp).
template <int DC, int DP>
__attribute__((always_inline)) inline void subtract_product(double* __restrict S,
                                                            const double* __restrict Y1,
                                                            const double* __restrict Y2, int di,
                                                            int dj, int dp) {
  const int DI = DC == Eigen::Dynamic ? di : DC;
  const int DJ = DC == Eigen::Dynamic ? dj : DC;
  const int DPP = DP == Eigen::Dynamic ? dp : DP;
  for (int c = 0; c < DJ; ++c) {
    double* out = S + c * DI;
    for (int k = 0; k < DPP; ++k) {
      const double w = Y2[k * DJ + c];
      const double* in = Y1 + k * DI;
      for (int r = 0; r < DI; ++r) out[r] -= in[r] * w;
    }
  }
}

/// Eight doubles, one AVX-512 register (or two AVX2 ones, depending on the clone).
typedef double Lanes8 __attribute__((vector_size(8 * sizeof(double))));

/// Whether the group's stacked S blocks are 9 x 9 blocks in the packed layout (see
/// packed_index()): every camera 9-dimensional, every point 3-dimensional.
template <int DC, int DP>
constexpr bool kPacked9 = DC == 9 && DP == 3;

/// Where element (r, c) of a 9 x 9 block sits in the packed layout: rows 0-7 of each column
/// first (column c's at 8 c), then row 8 of every column (at 72 + c), so that both parts are
/// runs of eight for the vector updates of subtract_product_9_3().
constexpr std::size_t packed_index(int r, int c) {
  return r < 8 ? static_cast<std::size_t>(c) * 8 + static_cast<std::size_t>(r)
               : 72 + static_cast<std::size_t>(c);
}

/// Offset of element (r, c) of a di x dj block in the group's stack.
template <int DC, int DP>
[[gnu::always_inline]] inline std::size_t stack_index(int r, int c, int di) {
  if constexpr (kPacked9<DC, DP>) return packed_index(r, c);
  return static_cast<std::size_t>(c) * static_cast<std::size_t>(di) + static_cast<std::size_t>(r);
}

/// S (9 x 9, packed layout) -= Y1 (9 x 3) Y2^T (9 x 3), Y1 and Y2 column-major: the same sums in
/// the same order as subtract_product<9, 3>(), eight rows (or columns) a vector operation.
[[gnu::always_inline]] inline void subtract_product_9_3(double* __restrict S,
                                                        const double* __restrict Y1,
                                                        const double* __restrict Y2) {
  Lanes8 a0, a1, a2, s;
  __builtin_memcpy(&a0, Y1, sizeof(Lanes8));
  __builtin_memcpy(&a1, Y1 + 9, sizeof(Lanes8));
  __builtin_memcpy(&a2, Y1 + 18, sizeof(Lanes8));
  for (int c = 0; c < 9; ++c) {  // rows 0-7 of column c
    __builtin_memcpy(&s, S + c * 8, sizeof(Lanes8));
    s -= a0 * Y2[c];
    s -= a1 * Y2[9 + c];
    s -= a2 * Y2[18 + c];
    __builtin_memcpy(S + c * 8, &s, sizeof(Lanes8));
  }
  Lanes8 b0, b1, b2;  // row 8 of columns 0-7, then of column 8
  __builtin_memcpy(&b0, Y2, sizeof(Lanes8));
  __builtin_memcpy(&b1, Y2 + 9, sizeof(Lanes8));
  __builtin_memcpy(&b2, Y2 + 18, sizeof(Lanes8));
  __builtin_memcpy(&s, S + 72, sizeof(Lanes8));
  s -= b0 * Y1[8];
  s -= b1 * Y1[17];
  s -= b2 * Y1[26];
  __builtin_memcpy(S + 72, &s, sizeof(Lanes8));
  S[80] -= Y1[8] * Y2[8];
  S[80] -= Y1[17] * Y2[17];
  S[80] -= Y1[26] * Y2[26];
}

/// Y = W L^-T for W (DC x 3) and the lower-triangular L^-1 (3 x 3), all column-major: the six
/// products the triangle leaves (L^-T's upper zeros skipped), each column of W in turn.
template <int DC>
__attribute__((always_inline)) inline void lower_product_3(const double* __restrict W,
                                                           const double* __restrict L_inverse,
                                                           double* __restrict Y) {
  const double l00 = L_inverse[0], l10 = L_inverse[1], l20 = L_inverse[2];
  const double l11 = L_inverse[4], l21 = L_inverse[5], l22 = L_inverse[8];
  const double* w0 = W;
  const double* w1 = W + DC;
  const double* w2 = W + 2 * DC;
  double* y0 = Y;
  double* y1 = Y + DC;
  double* y2 = Y + 2 * DC;
  for (int r = 0; r < DC; ++r) {
    y0[r] = w0[r] * l00;
    y1[r] = w0[r] * l10 + w1[r] * l11;
    y2[r] = w0[r] * l20 + w1[r] * l21 + w2[r] * l22;
  }
}

/// For every point a camera of the group sees, in point order, and each such camera j:
/// S_ij -= Y_ip Y_jp^T for every camera i >= j that sees the point too (the point's edges from
/// j's own one on, by camera), and (with in.u) r_j -= Y_jp u_p. A point's edges are read once per
/// group, not once per camera. Without in.stack, only the right-hand side.
template <int DC, int DP>
__attribute__((always_inline)) inline void reduce_group_body(const GroupInput& in) {
  for (const std::size_t* it = in.points_begin; it != in.points_end; ++it) {
    const std::size_t p = *it;
    const int dp = in.pt_dim[p];
    const std::size_t end = in.pt_edge_begin[p + 1];
    std::size_t first = in.pt_edge_begin[p];
    while (first < end && in.edge_cam[first] < in.first_camera) ++first;
    // Y = W L^-T of the edges from the group's first one on (W V^-1 W^T = Y Y^T).
    const ConstMapMatrix<DP, DP> L_inverse(in.l_inverse + in.pt_v_offset[p], dp, dp);
    std::size_t y_offset = 0;
    for (std::size_t f = first; f < end; ++f) {
      const int dc = in.cam_dim[in.edge_cam[f]];
      if constexpr (DC != Eigen::Dynamic && DP == 3) {
        lower_product_3<DC>(in.w + in.edge_y_offset[f], L_inverse.data(), in.y + y_offset);
      } else {
        MapMatrix<DC, DP>(in.y + y_offset, dc, dp).noalias() =
            ConstMapMatrix<DC, DP>(in.w + in.edge_y_offset[f], dc, dp)
                .lazyProduct(L_inverse.transpose());
      }
      y_offset += static_cast<std::size_t>(dc) * static_cast<std::size_t>(dp);
    }
    if (in.u != nullptr) {  // the group's cameras' share of the reduced right-hand side
      const double* u = in.u + (in.pt_offset[p] - in.ns);
      std::size_t yr = 0;
      for (std::size_t e = first; e < end && in.edge_cam[e] < in.end_camera; ++e) {
        const int c = in.edge_cam[e];
        const int dc = in.cam_dim[c];
        subtract_y_u<DC, DP>(in.reduced_rhs + in.cam_offset[c], in.y + yr, u, dc, dp);
        yr += static_cast<std::size_t>(dc) * static_cast<std::size_t>(dp);
      }
    }
    if (in.stack == nullptr) continue;
    std::size_t ye = 0;  // offset of edge e's Y
    for (std::size_t e = first; e < end; ++e) {
      const int j = in.edge_cam[e];
      if (j >= in.end_camera) break;
      const int dj = in.cam_dim[j];
      const double* Yj = in.y + ye;
      const std::size_t* offsets =
          in.row_offset + static_cast<std::size_t>(j - in.first_camera) * in.num_cameras;
      std::size_t yf = ye;
      for (std::size_t f = e; f < end; ++f) {
        const auto i = static_cast<std::size_t>(in.edge_cam[f]);
        if constexpr (kPacked9<DC, DP>) {
          subtract_product_9_3(in.stack + offsets[i], in.y + yf, Yj);
        } else {
          subtract_product<DC, DP>(in.stack + offsets[i], in.y + yf, Yj, in.cam_dim[i], dj, dp);
        }
        yf += static_cast<std::size_t>(in.cam_dim[i]) * static_cast<std::size_t>(dp);
      }
      ye += static_cast<std::size_t>(dj) * static_cast<std::size_t>(dp);
    }
  }
}

CARAT_MULTIVERSION_WIDE void reduce_group_9_3(const GroupInput& in) { reduce_group_body<9, 3>(in); }
CARAT_MULTIVERSION void reduce_group_6_3(const GroupInput& in) { reduce_group_body<6, 3>(in); }
CARAT_MULTIVERSION void reduce_group_any(const GroupInput& in) {
  reduce_group_body<Eigen::Dynamic, Eigen::Dynamic>(in);
}

}  // namespace

SchurEliminator::SchurEliminator(const SchurStructure& structure, const SchurValues& values,
                                 Ordering ordering)
    : s_(structure),
      h_(values),
      l_inverse_(structure.v_size, 0.0),
      u_(at(structure.n - structure.ns), 0.0),
      reduced_(structure.rows.size(), 0.0),
      cholmod_(std::make_unique<CholmodSession>()) {
  if (s_.ns == 0) return;
  cholmod_->set_lower_matrix(at(s_.ns), s_.colptr.data(), s_.rows.data(), reduced_.data(),
                             reduced_.size());
  cholmod_->common().supernodal = CHOLMOD_SUPERNODAL;
  cholmod_->analyze("Schur complement", ordering);
  ordering_name_ = cholmod_->chosen_ordering();
  factor_nnz_ = static_cast<std::size_t>(cholmod_->common().lnz);
  factor_flops_ = cholmod_->common().fl;
}

SchurEliminator::~SchurEliminator() = default;

/// Per point: V + damping = L L^T, L^-1 kept, and Y = W L^-T per edge, so that
/// W V^-1 W^T = Y Y^T. False if a V is not positive definite.
template <int DC, int DP>
bool SchurEliminator::eliminate_points(const Eigen::VectorXd& damping) {
  std::atomic<bool> failed{false};
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, s_.pt_dim.size(), 256),
      [&](const tbb::blocked_range<std::size_t>& range) {
        using MatrixP = Eigen::Matrix<double, DP, DP>;
        MatrixP V_damped;
        Eigen::LLT<MatrixP> llt;
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
          const int dp = s_.pt_dim[p];
          MapMatrix<DP, DP> L_inverse(l_inverse_.data() + s_.pt_v_offset[p], dp, dp);
          if constexpr (DP == 3) {
            if (!inverse_cholesky_3(h_.v.data() + s_.pt_v_offset[p],
                                    damping.data() + s_.pt_offset[p], L_inverse.data())) {
              failed.store(true, std::memory_order_relaxed);
              continue;
            }
          } else {
            V_damped = ConstMapMatrix<DP, DP>(h_.v.data() + s_.pt_v_offset[p], dp, dp);
            V_damped.diagonal() += damping.segment(s_.pt_offset[p], dp);
            llt.compute(V_damped);
            if (llt.info() != Eigen::Success) {
              failed.store(true, std::memory_order_relaxed);
              continue;
            }
            L_inverse.setIdentity(dp, dp);
            llt.matrixL().solveInPlace(L_inverse);
          }
        }
      });
  return !failed.load();
}

/// u_p = L^-1 rhs_p per point, into u_.
template <int DC, int DP>
void SchurEliminator::point_rhs(const double* rhs) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, s_.pt_dim.size(), 512),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t p = range.begin(); p != range.end(); ++p) {
                        const int dp = s_.pt_dim[p];
                        const ConstMapMatrix<DP, DP> L_inverse(
                            l_inverse_.data() + s_.pt_v_offset[p], dp, dp);
                        MapVector<DP>(u_.data() + (s_.pt_offset[p] - s_.ns), dp).noalias() =
                            L_inverse.lazyProduct(ConstMapVector<DP>(rhs + s_.pt_offset[p], dp));
                      }
                    });
}

/// Runs reduce_group_body() over the groups, a group per task: with `damping`, each group's
/// blocks of S = A + diag(damping) - sum over shared points of Y_i Y_j^T into the CSC values (each
/// block's sum in point order); with `rhs`, its cameras' reduced right-hand side rhs_camera -
/// sum over their points of Y u (u_ made from rhs first) into `reduced_rhs`.
template <int DC, int DP>
void SchurEliminator::run_groups(const Eigen::VectorXd* damping, const double* rhs,
                                 double* reduced_rhs) {
  struct GroupScratch {
    std::vector<double> stack;
    std::vector<std::size_t> row_offset;
    std::vector<double> y;
  };
  const std::size_t nc = s_.cam_dim.size();
  const std::size_t num_groups = s_.group_points_begin.size() - 1;
  tbb::enumerable_thread_specific<GroupScratch> scratch;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, num_groups, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        GroupScratch& local = scratch.local();
        if (damping != nullptr) {
          local.stack.resize(s_.max_group_values);
          local.row_offset.resize(s_.group_cameras * nc);
        }
        local.y.resize(s_.max_point_y);
        for (std::size_t group = range.begin(); group != range.end(); ++group) {
          const auto [j0, j1] = s_.group_range(group);
          if (rhs != nullptr) {
            for (std::size_t c = j0; c < j1; ++c)
              std::copy_n(rhs + s_.cam_offset[c], s_.cam_dim[c], reduced_rhs + s_.cam_offset[c]);
          }
          // The group's blocks, stacked, start as A (+ damping on the diagonal blocks).
          std::size_t offset = 0;
          for (std::size_t j = j0; j < j1 && damping != nullptr; ++j) {
            const int dj = s_.cam_dim[j];
            std::size_t* rows = local.row_offset.data() + (j - j0) * nc;
            for (std::size_t k = s_.column_pair_begin[j]; k < s_.column_pair_begin[j + 1]; ++k) {
              const SchurStructure::Pair& pair = s_.pairs[k];
              const std::size_t size = at(s_.cam_dim[at(pair.row_cam)]) * at(dj);
              rows[at(pair.row_cam)] = offset;
              const double* a = h_.a.data() + pair.h_offset;
              double* block = local.stack.data() + offset;
              if constexpr (kPacked9<DC, DP>) {
                for (int c = 0; c < 9; ++c)
                  for (int r = 0; r < 9; ++r) block[packed_index(r, c)] = a[c * 9 + r];
              } else {
                std::copy_n(a, size, block);
              }
              offset += size;
            }
            double* diagonal = local.stack.data() + rows[j];
            for (int r = 0; r < dj; ++r)
              diagonal[stack_index<DC, DP>(r, r, dj)] += (*damping)[s_.cam_offset[j] + r];
          }
          const GroupInput in{s_.group_points.data() + s_.group_points_begin[group],
                              s_.group_points.data() + s_.group_points_begin[group + 1],
                              static_cast<int>(j0),
                              static_cast<int>(j1),
                              nc,
                              s_.edge_cam.data(),
                              s_.edge_w_offset.data(),
                              s_.pt_edge_begin.data(),
                              s_.cam_dim.data(),
                              s_.pt_dim.data(),
                              h_.w.data(),
                              l_inverse_.data(),
                              s_.pt_v_offset.data(),
                              local.y.data(),
                              local.row_offset.data(),
                              damping != nullptr ? local.stack.data() : nullptr,
                              rhs != nullptr ? u_.data() : nullptr,
                              s_.pt_offset.data(),
                              s_.ns,
                              s_.cam_offset.data(),
                              reduced_rhs};
          if constexpr (DC == 9 && DP == 3) {
            reduce_group_9_3(in);
          } else if constexpr (DC == 6 && DP == 3) {
            reduce_group_6_3(in);
          } else {
            reduce_group_any(in);
          }
          for (std::size_t j = j0; j < j1 && damping != nullptr; ++j) {
            const int dj = s_.cam_dim[j];
            const std::size_t* rows = local.row_offset.data() + (j - j0) * nc;
            for (std::size_t k = s_.column_pair_begin[j]; k < s_.column_pair_begin[j + 1]; ++k) {
              const SchurStructure::Pair& pair = s_.pairs[k];
              const int di = s_.cam_dim[at(pair.row_cam)];
              const double* S = local.stack.data() + rows[at(pair.row_cam)];
              const bool diagonal = at(pair.row_cam) == j;
              for (int c = 0; c < dj; ++c) {
                double* column = reduced_.data() + s_.colptr[at(s_.cam_offset[j] + c)];
                if (diagonal) {
                  for (int r = c; r < dj; ++r) column[r - c] = S[stack_index<DC, DP>(r, c, di)];
                } else {
                  double* dst = column + (dj - c) + pair.row_in_column;
                  for (int r = 0; r < di; ++r) dst[r] = S[stack_index<DC, DP>(r, c, di)];
                }
              }
            }
          }
        }
      });
}

template <int DC, int DP>
bool SchurEliminator::eliminate(const Eigen::VectorXd& damping) {
  if (!eliminate_points<DC, DP>(damping)) return false;
  const bool fuse = expected_rhs_.size() == static_cast<std::size_t>(s_.n);
  if (fuse) point_rhs<DC, DP>(expected_rhs_.data());
  run_groups<DC, DP>(&damping, fuse ? expected_rhs_.data() : nullptr, fused_reduced_.data());
  return true;
}

bool SchurEliminator::factorize(const Eigen::VectorXd& damping) {
  const Stopwatch t0;
  fused_ready_ = false;
  const bool fuse = expected_rhs_.size() == at(s_.n);
  fused_reduced_.resize(fuse ? at(s_.ns) : 0);
  bool ok = false;
  switch (s_.kernel) {
    case SchurKernel::kCamera9Point3:
      ok = eliminate<9, 3>(damping);
      break;
    case SchurKernel::kCamera6Point3:
      ok = eliminate<6, 3>(damping);
      break;
    case SchurKernel::kDynamic:
      ok = eliminate<Eigen::Dynamic, Eigen::Dynamic>(damping);
      break;
  }
  seconds_ += t0.elapsed_s();
  if (!ok) return false;
  if (s_.ns > 0 && !cholmod_->factorize()) return false;
  fused_ready_ = fuse;  // only with a factorization to solve with
  return true;
}

void SchurEliminator::expect_rhs(const Eigen::VectorXd& rhs) {
  expected_rhs_.assign(rhs.data(), rhs.data() + rhs.size());
  fused_ready_ = false;
}

/// reduced = rhs_cameras - sum over each camera's edges of W_e V^-1 rhs_point, formed as
/// factorize() forms it for the expected right-hand side (Y_e L^-1 rhs_point, each camera's sum in
/// point order), so that both give the same bits.
template <int DC, int DP>
void SchurEliminator::reduce_rhs(const Eigen::VectorXd& rhs, double* reduced) {
  point_rhs<DC, DP>(rhs.data());
  run_groups<DC, DP>(nullptr, rhs.data(), reduced);
}

/// x_point = V^-1 (rhs_point - sum over its edges of W_e^T x_camera); x_cameras copied.
template <int DC, int DP>
void SchurEliminator::back_substitute(const Eigen::VectorXd& rhs, const double* x_cameras,
                                      double* x) const {
  std::copy_n(x_cameras, s_.ns, x);
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, s_.pt_dim.size(), 256),
      [&](const tbb::blocked_range<std::size_t>& range) {
        Eigen::Matrix<double, DP, 1> t;
        for (std::size_t p = range.begin(); p != range.end(); ++p) {
          const int dp = s_.pt_dim[p];
          t = rhs.segment(s_.pt_offset[p], dp);
          for (std::size_t e = s_.pt_edge_begin[p]; e < s_.pt_edge_begin[p + 1]; ++e) {
            const auto c = at(s_.edge_cam[e]);
            const int dc = s_.cam_dim[c];
            t.noalias() -= ConstMapMatrix<DC, DP>(h_.w.data() + s_.edge_w_offset[e], dc, dp)
                               .transpose()
                               .lazyProduct(ConstMapVector<DC>(x_cameras + s_.cam_offset[c], dc));
          }
          const ConstMapMatrix<DP, DP> L_inverse(l_inverse_.data() + s_.pt_v_offset[p], dp, dp);
          MapVector<DP>(x + s_.pt_offset[p], dp).noalias() =
              L_inverse.transpose().lazyProduct(L_inverse.lazyProduct(t));
        }
      });
}

void SchurEliminator::solve(const Eigen::VectorXd& rhs, Eigen::VectorXd* x) {
  Stopwatch t0;
  Eigen::VectorXd reduced(s_.ns);
  const bool fused =
      fused_ready_ && rhs.size() == s_.n &&
      std::equal(rhs.data(), rhs.data() + rhs.size(), expected_rhs_.data(), [](double a, double b) {
        return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
      });
  if (fused) {
    std::copy(fused_reduced_.begin(), fused_reduced_.end(), reduced.data());
  } else {
    switch (s_.kernel) {
      case SchurKernel::kCamera9Point3:
        reduce_rhs<9, 3>(rhs, reduced.data());
        break;
      case SchurKernel::kCamera6Point3:
        reduce_rhs<6, 3>(rhs, reduced.data());
        break;
      case SchurKernel::kDynamic:
        reduce_rhs<Eigen::Dynamic, Eigen::Dynamic>(rhs, reduced.data());
        break;
    }
  }
  seconds_ += t0.elapsed_s();
  const double* x_cameras = reduced.data();
  if (s_.ns > 0) {
    x_cameras_.resize(at(s_.ns));
    cholmod_->solve(reduced.data(), x_cameras_.data(), "Schur complement");
    x_cameras = x_cameras_.data();
  }
  t0.restart();
  x->resize(s_.n);
  switch (s_.kernel) {
    case SchurKernel::kCamera9Point3:
      back_substitute<9, 3>(rhs, x_cameras, x->data());
      break;
    case SchurKernel::kCamera6Point3:
      back_substitute<6, 3>(rhs, x_cameras, x->data());
      break;
    case SchurKernel::kDynamic:
      back_substitute<Eigen::Dynamic, Eigen::Dynamic>(rhs, x_cameras, x->data());
      break;
  }
  seconds_ += t0.elapsed_s();
}

double SchurEliminator::take_seconds() {
  const double seconds = seconds_;
  seconds_ = 0.0;
  return seconds;
}

}  // namespace carat::internal
