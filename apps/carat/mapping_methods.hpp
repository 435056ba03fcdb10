#pragma once

// The global-mapping methods that `carat demo` and `carat map` run and compare: the pose-graph
// baselines and global registration error minimization with full, exact or random residuals.

#include <Eigen/Geometry>
#include <filesystem>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/registration/pose_graph_baseline.hpp"
#include "carat/registration/trajectory_error.hpp"

namespace carat::cli {

/// What every method starts from.
struct MappingInput {
  std::vector<std::shared_ptr<const Frame>> frames;  // preprocessed scans (empty with a store)
  std::shared_ptr<FrameStore> store;  // frames read on demand instead of `frames`, when set
  std::vector<FramePair> pairs;       // the dense graph
  std::vector<Eigen::Isometry3d> T_world_initial;  // initial guess
  int threads = 1;                                 // threads for every stage
  std::uint64_t seed = 1;                          // coreset / random sampling seed
  int residuals = 29;                              // M
  double max_correspondence_distance = 1.0;        // metres
  int rounds = 1;                                  // GRE correspondence rounds
  double pgo_cauchy_scale = 1.0;                   // Cauchy scale of the PGO baselines
  double gre_cauchy_scale = 0.0;                   // Cauchy scale per GRE factor (0: none)
  double gre_excess_cauchy_scale = 0.0;  // Cauchy scale on each GRE factor's excess (0: none)
  bool progress = true;                  // progress bars on a terminal
  bool covariance = false;               // every pose's covariance after the solve
  // When set, GRE builds each round's factors (parallel to the pairs) with this instead of from
  // `frames` (carat map under MPI: over the ranks).
  std::function<std::vector<RegistrationFactor>(std::span<const FramePair>,
                                                std::span<const Eigen::Isometry3d>,
                                                const GlobalRegistrationOptions&)>
      build_factors;
};

/// One method's result and costs.
struct MethodResult {
  std::string key;                               // e.g. "gre_exact"
  std::string label;                             // e.g. "GRE exact (M=29)"
  std::vector<Eigen::Isometry3d> T_world_frame;  // optimized poses
  double time_s = 0.0;                           // optimization: GRE compression + solve; PGO solve
  double total_s = 0.0;  // everything after the dense graph: + correspondences / pairwise GICP
  std::vector<std::pair<std::string, double>> breakdown;  // stage -> seconds
  std::size_t memory_bytes = 0;                  // residual data held during the optimization
  std::size_t correspondence_bytes = 0;          // correspondence data built (GRE), 0 for PGO
  int iterations = 0;                            // solver iterations
  std::string termination;                       // solver termination
  std::vector<double> factor_costs;              // per pair, for the graph picture (GRE)
  std::vector<std::size_t> factor_memory_bytes;  // per factor: residual data held
  std::vector<std::size_t> factor_correspondence_bytes;  // per factor (GRE): full block built
  std::optional<AteStatistics> ate;                      // against the reference, when there is one
  std::vector<se3::Matrix6d> covariance;  // with MappingInput::covariance: per pose (first: zero)
  double covariance_s = 0.0;              // time of the covariances
};

/// GICP between every graph pair from the initial poses (shared by the PGO baselines).
std::vector<PairRegistration> register_graph_pairs(const MappingInput& input);

/// A pose-graph baseline over the registered pairs; its registration time is the pairs' own
/// alignment times shared over the threads.
MethodResult run_pose_graph(const MappingInput& input,
                            const std::vector<PairRegistration>& registrations,
                            PoseGraphInformation information);

/// Global registration error minimization with the given sampling; `on_iteration`, when set,
/// sees the poses at every LM iteration.
MethodResult run_registration(const MappingInput& input, ResidualSampling sampling,
                              const RegistrationIterationCallback& on_iteration = {});

/// The result as a JSON object (ate_* fields only when ate is set).
nlohmann::json to_json(const MethodResult& result);

/// A fixed-width table: method, ATE (mean ± std, rmse), iterations, times, memory.
std::string results_table(const std::vector<MethodResult>& results);

}  // namespace carat::cli
