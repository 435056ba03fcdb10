// Solves a tiny pose graph through the installed carat package (its umbrella header).
#include <carat/carat.hpp>
#include <cmath>
#include <cstdio>
#include <memory>

int main() {
  carat::Problem problem;
  const auto a = problem.add_se3(Eigen::Isometry3d::Identity());
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  guess.translation() = Eigen::Vector3d(0.5, -0.2, 0.1);
  const auto b = problem.add_se3(guess);
  problem.set_constant(a);
  Eigen::Isometry3d measured = Eigen::Isometry3d::Identity();
  measured.translation() = Eigen::Vector3d(1.0, 2.0, 3.0);
  problem.add_residual_block(
      std::make_shared<carat::RelativePoseBlock>(measured, carat::se3::Matrix6d::Identity()),
      {a, b});
  carat::SolverOptions options;
  options.function_tolerance = 1e-14;
  options.parameter_tolerance = 1e-14;
  const carat::SolverSummary summary = carat::solve(options, problem);
  const double error = (problem.se3(b).translation() - measured.translation()).norm();
  std::printf("%s\n", summary.brief_report().c_str());
  if (summary.termination != carat::TerminationType::kConvergence || error > 1e-9) {
    std::printf("consumer: FAILED (error %.3e)\n", error);
    return 1;
  }
  std::printf("consumer: ok (carat %s)\n", carat::version());
  return 0;
}
