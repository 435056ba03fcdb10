#include "carat/registration/mapping.hpp"

#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"

namespace carat {
namespace {

/// The options with num_threads copied into every stage.
MappingOptions threaded(const MappingOptions& options) {
  if (options.num_threads < 1) {
    throw Error("mapping: num_threads must be >= 1, got " + std::to_string(options.num_threads));
  }
  MappingOptions out = options;
  const int threads = options.num_threads;
  out.loops.num_threads = threads;
  out.graph.num_threads = threads;
  out.registration.num_threads = threads;
  out.registration.solver.num_threads = threads;
  out.pose_graph.solver.num_threads = threads;
  return out;
}

/// The progress of one stage as a (done, total) callback; empty when there is none.
std::function<void(std::size_t, std::size_t)> stage_progress(const MappingProgress& progress,
                                                             MappingStage stage) {
  if (!progress) return {};
  return [progress, stage](std::size_t done, std::size_t total) { progress(stage, done, total); };
}

/// GRE over the graph.
void optimize_registration_stage(FrameStore& frames, const MappingOptions& options,
                                 const MappingProgress& progress, MappingResult* out) {
  const std::vector<FramePair>& pairs = out->graph.pairs;
  const std::vector<Eigen::Isometry3d>& start = out->graph.T_world_start;
  const GlobalRegistrationOptions& gre = options.registration;
  const GlobalRegistrationResult result =
      options.hold_factors ? optimize_held_registration(
                                 [&](std::span<const Eigen::Isometry3d> T_world_start,
                                     std::span<const std::size_t> order) {
                                   return options.hold_factors(pairs, T_world_start, order, gre);
                                 },
                                 pairs, start, gre)
      : options.build_factors
          ? optimize_registration(
                [&](std::span<const Eigen::Isometry3d> T_world_frame) {
                  return options.build_factors(pairs, T_world_frame, gre);
                },
                pairs, start, gre)
          : optimize_registration(frames, pairs, start, gre,
                                  stage_progress(progress, MappingStage::kFactors));
  out->T_world_frame = result.T_world_frame;
  out->summary = result.summary;
  out->rounds = result.rounds;
  out->factor_stats = result.stats;
  out->factor_costs = result.factor_costs;
  out->factor_residual_bytes = result.factor_residual_bytes;
  out->factor_correspondence_bytes = result.factor_correspondence_bytes;
  out->covariance = result.covariance;
  out->covariance_s = result.covariance_s;
  const RegistrationFactorStats& s = result.stats;
  out->times.add("factors", s.correspondence_s + s.compression_s + s.minimum_s);
  out->times.add("solve", result.summary.time.total_s);
}

/// PGO over the graph.
void optimize_pose_graph_stage(FrameStore& frames, const MappingOptions& options,
                               const MappingProgress& progress,
                               std::span<const PairRegistration> registrations,
                               MappingResult* out) {
  const std::vector<FramePair>& pairs = out->graph.pairs;
  const std::vector<Eigen::Isometry3d>& start = out->graph.T_world_start;
  if (registrations.empty()) {
    const Stopwatch time;
    out->registrations =
        register_pairs(frames, pairs, start, options.pair_alignment, options.num_threads,
                       stage_progress(progress, MappingStage::kPairRegistration));
    out->times.add("pair_registration", time.elapsed_s());
  } else {
    if (registrations.size() != pairs.size()) {
      throw Error("mapping: " + std::to_string(registrations.size()) + " registrations for " +
                  std::to_string(pairs.size()) + " pairs");
    }
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const FramePair& a = registrations[k].pair;
      if (a.target != pairs[k].target || a.source != pairs[k].source) {
        throw Error("mapping: registration " + std::to_string(k) + " is of frames " +
                    std::to_string(a.target) + "-" + std::to_string(a.source) + ", pair " +
                    std::to_string(k) + " of frames " + std::to_string(pairs[k].target) + "-" +
                    std::to_string(pairs[k].source));
      }
    }
    out->registrations.assign(registrations.begin(), registrations.end());
  }
  const PoseGraphBaselineResult result =
      optimize_pose_graph_baseline(start, out->registrations, options.pose_graph);
  out->T_world_frame = result.T_world_frame;
  out->summary = result.summary;
  out->unconverged_pairs = result.unconverged_pairs;
  out->covariance = result.covariance;
  out->covariance_s = result.covariance_s;
  // Every edge is one relative-pose block of the same size.
  if (!pairs.empty()) {
    out->factor_residual_bytes.assign(pairs.size(),
                                      result.summary.residual_memory_bytes / pairs.size());
  }
  out->times.add("solve", result.summary.time.total_s);
}

}  // namespace

const char* to_string(MappingMethod method) {
  return method == MappingMethod::kPoseGraph ? "pgo" : "gre";
}

MappingMethod parse_mapping_method(std::string_view name) {
  if (name == "gre") return MappingMethod::kRegistration;
  if (name == "pgo") return MappingMethod::kPoseGraph;
  throw Error("unknown mapping method " + quote_bytes(name) + " (valid: gre, pgo)");
}

SolverOptions mapping_solver_options() {
  SolverOptions options;
  options.max_iterations = 100;
  return options;
}

GlobalRegistrationOptions MappingOptions::default_registration() {
  GlobalRegistrationOptions options;
  options.solver = mapping_solver_options();
  return options;
}

PoseGraphBaselineOptions MappingOptions::default_pose_graph() {
  PoseGraphBaselineOptions options;
  options.solver = mapping_solver_options();
  return options;
}

MapGraph build_map_graph(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_initial,
                         const MappingOptions& options, const MappingProgress& progress) {
  const MappingOptions o = threaded(options);
  MapGraph out;
  out.T_world_start.assign(T_world_initial.begin(), T_world_initial.end());
  if (o.close_loops) {
    const Stopwatch time;
    out.loops = close_loops(frames, T_world_initial, o.loops,
                            stage_progress(progress, MappingStage::kLoops), o.loop_stages);
    if (!out.loops->loops.empty()) out.T_world_start = out.loops->T_world_frame;
    out.times.add("loops", time.elapsed_s());
  }
  const Stopwatch time;
  if (o.measure_overlaps) {
    if (frames.size() != out.T_world_start.size()) {
      throw Error("build_dense_graph: " + std::to_string(frames.size()) + " frames but " +
                  std::to_string(out.T_world_start.size()) + " poses");
    }
    std::vector<FramePair> candidates = dense_graph_candidates(out.T_world_start, o.graph);
    o.measure_overlaps(candidates, out.T_world_start, o.graph,
                       stage_progress(progress, MappingStage::kDenseGraph));
    out.pairs = select_dense_graph(candidates, o.graph);
  } else {
    out.pairs = build_dense_graph(frames, out.T_world_start, o.graph,
                                  stage_progress(progress, MappingStage::kDenseGraph));
  }
  out.times.add("dense_graph", time.elapsed_s());
  return out;
}

MappingResult optimize_map(FrameStore& frames, MapGraph graph, const MappingOptions& options,
                           const MappingProgress& progress,
                           std::span<const PairRegistration> registrations) {
  const MappingOptions o = threaded(options);
  MappingResult out;
  out.graph = std::move(graph);
  out.method = o.method;
  out.times = out.graph.times;
  if (o.method == MappingMethod::kPoseGraph) {
    optimize_pose_graph_stage(frames, o, progress, registrations, &out);
  } else {
    optimize_registration_stage(frames, o, progress, &out);
  }
  if (!out.covariance.empty()) out.times.add("covariance", out.covariance_s);
  return out;
}

MappingResult map_frames(FrameStore& frames, std::span<const Eigen::Isometry3d> T_world_initial,
                         const MappingOptions& options, const MappingProgress& progress) {
  return optimize_map(frames, build_map_graph(frames, T_world_initial, options, progress), options,
                      progress);
}

}  // namespace carat
