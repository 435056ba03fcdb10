// A custom binary registration block written once as a functor of the relative pose
// T_ij = T_world_i^-1 T_world_j: point-to-line, for edge points (LOAM-style) against lines of a
// target map. carat differentiates it automatically in the tangent of T_ij, so the block has a
// 6-column reduced Jacobian and compresses to 29 rows that reproduce its whole 12 x 12 H, b and
// c for both poses. The example builds 6,000 matches, compresses them, solves for the source
// pose from a perturbed start, and checks the compressed model and the recovered pose.
// Prints a report, or one JSON object with --json; exits 1 if a check fails.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

#include "carat/base/stopwatch.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/residuals/relative_pose_autodiff_block.hpp"
#include "carat/solver/jacobian_checker.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solve.hpp"

namespace {

/// A source point and the target line it lies on (a point on the line and its unit direction),
/// both in their frames' coordinates.
struct LineMatch {
  Eigen::Vector3d source;
  Eigen::Vector3d line_point;
  Eigen::Vector3d line_direction;
};

/// The offset of T_ij p from the line, perpendicular to it (3 rows, rank 2).
struct PointToLine {
  template <typename T>
  bool operator()(const LineMatch& m, const carat::lie::Pose<T>& T_ij, T* residuals) const {
    const Eigen::Matrix<T, 3, 1> d = m.line_direction.cast<T>();
    const Eigen::Matrix<T, 3, 1> q = T_ij.act(m.source.cast<T>()) - m.line_point.cast<T>();
    const Eigen::Matrix<T, 3, 1> offset = q - d * d.dot(q);
    for (int k = 0; k < 3; ++k) residuals[k] = offset[k];
    return true;
  }
};

}  // namespace

int main(int argc, char** argv) {
  const bool json = argc > 1 && std::strcmp(argv[1], "--json") == 0;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> along(-10.0, 10.0), offset(-5.0, 5.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  // The truth: T_target_source, a small motion.
  carat::se3::Vector6d xi;
  xi << 0.02, -0.01, 0.05, 0.4, -0.2, 0.1;
  const Eigen::Isometry3d T_target_source = carat::se3::exp(xi);
  // Lines of the target map in three directions; source points on them, seen from the source.
  std::vector<LineMatch> matches;
  for (int k = 0; k < 6000; ++k) {
    const Eigen::Vector3d d = Eigen::Vector3d::Unit(k % 3);
    Eigen::Vector3d a(offset(rng), offset(rng), offset(rng));
    a -= d * d.dot(a);  // the line's point closest to the origin
    const Eigen::Vector3d on_line = a + along(rng) * d;
    const Eigen::Vector3d noisy = on_line + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    matches.push_back({T_target_source.inverse() * noisy, a, d});
  }
  auto block = carat::make_relative_pose_block<3>(PointToLine{}, matches, "point-to-line");

  // Problem: the target pose fixed at the origin, the source pose perturbed from the truth.
  carat::se3::Vector6d perturbation;
  perturbation << 0.03, 0.02, -0.04, 0.3, -0.3, 0.2;
  const Eigen::Isometry3d start = T_target_source * carat::se3::exp(perturbation);
  carat::Problem problem;
  const carat::VariableId target = problem.add_se3(Eigen::Isometry3d::Identity());
  const carat::VariableId source = problem.add_se3(start);
  problem.set_constant(target);

  // Exact compression at the start: 29 rows with the full H, b and c (both poses).
  const double* values[2] = {problem.value(target).data(), problem.value(source).data()};
  carat::Stopwatch stopwatch;
  const auto compressed = carat::compress(block, values);
  const double compress_s = stopwatch.elapsed_s();
  Eigen::VectorXd r_full, r_small;
  Eigen::MatrixXd J_full, J_small;
  carat::evaluate_full_jacobian(*block, values, &r_full, &J_full);
  carat::evaluate_full_jacobian(*compressed, values, &r_small, &J_small);
  const double h_error = (J_full.transpose() * J_full - J_small.transpose() * J_small).norm() /
                         (J_full.transpose() * J_full).norm();
  const double b_error = (J_full.transpose() * r_full - J_small.transpose() * r_small).norm() /
                         (J_full.transpose() * r_full).norm();
  const double c_error =
      std::abs(r_full.squaredNorm() - r_small.squaredNorm()) / r_full.squaredNorm();

  // Solve with the compressed block (the motion is small: one compression suffices here).
  problem.add_residual_block(compressed, {target, source});
  carat::SolverOptions options;
  options.max_iterations = 50;
  stopwatch.restart();
  const carat::SolverSummary summary = carat::solve(options, problem);
  const double solve_s = stopwatch.elapsed_s();
  const carat::se3::Vector6d error =
      carat::se3::log(T_target_source.inverse() * problem.se3(source));
  const double rotation_error_deg = error.head<3>().norm() * 180.0 / M_PI;
  const double translation_error_m = error.tail<3>().norm();

  const bool ok = compressed->num_rows() == 29 && h_error < 1e-12 && b_error < 1e-12 &&
                  c_error < 1e-12 && translation_error_m < 5e-3 && rotation_error_deg < 0.05 &&
                  summary.is_solution_usable();
  if (json) {
    std::printf(
        "{\n  \"matches\": %zu,\n  \"rows\": %d,\n  \"compressed_rows\": %d,\n"
        "  \"bytes\": %zu,\n  \"compressed_bytes\": %zu,\n  \"relative_error_H\": %.3e,\n"
        "  \"relative_error_b\": %.3e,\n  \"relative_error_c\": %.3e,\n  \"compress_s\": %.6f,\n"
        "  \"solve_s\": %.6f,\n  \"iterations\": %d,\n  \"translation_error_m\": %.6e,\n"
        "  \"rotation_error_deg\": %.6e,\n  \"ok\": %s\n}\n",
        matches.size(), block->num_rows(), compressed->num_rows(), block->memory_bytes(),
        compressed->memory_bytes(), h_error, b_error, c_error, compress_s, solve_s,
        summary.num_iterations, translation_error_m, rotation_error_deg, ok ? "true" : "false");
  } else {
    std::printf("point-to-line block: %zu matches, %d rows, %zu bytes\n", matches.size(),
                block->num_rows(), block->memory_bytes());
    std::printf(
        "compressed to %d rows (%zu bytes) in %.3f ms; relative error H %.1e, b %.1e, c %.1e\n",
        compressed->num_rows(), compressed->memory_bytes(), 1e3 * compress_s, h_error, b_error,
        c_error);
    std::printf("solved in %d iterations (%.3f ms): pose error %.2e m, %.2e deg\n",
                summary.num_iterations, 1e3 * solve_s, translation_error_m, rotation_error_deg);
    std::printf("%s\n", ok ? "ok" : "FAILED");
  }
  return ok ? 0 : 1;
}
