#include "carat/registration/align.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/correspondences.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/point_to_plane_block.hpp"
#include "carat/residuals/point_to_point_block.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/solve.hpp"

namespace carat {
namespace {

/// The residual block of `method` over the pairs (target index, source index), built at T.
std::shared_ptr<const ResidualBlock> make_block(
    RegistrationMethod method, const PointCloud& target, const PointCloud& source,
    const std::vector<std::array<std::uint32_t, 2>>& pairs, const Eigen::Isometry3d& T) {
  if (method == RegistrationMethod::kGicp) {
    return std::make_shared<GicpBlock>(target.points, target.covariances, source.points,
                                       source.covariances, pairs, T);
  }
  std::vector<Eigen::Vector3d> target_means, source_means, normal;
  for (const auto& [t, s] : pairs) {
    target_means.push_back(target.point(t));
    source_means.push_back(source.point(s));
    if (method == RegistrationMethod::kPointToPlane) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(target.covariance(t));
      normal.push_back(eig.eigenvectors().col(0));
    }
  }
  if (method == RegistrationMethod::kPointToPlane)
    return std::make_shared<PointToPlaneBlock>(target_means, normal, source_means);
  return std::make_shared<PointToPointBlock>(target_means, source_means);
}

std::string format_number(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%g", value);
  return text;
}

/// Throws carat::Error naming the first setting out of range.
void check_settings(const AlignSettings& s) {
  const auto fail = [](const std::string& what, const std::string& rule, double value) {
    throw Error("align: " + what + " must be " + rule + ", got " + format_number(value));
  };
  if (!(std::isfinite(s.max_correspondence_distance) && s.max_correspondence_distance > 0.0))
    fail("max_correspondence_distance", "finite and > 0 (metres)", s.max_correspondence_distance);
  if (s.max_iterations < 0) fail("max_iterations", ">= 0", s.max_iterations);
  if (!(std::isfinite(s.translation_tolerance) && s.translation_tolerance >= 0.0))
    fail("translation_tolerance", "finite and >= 0 (metres)", s.translation_tolerance);
  if (!(std::isfinite(s.rotation_tolerance) && s.rotation_tolerance >= 0.0))
    fail("rotation_tolerance", "finite and >= 0 (radians)", s.rotation_tolerance);
  if (s.min_correspondences < 1) fail("min_correspondences", ">= 1", s.min_correspondences);
  if (s.num_threads < 1) fail("num_threads", ">= 1", s.num_threads);
}

}  // namespace

AlignResult align(const PointCloud& target, const KdTree& target_tree, const PointCloud& source,
                  const Eigen::Isometry3d& T_target_source_init, const AlignSettings& settings) {
  if (!target.has_covariances())
    throw Error("align: the target cloud has no covariances (run estimate_covariances)");
  if (!source.has_covariances())
    throw Error("align: the source cloud has no covariances (run estimate_covariances)");
  check_settings(settings);
  if (!T_target_source_init.matrix().allFinite())
    throw Error("align: the initial pose T_target_source is not finite");
  AlignResult result;
  result.T_target_source = T_target_source_init;
  const int threads = std::clamp(settings.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  arena.execute([&] {
    SolverOptions options;
    options.max_iterations = 1;
    options.num_threads = threads;
    options.record_iterations = false;
    std::shared_ptr<const ResidualBlock> last_block;
    std::vector<std::array<std::uint32_t, 2>> pairs;  // of the last search
    for (int iteration = 0; iteration < settings.max_iterations; ++iteration) {
      Stopwatch stage;
      pairs = find_nearest_pairs(target, target_tree, source, result.T_target_source,
                                 settings.max_correspondence_distance, pairs);
      result.search_s += stage.restart();
      if (static_cast<int>(pairs.size()) < settings.min_correspondences) {
        char distance[32];
        std::snprintf(distance, sizeof(distance), "%g", settings.max_correspondence_distance);
        throw Error("only " + std::to_string(pairs.size()) + " correspondences within " + distance +
                    " m (need " + std::to_string(settings.min_correspondences) +
                    "); the clouds do not overlap at this estimate");
      }
      const auto block = make_block(settings.method, target, source, pairs, result.T_target_source);
      last_block = block;
      Problem problem;
      const VariableId target_pose = problem.add_se3(Eigen::Isometry3d::Identity());
      const VariableId source_pose = problem.add_se3(result.T_target_source);
      problem.set_constant(target_pose);
      problem.add_residual_block(block, {target_pose, source_pose});
      const SolverSummary summary = solve(options, problem);
      const Eigen::Isometry3d previous = result.T_target_source;
      if (summary.termination == TerminationType::kFailure) {
        // No usable step: the estimate stays where it is and is not called converged.
        result.optimize_s += stage.elapsed_s();
        result.iterations = iteration + 1;
        result.num_correspondences = static_cast<int>(pairs.size());
        break;
      }
      result.T_target_source = problem.se3(source_pose);
      result.optimize_s += stage.elapsed_s();
      result.iterations = iteration + 1;
      result.num_correspondences = static_cast<int>(pairs.size());
      const se3::Vector6d step = se3::log(previous.inverse() * result.T_target_source);
      if (step.head<3>().norm() < settings.rotation_tolerance &&
          step.tail<3>().norm() < settings.translation_tolerance) {
        result.converged = true;
        break;
      }
    }
    // The Hessian and error at the result: with the last correspondences when the last step was
    // below tolerance (they are those of the result), else with a fresh search.
    std::shared_ptr<const ResidualBlock> block = result.converged ? last_block : nullptr;
    if (!block) {
      pairs = find_nearest_pairs(target, target_tree, source, result.T_target_source,
                                 settings.max_correspondence_distance, pairs);
      if (!pairs.empty())
        block = make_block(settings.method, target, source, pairs, result.T_target_source);
    }
    if (block) {
      double identity[7], pose[7];
      se3::to_storage(Eigen::Isometry3d::Identity(), identity);
      se3::to_storage(result.T_target_source, pose);
      const double* params[2] = {identity, pose};
      Eigen::MatrixXd H = Eigen::MatrixXd::Zero(6, 6);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(6);
      result.error = block->accumulate(params, H, b);
      result.H = H;
      // Degeneracy on a scale-free H: rotations measured at the source's median radius (an
      // outlier far away would inflate a mean), so every direction is in metres. Along a surface
      // normal GICP weighs a point 1000 x more than along the surface (covariance eigenvalues
      // 1e-3, 1, 1); a direction below 5e-3 of the best one is held only by the in-surface
      // terms, i.e. not by the geometry.
      std::vector<double> radii(source.size());
      for (std::size_t i = 0; i < source.size(); ++i) radii[i] = source.point(i).norm();
      const std::size_t middle = radii.size() / 2;
      std::nth_element(radii.begin(), radii.begin() + static_cast<std::ptrdiff_t>(middle),
                       radii.end());
      const double radius = std::max(radii.empty() ? 0.0 : radii[middle], 1e-6);
      se3::Vector6d scale;
      scale << 1.0 / radius, 1.0 / radius, 1.0 / radius, 1.0, 1.0, 1.0;
      const se3::Matrix6d normalized = scale.asDiagonal() * result.H * scale.asDiagonal();
      const Eigen::SelfAdjointEigenSolver<se3::Matrix6d> eig(normalized, Eigen::EigenvaluesOnly);
      const double largest = eig.eigenvalues().maxCoeff();
      result.min_eigenvalue_ratio = largest > 0.0 ? eig.eigenvalues().minCoeff() / largest : 0.0;
      for (int k = 0; k < 6; ++k)
        if (largest > 0.0 && eig.eigenvalues()[k] > 5e-3 * largest) ++result.constrained_dof;
    }
  });
  return result;
}

const char* to_string(RegistrationMethod method) {
  switch (method) {
    case RegistrationMethod::kGicp:
      return "gicp";
    case RegistrationMethod::kPointToPlane:
      return "point-to-plane";
    case RegistrationMethod::kPointToPoint:
      return "point-to-point";
  }
  return "unknown";
}

RegistrationMethod parse_registration_method(std::string_view name) {
  if (name == "gicp") return RegistrationMethod::kGicp;
  if (name == "point-to-plane") return RegistrationMethod::kPointToPlane;
  if (name == "point-to-point") return RegistrationMethod::kPointToPoint;
  throw Error("unknown registration method " + quote_bytes(name) +
              " (valid: gicp, point-to-plane, point-to-point)");
}

}  // namespace carat
