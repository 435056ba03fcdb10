#include "carat/residuals/pose_gram.hpp"

#include "pose_gram_sum.hpp"

namespace carat {
namespace {

/// Position of the symmetric pair (a, b) in an upper triangle stored as 00 01 02 11 12 22.
constexpr int kPair[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};

/// [e_k]x, the cross-product matrix of the k-th unit vector.
Eigen::Matrix3d unit_skew(int k) {
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  const int i = (k + 1) % 3, j = (k + 2) % 3;
  S(j, i) = 1.0;
  S(i, j) = -1.0;
  return S;
}

}  // namespace

PoseEmbedding PoseEmbedding::about(const Eigen::Isometry3d& T_target_source_reference,
                                   const Eigen::Vector3d& source_centre) {
  PoseEmbedding e;
  e.R_target_source_reference = T_target_source_reference.linear();
  e.t_target_source_reference = T_target_source_reference.translation();
  e.source_centre = source_centre;
  return e;
}

Eigen::Matrix<double, 13, 1> PoseEmbedding::value(const Eigen::Isometry3d& T_target_source) const {
  const Eigen::Matrix3d dR = T_target_source.linear() - R_target_source_reference;
  Eigen::Matrix<double, 13, 1> y;
  y.head<9>() = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dR.data());
  y.segment<3>(9) =
      (T_target_source.translation() - t_target_source_reference) + dR * source_centre;
  y[12] = 1.0;
  return y;
}

Eigen::Matrix<double, 13, 6> PoseEmbedding::jacobian(
    const Eigen::Isometry3d& T_target_source) const {
  const Eigen::Matrix3d R = T_target_source.linear();
  Eigen::Matrix<double, 13, 6> D = Eigen::Matrix<double, 13, 6>::Zero();
  for (int k = 0; k < 3; ++k) {
    // T <- T Exp(xi): R <- R Exp(omega) moves R by R [omega]x, t by R v (first order).
    const Eigen::Matrix3d dR = R * unit_skew(k);
    D.col(k).head<9>() = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dR.data());
    D.col(k).segment<3>(9) = dR * source_centre;
    D.col(3 + k).segment<3>(9) = R.col(k);
  }
  return D;
}

namespace internal {

PoseGramSum::PoseGramSum(const Eigen::Isometry3d& T_target_source_reference,
                         const Eigen::Vector3d& source_centre)
    : embedding_(PoseEmbedding::about(T_target_source_reference, source_centre)) {
  const Eigen::Matrix3d R = T_target_source_reference.linear();
  for (int i = 0; i < 9; ++i) r_[i] = R.data()[i];  // column-major
  for (int i = 0; i < 3; ++i) {
    t_[i] = T_target_source_reference.translation()[i];
    c_[i] = source_centre[i];
  }
}

void PoseGramSum::flush() {
  for (int l = 0; l < kLanes; ++l) {
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) total_.pp_omega[i][j] += lanes_.pp_omega[i][j][l];
    }
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 9; ++j) total_.p_right[i][j] += lanes_.p_right[i][j][l];
    }
    for (int j = 0; j < 10; ++j) total_.right[j] += lanes_.right[j][l];
  }
  lanes_ = LaneSums{};
  groups_ = 0;
}

PoseGram PoseGramSum::finish() {
  if (lane_ > 0) {  // the last items, beside lanes of zero items
    for (int l = lane_; l < kLanes; ++l) {
      for (auto& row : left_) row[l] = 0.0;
      for (auto& row : right_) row[l] = 0.0;
    }
    add_lanes();
  }
  flush();
  const Sums& T = total_;
  PoseGram out;
  out.embedding = embedding_;
  out.rows = rows_;
  Eigen::Matrix<double, 13, 13>& G = out.gram;
  // g = [-(p (x) l); -l; r0]: the rotation block is sum Omega_aa' p_b p_b', rotation-translation
  // sum p_b Omega_ae, rotation-constant -sum p_b w_a, translation sum Omega, translation-constant
  // -sum w, constant-constant sum s.
  for (int b = 0; b < 3; ++b) {
    for (int a = 0; a < 3; ++a) {
      const int row = a + 3 * b;
      for (int b2 = 0; b2 < 3; ++b2) {
        for (int a2 = 0; a2 < 3; ++a2) G(row, a2 + 3 * b2) = T.pp_omega[kPair[b][b2]][kPair[a][a2]];
      }
      for (int e = 0; e < 3; ++e) G(row, 9 + e) = G(9 + e, row) = T.p_right[b][kPair[a][e]];
      G(row, 12) = G(12, row) = -T.p_right[b][6 + a];
    }
  }
  for (int e = 0; e < 3; ++e) {
    for (int e2 = 0; e2 < 3; ++e2) G(9 + e, 9 + e2) = T.right[kPair[e][e2]];
    G(9 + e, 12) = G(12, 9 + e) = -T.right[6 + e];
  }
  G(12, 12) = T.right[9];
  return out;
}

}  // namespace internal
}  // namespace carat
