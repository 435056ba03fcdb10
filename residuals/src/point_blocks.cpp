#include <array>
#include <cmath>
#include <string>

#include "carat/base/error.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/residuals/point_to_plane_block.hpp"
#include "carat/residuals/point_to_point_block.hpp"
#include "carat/residuals/registration_rows.hpp"
#include "pose_gram_sum.hpp"

namespace carat {
namespace {

/// Row value and reduced Jacobian of w . (target - T source): J = [(R^T w) x source, -R^T w].
double weighted_row(const Eigen::Isometry3d& T, const Eigen::Vector3d& w,
                    const Eigen::Vector3d& target, const Eigen::Vector3d& source,
                    double* jacobian) {
  if (jacobian) {
    const Eigen::Vector3d wr = T.linear().transpose() * w;
    const Eigen::Vector3d d_omega = wr.cross(source);
    for (int i = 0; i < 3; ++i) {
      jacobian[i] = d_omega[i];
      jacobian[3 + i] = -wr[i];
    }
  }
  return w.dot(target - T * source);
}

std::array<double, 3> to_array(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

/// Adds one row n . (target - T_ref source) to a Gram sum (Omega = n n^T).
void add_row(internal::PoseGramSum& sum, const Eigen::Vector3d& n, const Eigen::Vector3d& target,
             const Eigen::Vector3d& source) {
  const std::array<double, 3> mu = to_array(source);
  const std::array<double, 3> q = sum.apply_reference(mu);
  const double r0 =
      n.x() * (target.x() - q[0]) + n.y() * (target.y() - q[1]) + n.z() * (target.z() - q[2]);
  sum.add(
      {n.x() * n.x(), n.x() * n.y(), n.x() * n.z(), n.y() * n.y(), n.y() * n.z(), n.z() * n.z()},
      mu, {n.x() * r0, n.y() * r0, n.z() * r0}, r0 * r0, 1);
}

void check_pairs(std::size_t a, std::size_t b, const char* who) {
  if (a == 0) throw Error(std::string(who) + ": no correspondences");
  if (a != b)
    throw Error(std::string(who) + ": " + std::to_string(a) + " target points but " +
                std::to_string(b) + " source points");
}

}  // namespace

PointToPointBlock::PointToPointBlock(std::span<const Eigen::Vector3d> points_target,
                                     std::span<const Eigen::Vector3d> points_source)
    : target_(points_target.begin(), points_target.end()),
      source_(points_source.begin(), points_source.end()) {
  check_pairs(target_.size(), source_.size(), "PointToPointBlock");
  for (std::size_t k = 0; k < target_.size(); ++k) {
    if (!target_[k].allFinite() || !source_[k].allFinite()) {
      throw Error("PointToPointBlock: correspondence " + std::to_string(k) +
                  " has a non-finite value");
    }
  }
}

void PointToPointBlock::reduced_map(ParameterPointers params, double* A) const {
  relative_pose_reduced_map(params, A);
}

void PointToPointBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                      double* residuals, double* jacobian) const {
  const Eigen::Isometry3d T = relative_pose(params);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const int row = rows[k];
    const auto pair = static_cast<std::size_t>(
        rows_.empty() ? row / 3 : rows_[static_cast<std::size_t>(row)] >> 2);
    const int c = rows_.empty() ? row % 3 : (rows_[static_cast<std::size_t>(row)] & 3);
    residuals[k] = weighted_row(T, Eigen::Vector3d::Unit(c), target_[pair], source_[pair],
                                jacobian ? jacobian + 6 * k : nullptr);
  }
}

std::unique_ptr<ResidualBlock> PointToPointBlock::extract_rows(std::span<const int> rows) const {
  auto out = std::unique_ptr<PointToPointBlock>(new PointToPointBlock());
  for (int row : rows) {
    const auto pair = static_cast<std::size_t>(
        rows_.empty() ? row / 3 : rows_[static_cast<std::size_t>(row)] >> 2);
    const int c = rows_.empty() ? row % 3 : (rows_[static_cast<std::size_t>(row)] & 3);
    out->rows_.push_back(static_cast<int>(out->target_.size() << 2) | c);
    out->target_.push_back(target_[pair]);
    out->source_.push_back(source_[pair]);
  }
  return out;
}

std::shared_ptr<const ResidualBlock> PointToPointBlock::exact_form(ParameterPointers params) const {
  return lossless_form(*this, params);
}

PoseGram PointToPointBlock::pose_gram(const Eigen::Isometry3d& T_target_source_reference) const {
  internal::PoseGramSum sum(
      T_target_source_reference,
      internal::mean_point(source_.size(), [&](std::size_t k) { return source_[k]; }));
  if (!rows_.empty()) {  // an extract: component (row & 3) of pair (row >> 2)
    for (int row : rows_) {
      const auto pair = static_cast<std::size_t>(row >> 2);
      add_row(sum, Eigen::Vector3d::Unit(row & 3), target_[pair], source_[pair]);
    }
    return sum.finish();
  }
  for (std::size_t k = 0; k < target_.size(); ++k) {  // three rows, Omega = I
    const std::array<double, 3> mu = to_array(source_[k]);
    const std::array<double, 3> q = sum.apply_reference(mu);
    const std::array<double, 3> d = {target_[k].x() - q[0], target_[k].y() - q[1],
                                     target_[k].z() - q[2]};
    sum.add({1.0, 0.0, 0.0, 1.0, 0.0, 1.0}, mu, d, d[0] * d[0] + d[1] * d[1] + d[2] * d[2], 3);
  }
  return sum.finish();
}

std::size_t PointToPointBlock::memory_bytes() const {
  return (target_.size() + source_.size()) * sizeof(Eigen::Vector3d) + rows_.size() * sizeof(int);
}

PointToPlaneBlock::PointToPlaneBlock(std::span<const Eigen::Vector3d> points_target,
                                     std::span<const Eigen::Vector3d> normals_target,
                                     std::span<const Eigen::Vector3d> points_source)
    : target_(points_target.begin(), points_target.end()),
      normal_(normals_target.begin(), normals_target.end()),
      source_(points_source.begin(), points_source.end()) {
  check_pairs(target_.size(), source_.size(), "PointToPlaneBlock");
  if (normal_.size() != target_.size()) {
    throw Error("PointToPlaneBlock: " + std::to_string(target_.size()) + " target points but " +
                std::to_string(normal_.size()) + " normals");
  }
  for (std::size_t k = 0; k < target_.size(); ++k) {
    if (!target_[k].allFinite() || !source_[k].allFinite() || !normal_[k].allFinite()) {
      throw Error("PointToPlaneBlock: correspondence " + std::to_string(k) +
                  " has a non-finite value");
    }
    const double n = normal_[k].norm();
    if (!(n > 1e-12))
      throw Error("PointToPlaneBlock: normal " + std::to_string(k) + " has zero length");
    normal_[k] /= n;
  }
}

void PointToPlaneBlock::reduced_map(ParameterPointers params, double* A) const {
  relative_pose_reduced_map(params, A);
}

void PointToPlaneBlock::evaluate_rows(ParameterPointers params, std::span<const int> rows,
                                      double* residuals, double* jacobian) const {
  const Eigen::Isometry3d T = relative_pose(params);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto pair = static_cast<std::size_t>(rows[k]);
    residuals[k] = weighted_row(T, normal_[pair], target_[pair], source_[pair],
                                jacobian ? jacobian + 6 * k : nullptr);
  }
}

std::unique_ptr<ResidualBlock> PointToPlaneBlock::extract_rows(std::span<const int> rows) const {
  return extract_scaled(rows, {});
}

std::unique_ptr<ResidualBlock> PointToPlaneBlock::extract_weighted_rows(
    std::span<const int> rows, std::span<const double> weights) const {
  check_row_weights("PointToPlaneBlock", rows, weights);
  return extract_scaled(rows, weights);
}

std::unique_ptr<PointToPlaneBlock> PointToPlaneBlock::extract_scaled(
    std::span<const int> rows, std::span<const double> weights) const {
  auto out = std::unique_ptr<PointToPlaneBlock>(new PointToPlaneBlock());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const auto pair = static_cast<std::size_t>(rows[k]);
    out->target_.push_back(target_[pair]);
    out->normal_.push_back(
        weights.empty() ? normal_[pair] : Eigen::Vector3d(std::sqrt(weights[k]) * normal_[pair]));
    out->source_.push_back(source_[pair]);
  }
  return out;
}

std::shared_ptr<const ResidualBlock> PointToPlaneBlock::exact_form(ParameterPointers params) const {
  return lossless_form(*this, params);
}

PoseGram PointToPlaneBlock::pose_gram(const Eigen::Isometry3d& T_target_source_reference) const {
  internal::PoseGramSum sum(
      T_target_source_reference,
      internal::mean_point(source_.size(), [&](std::size_t k) { return source_[k]; }));
  for (std::size_t k = 0; k < target_.size(); ++k) add_row(sum, normal_[k], target_[k], source_[k]);
  return sum.finish();
}

std::size_t PointToPlaneBlock::memory_bytes() const {
  return 3 * target_.size() * sizeof(Eigen::Vector3d);
}

}  // namespace carat
