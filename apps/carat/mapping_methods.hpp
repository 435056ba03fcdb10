#pragma once

// The global-mapping methods that `carat demo`, `carat map` and `carat paper` run and compare
// (the pose-graph baselines and global registration error minimization with full, exact, random
// or lossless residuals), as rows of their reports. The pipeline itself is the library's
// (carat/registration/mapping.hpp).

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
#include "carat/registration/mapping.hpp"
#include "carat/registration/pair_registration.hpp"
#include "carat/registration/pose_graph_baseline.hpp"
#include "carat/registration/trajectory_error.hpp"

namespace carat::cli {

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
  std::vector<se3::Matrix6d> covariance;  // with the method's covariance option: per pose
  double covariance_s = 0.0;              // time of the covariances
};

/// The progress bar's label of a mapping stage.
std::string mapping_stage_label(MappingStage stage);

/// Refuses (UsageError) a GRE run with full factors that this machine cannot hold: a factor
/// holds at most 96 bytes per source point (`points`: per frame, after downsampling). `advice`
/// closes the message, e.g. "use --sampling exact".
void check_full_factor_memory(std::span<const std::size_t> points, std::span<const FramePair> pairs,
                              const std::string& advice);

/// `options` with GRE and `sampling` as the method.
MappingOptions registration_method(MappingOptions options, ResidualSampling sampling);

/// `options` with a pose-graph baseline of `information` as the method.
MappingOptions pose_graph_method(MappingOptions options, PoseGraphInformation information);

/// A mapping result as a row of the report: method key and label, times (PGO's registration
/// time is the pairs' own alignment times shared over the threads), memory, iterations.
MethodResult describe_method(const MappingResult& result, const MappingOptions& options);

/// Runs `options`' method on `graph` (progress bars on a terminal when `progress`) and
/// describes it. PGO: `*registrations`, when given and not empty, are the pairs' GICP results to
/// use; when given and empty, they are filled with those this run computed.
MethodResult run_method(FrameStore& frames, const MapGraph& graph, const MappingOptions& options,
                        bool progress, std::vector<PairRegistration>* registrations = nullptr);

/// The result as a JSON object (ate_* fields only when ate is set).
nlohmann::json to_json(const MethodResult& result);

/// A fixed-width table: method, ATE (mean ± std, rmse), iterations, times, memory.
std::string results_table(const std::vector<MethodResult>& results);

}  // namespace carat::cli
