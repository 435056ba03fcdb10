#include "schur_eliminator.hpp"

#include <cholmod.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <atomic>
#include <cmath>

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
  double* stack;                  // the group's columns of S blocks (column-major per block)
};

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
/// j's own one on, by camera). A point's edges are read once per group, not once per camera.
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
        subtract_product<DC, DP>(in.stack + offsets[i], in.y + yf, Yj, in.cam_dim[i], dj, dp);
        yf += static_cast<std::size_t>(in.cam_dim[i]) * static_cast<std::size_t>(dp);
      }
      ye += static_cast<std::size_t>(dj) * static_cast<std::size_t>(dp);
    }
  }
}

CARAT_MULTIVERSION void reduce_group_9_3(const GroupInput& in) { reduce_group_body<9, 3>(in); }
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
      z_(at(structure.n - structure.ns), 0.0),
      reduced_(structure.rows.size(), 0.0),
      cholmod_(std::make_unique<CholmodSession>()) {
  if (s_.ns == 0) return;
  cholmod_->set_lower_matrix(at(s_.ns), s_.colptr.data(), s_.rows.data(), reduced_.data(),
                             reduced_.size());
  cholmod_->common().supernodal = CHOLMOD_SUPERNODAL;
  cholmod_->set_ordering(ordering);
  cholmod_->analyze("Schur complement");
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

/// S = A + diag(damping) - sum over shared points of Y_i Y_j^T, into the CSC values; a column of
/// camera blocks per task, each block's sum in point order.
template <int DC, int DP>
void SchurEliminator::form_reduced_system(const Eigen::VectorXd& damping) {
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
        local.stack.resize(s_.max_group_values);
        local.row_offset.resize(SchurStructure::kGroupCameras * nc);
        local.y.resize(s_.max_point_y);
        for (std::size_t group = range.begin(); group != range.end(); ++group) {
          const auto [j0, j1] = s_.group_range(group);
          // The group's blocks, stacked, start as A (+ damping on the diagonal blocks).
          std::size_t offset = 0;
          for (std::size_t j = j0; j < j1; ++j) {
            const int dj = s_.cam_dim[j];
            std::size_t* rows = local.row_offset.data() + (j - j0) * nc;
            for (std::size_t k = s_.column_pair_begin[j]; k < s_.column_pair_begin[j + 1]; ++k) {
              const SchurStructure::Pair& pair = s_.pairs[k];
              const std::size_t size = at(s_.cam_dim[at(pair.row_cam)]) * at(dj);
              rows[at(pair.row_cam)] = offset;
              std::copy_n(h_.a.data() + pair.h_offset, size, local.stack.data() + offset);
              offset += size;
            }
            double* diagonal = local.stack.data() + rows[j];
            for (int r = 0; r < dj; ++r)
              diagonal[at(r) * at(dj) + at(r)] += damping[s_.cam_offset[j] + r];
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
                              local.stack.data()};
          if constexpr (DC == 9 && DP == 3) {
            reduce_group_9_3(in);
          } else if constexpr (DC == 6 && DP == 3) {
            reduce_group_6_3(in);
          } else {
            reduce_group_any(in);
          }
          for (std::size_t j = j0; j < j1; ++j) {
            const int dj = s_.cam_dim[j];
            const std::size_t* rows = local.row_offset.data() + (j - j0) * nc;
            for (std::size_t k = s_.column_pair_begin[j]; k < s_.column_pair_begin[j + 1]; ++k) {
              const SchurStructure::Pair& pair = s_.pairs[k];
              const int di = s_.cam_dim[at(pair.row_cam)];
              const double* S = local.stack.data() + rows[at(pair.row_cam)];
              const bool diagonal = at(pair.row_cam) == j;
              for (int c = 0; c < dj; ++c) {
                double* column = reduced_.data() + s_.colptr[at(s_.cam_offset[j] + c)];
                const double* src = S + at(c) * at(di);
                if (diagonal) {
                  for (int r = c; r < dj; ++r) column[r - c] = src[r];
                } else {
                  double* dst = column + (dj - c) + pair.row_in_column;
                  for (int r = 0; r < di; ++r) dst[r] = src[r];
                }
              }
            }
          }
        }
      });
}

bool SchurEliminator::factorize(const Eigen::VectorXd& damping) {
  const Stopwatch t0;
  bool ok = false;
  switch (s_.kernel) {
    case SchurKernel::kCamera9Point3:
      ok = eliminate_points<9, 3>(damping);
      if (ok) form_reduced_system<9, 3>(damping);
      break;
    case SchurKernel::kCamera6Point3:
      ok = eliminate_points<6, 3>(damping);
      if (ok) form_reduced_system<6, 3>(damping);
      break;
    case SchurKernel::kDynamic:
      ok = eliminate_points<Eigen::Dynamic, Eigen::Dynamic>(damping);
      if (ok) form_reduced_system<Eigen::Dynamic, Eigen::Dynamic>(damping);
      break;
  }
  seconds_ += t0.elapsed_s();
  if (!ok) return false;
  if (s_.ns == 0) return true;
  return cholmod_->factorize();
}

/// u = V^-1 rhs_point = L^-T L^-1 rhs_point per point (kept in z_), then reduced =
/// rhs_cameras - sum over each camera's edges of W_e u_point.
template <int DC, int DP>
void SchurEliminator::reduce_rhs(const Eigen::VectorXd& rhs, double* reduced) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, s_.pt_dim.size(), 512),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t p = range.begin(); p != range.end(); ++p) {
                        const int dp = s_.pt_dim[p];
                        const ConstMapMatrix<DP, DP> L_inverse(
                            l_inverse_.data() + s_.pt_v_offset[p], dp, dp);
                        MapVector<DP>(z_.data() + (s_.pt_offset[p] - s_.ns), dp).noalias() =
                            L_inverse.transpose().lazyProduct(
                                L_inverse.lazyProduct(rhs.segment(s_.pt_offset[p], dp)));
                      }
                    });
  // Per group of cameras (as in form_reduced_system()): each point's edges read in sequence,
  // each camera's sum in point order.
  const std::size_t num_groups = s_.group_points_begin.size() - 1;
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, num_groups, 1),
      [&](const tbb::blocked_range<std::size_t>& range) {
        for (std::size_t group = range.begin(); group != range.end(); ++group) {
          const auto [j0, j1] = s_.group_range(group);
          for (std::size_t c = j0; c < j1; ++c) {
            const int dc = s_.cam_dim[c];
            MapVector<DC>(reduced + s_.cam_offset[c], dc) = rhs.segment(s_.cam_offset[c], dc);
          }
          for (std::size_t k = s_.group_points_begin[group]; k < s_.group_points_begin[group + 1];
               ++k) {
            const std::size_t p = s_.group_points[k];
            const int dp = s_.pt_dim[p];
            const ConstMapVector<DP> z(z_.data() + (s_.pt_offset[p] - s_.ns), dp);
            for (std::size_t e = s_.pt_edge_begin[p]; e < s_.pt_edge_begin[p + 1]; ++e) {
              const auto c = at(s_.edge_cam[e]);
              if (c < j0) continue;
              if (c >= j1) break;
              const int dc = s_.cam_dim[c];
              MapVector<DC>(reduced + s_.cam_offset[c], dc).noalias() -=
                  ConstMapMatrix<DC, DP>(h_.w.data() + s_.edge_w_offset[e], dc, dp).lazyProduct(z);
            }
          }
        }
      });
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
