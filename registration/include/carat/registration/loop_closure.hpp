#pragma once

/// Loop closure from an odometry guess: Scan Context candidates (scan_context.hpp), each
/// validated by GICP from the yaw its descriptor gives and from the guess, and a pose graph of
/// the odometry and the accepted loops solved from the guess.

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/registration/pose_graph_baseline.hpp"
#include "carat/registration/scan_context.hpp"

namespace carat {

/// Settings of close_loops() and its two stages.
struct LoopClosureOptions {
  ScanContextOptions descriptor;    ///< the descriptor of every frame
  double exclude_recent_m = 100.0;  ///< a frame's candidates lie at least this far back along
                                    ///< the guess's path (metres), so that the scans just
                                    ///< before it are not proposed as loops
  int ring_key_candidates = 10;     ///< nearest ring keys whose descriptors are compared (>= 1)
  double max_descriptor_distance = 0.35;     ///< candidates must match at least this well
  double max_correspondence_distance = 1.0;  ///< metres: GICP's last stage (a first stage uses
                                             ///< three times this); the inlier distance
  double max_drift_fraction = 0.1;   ///< a loop is accepted only if its relative pose moves the
                                     ///< newer frame, against the guess's, by at most this
                                     ///< fraction of the path the guess travels between the two
                                     ///< frames (> 0; infinity: no limit): odometry drifts by a
                                     ///< few percent, while a repeated place (the same block of a
                                     ///< grid city) aligns at whole block lengths off
  double min_inlier_fraction = 0.8;  ///< share of the source's points within that distance of
                                     ///< the target at the result, for a loop to be accepted;
                                     ///< high because the ground matches almost anywhere (in
                                     ///< the synthetic city true loops reach 0.94 or more, a
                                     ///< neighbouring corner aligned wrongly up to 0.68)
  PoseGraphBaselineOptions graph;    ///< the loop-closure pose graph (GICP-Hessian information,
                                     ///< Cauchy kernel), solved after a kernel-free pass
  int num_threads = 1;               ///< threads over frames and candidates (>= 1)
};

/// A frame pair whose descriptors match: a possible loop.
struct LoopCandidate {
  FramePair pair;                    ///< target: the older frame, source: the newer one
  double descriptor_distance = 1.0;  ///< ScanContextMatch::distance
  double yaw = 0.0;                  ///< radians: the rotation about z of T_target_source that
                                     ///< the descriptors' best shift stands for
};

/// Why a candidate was accepted or not.
enum class LoopVerdict {
  kAccepted,         ///< converged, fully constrained, enough inliers
  kNotConverged,     ///< GICP did not converge from either start, or found too few pairs
  kDegenerate,       ///< the pair constrains fewer than 6 directions (a corridor, a plane)
  kFewInliers,       ///< converged, but too few of the source's points match the target
  kTooFarFromGuess,  ///< moves the newer frame farther from the guess than odometry drifts
                     ///< (LoopClosureOptions::max_drift_fraction)
};

/// Name of a verdict: "accepted", "not converged", "degenerate", "few inliers", "too far from
/// the guess".
const char* to_string(LoopVerdict verdict);

/// The validation of one candidate.
struct LoopCheck {
  LoopCandidate candidate;                           ///< what was checked
  LoopVerdict verdict = LoopVerdict::kNotConverged;  ///< the outcome
  double inlier_fraction = 0.0;                      ///< of the better of the two starts
  PairRegistration registration;                     ///< GICP's result from the better start
};

/// Everything close_loops() found.
struct LoopClosureResult {
  std::vector<int> sparse_frames;                ///< frames too sparse for a descriptor
  std::vector<LoopCandidate> candidates;         ///< at most one per frame, by source frame
  std::vector<LoopCheck> checks;                 ///< parallel to candidates
  std::vector<PairRegistration> odometry;        ///< consecutive pairs registered from the guess
  std::vector<PairRegistration> loops;           ///< the accepted loops
  std::vector<Eigen::Isometry3d> T_world_frame;  ///< the pose graph's result; the guess when no
                                                 ///< loop was accepted
  SolverSummary summary;                         ///< the last pose-graph solve (empty: none)
};

/// Scan Context candidates: for every frame with a descriptor, the best-matching older frame
/// (among the ring_key_candidates nearest ring keys of frames at least exclude_recent_m back
/// along T_world_guess's path) when it matches within max_descriptor_distance. Deterministic,
/// parallel over frames; frames too sparse for a descriptor are listed in *sparse_frames (may be
/// null). Throws carat::Error for mismatched counts or options out of range.
/// Each frame is requested once, in index order.
std::vector<LoopCandidate> find_loop_candidates(FrameStore& frames,
                                                std::span<const Eigen::Isometry3d> T_world_guess,
                                                const LoopClosureOptions& options,
                                                std::vector<int>* sparse_frames = nullptr);

/// find_loop_candidates() from descriptors already made, one per frame (make_scan_context() of
/// each frame's cloud with options.descriptor, e.g. on other processes). Throws carat::Error for
/// mismatched counts or options out of range.
std::vector<LoopCandidate> find_loop_candidates(std::span<const ScanContext> descriptors,
                                                std::span<const Eigen::Isometry3d> T_world_guess,
                                                const LoopClosureOptions& options,
                                                std::vector<int>* sparse_frames = nullptr);

/// GICP for every candidate from two starts: the descriptor's yaw (no translation) and the
/// guess's relative pose; the start whose result matches more of the source's points counts.
/// Parallel over candidates; results do not depend on the thread count.
std::vector<LoopCheck> validate_loop_candidates(FrameStore& frames,
                                                std::span<const Eigen::Isometry3d> T_world_guess,
                                                std::span<const LoopCandidate> candidates,
                                                const LoopClosureOptions& options);

/// Where close_loops() makes its descriptors and runs its GICP (e.g. shared over the ranks of an
/// MPI job); each must return what the library function it stands for returns for the same
/// arguments.
struct LoopClosureStages {
  /// The Scan Context descriptor of each of the frames (their count given) with these options,
  /// as make_scan_context() makes it; empty: made in this process.
  std::function<std::vector<ScanContext>(std::size_t, const ScanContextOptions&)> describe;
  /// validate_loop_candidates() of the candidates at the guess; empty: run in this process.
  std::function<std::vector<LoopCheck>(std::span<const LoopCandidate>,
                                       std::span<const Eigen::Isometry3d>,
                                       const LoopClosureOptions&)>
      validate;
  /// register_pairs() of the consecutive pairs at the guess with these settings; empty: run in
  /// this process.
  std::function<std::vector<PairRegistration>(
      std::span<const FramePair>, std::span<const Eigen::Isometry3d>, const AlignSettings&)>
      register_consecutive;
};

/// Candidates, their validation, GICP of every consecutive pair from the guess, and (when a loop
/// was accepted) the pose graph of odometry and loops solved from the guess: first without a
/// kernel, then with options.graph. Throws carat::Error as the stages do (fewer than 2 frames,
/// mismatched counts, a consecutive pair GICP cannot align). `progress`, if set, gets (steps
/// done, steps) from any thread.
LoopClosureResult close_loops(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_guess,
                              const LoopClosureOptions& options,
                              const std::function<void(std::size_t, std::size_t)>& progress = {});

/// close_loops() with its descriptors, validation and consecutive registrations made by `stages`
/// (where set).
LoopClosureResult close_loops(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_guess,
                              const LoopClosureOptions& options,
                              const std::function<void(std::size_t, std::size_t)>& progress,
                              const LoopClosureStages& stages);

/// Deprecated: find_loop_candidates() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline std::vector<LoopCandidate>
find_loop_candidates(std::span<const std::shared_ptr<const Frame>> frames,
                     std::span<const Eigen::Isometry3d> T_world_guess,
                     const LoopClosureOptions& options, std::vector<int>* sparse_frames = nullptr) {
  FrameStore store = resident_store(frames);
  return find_loop_candidates(store, T_world_guess, options, sparse_frames);
}

/// Deprecated: validate_loop_candidates() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline std::vector<LoopCheck>
validate_loop_candidates(std::span<const std::shared_ptr<const Frame>> frames,
                         std::span<const Eigen::Isometry3d> T_world_guess,
                         std::span<const LoopCandidate> candidates,
                         const LoopClosureOptions& options) {
  FrameStore store = resident_store(frames);
  return validate_loop_candidates(store, T_world_guess, candidates, options);
}

/// Deprecated: close_loops() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline LoopClosureResult close_loops(
    std::span<const std::shared_ptr<const Frame>> frames,
    std::span<const Eigen::Isometry3d> T_world_guess, const LoopClosureOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return close_loops(store, T_world_guess, options, progress);
}

}  // namespace carat
