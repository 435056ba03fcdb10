#include "carat/registration/trajectory_error.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/base/statistics.hpp"

namespace carat {
namespace {

constexpr double kRadiansToDegrees = 180.0 / 3.14159265358979323846;

// Rotation angle of a (near-)rotation matrix in radians, accurate near 0 and near pi.
double rotation_angle(const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q = Eigen::Quaterniond(R).normalized();
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

// Minimum of int values over ranges of positions, with values erased to INT_MAX one at a time.
class MinTree {
 public:
  explicit MinTree(std::size_t size) : size_(size), tree_(2 * size, INT_MAX) {}
  // Sets the value at `position` before build().
  void init(std::size_t position, int value) { tree_[size_ + position] = value; }
  void build() {
    for (std::size_t k = size_; k-- > 1;) tree_[k] = std::min(tree_[2 * k], tree_[2 * k + 1]);
  }
  void erase(std::size_t position) {
    std::size_t k = size_ + position;
    tree_[k] = INT_MAX;
    for (k /= 2; k >= 1; k /= 2) tree_[k] = std::min(tree_[2 * k], tree_[2 * k + 1]);
  }
  // Minimum over positions [begin, end); INT_MAX when empty.
  int min(std::size_t begin, std::size_t end) const {
    int result = INT_MAX;
    for (begin += size_, end += size_; begin < end; begin /= 2, end /= 2) {
      if (begin & 1) result = std::min(result, tree_[begin++]);
      if (end & 1) result = std::min(result, tree_[--end]);
    }
    return result;
  }

 private:
  std::size_t size_;
  std::vector<int> tree_;
};

/// Positions fix an alignment's rotation only when they span a plane. When the estimate's
/// positions lie on a line, a rotation about that line (through the aligned centroid) leaves
/// every position where it is; when they coincide, any rotation about them does. That free
/// rotation is settled by the orientations instead: the one that best aligns R_estimate onto
/// R_reference (largest sum of trace(R_reference^T R R_estimate)). Translation errors do not
/// change; rotation errors are no longer arbitrary.
Eigen::Isometry3d settle_free_rotation(const Eigen::Isometry3d& T,
                                       std::span<const Eigen::Isometry3d> estimate,
                                       std::span<const Eigen::Isometry3d> reference,
                                       std::span<const Eigen::Vector3d> points) {
  const double count = static_cast<double>(points.size());
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) centroid += p / count;
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) spread += (p - centroid) * (p - centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(spread);
  const Eigen::Vector3d lambda = eigen.eigenvalues();  // ascending
  const double scale = std::max(1.0, centroid.squaredNorm());
  const bool coincide = !(lambda[2] > 1e-24 * scale);
  const bool collinear = coincide || !(lambda[1] > 1e-12 * lambda[2]);
  if (!collinear) return T;
  // X = sum R_estimate R_reference^T, after the alignment's rotation so far.
  Eigen::Matrix3d X = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < points.size(); ++k) {
    X += T.linear() * estimate[k].linear() * reference[k].linear().transpose();
  }
  Eigen::Matrix3d R_free = Eigen::Matrix3d::Identity();
  if (coincide) {  // any rotation: the best one, R = V diag(1, 1, det) U^T from X = U S V^T
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(X, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() > 0.0 ? 1.0 : -1.0;
    R_free = svd.matrixV() * D * svd.matrixU().transpose();
  } else {  // about the line's direction a: maximize trace(Rot(a, phi) X) over phi
    const Eigen::Vector3d a = (T.linear() * eigen.eigenvectors().col(2)).normalized();
    Eigen::Matrix3d skew;
    skew << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
    const double along = a.dot(X * a);
    const double phi = std::atan2((skew * X).trace(), X.trace() - along);
    R_free = Eigen::AngleAxisd(phi, a).toRotationMatrix();
  }
  const Eigen::Vector3d pivot = T * centroid;  // stays where it is
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = R_free * T.linear();
  out.translation() = R_free * (T.translation() - pivot) + pivot;
  return out;
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
  if (!T.matrix().allFinite()) throw Error("the alignment overflows (coordinates too large)");
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
      throw Error("ATE alignment needs at least 3 poses, got " + std::to_string(n));
    }
    std::vector<Eigen::Vector3d> estimate_points(n);
    std::vector<Eigen::Vector3d> reference_points(n);
    for (std::size_t k = 0; k < n; ++k) {
      estimate_points[k] = estimate[k].translation();
      reference_points[k] = reference[k].translation();
    }
    stats.T_reference_estimate = align_umeyama(estimate_points, reference_points);
    stats.T_reference_estimate =
        settle_free_rotation(stats.T_reference_estimate, estimate, reference, estimate_points);
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
      throw Error("the error of pose " + std::to_string(k) + " overflows (coordinates too large)");
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
  stats.median = median(errors);
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

  // The greedy rule (take the pair smallest in (difference, estimate, reference) among the
  // candidates whose two poses are both unused, repeat) without listing the candidates. All
  // stamps go into one array sorted by (stamp, estimate before reference); a doubly linked list
  // threads the unused ones. d(a, b) = |a - b| as rounded is monotone along that order, so the
  // smallest difference d* over unused pairs is met by a "link": two neighbours in the list of
  // different kinds. Every pair at d* spans exactly one link, and its two ends lie in the runs of
  // one kind on either side: if d* = 0 its stamps are equal and estimates precede references;
  // if d* > 0 a stretch of diameter <= d* holding kinds X, Y, X in this order would give
  // d(X, Y) >= d* twice, so its rounded diameter would be at least fl(d* + pred(d*)) > d*.
  // So at d* a link's smallest pair is found by two binary searches on the stamps and two range
  // minima of unused indices. A heap holds each link once, under a key that never exceeds its
  // current smallest pair; a popped link whose key is out of date is pushed again with its
  // current one, and a popped link whose key is current holds the overall smallest pair.
  struct Stamp {
    double value;
    bool is_reference;
    int index;
  };
  const std::size_t num_stamps = estimate_stamps.size() + reference_stamps.size();
  std::vector<Stamp> stamps;
  stamps.reserve(num_stamps);
  for (std::size_t k = 0; k < estimate_stamps.size(); ++k) {
    stamps.push_back({estimate_stamps[k], false, static_cast<int>(k)});
  }
  for (std::size_t k = 0; k < reference_stamps.size(); ++k) {
    stamps.push_back({reference_stamps[k], true, static_cast<int>(k)});
  }
  std::sort(stamps.begin(), stamps.end(), [](const Stamp& a, const Stamp& b) {
    return std::tie(a.value, a.is_reference, a.index) < std::tie(b.value, b.is_reference, b.index);
  });
  std::vector<std::size_t> estimate_position(estimate_stamps.size());
  std::vector<std::size_t> reference_position(reference_stamps.size());
  for (std::size_t p = 0; p < num_stamps; ++p) {
    (stamps[p].is_reference ? reference_position : estimate_position)[stamps[p].index] = p;
  }
  MinTree unused_estimates(num_stamps);
  MinTree unused_references(num_stamps);
  for (std::size_t p = 0; p < num_stamps; ++p) {
    (stamps[p].is_reference ? unused_references : unused_estimates).init(p, stamps[p].index);
  }
  unused_estimates.build();
  unused_references.build();

  constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  std::vector<std::size_t> previous(num_stamps);
  std::vector<std::size_t> next(num_stamps);
  std::vector<char> unused(num_stamps, 1);
  for (std::size_t p = 0; p < num_stamps; ++p) {
    previous[p] = p == 0 ? kNone : p - 1;
    next[p] = p + 1 == num_stamps ? kNone : p + 1;
  }
  // Rounded like the candidates of the plain greedy rule: |estimate - reference|. Rounding is
  // symmetric, so the order of the two operands does not matter.
  const auto distance = [&](std::size_t a, std::size_t b) {
    return std::abs(stamps[a].value - stamps[b].value);
  };
  // First position in [begin, end) at which `inside` is false (it is true, then false).
  const auto partition = [](std::size_t begin, std::size_t end, const auto& inside) {
    while (begin < end) {
      const std::size_t middle = begin + (end - begin) / 2;
      if (inside(middle)) {
        begin = middle + 1;
      } else {
        end = middle;
      }
    }
    return begin;
  };

  struct Link {
    double difference;
    int estimate;   // smallest pair across the link when last computed; -1 before that
    int reference;  // (the key is a lower bound of the link's smallest pair)
    std::size_t left;
    std::size_t right;
  };
  const auto later = [](const Link& a, const Link& b) {
    return std::tie(a.difference, a.estimate, a.reference) >
           std::tie(b.difference, b.estimate, b.reference);
  };
  std::vector<Link> heap;
  heap.reserve(num_stamps);
  const auto add_link = [&](std::size_t left) {
    if (left == kNone || !unused[left]) return;
    const std::size_t right = next[left];
    if (right == kNone || stamps[left].is_reference == stamps[right].is_reference) return;
    const double difference = distance(left, right);
    if (!(difference <= max_difference)) return;
    heap.push_back({difference, -1, -1, left, right});
    std::push_heap(heap.begin(), heap.end(), later);
  };
  const auto remove = [&](std::size_t p) {
    unused[p] = 0;
    const std::size_t before = previous[p];
    const std::size_t after = next[p];
    if (before != kNone) next[before] = after;
    if (after != kNone) previous[after] = before;
    return before;
  };
  for (std::size_t p = 0; p + 1 < num_stamps; ++p) add_link(p);

  std::vector<std::pair<int, int>> pairs;
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), later);
    Link link = heap.back();
    heap.pop_back();
    const std::size_t left = link.left;
    const std::size_t right = link.right;
    if (!unused[left] || !unused[right] || next[left] != right) continue;
    // link.difference is the smallest difference over unused pairs: every pair at it spanning
    // this link joins the run of one kind ending at `left` to the run of the other kind
    // starting at `right`, and no other unused stamp lies in the ranges searched below.
    const double difference = link.difference;
    int estimate = 0;
    int reference = 0;
    if (!stamps[left].is_reference) {
      const std::size_t begin =
          partition(0, left, [&](std::size_t p) { return !(distance(p, right) <= difference); });
      estimate = unused_estimates.min(begin, left + 1);
      const std::size_t e = estimate_position[static_cast<std::size_t>(estimate)];
      const std::size_t end =
          partition(right, num_stamps, [&](std::size_t p) { return distance(e, p) <= difference; });
      reference = unused_references.min(right, end);
    } else {
      const std::size_t end = partition(
          right, num_stamps, [&](std::size_t p) { return distance(left, p) <= difference; });
      estimate = unused_estimates.min(right, end);
      const std::size_t e = estimate_position[static_cast<std::size_t>(estimate)];
      const std::size_t begin =
          partition(0, left, [&](std::size_t p) { return !(distance(p, e) <= difference); });
      reference = unused_references.min(begin, left + 1);
    }
    if (estimate != link.estimate || reference != link.reference) {
      link.estimate = estimate;  // the key grew since it was pushed: queue it again
      link.reference = reference;
      heap.push_back(link);
      std::push_heap(heap.begin(), heap.end(), later);
      continue;
    }
    pairs.emplace_back(estimate, reference);
    const std::size_t e = estimate_position[static_cast<std::size_t>(estimate)];
    const std::size_t r = reference_position[static_cast<std::size_t>(reference)];
    unused_estimates.erase(e);
    unused_references.erase(r);
    const std::size_t before_estimate = remove(e);
    const std::size_t before_reference = remove(r);
    add_link(before_estimate);
    if (before_reference != before_estimate) add_link(before_reference);
    // The pair need not hold an end of the link (stamps a fraction of an ulp apart): then the
    // link stays, and its key stays a lower bound.
    if (unused[left] && unused[right]) {
      heap.push_back(link);
      std::push_heap(heap.begin(), heap.end(), later);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace carat
