#pragma once

/// The mapping pipeline: frames and a starting trajectory in, an optimized trajectory out.
/// Optionally loops are closed first (Scan Context candidates, GICP validation, a pose graph of
/// odometry and loops); then the dense graph of overlapping pairs is built at the start, and
/// either the registration errors of all pairs are minimized together (GRE, Koide et al. 2023)
/// or a pose graph of pairwise GICP results is solved (PGO). `carat map`, `carat demo`,
/// `carat paper`, the MPI path and Python's mapping calls all run it.

#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "carat/base/stage_times.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/held_factors.hpp"
#include "carat/registration/loop_closure.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/registration/pose_graph_baseline.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat {

/// The optimization that maps the frames over the dense graph.
enum class MappingMethod {
  kRegistration,  ///< global registration error minimization: one GICP factor per pair (GRE)
  kPoseGraph,     ///< a pose graph of each pair's GICP result (PGO)
};

/// Name of a method: "gre" or "pgo".
const char* to_string(MappingMethod method);
/// Parses "gre" or "pgo"; throws carat::Error listing them otherwise.
MappingMethod parse_mapping_method(std::string_view name);

/// The stages of the pipeline, in order, as the progress callback names them.
enum class MappingStage {
  kLoops,             ///< loop closure (with MappingOptions::close_loops)
  kDenseGraph,        ///< overlap tests of the dense graph
  kPairRegistration,  ///< PGO: GICP of every pair
  kFactors,           ///< GRE: building (and compressing) the factors, once per round
};

/// Progress of a stage: (stage, done, total), from any thread.
using MappingProgress = std::function<void(MappingStage, std::size_t, std::size_t)>;

/// Builds one round's GRE factors of `pairs` at T_world_frame, parallel to the pairs (e.g. over
/// the ranks of an MPI job); see optimize_registration()'s builder overload.
using MappingFactorBuilder = std::function<std::vector<RegistrationFactor>(
    std::span<const FramePair>, std::span<const Eigen::Isometry3d>,
    const GlobalRegistrationOptions&)>;

/// Builds one round's GRE factors of `pairs` at T_world_start where they will stay (e.g. on the
/// ranks of an MPI job), blocks in `order`; see optimize_held_registration().
using MappingFactorHolder = std::function<std::shared_ptr<HeldRegistrationFactors>(
    std::span<const FramePair> pairs, std::span<const Eigen::Isometry3d> T_world_start,
    std::span<const std::size_t> order, const GlobalRegistrationOptions&)>;

/// Measures the overlap of each of the dense graph's candidate pairs at T_world_frame into its
/// `overlap` as measure_overlaps() does (e.g. a share on each rank of an MPI job), reporting
/// (done, total) of what it measures itself to the progress callback, which may be empty.
using MappingOverlapMeasurer = std::function<void(
    std::span<FramePair>, std::span<const Eigen::Isometry3d>, const DenseGraphOptions&,
    const std::function<void(std::size_t, std::size_t)>&)>;

/// LM settings of the mapping solves: 100 iterations at most, else SolverOptions' defaults.
SolverOptions mapping_solver_options();

/// Settings of every stage. Thread counts of the stage options are ignored: num_threads is
/// copied into each.
struct MappingOptions {
  int num_threads = 1;       ///< threads of every stage (>= 1)
  bool close_loops = false;  ///< close loops before the dense graph is built
  LoopClosureOptions loops;  ///< the loop step
  DenseGraphOptions graph;   ///< the dense graph, built at the start (after loops)
  MappingMethod method = MappingMethod::kRegistration;  ///< what optimizes the poses
  /// GRE: sampling (full, exact, random, lossless), rows per factor, correspondence distance,
  /// rounds, kernels, LM settings, covariances, per-iteration callback.
  GlobalRegistrationOptions registration = default_registration();
  /// PGO: GICP of every pair (each alignment single-threaded; pairs run in parallel).
  AlignSettings pair_alignment;
  /// PGO: factor information, Cauchy kernel, LM settings, covariances.
  PoseGraphBaselineOptions pose_graph = default_pose_graph();
  /// GRE: when set, builds each round's factors instead of this process (MPI).
  MappingFactorBuilder build_factors;
  /// GRE: when set, builds each round's factors where they stay, and the solve linearizes them
  /// there (MPI); it takes precedence over build_factors.
  MappingFactorHolder hold_factors;
  /// When set, measures the dense graph's candidates instead of this process (MPI); the graph is
  /// the one build_dense_graph() finds from the same measurements.
  MappingOverlapMeasurer measure_overlaps;
  /// Where the loop step's descriptors, validation and consecutive registrations are made (MPI);
  /// empty members: in this process.
  LoopClosureStages loop_stages;

  /// GlobalRegistrationOptions with mapping_solver_options().
  static GlobalRegistrationOptions default_registration();
  /// PoseGraphBaselineOptions with mapping_solver_options().
  static PoseGraphBaselineOptions default_pose_graph();
};

/// What the stages before the optimization found: the start and the dense graph.
struct MapGraph {
  std::vector<Eigen::Isometry3d> T_world_start;  ///< the optimization's start: the initial
                                                 ///< guess, or the loop pose graph's result
  std::optional<LoopClosureResult> loops;        ///< with MappingOptions::close_loops
  std::vector<FramePair> pairs;                  ///< the dense graph at T_world_start
  StageTimes times;                              ///< "loops", "dense_graph" (seconds)
};

/// The optimization's result, with the graph it ran on.
struct MappingResult {
  MapGraph graph;                                       ///< start, loops, pairs, their stage times
  MappingMethod method = MappingMethod::kRegistration;  ///< which optimization ran
  std::vector<Eigen::Isometry3d> T_world_frame;         ///< optimized poses (frame 0 held constant)
  SolverSummary summary;                                ///< the solve (GRE: over all rounds)
  int rounds = 0;                                       ///< GRE correspondence rounds run (PGO: 0)
  RegistrationFactorStats factor_stats;                 ///< GRE: building the factors
  std::vector<double> factor_costs;                     ///< GRE, per pair: squared error / corresp.
  std::vector<std::size_t> factor_residual_bytes;       ///< per pair: bytes held in the solve
  std::vector<std::size_t> factor_correspondence_bytes;  ///< GRE, per pair: full block bytes
  std::vector<PairRegistration> registrations;           ///< PGO, per pair: its GICP result
  std::size_t unconverged_pairs = 0;  ///< PGO: registrations that did not converge
  /// With the method's covariance option: per frame, the covariance of its pose's right
  /// perturbation [omega (rad), v (m)]; zero for frame 0.
  std::vector<se3::Matrix6d> covariance;
  double covariance_s = 0.0;  ///< wall time of the covariances
  /// Wall seconds: the graph's stages, then "pair_registration" (PGO), "factors" (GRE: all
  /// rounds' building), "solve" (the LM solves), "covariance".
  StageTimes times;
};

/// Loops (when asked) and the dense graph at the start. T_world_initial: one pose per frame.
/// Throws carat::Error as close_loops() and build_dense_graph() do, or for num_threads < 1.
MapGraph build_map_graph(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_initial,
                         const MappingOptions& options, const MappingProgress& progress = {});

/// The optimization stage alone, over `graph`'s pairs from its start. PGO takes
/// `registrations` (the pairs' GICP results from an earlier run on the same graph, parallel to
/// its pairs) instead of registering the pairs again when given. Throws carat::Error as
/// optimize_registration() or optimize_pose_graph_baseline() do, or for registrations that are
/// not parallel to the pairs.
MappingResult optimize_map(FrameStore& frames, MapGraph graph, const MappingOptions& options,
                           const MappingProgress& progress = {},
                           std::span<const PairRegistration> registrations = {});

/// The whole job: build_map_graph() then optimize_map().
MappingResult map_frames(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_initial,
                         const MappingOptions& options, const MappingProgress& progress = {});

}  // namespace carat
