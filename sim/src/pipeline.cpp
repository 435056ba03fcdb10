#include "carat/sim/pipeline.hpp"

#include <atomic>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/odometry.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"

namespace carat {
namespace {

/// The stage's progress as the stage functions report it, or nothing.
std::function<void(std::size_t, std::size_t)> stage_progress(
    const SyntheticPipelineProgress& progress, SyntheticPipelineStage stage) {
  if (!progress) return {};
  return [&progress, stage](std::size_t done, std::size_t total) { progress(stage, done, total); };
}

}  // namespace

SyntheticPipeline simulate_pipeline(const SyntheticPipelineOptions& options,
                                    const SyntheticPipelineProgress& progress) {
  if (options.threads < 1) {
    throw Error("SyntheticPipelineOptions.threads: must be >= 1, got " +
                std::to_string(options.threads));
  }
  SyntheticPipeline out;
  Stopwatch stage_time;
  const SyntheticWorld world(options.world);
  out.T_world_truth = world.trajectory(options.drive);
  out.timings.simulate_s = stage_time.restart();

  std::atomic<std::size_t> raw_points{0};
  const std::uint64_t seed = options.world.seed;
  out.frames = preprocess_frames(
      out.T_world_truth.size(),
      [&](std::size_t k) {
        PointCloud scan = world.scan(out.T_world_truth[k], synthetic_frame_noise_seed(seed, k));
        raw_points += scan.size();
        return scan;
      },
      [](std::size_t k) { return "synthetic frame " + std::to_string(k); }, options.preprocess,
      options.threads, stage_progress(progress, SyntheticPipelineStage::kPreprocess));
  out.raw_points = raw_points.load();
  out.timings.preprocess_s = stage_time.restart();

  out.T_world_drift = apply_drift(out.T_world_truth, options.drift);
  FrameStore frames(out.frames);
  if (options.odometry) {
    out.T_world_initial =
        run_odometry(frames, out.T_world_drift, options.odometry_settings, options.threads,
                     stage_progress(progress, SyntheticPipelineStage::kOdometry))
            .T_world_frame;
  } else {
    out.T_world_initial = out.T_world_drift;
  }
  out.timings.initial_guess_s = stage_time.restart();

  if (options.dense_graph) {
    DenseGraphOptions graph = options.graph;
    graph.num_threads = options.threads;
    out.pairs = build_dense_graph(frames, out.T_world_initial, graph,
                                  stage_progress(progress, SyntheticPipelineStage::kDenseGraph));
  }
  out.timings.dense_graph_s = stage_time.elapsed_s();
  return out;
}

}  // namespace carat
