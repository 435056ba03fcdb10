#include "carat/registration/trajectory_error.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <climits>
#include <cmath>
#include <numeric>
#include <string>
#include <tuple>

#include "carat/solver/error.hpp"

namespace carat {
namespace {

constexpr double kRadiansToDegrees = 180.0 / 3.14159265358979323846;

// Rotation angle of a (near-)rotation matrix in radians, accurate near 0 and near pi.
double rotation_angle(const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q = Eigen::Quaterniond(R).normalized();
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

}  // namespace

Eigen::Isometry3d align_umeyama(std::span<const Eigen::Vector3d> estimate,
                                std::span<const Eigen::Vector3d> reference) {
  const std::size_t n = estimate.size();
  if (n != reference.size()) {
    throw Error("align_umeyama: " + std::to_string(n) + " estimate points but " +
                std::to_string(reference.size()) + " reference points");
  }
  if (n < 3) {
    throw Error("align_umeyama: needs at least 3 point pairs, got " + std::to_string(n));
  }
  // Work on coordinates scaled into [-1, 1] so that sums and products cannot overflow.
  double scale = 1.0;
  for (std::size_t k = 0; k < n; ++k) {
    if (!estimate[k].allFinite()) {
      throw Error("align_umeyama: estimate point " + std::to_string(k) + " is not finite");
    }
    if (!reference[k].allFinite()) {
      throw Error("align_umeyama: reference point " + std::to_string(k) + " is not finite");
    }
    scale =
        std::max({scale, estimate[k].cwiseAbs().maxCoeff(), reference[k].cwiseAbs().maxCoeff()});
  }
  // Eigen's Umeyama (rigid, no scaling) on the scaled coordinates, then undo the scale.
  const double inverse_scale = 1.0 / scale;
  Eigen::Matrix3Xd source(3, static_cast<Eigen::Index>(n)), target(3, static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) {
    source.col(static_cast<Eigen::Index>(k)) = inverse_scale * estimate[k];
    target.col(static_cast<Eigen::Index>(k)) = inverse_scale * reference[k];
  }
  const Eigen::Matrix4d M = Eigen::umeyama(source, target, false);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = M.topLeftCorner<3, 3>();
  T.translation() = scale * M.topRightCorner<3, 1>();
  if (!T.matrix().allFinite()) throw Error("align_umeyama: numerical overflow");
  return T;
}

AteStatistics compute_ate(std::span<const Eigen::Isometry3d> estimate,
                          std::span<const Eigen::Isometry3d> reference, const AteOptions& options) {
  const std::size_t n = estimate.size();
  if (n != reference.size()) {
    throw Error("compute_ate: the estimate has " + std::to_string(n) +
                " poses but the reference has " + std::to_string(reference.size()));
  }
  if (n == 0) throw Error("compute_ate: no poses");
  if (n > static_cast<std::size_t>(INT_MAX)) throw Error("compute_ate: too many poses");
  for (std::size_t k = 0; k < n; ++k) {
    if (!estimate[k].matrix().allFinite()) {
      throw Error("compute_ate: estimate pose " + std::to_string(k) + " is not finite");
    }
    if (!reference[k].matrix().allFinite()) {
      throw Error("compute_ate: reference pose " + std::to_string(k) + " is not finite");
    }
  }
  AteStatistics stats;
  stats.num_poses = static_cast<int>(n);
  if (options.align) {
    if (n < 3) {
      throw Error("compute_ate: alignment needs at least 3 poses, got " + std::to_string(n));
    }
    std::vector<Eigen::Vector3d> estimate_points(n);
    std::vector<Eigen::Vector3d> reference_points(n);
    for (std::size_t k = 0; k < n; ++k) {
      estimate_points[k] = estimate[k].translation();
      reference_points[k] = reference[k].translation();
    }
    stats.T_reference_estimate = align_umeyama(estimate_points, reference_points);
  }
  const Eigen::Isometry3d& T = stats.T_reference_estimate;
  std::vector<double> errors(n);
  double sum = 0.0;
  double sum_squares = 0.0;
  double angle_sum = 0.0;
  double angle_sum_squares = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d aligned = T * estimate[k].translation();
    errors[k] = (aligned - reference[k].translation()).norm();
    if (!std::isfinite(errors[k])) {
      throw Error("compute_ate: the error of pose " + std::to_string(k) + " overflows");
    }
    sum += errors[k];
    sum_squares += errors[k] * errors[k];
    const double angle = kRadiansToDegrees * rotation_angle(reference[k].linear().transpose() *
                                                            T.linear() * estimate[k].linear());
    angle_sum += angle;
    angle_sum_squares += angle * angle;
    stats.rotation_max_deg = std::max(stats.rotation_max_deg, angle);
  }
  const double count = static_cast<double>(n);
  stats.mean = sum / count;
  stats.rmse = std::sqrt(sum_squares / count);
  double variance = 0.0;
  for (double e : errors) variance += (e - stats.mean) * (e - stats.mean);
  stats.std = std::sqrt(variance / count);
  stats.rotation_mean_deg = angle_sum / count;
  stats.rotation_rmse_deg = std::sqrt(angle_sum_squares / count);
  const auto [min, max] = std::minmax_element(errors.begin(), errors.end());
  stats.min = *min;
  stats.max = *max;
  const std::size_t middle = n / 2;
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(middle),
                   errors.end());
  stats.median = errors[middle];
  if (n % 2 == 0) {
    const double below =
        *std::max_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(middle));
    stats.median = 0.5 * (stats.median + below);
  }
  return stats;
}

std::vector<std::pair<int, int>> associate_by_stamp(std::span<const double> estimate_stamps,
                                                    std::span<const double> reference_stamps,
                                                    double max_difference) {
  if (!(std::isfinite(max_difference) && max_difference >= 0.0)) {
    throw Error("associate_by_stamp: max_difference must be finite and non-negative, got " +
                std::to_string(max_difference));
  }
  const auto check = [](std::span<const double> stamps, const char* which) {
    if (stamps.size() > static_cast<std::size_t>(INT_MAX)) {
      throw Error(std::string("associate_by_stamp: too many ") + which + " stamps");
    }
    for (std::size_t k = 0; k < stamps.size(); ++k) {
      if (!std::isfinite(stamps[k])) {
        throw Error(std::string("associate_by_stamp: ") + which + " stamp " + std::to_string(k) +
                    " is not finite");
      }
    }
  };
  check(estimate_stamps, "estimate");
  check(reference_stamps, "reference");
  std::vector<int> order(reference_stamps.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return reference_stamps[a] < reference_stamps[b]; });
  std::vector<double> sorted(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) sorted[k] = reference_stamps[order[k]];

  struct Candidate {
    double difference;
    int estimate;
    int reference;
  };
  std::vector<Candidate> candidates;
  for (std::size_t e = 0; e < estimate_stamps.size(); ++e) {
    const double stamp = estimate_stamps[e];
    auto j = static_cast<std::size_t>(
        std::lower_bound(sorted.begin(), sorted.end(), stamp - max_difference) - sorted.begin());
    // stamp - max_difference is rounded: step back over any neighbour that still qualifies.
    while (j > 0 && std::abs(stamp - sorted[j - 1]) <= max_difference) --j;
    for (; j < sorted.size() && !(sorted[j] - stamp > max_difference); ++j) {
      const double difference = std::abs(stamp - sorted[j]);
      if (difference <= max_difference) {
        candidates.push_back({difference, static_cast<int>(e), order[j]});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.difference, a.estimate, a.reference) <
           std::tie(b.difference, b.estimate, b.reference);
  });
  std::vector<char> estimate_used(estimate_stamps.size(), 0);
  std::vector<char> reference_used(reference_stamps.size(), 0);
  std::vector<std::pair<int, int>> pairs;
  for (const Candidate& c : candidates) {
    if (estimate_used[c.estimate] || reference_used[c.reference]) continue;
    estimate_used[c.estimate] = 1;
    reference_used[c.reference] = 1;
    pairs.emplace_back(c.estimate, c.reference);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace carat
