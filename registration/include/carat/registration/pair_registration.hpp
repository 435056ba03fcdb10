#pragma once

/// GICP scan matching of many frame pairs at once (the measurements of odometry and of the
/// pose-graph baselines).

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/align.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/solver/se3.hpp"

namespace carat {

/// The scan-matching result of one frame pair.
struct PairRegistration {
  FramePair pair;                                                     ///< which frames
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  ///< aligned relative pose
  se3::Matrix6d H = se3::Matrix6d::Zero();  ///< GICP J^T J at the result (right tangent [w, v])
  double error = 0.0;                       ///< GICP sum of squared residuals at the result
  int num_correspondences = 0;              ///< pairs used in the last iteration
  int iterations = 0;                       ///< outer GICP iterations
  bool converged = false;                   ///< the last step was below tolerance
  int constrained_dof = 0;  ///< directions the pair's geometry fixes (AlignResult::constrained_dof)
  double align_s = 0.0;     ///< wall time of this pair's alignment (1 thread)

  /// Whether the relative pose can be trusted: converged and all 6 directions fixed.
  bool reliable() const { return converged && constrained_dof >= 6; }
  /// Why it cannot ("did not converge", "fixes only 3 of 6 degrees of freedom"), or "".
  std::string problem() const;
};

/// Aligns every pair (source onto target) starting from the relative pose that T_world_frame
/// implies, in parallel over pairs with `num_threads` threads (each alignment single-threaded,
/// so results do not depend on the thread count). Throws carat::Error naming the pair when an
/// alignment fails. `progress`, if set, gets (pairs done, pairs) from any thread.
/// A store that reads frames on demand is walked in locality_order().
std::vector<PairRegistration> register_pairs(
    FrameStore& frames, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const AlignSettings& settings,
    int num_threads, const std::function<void(std::size_t, std::size_t)>& progress = {});

/// Deprecated: the same from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline std::vector<PairRegistration>
register_pairs(std::span<const std::shared_ptr<const Frame>> frames,
               std::span<const FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_frame,
               const AlignSettings& settings, int num_threads,
               const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return register_pairs(store, pairs, T_world_frame, settings, num_threads, progress);
}

}  // namespace carat
