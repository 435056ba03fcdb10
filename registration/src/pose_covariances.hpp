#pragma once

// Internal: the marginal covariance of every pose of a solved registration or pose-graph
// problem, as the mapping pipelines report it.

#include <span>
#include <vector>

#include "carat/base/stopwatch.hpp"
#include "carat/solver/covariance.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/se3.hpp"

namespace carat::internal {

/// Per pose variable (SE(3)), its covariance at the problem's current values (zero for a
/// constant one); *seconds gets the wall time. Throws carat::Error as carat::Covariance does.
inline std::vector<se3::Matrix6d> pose_covariances(const Problem& problem,
                                                   std::span<const VariableId> poses,
                                                   int num_threads, double* seconds) {
  const Stopwatch time;
  Covariance::Options options;
  options.num_threads = num_threads;
  const Covariance covariance(problem, options);
  std::vector<se3::Matrix6d> out;
  for (const Eigen::MatrixXd& block : covariance.blocks(poses)) {
    out.push_back(block.size() == 0 ? se3::Matrix6d::Zero() : se3::Matrix6d(block));
  }
  *seconds = time.elapsed_s();
  return out;
}

}  // namespace carat::internal
