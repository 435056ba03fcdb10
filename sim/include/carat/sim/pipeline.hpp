#pragma once

/// The synthetic mapping pipeline in one call: the world, a drive around its circuit, the
/// preprocessed frames, a drifting initial guess (optionally refined by GICP odometry) and the
/// dense graph of overlapping frame pairs at that guess.

#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <memory>
#include <vector>

#include "carat/registration/align.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/sim/circuit_options.hpp"
#include "carat/sim/drift.hpp"
#include "carat/sim/world_options.hpp"

namespace carat {

/// Settings of simulate_pipeline(); the defaults are those of `carat demo`.
struct SyntheticPipelineOptions {
  SyntheticWorldOptions world;       ///< the scene and the sensor (world.seed seeds the noise)
  SyntheticTrajectoryOptions drive;  ///< the ground-truth circuit (frames, laps)
  PreprocessOptions preprocess;      ///< downsampling and covariances of every scan
  /// The drifting initial guess: 0.02 m and 0.1 deg of std-dev per metre travelled.
  DriftOptions drift{.seed = 1, .translation_sigma = 0.02, .rotation_sigma_deg = 0.1};
  bool odometry = true;  ///< refine the drifting guess by GICP odometry
  /// GICP of the odometry: correspondences up to 2 m.
  AlignSettings odometry_settings = [] {
    AlignSettings settings;
    settings.max_correspondence_distance = 2.0;
    return settings;
  }();
  bool dense_graph = true;  ///< build the dense graph at the initial guess
  DenseGraphOptions graph;  ///< overlap test of the dense graph (its num_threads is `threads`)
  int threads = 1;          ///< threads of every stage (>= 1)
};

/// Stages of simulate_pipeline(), in order, as the progress callback names them.
enum class SyntheticPipelineStage {
  kPreprocess,  ///< scans simulated and preprocessed (done, total frames)
  kOdometry,    ///< GICP odometry (done, total frames)
  kDenseGraph,  ///< overlap assessment (done, total pairs tested)
};

/// Progress of simulate_pipeline(): (stage, done, total).
using SyntheticPipelineProgress =
    std::function<void(SyntheticPipelineStage, std::size_t, std::size_t)>;

/// Wall-clock seconds of each stage of simulate_pipeline().
struct SyntheticPipelineTimings {
  double simulate_s = 0.0;       ///< world and circuit
  double preprocess_s = 0.0;     ///< scans simulated and preprocessed
  double initial_guess_s = 0.0;  ///< drift and odometry
  double dense_graph_s = 0.0;    ///< overlap assessment
};

/// What simulate_pipeline() produces; poses are T_world_frame, metres, world frame of the scene.
struct SyntheticPipeline {
  std::vector<Eigen::Isometry3d> T_world_truth;      ///< ground truth of every frame
  std::vector<std::shared_ptr<const Frame>> frames;  ///< preprocessed scans, sensor frame
  std::vector<Eigen::Isometry3d> T_world_drift;      ///< the drifting guess
  std::vector<Eigen::Isometry3d> T_world_initial;    ///< drift refined by odometry (if enabled)
  std::vector<FramePair> pairs;      ///< dense graph at T_world_initial (if enabled)
  std::size_t raw_points = 0;        ///< points of all scans before downsampling
  SyntheticPipelineTimings timings;  ///< seconds per stage
};

/// Runs the pipeline: frame k is scanned with noise seed synthetic_frame_noise_seed(world.seed,
/// k) and preprocessed (raw scans are never all held), the guess is apply_drift() of the truth,
/// then run_odometry() from it, then build_dense_graph() at the result. Deterministic; the
/// result does not depend on the number of threads. Throws carat::Error as the stages do.
SyntheticPipeline simulate_pipeline(const SyntheticPipelineOptions& options,
                                    const SyntheticPipelineProgress& progress = {});

}  // namespace carat
