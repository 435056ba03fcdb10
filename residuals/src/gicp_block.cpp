#include "carat/residuals/gicp_block.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <cmath>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/multiversion.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/residuals/registration_rows.hpp"
#include "pose_gram_sum.hpp"

namespace carat {
namespace {

constexpr std::size_t kChunk = 512;

/// The upper-triangular W (w0 w1 w2; 0 w3 w4; 0 0 w5) with W^T W = C^-1 for the symmetric C
/// given by its upper triangle (c00 c01 c02 c11 c12 c22), in closed form: the inverse by
/// cofactors, then its 3 x 3 Cholesky factor. False unless C is positive definite. Without a
/// branch (W holds NaNs or garbage when false), so that a loop over it vectorizes.
[[gnu::always_inline]] inline bool whitening_of(const double* C, double* W) {
  const double c00 = C[0], c01 = C[1], c02 = C[2], c11 = C[3], c12 = C[4], c22 = C[5];
  // Cofactors of the symmetric C.
  const double a00 = c11 * c22 - c12 * c12, a01 = c02 * c12 - c01 * c22,
               a02 = c01 * c12 - c02 * c11;
  const double a11 = c00 * c22 - c02 * c02, a12 = c01 * c02 - c00 * c12,
               a22 = c00 * c11 - c01 * c01;
  const double det = c00 * a00 + c01 * a01 + c02 * a02;
  const double inv = 1.0 / det;
  const double i00 = a00 * inv, i01 = a01 * inv, i02 = a02 * inv;
  const double i11 = a11 * inv, i12 = a12 * inv, i22 = a22 * inv;
  const double w0 = std::sqrt(i00);
  const double w1 = i01 / w0, w2 = i02 / w0;
  const double s3 = i11 - w1 * w1;
  const double w3 = std::sqrt(s3);
  const double w4 = (i12 - w1 * w2) / w3;
  const double s5 = i22 - w2 * w2 - w4 * w4;
  const double w5 = std::sqrt(s5);
  W[0] = w0;
  W[1] = w1;
  W[2] = w2;
  W[3] = w3;
  W[4] = w4;
  W[5] = w5;
  const double sum = w0 + w1 + w2 + w3 + w4 + w5;
  // Leading minors of C positive <=> C positive definite; then the factor must be finite
  // (sum - sum is 0 exactly when the sum is finite).
  return (c00 > 0.0) & (a22 > 0.0) & (det > 0.0) & (s3 > 0.0) & (s5 > 0.0) & (sum - sum == 0.0);
}

/// T_ij as scalars: an Eigen temporary per point costs a store-forwarding stall in these loops.
struct Pose {
  explicit Pose(const Eigen::Isometry3d& T) {
    const Eigen::Matrix3d R = T.linear();            // (a block of the 4 x 4 matrix: copy it first)
    for (int i = 0; i < 9; ++i) r[i] = R.data()[i];  // column-major
    for (int i = 0; i < 3; ++i) t[i] = T.translation()[i];
  }
  /// T mu.
  [[gnu::always_inline]] std::array<double, 3> apply(const std::array<double, 3>& mu) const {
    return {(r[0] * mu[0] + r[3] * mu[1] + r[6] * mu[2]) + t[0],
            (r[1] * mu[0] + r[4] * mu[1] + r[7] * mu[2]) + t[1],
            (r[2] * mu[0] + r[5] * mu[1] + r[8] * mu[2]) + t[2]};
  }
  /// mu_target - T mu_source.
  [[gnu::always_inline]] std::array<double, 3> difference(
      const std::array<double, 3>& target, const std::array<double, 3>& source) const {
    const std::array<double, 3> q = apply(source);
    return {target[0] - q[0], target[1] - q[1], target[2] - q[2]};
  }
  double r[9];
  double t[3];
};

[[gnu::always_inline]] inline double dot3(const std::array<double, 3>& a,
                                          const std::array<double, 3>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/// Row c of the upper-triangular W = [w0 w1 w2; 0 w3 w4; 0 0 w5], zeros included.
[[gnu::always_inline]] inline std::array<double, 3> whitening_row(const std::array<double, 6>& w,
                                                                  int c) {
  if (c == 0) return {w[0], w[1], w[2]};
  if (c == 1) return {0.0, w[3], w[4]};
  return {0.0, 0.0, w[5]};
}

/// Jacobian of r = l . (mu_target - T Exp(xi) mu) w.r.t. xi = [omega, v]: [a x mu, -a] with
/// a = R^T l.
/// (Forced inline and written with every load before the first store: as a call, and with J
/// possibly aliasing R or mu, it was a quarter of a compression.)
[[gnu::always_inline]] inline void jacobian_row(const Pose& T, const std::array<double, 3>& ell,
                                                const std::array<double, 3>& mu, double* J) {
  const double* r = T.r;
  const double m0 = mu[0], m1 = mu[1], m2 = mu[2];
  const double a0 = ell[0] * r[0] + ell[1] * r[1] + ell[2] * r[2];
  const double a1 = ell[0] * r[3] + ell[1] * r[4] + ell[2] * r[5];
  const double a2 = ell[0] * r[6] + ell[1] * r[7] + ell[2] * r[8];
  const double j0 = a1 * m2 - a2 * m1, j1 = a2 * m0 - a0 * m2, j2 = a0 * m1 - a1 * m0;
  J[0] = j0;
  J[1] = j1;
  J[2] = j2;
  J[3] = -a0;
  J[4] = -a1;
  J[5] = -a2;
}

/// The fused covariance C_target + R C_source R^T, both given by their upper triangles
/// (xx xy xz yy yz zz); R row-major.
[[gnu::always_inline]] inline void fuse(const double* target, const double* source, const double* R,
                                        double* fused) {
  const double s00 = source[0], s01 = source[1], s02 = source[2], s11 = source[3], s12 = source[4],
               s22 = source[5];
  double M[3][3];  // R C_source
  for (int i = 0; i < 3; ++i) {
    M[i][0] = R[3 * i] * s00 + R[3 * i + 1] * s01 + R[3 * i + 2] * s02;
    M[i][1] = R[3 * i] * s01 + R[3 * i + 1] * s11 + R[3 * i + 2] * s12;
    M[i][2] = R[3 * i] * s02 + R[3 * i + 1] * s12 + R[3 * i + 2] * s22;
  }
  const auto rotated = [&](int i, int j) {
    return M[i][0] * R[3 * j] + M[i][1] * R[3 * j + 1] + M[i][2] * R[3 * j + 2];
  };
  fused[0] = target[0] + rotated(0, 0);
  fused[1] = target[1] + rotated(0, 1);
  fused[2] = target[2] + rotated(0, 2);
  fused[3] = target[3] + rotated(1, 1);
  fused[4] = target[4] + rotated(1, 2);
  fused[5] = target[5] + rotated(2, 2);
}

/// The whitening W of the fused covariance C_target + R C_source R^T (upper triangles, R
/// row-major); false unless it is positive definite.
bool fused_whitening(const std::array<double, 6>& target, const std::array<double, 6>& source,
                     const double* R, std::array<double, 6>* W) {
  double fused[6];
  fuse(target.data(), source.data(), R, fused);
  return whitening_of(fused, W->data());
}

/// Covariance pairs whitened at once.
constexpr std::size_t kBatch = 8;

/// fused_whitening() of kBatch pairs given lane by lane (target[e * kBatch + lane]: entry e of
/// pair lane's target covariance; W alike), written for the compiler to vectorize over the
/// lanes: the same operations in the same order, so each lane has the bits fused_whitening()
/// gives it (this file is compiled without fused multiply-adds). ok[lane] is 1 where it
/// succeeded.
CARAT_MULTIVERSION_WIDE void fused_whitenings(const double* __restrict target,
                                              const double* __restrict source,
                                              const double* __restrict R, double* __restrict W,
                                              int* __restrict ok) {
  for (std::size_t lane = 0; lane < kBatch; ++lane) {
    double t[6], c[6], fused[6], w[6];
    for (std::size_t e = 0; e < 6; ++e) {
      t[e] = target[e * kBatch + lane];
      c[e] = source[e * kBatch + lane];
    }
    fuse(t, c, R, fused);
    ok[lane] = whitening_of(fused, w);
    for (std::size_t e = 0; e < 6; ++e) W[e * kBatch + lane] = w[e];
  }
}

/// The residuals and Jacobian rows of kBatch whole correspondences, given lane by lane
/// (target[e * kBatch + lane]: coordinate e of correspondence lane's target mean; source alike;
/// whitening[e * kBatch + lane]: entry e of its W), rows written in order (three a
/// correspondence), through the scalar helpers evaluate_rows() uses, written for the compiler to
/// vectorize over the lanes: each row has the bits evaluate_rows() gives it one at a time.
CARAT_MULTIVERSION_WIDE void whole_rows(const Pose& T, const double* __restrict target,
                                        const double* __restrict source,
                                        const double* __restrict whitening,
                                        double* __restrict residuals, double* __restrict jacobian) {
  for (std::size_t lane = 0; lane < kBatch; ++lane) {
    const std::array<double, 3> mu = {source[lane], source[kBatch + lane],
                                      source[2 * kBatch + lane]};
    const std::array<double, 3> d =
        T.difference({target[lane], target[kBatch + lane], target[2 * kBatch + lane]}, mu);
    std::array<double, 6> w;
    for (std::size_t e = 0; e < 6; ++e) w[e] = whitening[e * kBatch + lane];
    for (int c = 0; c < 3; ++c) {
      const std::size_t row = 3 * lane + static_cast<std::size_t>(c);
      const std::array<double, 3> ell = whitening_row(w, c);
      residuals[row] = dot3(ell, d);
      jacobian_row(T, ell, mu, jacobian + 6 * row);
    }
  }
}

/// The rotation of T, row-major.
std::array<double, 9> row_major(const Eigen::Isometry3d& T) {
  std::array<double, 9> R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) R[static_cast<std::size_t>(3 * i + j)] = T.linear()(i, j);
  return R;
}

/// The upper triangle of sym(A) = (A + A^T) / 2.
std::array<double, 6> symmetric_part(const Eigen::Matrix3d& A) {
  return {A(0, 0), 0.5 * (A(0, 1) + A(1, 0)), 0.5 * (A(0, 2) + A(2, 0)),
          A(1, 1), 0.5 * (A(1, 2) + A(2, 1)), A(2, 2)};
}

}  // namespace

GicpBlock::GicpBlock(std::span<const GicpCorrespondence> correspondences,
                     const Eigen::Isometry3d& T_target_source) {
  if (correspondences.empty()) throw Error("GicpBlock: no correspondences");
  const std::array<double, 9> R = row_major(T_target_source);
  points_.reserve(correspondences.size());
  for (std::size_t k = 0; k < correspondences.size(); ++k) {
    const auto& c = correspondences[k];
    // One sum catches any NaN or infinity (and, rarely, finite values whose sum overflows: the
    // exact test below then decides).
    const double sum = c.mean_target.sum() + c.mean_source.sum() + c.covariance_target.sum() +
                       c.covariance_source.sum();
    if (!std::isfinite(sum) &&
        (!c.mean_target.allFinite() || !c.mean_source.allFinite() ||
         !c.covariance_target.allFinite() || !c.covariance_source.allFinite())) {
      throw Error("GicpBlock: correspondence " + std::to_string(k) + " has a non-finite value");
    }
    std::array<double, 6> W;
    if (!fused_whitening(symmetric_part(c.covariance_target), symmetric_part(c.covariance_source),
                         R.data(), &W)) {
      throw Error("GicpBlock: correspondence " + std::to_string(k) +
                  ": fused covariance is not positive definite");
    }
    Point p;
    p.target = {c.mean_target.x(), c.mean_target.y(), c.mean_target.z()};
    p.source = {c.mean_source.x(), c.mean_source.y(), c.mean_source.z()};
    p.whitening = W;
    points_.push_back(p);
  }
}

GicpBlock::GicpBlock(std::span<const Eigen::Vector3f> target_means,
                     std::span<const Eigen::Matrix<float, 6, 1>> target_covariances,
                     std::span<const Eigen::Vector3f> source_means,
                     std::span<const Eigen::Matrix<float, 6, 1>> source_covariances,
                     std::span<const std::array<std::uint32_t, 2>> pairs,
                     const Eigen::Isometry3d& T_target_source) {
  if (pairs.empty()) throw Error("GicpBlock: no correspondences");
  if (target_covariances.size() != target_means.size() ||
      source_covariances.size() != source_means.size()) {
    throw Error("GicpBlock: " + std::to_string(target_means.size()) + " target means but " +
                std::to_string(target_covariances.size()) + " covariances, " +
                std::to_string(source_means.size()) + " source means but " +
                std::to_string(source_covariances.size()) + " covariances");
  }
  const std::array<double, 9> R = row_major(T_target_source);
  enum Fault : int { kNone, kIndex, kNonFinite, kNotPositiveDefinite };
  // Why pair k cannot be built, short of the whitening (kNone when it can be tried).
  const auto check = [&](std::size_t k) {
    const auto [t, s] = pairs[k];
    if (t >= target_means.size() || s >= source_means.size()) return kIndex;
    const Eigen::Vector3f& mt = target_means[t];
    const Eigen::Vector3f& ms = source_means[s];
    const Eigen::Matrix<float, 6, 1>& ct = target_covariances[t];
    const Eigen::Matrix<float, 6, 1>& cs = source_covariances[s];
    if (!std::isfinite(mt.sum() + ms.sum() + ct.sum() + cs.sum()) &&
        (!mt.allFinite() || !ms.allFinite() || !ct.allFinite() || !cs.allFinite())) {
      return kNonFinite;
    }
    return kNone;
  };
  points_.resize(pairs.size());
  std::atomic<std::size_t> first_fault{pairs.size()};
  const auto fault_at = [&](std::size_t k) {
    std::size_t seen = first_fault.load(std::memory_order_relaxed);
    while (k < seen && !first_fault.compare_exchange_weak(seen, k, std::memory_order_relaxed)) {
    }
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, pairs.size(), 1024), [&](const auto& range) {
    // Whitenings kBatch pairs at a time; a pair that fails its checks is whitened as the
    // identity and reported.
    double target[6 * kBatch], source[6 * kBatch], W[6 * kBatch];
    int ok[kBatch];
    bool usable[kBatch];
    for (std::size_t k0 = range.begin(); k0 < range.end(); k0 += kBatch) {
      const std::size_t n = std::min<std::size_t>(kBatch, range.end() - k0);
      for (std::size_t lane = 0; lane < kBatch; ++lane) {
        const std::size_t k = k0 + lane;
        usable[lane] = lane < n && check(k) == kNone;
        if (!usable[lane]) {
          for (std::size_t e = 0; e < 6; ++e)
            target[e * kBatch + lane] = source[e * kBatch + lane] = e == 0 || e == 3 || e == 5;
          continue;
        }
        const Eigen::Matrix<float, 6, 1>& ct = target_covariances[pairs[k][0]];
        const Eigen::Matrix<float, 6, 1>& cs = source_covariances[pairs[k][1]];
        for (std::size_t e = 0; e < 6; ++e) {
          target[e * kBatch + lane] = ct[static_cast<Eigen::Index>(e)];
          source[e * kBatch + lane] = cs[static_cast<Eigen::Index>(e)];
        }
      }
      fused_whitenings(target, source, R.data(), W, ok);
      for (std::size_t lane = 0; lane < n; ++lane) {
        const std::size_t k = k0 + lane;
        if (!ok[lane] || !usable[lane]) {
          fault_at(k);
          return;
        }
        const Eigen::Vector3f& mt = target_means[pairs[k][0]];
        const Eigen::Vector3f& ms = source_means[pairs[k][1]];
        Point& p = points_[k];
        p.target = {mt.x(), mt.y(), mt.z()};
        p.source = {ms.x(), ms.y(), ms.z()};
        for (std::size_t e = 0; e < 6; ++e) p.whitening[e] = W[e * kBatch + lane];
      }
    }
  });
  // The first faulty pair, whatever the scheduling was.
  const std::size_t k = first_fault.load();
  if (k == pairs.size()) return;
  switch (check(k)) {
    case kIndex:
      throw Error("GicpBlock: pair " + std::to_string(k) + " names target point " +
                  std::to_string(pairs[k][0]) + " of " + std::to_string(target_means.size()) +
                  " and source point " + std::to_string(pairs[k][1]) + " of " +
                  std::to_string(source_means.size()));
    case kNonFinite:
      throw Error("GicpBlock: correspondence " + std::to_string(k) + " has a non-finite value");
    default:
      throw Error("GicpBlock: correspondence " + std::to_string(k) +
                  ": fused covariance is not positive definite");
  }
}

void GicpBlock::reduced_map(ParameterPointers params, double* A) const {
  relative_pose_reduced_map(params, A);
}

void GicpBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                              double* residuals, double* jacobian) const {
  const Pose T(relative_pose(params));
  if (!rows_.empty()) {  // an extract: r = offset - l . (T mu)
    for (std::size_t k = 0; k < rows.size(); ++k) {
      const Row& row = rows_[static_cast<std::size_t>(rows[k])];
      const std::array<double, 3> q = T.apply(row.source);
      residuals[k] = row.offset - dot3(row.ell, q);
      if (jacobian) jacobian_row(T, row.ell, row.source, jacobian + 6 * k);
    }
    return;
  }
  // Rows come in groups of up to three per correspondence: the difference mu_target - T mu is
  // computed once per correspondence and reused by its rows. Every path below goes through the
  // same scalar helpers (whole_rows() runs them lane by lane), so a row has the same bits
  // whichever way it was asked for.
  std::size_t k = 0;
  if (jacobian) {
    // Leading batches of whole correspondences in order (every row of the block, as compress()
    // asks for), kBatch at a time.
    double target[3 * kBatch], source[3 * kBatch], whitening[6 * kBatch];
    const auto in_order = [&](std::size_t at) {
      const int first = rows[at];
      if (first % 3 != 0) return false;
      for (std::size_t j = 1; j < 3 * kBatch; ++j)
        if (rows[at + j] != first + static_cast<int>(j)) return false;
      return true;
    };
    while (k + 3 * kBatch <= rows.size() && in_order(k)) {
      const auto first = static_cast<std::size_t>(rows[k] / 3);
      for (std::size_t lane = 0; lane < kBatch; ++lane) {
        const Point& p = points_[first + lane];
        for (std::size_t e = 0; e < 3; ++e) {
          target[e * kBatch + lane] = p.target[e];
          source[e * kBatch + lane] = p.source[e];
        }
        for (std::size_t e = 0; e < 6; ++e) whitening[e * kBatch + lane] = p.whitening[e];
      }
      whole_rows(T, target, source, whitening, residuals + k, jacobian + 6 * k);
      k += 3 * kBatch;
    }
  }
  std::size_t cached = static_cast<std::size_t>(-1);
  std::array<double, 3> d{};
  for (; k < rows.size(); ++k) {
    const int row = rows[k];
    const auto index = static_cast<std::size_t>(row / 3);
    const Point& p = points_[index];
    if (row % 3 == 0 && k + 2 < rows.size() && rows[k + 1] == row + 1 && rows[k + 2] == row + 2) {
      // A whole correspondence in order (every row of the block, as compress() asks for).
      d = T.difference(p.target, p.source);
      for (int c = 0; c < 3; ++c) {
        const std::array<double, 3> ell = whitening_row(p.whitening, c);
        residuals[k + static_cast<std::size_t>(c)] = dot3(ell, d);
        if (jacobian) {
          jacobian_row(T, ell, p.source, jacobian + 6 * (k + static_cast<std::size_t>(c)));
        }
      }
      cached = index;
      k += 2;
      continue;
    }
    if (index != cached) {
      cached = index;
      d = T.difference(p.target, p.source);
    }
    const std::array<double, 3> ell = whitening_row(p.whitening, row % 3);
    residuals[k] = dot3(ell, d);
    if (jacobian) jacobian_row(T, ell, p.source, jacobian + 6 * k);
  }
}

double GicpBlock::accumulate_at(const Eigen::Isometry3d& T_target_source,
                                Eigen::Matrix<double, 6, 6>* H_out,
                                Eigen::Matrix<double, 6, 1>* b_out) const {
  const Pose T(T_target_source);
  const double* R = T.r;  // column-major: R(i, j) = R[i + 3 j]
  const std::size_t n = points_.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  // Per chunk: the upper triangle of H (21, row by row), b (6) and c.
  using Partial = std::array<double, 28>;
  std::vector<Partial> partial(chunks);
  const auto work = [&](std::size_t chunk) {
    Partial sum{};
    const std::size_t end = std::min(n, (chunk + 1) * kChunk);
    for (std::size_t k = chunk * kChunk; k < end; ++k) {
      const Point& p = points_[k];
      const double w0 = p.whitening[0], w1 = p.whitening[1], w2 = p.whitening[2];
      const double w3 = p.whitening[3], w4 = p.whitening[4], w5 = p.whitening[5];
      const double m0 = p.source[0], m1 = p.source[1], m2 = p.source[2];
      const std::array<double, 3> d = T.difference(p.target, p.source);
      // r = W d; the Jacobian is J = M G with M = W R and G = [[mu]x, -I].
      const double r0 = w0 * d[0] + w1 * d[1] + w2 * d[2], r1 = w3 * d[1] + w4 * d[2],
                   r2 = w5 * d[2];
      double M[3][3];
      for (int j = 0; j < 3; ++j) {
        const double R0 = R[3 * j], R1 = R[1 + 3 * j], R2 = R[2 + 3 * j];
        M[0][j] = w0 * R0 + w1 * R1 + w2 * R2;
        M[1][j] = w3 * R1 + w4 * R2;
        M[2][j] = w5 * R2;
      }
      // A = M^T M and v = M^T r.
      double A[3][3], v[3];
      for (int i = 0; i < 3; ++i) {
        for (int j = i; j < 3; ++j)
          A[i][j] = M[0][i] * M[0][j] + M[1][i] * M[1][j] + M[2][i] * M[2][j];
        v[i] = M[0][i] * r0 + M[1][i] * r1 + M[2][i] * r2;
      }
      A[1][0] = A[0][1];
      A[2][0] = A[0][2];
      A[2][1] = A[1][2];
      // H = G^T A G = [-S A S, S A; -A S, A] with S = [mu]x; b = G^T v = [v x mu; -v].
      double C[3][3];  // S A
      for (int j = 0; j < 3; ++j) {
        C[0][j] = m1 * A[2][j] - m2 * A[1][j];
        C[1][j] = m2 * A[0][j] - m0 * A[2][j];
        C[2][j] = m0 * A[1][j] - m1 * A[0][j];
      }
      double E[3][3];  // -S A S = -C S, upper triangle
      for (int i = 0; i < 3; ++i) {
        E[i][0] = C[i][2] * m1 - C[i][1] * m2;
        E[i][1] = C[i][0] * m2 - C[i][2] * m0;
        E[i][2] = C[i][1] * m0 - C[i][0] * m1;
      }
      int at = 0;
      for (int i = 0; i < 3; ++i) {
        for (int j = i; j < 3; ++j) sum[at++] += E[i][j];
        for (int j = 0; j < 3; ++j) sum[at++] += C[i][j];
      }
      for (int i = 0; i < 3; ++i)
        for (int j = i; j < 3; ++j) sum[at++] += A[i][j];
      sum[21] += v[1] * m2 - v[2] * m1;
      sum[22] += v[2] * m0 - v[0] * m2;
      sum[23] += v[0] * m1 - v[1] * m0;
      sum[24] -= v[0];
      sum[25] -= v[1];
      sum[26] -= v[2];
      sum[27] += r0 * r0 + r1 * r1 + r2 * r2;
    }
    partial[chunk] = sum;
  };
  if (chunks > 1) {
    tbb::parallel_for(std::size_t{0}, chunks, work);
  } else {
    work(0);
  }
  // Sum the chunks in a fixed order: the same result with any number of threads.
  Partial total{};
  for (const Partial& p : partial)
    for (std::size_t i = 0; i < total.size(); ++i) total[i] += p[i];
  int at = 0;
  for (int i = 0; i < 6; ++i) {
    for (int j = i; j < 6; ++j) {
      (*H_out)(i, j) = total[static_cast<std::size_t>(at++)];
      (*H_out)(j, i) = (*H_out)(i, j);
    }
  }
  for (int i = 0; i < 6; ++i) (*b_out)[i] = total[21 + static_cast<std::size_t>(i)];
  return total[27];
}

double GicpBlock::accumulate(ParameterPointers params, Eigen::Ref<Eigen::MatrixXd> H_r,
                             Eigen::Ref<Eigen::VectorXd> b_r) const {
  if (!rows_.empty()) return ResidualBlock::accumulate(params, H_r, b_r);  // an extract: few rows
  Eigen::Matrix<double, 6, 6> H;
  Eigen::Matrix<double, 6, 1> b;
  const double c = accumulate_at(relative_pose(params), &H, &b);
  H_r += H;
  b_r += b;
  return c;
}

double GicpBlock::squared_norm(ParameterPointers params) const {
  if (!rows_.empty()) return ResidualBlock::squared_norm(params);
  const Pose T(relative_pose(params));
  const std::size_t n = points_.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<double> partial(chunks, 0.0);
  const auto work = [&](std::size_t chunk) {
    double c = 0.0;
    const std::size_t end = std::min(n, (chunk + 1) * kChunk);
    for (std::size_t k = chunk * kChunk; k < end; ++k) {
      const Point& p = points_[k];
      const std::array<double, 3> d = T.difference(p.target, p.source);
      const double r0 = p.whitening[0] * d[0] + p.whitening[1] * d[1] + p.whitening[2] * d[2];
      const double r1 = p.whitening[3] * d[1] + p.whitening[4] * d[2];
      const double r2 = p.whitening[5] * d[2];
      c += r0 * r0 + r1 * r1 + r2 * r2;
    }
    partial[chunk] = c;
  };
  if (chunks > 1) {
    tbb::parallel_for(std::size_t{0}, chunks, work);
  } else {
    work(0);
  }
  // In a fixed order, as accumulate_at() sums: the same cost with any number of threads.
  double c = 0.0;
  for (const double p : partial) c += p;
  return c;
}

namespace {

/// True if `rows` are whole correspondences in order (rows 3k, 3k + 1, 3k + 2 together).
bool whole_correspondences(std::span<const int> rows) {
  if (rows.size() % 3 != 0) return false;
  for (std::size_t k = 0; k < rows.size(); k += 3) {
    if (rows[k] % 3 != 0 || rows[k + 1] != rows[k] + 1 || rows[k + 2] != rows[k] + 2) return false;
  }
  return true;
}

}  // namespace

GicpBlock::Row GicpBlock::row_of(int row) const {
  if (!rows_.empty()) return rows_[static_cast<std::size_t>(row)];
  const Point& p = points_[static_cast<std::size_t>(row / 3)];
  Row r;
  r.ell = whitening_row(p.whitening, row % 3);
  r.offset = dot3(r.ell, p.target);
  r.source = p.source;
  return r;
}

std::unique_ptr<ResidualBlock> GicpBlock::extract_rows(std::span<const int> rows) const {
  auto out = std::unique_ptr<GicpBlock>(new GicpBlock());
  // Whole correspondences in row order (random sampling of points) stay correspondences: 96
  // bytes for three rows beat 3 x 56.
  if (rows_.empty() && whole_correspondences(rows)) {
    out->points_.reserve(rows.size() / 3);
    for (std::size_t k = 0; k < rows.size(); k += 3) {
      out->points_.push_back(points_[static_cast<std::size_t>(rows[k] / 3)]);
    }
    return out;
  }
  out->rows_.reserve(rows.size());
  for (int row : rows) out->rows_.push_back(row_of(row));
  return out;
}

std::unique_ptr<ResidualBlock> GicpBlock::extract_weighted_rows(
    std::span<const int> rows, std::span<const double> weights) const {
  check_row_weights("GicpBlock", rows, weights);
  if (rows_.empty() && whole_correspondences(rows)) return nullptr;
  auto out = std::unique_ptr<GicpBlock>(new GicpBlock());
  out->rows_.reserve(rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const double s = std::sqrt(weights[k]);
    Row r = row_of(rows[k]);
    for (double& v : r.ell) v *= s;
    r.offset *= s;
    out->rows_.push_back(r);
  }
  return out;
}

std::shared_ptr<const ResidualBlock> GicpBlock::exact_form(ParameterPointers params) const {
  return lossless_form(*this, params);
}

PoseGram GicpBlock::pose_gram(const Eigen::Isometry3d& T_target_source_reference) const {
  return pose_gram_of(points_, rows_, T_target_source_reference);
}

// Vector code for the lanes of PoseGramSum (a virtual function cannot be multiversioned).
CARAT_MULTIVERSION PoseGram
GicpBlock::pose_gram_of(std::span<const Point> points, std::span<const Row> rows,
                        const Eigen::Isometry3d& T_target_source_reference) {
  const auto as_vector = [](const std::array<double, 3>& a) {
    return Eigen::Vector3d(a[0], a[1], a[2]);
  };
  const Eigen::Vector3d centre =
      rows.empty() ? internal::mean_point(
                         points.size(), [&](std::size_t k) { return as_vector(points[k].source); })
                   : internal::mean_point(rows.size(),
                                          [&](std::size_t k) { return as_vector(rows[k].source); });
  internal::PoseGramSum sum(T_target_source_reference, centre);
  for (const Row& row : rows) {  // an extract: one row each, Omega = l l^T
    const std::array<double, 3> q = sum.apply_reference(row.source);
    const std::array<double, 3>& l = row.ell;
    const double r0 = row.offset - dot3(l, q);
    sum.add({l[0] * l[0], l[0] * l[1], l[0] * l[2], l[1] * l[1], l[1] * l[2], l[2] * l[2]},
            row.source, {l[0] * r0, l[1] * r0, l[2] * r0}, r0 * r0, 1);
  }
  for (const Point& p : points) {  // three rows each, Omega = W^T W
    const std::array<double, 3> q = sum.apply_reference(p.source);
    const double d0 = p.target[0] - q[0], d1 = p.target[1] - q[1], d2 = p.target[2] - q[2];
    const auto& w = p.whitening;  // W = [w0 w1 w2; 0 w3 w4; 0 0 w5]
    const double r0 = w[0] * d0 + w[1] * d1 + w[2] * d2, r1 = w[3] * d1 + w[4] * d2, r2 = w[5] * d2;
    sum.add({w[0] * w[0], w[0] * w[1], w[0] * w[2], w[1] * w[1] + w[3] * w[3],
             w[1] * w[2] + w[3] * w[4], w[2] * w[2] + w[4] * w[4] + w[5] * w[5]},
            p.source, {w[0] * r0, w[1] * r0 + w[3] * r1, w[2] * r0 + w[4] * r1 + w[5] * r2},
            r0 * r0 + r1 * r1 + r2 * r2, 3);
  }
  return sum.finish();
}

std::size_t GicpBlock::memory_bytes() const {
  return points_.size() * sizeof(Point) + rows_.size() * sizeof(Row);
}

}  // namespace carat
