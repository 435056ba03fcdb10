// carat map --frames DIR (--poses FILE | --initial FILE | both) [--poses-format kitti|tum|graph]
//           [--initial-format F] [--loops | --no-loops] [--method gre|pgo]
//           [--sampling exact|random|full|lossless] [--residuals M] [--perturb-m X --perturb-deg Y]
//           [--seed S] [--out FILE] [--covariance FILE] [--json]
// Global trajectory optimization on real scans. The start is --initial (an odometry file), or
// the reference --poses, optionally perturbed (frame 0 stays: it is the gauge). With --loops
// (the default when --initial is given) loops are closed first: Scan Context candidates
// validated by GICP and a pose graph of odometry and loops. Then the dense graph of overlapping
// pairs at the start, and the registration errors of all pairs (gre) or a pose graph of pairwise
// GICP results (pgo) optimized. Reports the ATE against --poses when given, and writes the
// optimized trajectory to --out.
#include <cstdint>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/scan_opening.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "covariance_output.hpp"
#include "loops_report.hpp"
#include "map_trajectories.hpp"
#include "mapping_methods.hpp"
#include "mpi_map.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

struct MapArgs : MapTrajectoryArgs {
  bool loops = false;
  bool no_loops = false;
  std::string bin_format = "auto";
  std::string method = "gre";
  std::string sampling = "exact";
  std::string information = "hessian";
  int residuals = 29;
  double voxel = 0.25;
  double overlap = 0.2;
  double max_distance = 1.0;
  int rounds = 10;
  double gre_excess_cauchy = 0.0;
  std::string out;
  CovarianceRequest covariance;
  int threads = 0;
  bool drop_non_finite = false;
  double max_frame_memory_mb = 0.0;   // 0: every frame in memory
  double max_system_memory_mb = 0.0;  // 0: 80 % of the memory available
  bool mpi_solver_only = false;       // under mpirun: rank 0 holds no factor
  bool json = false;
};

/// Refuses options that do not apply to the run asked for (they would be silently ignored) and
/// contradictions; returns whether loops are closed.
bool check_arguments(const CLI::App& command, const MapArgs& args, bool mpi) {
  const ResidualSampling sampling = parse_residual_sampling(args.sampling);
  const bool gre = args.method == "gre";
  for (const char* option : {"--sampling", "--residuals", "--rounds", "--gre-excess-cauchy"}) {
    refuse_unused(command, option, gre, "to --method pgo");
  }
  refuse_unused(command, "--information", !gre, "to --method gre (it sets the PGO factors)");
  refuse_unused(command, "--residuals",
                sampling == ResidualSampling::kExact || sampling == ResidualSampling::kRandom,
                "to --sampling " + args.sampling);
  if (mpi) check_mpi_applicable(args.method, sampling);
  refuse_unused(command, "--mpi-solver-only", mpi, "outside mpirun (2 or more ranks)");
  const bool has_initial = !args.initial.empty();
  if (args.poses.empty() && !has_initial) {
    throw UsageError(
        "give --poses (a reference trajectory), --initial (a starting trajectory, "
        "e.g. from `carat odometry`), or both");
  }
  for (const char* option : {"--perturb-m", "--perturb-deg"}) {
    refuse_unused(command, option, !has_initial, "with --initial (the start is given)");
  }
  if (args.loops && args.no_loops) throw UsageError("--loops and --no-loops exclude each other");
  refuse_unused(command, "--no-loops", has_initial,
                "without --initial (the loop step is off unless --loops asks for it)");
  refuse_unused(command, "--initial-format", has_initial, "without --initial");
  return has_initial ? !args.no_loops : args.loops;
}

/// The library's options for the command line's settings.
MappingOptions mapping_options(const MapArgs& args, int threads, bool run_loops) {
  MappingOptions options;
  options.num_threads = threads;
  options.close_loops = run_loops;
  options.loops.max_correspondence_distance = args.max_distance;
  options.graph.overlap_threshold = args.overlap;
  options.method = parse_mapping_method(args.method);
  GlobalRegistrationOptions& gre = options.registration;
  gre.sampling = parse_residual_sampling(args.sampling);
  gre.residuals = args.residuals;
  gre.max_correspondence_distance = args.max_distance;
  gre.seed = args.seed;
  gre.rounds = args.rounds;
  gre.factor_excess_cauchy_scale = args.gre_excess_cauchy;
  gre.covariance = !args.covariance.path.empty();
  options.pair_alignment.max_correspondence_distance = args.max_distance;
  options.pose_graph.information = parse_pose_graph_information(args.information);
  options.pose_graph.covariance = gre.covariance;
  // The cap of every solve's linear system (the map's, the loop pose graph's, PGO's).
  const double system_bytes = args.max_system_memory_mb * 1024.0 * 1024.0;
  gre.solver.max_linear_system_bytes = system_bytes;
  options.pose_graph.solver.max_linear_system_bytes = system_bytes;
  options.loops.graph.solver.max_linear_system_bytes = system_bytes;
  return options;
}

/// The scans of --frames as frames: all read now, or on demand under --max-frame-memory (or
/// on demand without a cap when `on_demand`: rank 0 of an MPI job reads only the frames of its
/// shares).
std::shared_ptr<FrameStore> open_frames(const MapArgs& args, const std::vector<ScanFile>& files,
                                        int threads, bool on_demand, OpenScansOptions* scans) {
  scans->read.drop_non_finite = args.drop_non_finite;
  scans->preprocess.voxel_size = args.voxel;
  scans->num_threads = threads;
  const double cap = args.max_frame_memory_mb * 1024.0 * 1024.0;
  scans->max_bytes = static_cast<std::size_t>(cap);
  if (scans->max_bytes == 0 && on_demand) scans->max_bytes = SIZE_MAX;
  ProgressBar bar("reading and preprocessing", scans->max_bytes == 0);
  std::shared_ptr<FrameStore> store = open_scans(files, *scans, bar.callback());
  // A cap that cannot hold the two frames of one factor cannot build any: say so up front.
  if (scans->max_bytes > 0 && scans->max_bytes != SIZE_MAX) {
    const std::size_t pair_bytes = store->get(0)->memory_bytes() + store->get(1)->memory_bytes();
    if (static_cast<double>(pair_bytes) > cap) {
      char text[32];
      std::snprintf(text, sizeof(text), "%g", args.max_frame_memory_mb);
      throw UsageError("--max-frame-memory " + std::string(text) +
                       " MB cannot hold one pair of frames: " + files[0].path.filename().string() +
                       " and " + files[1].path.filename().string() + " take " +
                       format_bytes(static_cast<double>(pair_bytes)));
    }
  }
  return store;
}

/// The JSON report's fields beside the method's own.
void add_run_json(nlohmann::json* j, const MapArgs& args, const MappingResult& map,
                  FrameStore& store, const std::optional<AteStatistics>& initial_ate,
                  bool can_align) {
  (*j)["frames"] = store.size();
  (*j)["factors"] = map.graph.pairs.size();
  if (!store.resident()) {
    const FrameStoreStats stats = store.stats();
    const nlohmann::json cap =
        stats.max_bytes == SIZE_MAX ? nlohmann::json(nullptr) : nlohmann::json(stats.max_bytes);
    (*j)["frame_store"] = {{"max_bytes", cap},
                           {"requests", stats.requests},
                           {"hits", stats.hits},
                           {"loads", stats.loads},
                           {"point_loads", stats.point_loads},
                           {"evictions", stats.evictions},
                           {"peak_bytes", stats.peak_bytes}};
  }
  (*j)["peak_rss_bytes"] = peak_rss_bytes();
  (*j)["start"] = args.initial.empty() ? "reference" : "initial";
  if (initial_ate) {
    (*j)["initial_ate_rmse"] = initial_ate->rmse;
    (*j)["initial_ate_mean"] = initial_ate->mean;
    (*j)["initial_ate_rotation_rmse_deg"] = initial_ate->rotation_rmse_deg;
    (*j)["ate_aligned"] = can_align;
  }
  (*j)["dense_graph_s"] = map.times.seconds("dense_graph");
}

/// The text report's lines above the results table.
void print_run(const MapArgs& args, const MappingResult& map, FrameStore& store,
               const std::optional<AteStatistics>& initial_ate) {
  std::printf("carat map: %zu frames from %s, %zu factors in the dense graph\n", store.size(),
              args.frames.c_str(), map.graph.pairs.size());
  if (!store.resident()) {
    const FrameStoreStats stats = store.stats();
    const std::string cap = stats.max_bytes == SIZE_MAX
                                ? std::string("without a cap")
                                : "under " + format_bytes(static_cast<double>(stats.max_bytes));
    std::printf(
        "  frames read on demand %s: %zu reads for %zu requests (and %zu of points alone), at "
        "most %s held\n",
        cap.c_str(), stats.loads, stats.requests, stats.point_loads,
        format_bytes(static_cast<double>(stats.peak_bytes)).c_str());
  }
  if (initial_ate && !args.initial.empty()) {
    std::printf("  start (%s): ATE RMSE %.4f m, %.3f deg\n", args.initial.c_str(),
                initial_ate->rmse, initial_ate->rotation_rmse_deg);
  } else if (initial_ate) {
    std::printf("  start (perturbed by %.3g m / %.3g deg): ATE RMSE %.4f m, %.3f deg\n",
                args.perturb_m, args.perturb_deg, initial_ate->rmse,
                initial_ate->rotation_rmse_deg);
  } else {
    std::printf("  start: %s (no --poses: no ATE)\n", args.initial.c_str());
  }
  std::printf("%s\n", map.graph.loops ? loops_line(*map.graph.loops).c_str()
                                      : "  loops: not searched (--loops searches them)");
}

int run_map(const CLI::App& command, const MapArgs& args) {
  // Under mpirun every rank but 0 only builds the factors rank 0 asks for (mpi_map.hpp).
  const std::unique_ptr<MpiMapJob> mpi = MpiMapJob::start();
  if (mpi && mpi->rank() > 0) return mpi->serve(thread_count(args.threads));
  const int threads = thread_count(args.threads);
  const bool run_loops = check_arguments(command, args, mpi != nullptr);
  const std::vector<ScanFile> files =
      list_scan_folder(args.frames, parse_bin_layout(args.bin_format));
  std::vector<NamedInput> inputs;
  if (!args.poses.empty()) inputs.push_back({"--poses", args.poses});
  if (!args.initial.empty()) inputs.push_back({"--initial", args.initial});
  for (const ScanFile& file : files) inputs.push_back({"--frames", file.path.string()});
  check_covariance_request(command, args.covariance, inputs, "--out", args.out);
  if (!args.out.empty()) {
    check_output_file("--out", args.out, inputs);
    check_output_outside_folder("--out", args.out, {"--frames", args.frames});
  }
  if (files.size() < 2) throw Error(args.frames + ": at least 2 frames are needed");
  const MapTrajectories t = read_map_trajectories(args, files);
  std::unique_ptr<OutputFile> out_file;
  if (!args.out.empty()) out_file = std::make_unique<OutputFile>(args.out);

  // Open the scans, close loops and build the dense graph, then optimize.
  const Stopwatch preprocess_time;
  OpenScansOptions scans;
  const std::shared_ptr<FrameStore> store =
      open_frames(args, files, threads, mpi != nullptr, &scans);
  const double preprocess_s = preprocess_time.elapsed_s();
  MappingOptions options = mapping_options(args, threads, run_loops);
  StageBars<MappingStage> bars(mapping_stage_label, !args.json);
  if (mpi) mpi->attach({files, scans, file_sizes(files)}, store, &options, args.mpi_solver_only);
  // Under mpirun a failure of rank 0's own work (its solve: a linear system over the memory cap,
  // say) names the rank like the failures the other ranks report.
  const auto on_rank_0 = [&](auto&& stage) {
    if (!mpi) return stage();
    try {
      return stage();
    } catch (const Error& e) {
      const std::string message = e.what();
      if (message.rfind("rank ", 0) == 0) throw;
      throw Error("rank 0 of " + std::to_string(mpi->size()) + ": " + message);
    }
  };
  MapGraph graph = on_rank_0(
      [&] { return build_map_graph(*store, t.T_world_initial, options, bars.callback()); });
  bars.finish();
  const bool full = options.method == MappingMethod::kRegistration &&
                    options.registration.sampling == ResidualSampling::kFull;
  if (full) {
    check_full_factor_memory(store->frame_points(), graph.pairs,
                             "use --sampling exact or lossless, which keep a few rows per factor");
  }
  const MappingResult map =
      on_rank_0([&] { return optimize_map(*store, std::move(graph), options, bars.callback()); });
  bars.finish();
  MethodResult result = describe_method(map, options);

  // The ATE against the reference, before and after.
  const bool can_align = t.reference_poses.size() >= 3;
  AteOptions ate_options;
  ate_options.align = can_align;
  std::optional<AteStatistics> initial_ate;
  nlohmann::json loops = loops_json(map.graph.loops, map.times.seconds("loops"));
  if (!t.reference_poses.empty()) {
    initial_ate = compute_ate(t.T_world_initial, t.reference_poses, ate_options);
    result.ate = compute_ate(result.T_world_frame, t.reference_poses, ate_options);
    if (map.graph.loops) {
      loops["ate_rmse"] = compute_ate(map.graph.T_world_start, t.reference_poses, ate_options).rmse;
    }
  }

  // The outputs, complete before they go into place.
  if (out_file) {
    Trajectory optimized;
    optimized.stamps = t.start.stamps;
    optimized.ids = t.start.ids;
    for (const Eigen::Isometry3d& T : result.T_world_frame)
      optimized.poses.push_back(t.T_world_anchor * T);
    try {
      out_file->stream() << format_trajectory(optimized, t.out_format);
    } catch (const Error& e) {
      throw Error(args.out + ": " + e.what());
    }
  }
  std::unique_ptr<OutputFile> covariance_file;
  if (!args.covariance.path.empty()) {
    covariance_file = std::make_unique<OutputFile>(args.covariance.path);
    for (std::size_t k = 1; k < result.covariance.size(); ++k) {  // frame 0 is held constant
      write_covariance_line(covariance_file->stream(), static_cast<std::int64_t>(k),
                            result.covariance[k]);
    }
  }

  // The report.
  if (args.json) {
    nlohmann::json j = to_json(result);
    add_run_json(&j, args, map, *store, initial_ate, can_align);
    j["loops"] = loops;
    j["preprocess_s"] = preprocess_s;
    if (!args.out.empty()) j["out"] = args.out;
    if (covariance_file) {
      j["covariance"] = args.covariance.path;
      j["covariance_s"] = result.covariance_s;
    }
    if (mpi) j["mpi"] = mpi->report();
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    print_run(args, map, *store, initial_ate);
    if (mpi) std::printf("%s\n", mpi->summary_line().c_str());
    std::printf("%s", results_table({result}).c_str());
    if (result.ate) {
      std::printf("  rotation ATE RMSE %.4f deg; termination %s\n", result.ate->rotation_rmse_deg,
                  result.termination.c_str());
    } else {
      std::printf("  termination %s\n", result.termination.c_str());
    }
    if (!args.out.empty()) std::printf("  wrote %s\n", args.out.c_str());
    if (covariance_file) {
      std::printf("  wrote %s (covariances of frames 1..%zu, %.3f s)\n",
                  args.covariance.path.c_str(), result.covariance.size() - 1, result.covariance_s);
    }
  }
  flush_standard_output();  // the report is out: now the outputs go into place
  if (out_file) out_file->commit();
  if (covariance_file) covariance_file->commit();
  return 0;
}

}  // namespace

void register_map(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<MapArgs>();
  CLI::App* cmd =
      app.add_subcommand("map", "Optimize a trajectory over real scans by dense registration");
  cmd->add_option("--frames", args->frames,
                  "folder of scans (*.bin|*.pcd|*.ply or */points.bin, in natural name order)")
      ->check(path_value())
      ->required();
  cmd->add_option("--poses", args->poses,
                  "reference trajectory: T_world_frame per frame (graph.txt: by vertex id); the "
                  "start unless --initial is given, and the reference of the ATE")
      ->check(path_value());
  cmd->add_option("--initial", args->initial,
                  "start from this trajectory (odometry: `carat odometry`, KITTI / TUM / graph)")
      ->check(path_value());
  cmd->add_option("--initial-format", args->initial_format,
                  "format of --initial and of --out (default: --poses-format)")
      ->check(CLI::IsMember({"kitti", "tum", "graph"}));
  cmd->add_flag("--loops", args->loops,
                "close loops first: Scan Context candidates, GICP validation, a pose graph "
                "(default with --initial)");
  cmd->add_flag("--no-loops", args->no_loops, "do not search for loops (with --initial)");
  cmd->add_option("--poses-format", args->poses_format,
                  "format of --poses (and of --out when there is no --initial)")
      ->check(CLI::IsMember({"kitti", "tum", "graph"}))
      ->capture_default_str();
  cmd->add_option("--bin-format", args->bin_format,
                  "records of .bin scans (auto: xyz for */points.bin, else xyzi)")
      ->check(CLI::IsMember({"auto", "xyz", "xyzi"}))
      ->capture_default_str();
  cmd->add_option("--method", args->method, "gre: registration errors; pgo: pose graph")
      ->check(CLI::IsMember({"gre", "pgo"}))
      ->capture_default_str();
  cmd->add_option("--sampling", args->sampling,
                  "gre: rows kept per factor (exact: M-row coreset; lossless: <= 13 rows with the "
                  "full factor's cost at every pose)")
      ->check(CLI::IsMember({"exact", "random", "full", "lossless"}))
      ->capture_default_str();
  cmd->add_option("--information", args->information, "pgo: factor information")
      ->check(CLI::IsMember({"hessian", "identity"}))
      ->capture_default_str();
  cmd->add_option("--residuals", args->residuals, "M: rows kept per factor")
      ->check(integer_in(29, 100000))
      ->capture_default_str();
  cmd->add_option("--voxel", args->voxel, "downsampling voxel (m)")
      ->check(real_in(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--overlap", args->overlap, "overlap threshold of the dense graph")
      ->check(real_in(0.01, 1.0))
      ->capture_default_str();
  cmd->add_option("--max-distance", args->max_distance, "correspondence distance (m)")
      ->check(real_in(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--rounds", args->rounds, "gre: correspondence rounds (1: fixed at the start)")
      ->check(integer_in(1, 1000))
      ->capture_default_str();
  cmd->add_option("--gre-excess-cauchy", args->gre_excess_cauchy,
                  "gre: Cauchy scale on each factor's error above its own minimum (0: none, as "
                  "in the paper)")
      ->check(zero_or_real_in(1e-6, 1e9))
      ->capture_default_str();
  cmd->add_option("--perturb-m", args->perturb_m, "perturb poses 1.. by this translation (m)")
      ->check(real_in(0.0, 100.0))
      ->capture_default_str();
  cmd->add_option("--perturb-deg", args->perturb_deg, "... and this rotation (degrees)")
      ->check(real_in(0.0, 180.0))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the perturbation and sampling")
      ->check(seed_value())
      ->capture_default_str();
  cmd->add_option("--out", args->out,
                  "write the optimized trajectory here (format of --poses; never one of the "
                  "inputs)")
      ->check(path_value());
  add_covariance_options(cmd, &args->covariance,
                         "every frame's pose but the first (by its index in scan order, from 0)",
                         "");
  cmd->add_option("--threads", args->threads, "threads (0: all cores)")
      ->check(integer_in(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--drop-non-finite", args->drop_non_finite,
                "drop NaN / Inf points while reading (default: they are an error)");
  cmd->add_option("--max-frame-memory", args->max_frame_memory_mb,
                  "read frames on demand and keep at most this many MB of them (0: read every "
                  "frame once and keep all)")
      ->check(zero_or_real_in(1.0, 1e9))
      ->capture_default_str();
  cmd->add_option("--max-system-memory", args->max_system_memory_mb,
                  "most MB a solve's linear system (matrix and factor) may take; a larger one "
                  "ends the run with its estimate (0: 80 % of the memory available)")
      ->check(zero_or_real_in(1e-3, 1e9, "80 % of the memory available"))
      ->capture_default_str();
  cmd->add_flag("--mpi-solver-only", args->mpi_solver_only,
                "under mpirun: rank 0 builds and holds no factor, the other ranks share them all "
                "(the same result)");
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args, cmd] { return run_map(*cmd, *args); });
}

}  // namespace carat::cli
