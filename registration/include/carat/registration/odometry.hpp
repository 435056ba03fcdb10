#pragma once

/// LiDAR odometry: GICP between consecutive frames, chained into a trajectory.

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/frame_store.hpp"
#include "carat/registration/pair_registration.hpp"

namespace carat {

/// Odometry poses and the consecutive-pair measurements they were chained from.
struct OdometryResult {
  std::vector<Eigen::Isometry3d> T_world_frame;  ///< chained poses, the first one as given
  std::vector<PairRegistration> steps;           ///< step k aligns frame k+1 to frame k

  /// Steps that cannot be trusted (PairRegistration::reliable() is false): every pose after the
  /// first of them is wrong.
  std::size_t unreliable_steps() const;
  /// Names those steps, their frames and why ("000011 -> 000012 did not converge; ..."; at most
  /// `limit` of them, then how many more), with frame names from `frames` (else indices); "" when
  /// every step is reliable.
  std::string describe_unreliable_steps(FrameStore& frames, std::size_t limit = 5) const;
  /// Deprecated: the same with names from frames in memory.
  [[deprecated("wrap the frames in a carat::FrameStore")]] std::string describe_unreliable_steps(
      std::span<const std::shared_ptr<const Frame>> frames, std::size_t limit = 5) const {
    FrameStore store = resident_store(frames);
    return describe_unreliable_steps(store, limit);
  }
};

/// Aligns frame k+1 to frame k for every k, starting each alignment from the relative motion
/// of T_world_guess (wheel odometry, a drift model, or any prior), in parallel, and chains the
/// results from T_world_guess[0]. Throws carat::Error for fewer than 2 frames, mismatched
/// counts, or a failed alignment (naming the frames).
OdometryResult run_odometry(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_guess,
                            const AlignSettings& settings, int num_threads,
                            const std::function<void(std::size_t, std::size_t)>& progress = {});

/// Odometry from scans alone: aligns frame k+1 to frame k in order, each from the motion of the
/// step before (constant velocity; identity for the first), first with correspondences up to
/// three times settings.max_correspondence_distance, then with it, and chains the results from
/// the identity. Each alignment uses settings.num_threads. Throws carat::Error for fewer than 2
/// frames or a failed alignment (naming the frames). `progress`, if set, gets (steps done,
/// steps).
OdometryResult run_scan_odometry(
    FrameStore& frames, const AlignSettings& settings,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

/// Deprecated: run_odometry() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline OdometryResult run_odometry(
    std::span<const std::shared_ptr<const Frame>> frames,
    std::span<const Eigen::Isometry3d> T_world_guess, const AlignSettings& settings,
    int num_threads, const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return run_odometry(store, T_world_guess, settings, num_threads, progress);
}

/// Deprecated: run_scan_odometry() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline OdometryResult run_scan_odometry(
    std::span<const std::shared_ptr<const Frame>> frames, const AlignSettings& settings,
    const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return run_scan_odometry(store, settings, progress);
}

}  // namespace carat
