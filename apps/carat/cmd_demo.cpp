// carat demo [--frames N] [--seed S] [--residuals M] [--out DIR] [--json]: the main job on the
// built-in synthetic world. Simulates a LiDAR drive twice around a city block, runs GICP
// odometry from a drifting wheel-odometry guess, builds the dense graph of overlapping pairs,
// and compares PGO (identity), PGO (Hessian), GRE full, GRE exact (M), GRE random and GRE
// lossless: ATE against the ground truth, iterations, time breakdown and memory. Writes
// trajectories (KITTI, TUM) and SVG pictures to --out.
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/output_folder.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/sim/pipeline.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "loops_report.hpp"
#include "mapping_methods.hpp"
#include "mapping_output.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

/// carat's GRE setting for the demo: a second correspondence search at the first solve's poses,
/// and the excess Cauchy kernel (chosen on seeds 1-4 of the demo world, checked on seeds 5-8).
constexpr int kDefaultRounds = 2;
constexpr double kDefaultExcessCauchy = 0.3;

struct DemoArgs {
  int frames = 100;
  std::uint64_t seed = 1;
  int residuals = 29;
  std::string out = "carat-demo";
  std::string initial = "odometry";
  double overlap = 0.2;
  int rounds = kDefaultRounds;
  double max_distance = 1.0;
  double pgo_cauchy = 1.0;
  double gre_cauchy = 0.0;
  double gre_excess_cauchy = kDefaultExcessCauchy;
  bool paper = false;
  int threads = 0;
  bool json = false;
};

/// Heading drift of `--initial drift`, degrees per metre travelled.
constexpr double kDriftHeadingBiasDeg = 0.1;

/// A setting as printf's %g writes it.
std::string number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%g", value);
  return buffer;
}

/// The GRE setting in words, for the report.
std::string gre_setting(const DemoArgs& args) {
  std::string out = args.rounds == 1 ? std::string("correspondences fixed at the initial guess")
                                     : "correspondences searched in up to " +
                                           std::to_string(args.rounds) + " rounds";
  if (args.gre_excess_cauchy > 0.0) {
    out += ", excess Cauchy kernel " + number(args.gre_excess_cauchy);
  } else if (args.gre_cauchy > 0.0) {
    out += ", Cauchy kernel " + number(args.gre_cauchy) + " on each factor";
  } else {
    out += ", no kernel";
  }
  const bool paper = args.rounds == 1 && args.gre_excess_cauchy == 0.0 && args.gre_cauchy == 0.0;
  return out + (paper ? " (the paper's setting)" : " (--paper: the paper's setting)");
}

/// Memory the demo holds per frame at the default settings: the downsampled frame and, mostly,
/// its share of the full GRE factors (about 19 factors of ~270 kB per frame on the demo's drive).
constexpr double kBytesPerFrame = 6.5e6;

/// Refuses, before any work, a run this machine cannot hold.
void check_memory(const DemoArgs& args) {
  const double needed = kBytesPerFrame * args.frames;
  const double available = static_cast<double>(available_memory_bytes());
  if (needed > 0.8 * available) {
    throw UsageError("--frames " + std::to_string(args.frames) +
                     ": the demo holds every frame and " +
                     "the full GRE factors in memory, about " + format_bytes(needed) + "; " +
                     format_bytes(available) + " are available; use fewer --frames");
  }
}

/// The progress bar's label of a simulation stage.
std::string simulation_stage_label(SyntheticPipelineStage stage) {
  switch (stage) {
    case SyntheticPipelineStage::kPreprocess:
      return "simulating and preprocessing";
    case SyntheticPipelineStage::kOdometry:
      return "GICP odometry";
    case SyntheticPipelineStage::kDenseGraph:
      return "overlap assessment";
  }
  return "";
}

/// The library's options for the demo's settings (the method is set per method).
MappingOptions demo_mapping_options(const DemoArgs& args, int threads) {
  MappingOptions options;
  options.num_threads = threads;
  options.close_loops = args.initial == "drift";
  options.graph.overlap_threshold = args.overlap;
  GlobalRegistrationOptions& gre = options.registration;
  gre.residuals = args.residuals;
  gre.max_correspondence_distance = args.max_distance;
  gre.seed = args.seed;
  gre.rounds = args.rounds;
  gre.factor_cauchy_scale = args.gre_cauchy;
  gre.factor_excess_cauchy_scale = args.gre_excess_cauchy;
  options.pair_alignment.max_correspondence_distance = args.max_distance;
  options.pose_graph.cauchy_scale = args.pgo_cauchy;
  return options;
}

/// The demo's loop report: the loop step's JSON, how many accepted loops agree with the ground
/// truth, and the guess's ATE before and after the loop pose graph; *line gets it in words.
nlohmann::json demo_loops_json(const MapGraph& graph, std::span<const Eigen::Isometry3d> guess,
                               std::span<const Eigen::Isometry3d> truth, std::string* line) {
  nlohmann::json j = loops_json(graph.loops, graph.times.seconds("loops"));
  if (!graph.loops) return j;
  // Precision against the ground truth: a true loop's GICP result agrees with the true
  // relative pose.
  std::size_t correct = 0;
  for (const PairRegistration& loop : graph.loops->loops) {
    const Eigen::Isometry3d error = (truth[static_cast<std::size_t>(loop.pair.target)].inverse() *
                                     truth[static_cast<std::size_t>(loop.pair.source)])
                                        .inverse() *
                                    loop.T_target_source;
    correct += error.translation().norm() < 0.5;
  }
  const double before = compute_ate(guess, truth).rmse;
  const double after = compute_ate(graph.T_world_start, truth).rmse;
  j["accepted_correct"] = correct;
  j["ate_rmse_before"] = before;
  j["ate_rmse_after"] = after;
  *line = "  loops: " + std::to_string(graph.loops->loops.size()) + " of " +
          std::to_string(graph.loops->candidates.size()) + " Scan Context candidates accepted (" +
          std::to_string(correct) + " match the ground truth); ATE of the guess " + number(before) +
          " m -> " + number(after) + " m after the pose graph";
  return j;
}

int run_demo(const DemoArgs& args) {
  check_memory(args);
  check_output_folder("--out", args.out, {});
  OutputFolder folder(args.out, "carat demo");
  const int threads = thread_count(args.threads);
  nlohmann::json stages = nlohmann::json::object();

  // The world, the drive, preprocessing, the initial guess (a drifting wheel-odometry prior,
  // refined by GICP odometry by default) and the dense graph at the initial guess.
  SyntheticPipelineOptions pipeline_options;
  pipeline_options.world.seed = args.seed;
  pipeline_options.drive.frames = args.frames;
  pipeline_options.drive.laps = 2;
  pipeline_options.drift.seed = args.seed;
  pipeline_options.odometry = args.initial == "odometry";
  const bool drift = args.initial == "drift";
  if (drift) {
    // Wheel odometry whose heading drifts by 10 degrees per 100 m: the second lap starts metres
    // away from the first, so loops are closed (Scan Context, GICP, a pose graph) before the
    // dense graph is built at the result.
    pipeline_options.drift.heading_bias_deg = kDriftHeadingBiasDeg;
    pipeline_options.dense_graph = false;
  }
  pipeline_options.dense_graph = false;  // the mapping pipeline builds it
  pipeline_options.threads = threads;
  SyntheticPipeline pipeline;
  {
    StageBars<SyntheticPipelineStage> bars(simulation_stage_label, true);
    pipeline = simulate_pipeline(pipeline_options, bars.callback());
  }
  stages["simulate_s"] = pipeline.timings.simulate_s;
  stages["preprocess_s"] = pipeline.timings.preprocess_s;
  stages["initial_guess_s"] = pipeline.timings.initial_guess_s;
  const std::vector<Eigen::Isometry3d> truth = std::move(pipeline.T_world_truth);
  const std::vector<Eigen::Isometry3d> guess = std::move(pipeline.T_world_initial);
  FrameStore store(std::move(pipeline.frames));

  // Loops (with --initial drift) and the dense graph at the start, then every method on it.
  const MappingOptions options = demo_mapping_options(args, threads);
  MapGraph graph;
  {
    StageBars<MappingStage> bars(mapping_stage_label, !args.json);
    graph = build_map_graph(store, guess, options, bars.callback());
  }
  if (graph.loops) stages["loops_s"] = graph.times.seconds("loops");
  stages["dense_graph_s"] = graph.times.seconds("dense_graph");
  std::string loops_line;
  const nlohmann::json loops = demo_loops_json(graph, guess, truth, &loops_line);
  const std::vector<std::size_t> frame_points = store.frame_points();
  std::size_t points = 0;
  for (const std::size_t n : frame_points) points += n;
  check_full_factor_memory(frame_points, graph.pairs, "raise --overlap or use fewer --frames");
  std::vector<MethodResult> results;
  std::vector<PairRegistration> registrations;  // shared by the two PGO baselines
  for (PoseGraphInformation information :
       {PoseGraphInformation::kIdentity, PoseGraphInformation::kHessian}) {
    results.push_back(
        run_method(store, graph, pose_graph_method(options, information), true, &registrations));
  }
  for (ResidualSampling sampling : {ResidualSampling::kFull, ResidualSampling::kExact,
                                    ResidualSampling::kRandom, ResidualSampling::kLossless})
    results.push_back(run_method(store, graph, registration_method(options, sampling), true));
  const AteStatistics initial_ate = compute_ate(guess, truth);
  for (MethodResult& r : results) r.ate = compute_ate(r.T_world_frame, truth);

  // Files, into the temporary folder that becomes --out when all are written.
  const std::filesystem::path dir = folder.path();
  std::vector<std::filesystem::path> written;
  for (const auto& p : write_trajectory_pair(dir, "ground_truth", truth)) written.push_back(p);
  for (const auto& p : write_trajectory_pair(dir, "initial", guess)) written.push_back(p);
  for (const MethodResult& r : results)
    for (const auto& p : write_trajectory_pair(dir, r.key, r.T_world_frame)) written.push_back(p);
  const MethodResult* exact = &results[3];
  for (const auto& p : write_mapping_pictures(dir, truth, guess, results, graph.pairs, exact))
    written.push_back(p);

  nlohmann::json j;
  j["frames"] = store.size();
  j["factors"] = graph.pairs.size();
  j["seed"] = args.seed;
  j["residuals"] = args.residuals;
  j["threads"] = threads;
  j["points_raw"] = pipeline.raw_points;
  j["points_downsampled"] = points;
  j["initial"] = args.initial;
  j["gre_rounds"] = args.rounds;
  j["gre_excess_cauchy"] = args.gre_excess_cauchy;
  j["gre_cauchy"] = args.gre_cauchy;
  j["pgo_cauchy"] = args.pgo_cauchy;
  j["loops"] = loops;
  j["initial_ate_rmse"] = initial_ate.rmse;
  j["initial_ate_mean"] = initial_ate.mean;
  j["initial_ate_std"] = initial_ate.std;
  j["stages"] = stages;
  j["methods"] = nlohmann::json::array();
  for (const MethodResult& r : results) j["methods"].push_back(to_json(r));
  nlohmann::json files = nlohmann::json::array();
  for (const auto& p : written)
    files.push_back((std::filesystem::path(args.out) / p.filename()).string());
  j["files"] = files;
  written.push_back(dir / "demo.json");
  write_file_atomically(dir / "demo.json", [&](std::ostream& out) { out << j.dump(2) << '\n'; });

  if (args.json) {
    std::printf("%s\n", j.dump(2).c_str());
    flush_standard_output();  // the report is out: now the files go into place
    folder.commit();
    return 0;
  }
  std::printf("carat demo: synthetic city, %zu LiDAR frames (2 laps), seed %llu, %d threads\n",
              store.size(), static_cast<unsigned long long>(args.seed), threads);
  std::printf("  %zu points simulated, %zu after 0.5 m downsampling\n", pipeline.raw_points,
              points);
  std::printf("  initial guess (%s): ATE %.4f ± %.4f m (RMSE %.4f)\n", args.initial.c_str(),
              initial_ate.mean, initial_ate.std, initial_ate.rmse);
  if (!loops_line.empty()) std::printf("%s\n", loops_line.c_str());
  std::printf("  dense graph: %zu factors (overlap >= %.2f, plus consecutive pairs)\n",
              graph.pairs.size(), args.overlap);
  std::printf("  GRE: %s\n\n", gre_setting(args).c_str());
  std::printf("%s\n", results_table(results).c_str());
  std::printf("Time breakdown [s]\n");
  for (const MethodResult& r : results) {
    std::printf("  %-20s", r.label.c_str());
    for (const auto& [stage, seconds] : r.breakdown)
      std::printf(" %s %.3f", stage.c_str(), seconds);
    std::printf("\n");
  }
  std::printf("\nWrote %zu files to %s/ (trajectories, SVG pictures, demo.json)\n", written.size(),
              args.out.c_str());
  flush_standard_output();  // the report is out: now the files go into place
  folder.commit();
  return 0;
}

}  // namespace

void register_demo(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo", "Run the main job: dense global registration on the built-in synthetic world");
  cmd->add_option("--frames", args->frames, "LiDAR frames (two laps of the circuit)")
      ->check(integer_in(12, 100000))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "random seed of the world, noise and drift")
      ->check(seed_value())
      ->capture_default_str();
  cmd->add_option("--residuals", args->residuals, "M: residual rows kept per factor")
      ->check(integer_in(29, 100000))
      ->capture_default_str();
  cmd->add_option("--out", args->out,
                  "folder for trajectories, pictures and demo.json (an earlier carat output there "
                  "is replaced whole)")
      ->check(path_value())
      ->capture_default_str();
  cmd->add_option("--initial", args->initial,
                  "initial guess: GICP odometry from a drifting prior, or the drift itself (10 "
                  "degrees of heading drift per 100 m), whose loops are closed first")
      ->check(CLI::IsMember({"odometry", "drift"}))
      ->capture_default_str();
  cmd->add_option("--overlap", args->overlap, "overlap threshold of the dense graph")
      ->check(real_in(0.01, 1.0))
      ->capture_default_str();
  CLI::Option* rounds =
      cmd->add_option("--rounds", args->rounds,
                      "GRE correspondence rounds (1: fixed at the initial guess, as in the paper)")
          ->check(integer_in(1, 100))
          ->capture_default_str();
  cmd->add_option("--max-distance", args->max_distance, "correspondence distance (m)")
      ->check(real_in(0.05, 100.0))
      ->capture_default_str();
  cmd->add_option("--pgo-cauchy", args->pgo_cauchy,
                  "Cauchy scale of the PGO baselines on the whitened error (0: no kernel)")
      ->check(zero_or_real_in(1e-6, 1e9))
      ->capture_default_str();
  CLI::Option* gre_cauchy =
      cmd->add_option("--gre-cauchy", args->gre_cauchy,
                      "Cauchy scale on each GRE factor's whole error (0: none, as in the paper)")
          ->check(zero_or_real_in(1e-6, 1e9))
          ->capture_default_str();
  CLI::Option* excess =
      cmd->add_option("--gre-excess-cauchy", args->gre_excess_cauchy,
                      "Cauchy scale on each GRE factor's error above its own minimum, in the units "
                      "of the PGO kernel (0: none, as in the paper; off when --gre-cauchy is set)")
          ->check(zero_or_real_in(1e-6, 1e9))
          ->excludes(gre_cauchy)
          ->capture_default_str();
  cmd->add_flag("--paper", args->paper,
                "the paper's GRE: correspondences fixed at the initial guess and no kernel on the "
                "GRE factors (--rounds 1 --gre-excess-cauchy 0)")
      ->excludes(rounds)
      ->excludes(excess)
      ->excludes(gre_cauchy);
  cmd->add_option("--threads", args->threads, "threads (0: all cores)")
      ->check(integer_in(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args, excess] {
    DemoArgs settled = *args;
    if (settled.paper) {
      settled.rounds = 1;
      settled.gre_excess_cauchy = 0.0;
    } else if (settled.gre_cauchy > 0.0 && excess->count() == 0) {
      settled.gre_excess_cauchy = 0.0;  // one kernel at a time: the one asked for
    }
    return run_demo(settled);
  });
}

}  // namespace carat::cli
