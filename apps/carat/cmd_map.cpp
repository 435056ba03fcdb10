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
#include <tbb/info.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/point_cloud_io.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/loop_closure.hpp"
#include "carat/registration/pose_graph_baseline.hpp"
#include "carat/registration/pose_perturbation.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "covariance_output.hpp"
#include "mapping_methods.hpp"
#include "mpi_map.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

namespace fs = std::filesystem;

struct MapArgs {
  std::string frames;
  std::string poses;
  std::string poses_format = "kitti";
  std::string initial;
  std::string initial_format;  // empty: --poses-format
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
  double perturb_m = 0.0;
  double perturb_deg = 0.0;
  std::uint64_t seed = 1;
  std::string out;
  CovarianceRequest covariance;
  int threads = 0;
  bool drop_non_finite = false;
  double max_frame_memory_mb = 0.0;  // 0: every frame in memory
  bool json = false;
};

/// Refuses a GRE run with full factors that this machine cannot hold: a factor holds at most 96
/// bytes per source point (`points`: per frame, after downsampling).
void check_full_factor_memory(const std::vector<std::size_t>& points,
                              const std::vector<FramePair>& pairs) {
  double bytes = 0.0;
  for (const FramePair& pair : pairs)
    bytes += 96.0 * static_cast<double>(points[static_cast<std::size_t>(pair.source)]);
  const double available = static_cast<double>(available_memory_bytes());
  if (bytes > 0.8 * available) {
    throw UsageError("--sampling full: the " + std::to_string(pairs.size()) +
                     " factors of the dense graph would take up to " + format_bytes(bytes) + "; " +
                     format_bytes(available) +
                     " are available (use --sampling exact or lossless, which keep a few rows "
                     "per factor)");
  }
}

/// Refuses options that do not apply to the method chosen (they would be silently ignored).
void check_applicable(const CLI::App& command, const MapArgs& args, ResidualSampling sampling) {
  const bool gre = args.method == "gre";
  for (const char* option : {"--sampling", "--residuals", "--rounds", "--gre-excess-cauchy"}) {
    refuse_unused(command, option, gre, "to --method pgo");
  }
  refuse_unused(command, "--information", !gre, "to --method gre (it sets the PGO factors)");
  refuse_unused(command, "--residuals",
                sampling == ResidualSampling::kExact || sampling == ResidualSampling::kRandom,
                "to --sampling " + args.sampling);
}

/// Every pose expressed relative to the first: the solver's step tests are relative to the
/// size of the values, so poses millions of metres from the origin (georeferenced maps) would
/// stop the solve at once. Results are moved back with the same transform.
std::vector<Eigen::Isometry3d> relative_to(const Eigen::Isometry3d& T_world_anchor,
                                           const std::vector<Eigen::Isometry3d>& T_world_frame) {
  const Eigen::Isometry3d T_anchor_world = T_world_anchor.inverse();
  std::vector<Eigen::Isometry3d> out;
  out.reserve(T_world_frame.size());
  for (const Eigen::Isometry3d& T : T_world_frame) out.push_back(T_anchor_world * T);
  return out;
}

int run_map(const CLI::App& command, const MapArgs& args) {
  // Under mpirun every rank but 0 only builds the factors rank 0 asks for (mpi_map.hpp).
  const std::unique_ptr<MpiMapJob> mpi = MpiMapJob::start();
  if (mpi && mpi->rank() > 0) return mpi->serve(thread_count(args.threads));
  const ResidualSampling sampling = parse_residual_sampling(args.sampling);
  const PoseGraphInformation information = parse_pose_graph_information(args.information);
  check_applicable(command, args, sampling);
  if (mpi) check_mpi_applicable(args.method, sampling);
  const int threads = thread_count(args.threads);
  const bool has_reference = !args.poses.empty();
  const bool has_initial = !args.initial.empty();
  if (!has_reference && !has_initial) {
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
  const bool run_loops = has_initial ? !args.no_loops : args.loops;
  const TrajectoryFormat format = parse_trajectory_format(args.poses_format);
  const TrajectoryFormat initial_format = parse_trajectory_format(
      args.initial_format.empty() ? args.poses_format : args.initial_format);
  const std::vector<ScanFile> files =
      list_scan_folder(args.frames, parse_bin_layout(args.bin_format));
  std::unique_ptr<OutputFile> out_file;
  std::vector<NamedInput> inputs;
  if (has_reference) inputs.push_back({"--poses", args.poses});
  if (has_initial) inputs.push_back({"--initial", args.initial});
  for (const ScanFile& file : files) inputs.push_back({"--frames", file.path.string()});
  check_covariance_request(command, args.covariance, inputs, "--out", args.out);
  if (!args.out.empty()) {
    check_output_file("--out", args.out, inputs);
    check_output_outside_folder("--out", args.out, {"--frames", args.frames});
  }
  if (files.size() < 2) throw Error(args.frames + ": at least 2 frames are needed");
  // A trajectory file with one pose per frame, in scan order.
  const auto read_for_frames = [&](const std::string& option, const std::string& path,
                                   TrajectoryFormat fmt) {
    const Trajectory given = read_trajectory(path, fmt);
    if (files.size() != given.poses.size()) {
      throw Error(option + " " + path + " has " + std::to_string(given.poses.size()) +
                  " poses but --frames " + args.frames + " holds " + std::to_string(files.size()) +
                  " frames");
    }
    return poses_in_scan_order(given, fmt, files, path);
  };
  Trajectory reference;
  if (has_reference) reference = read_for_frames("--poses", args.poses, format);
  Trajectory initial;
  if (has_initial) initial = read_for_frames("--initial", args.initial, initial_format);
  if (!args.out.empty()) out_file = std::make_unique<OutputFile>(args.out);
  // Results are written in the frame of the start (the --initial file, else the reference).
  const Trajectory& start = has_initial ? initial : reference;
  const TrajectoryFormat out_format = has_initial ? initial_format : format;
  const Eigen::Isometry3d T_world_anchor = start.poses.front();
  std::vector<Eigen::Isometry3d> reference_poses;
  if (has_reference) reference_poses = relative_to(T_world_anchor, reference.poses);

  const Stopwatch preprocess_time;
  MappingInput input;
  input.threads = threads;
  input.seed = args.seed;
  input.residuals = args.residuals;
  input.max_correspondence_distance = args.max_distance;
  input.rounds = args.rounds;
  input.gre_excess_cauchy_scale = args.gre_excess_cauchy;
  input.covariance = !args.covariance.path.empty();
  PreprocessOptions preprocess;
  preprocess.voxel_size = args.voxel;
  ReadOptions read_options;
  read_options.drop_non_finite = args.drop_non_finite;
  // Reads, checks and preprocesses scan k (every frame, whether all are read up front or on
  // demand); a scan too small as read is named by its own count, before downsampling merges any.
  const auto read_frame = [&](std::size_t k) {
    PointCloud scan = read_scan(files[k], read_options);
    if (scan.size() < static_cast<std::size_t>(preprocess.min_points)) {
      throw Error(files[k].path.string() + ": only " + std::to_string(scan.size()) +
                  " points (at least " + std::to_string(preprocess.min_points) + " are needed)");
    }
    return scan;
  };
  const auto check_frame = [](const Frame& frame) {
    if (frame.constrained_dof() < 6) {
      throw Error(frame.name() + ": the scan fixes only " +
                  std::to_string(frame.constrained_dof()) +
                  " of 6 degrees of freedom (a degenerate scene, e.g. a single plane), so its "
                  "pose cannot be determined by registration");
    }
  };
  std::vector<std::size_t> frame_points(files.size(), 0);  // after downsampling
  if (args.max_frame_memory_mb > 0.0) {
    input.store = std::make_shared<FrameStore>(
        files.size(),
        [&, read_frame, check_frame](std::size_t k) {
          auto frame = preprocess_frame(read_frame(k), preprocess, files[k].path.string());
          check_frame(*frame);
          frame_points[k] = frame->size();
          return frame;
        },
        static_cast<std::size_t>(args.max_frame_memory_mb * 1024.0 * 1024.0));
    // A cap that cannot hold the two frames of one factor cannot build any: say so up front.
    const std::size_t pair_bytes =
        input.store->get(0)->memory_bytes() + input.store->get(1)->memory_bytes();
    if (static_cast<double>(pair_bytes) > args.max_frame_memory_mb * 1024.0 * 1024.0) {
      char cap[32];
      std::snprintf(cap, sizeof(cap), "%g", args.max_frame_memory_mb);
      throw UsageError("--max-frame-memory " + std::string(cap) +
                       " MB cannot hold one pair of frames: " + files[0].path.filename().string() +
                       " and " + files[1].path.filename().string() + " take " +
                       format_bytes(static_cast<double>(pair_bytes)));
    }
  } else {
    ProgressBar bar("reading and preprocessing", true);
    input.frames = preprocess_frames(
        files.size(), read_frame, [&](std::size_t k) { return files[k].path.string(); }, preprocess,
        threads, bar.callback());
    for (std::size_t k = 0; k < input.frames.size(); ++k) {
      check_frame(*input.frames[k]);
      frame_points[k] = input.frames[k]->size();
    }
  }
  const double preprocess_s = preprocess_time.elapsed_s();
  input.T_world_initial =
      has_initial ? relative_to(T_world_anchor, initial.poses)
                  : perturb_poses(reference_poses, args.perturb_m, args.perturb_deg, args.seed);

  // Loops: Scan Context candidates, GICP validation, the pose graph of odometry and loops.
  nlohmann::json loops_json = {{"ran", run_loops}};
  std::vector<Eigen::Isometry3d> start_poses = input.T_world_initial;
  std::string loops_line = "  loops: not searched (--loops searches them)";
  if (run_loops) {
    LoopClosureOptions loop_options;
    loop_options.num_threads = threads;
    loop_options.max_correspondence_distance = args.max_distance;
    const Stopwatch loop_time;
    LoopClosureResult closed;
    {
      ProgressBar bar("closing loops", !args.json);
      closed = input.store
                   ? close_loops(*input.store, input.T_world_initial, loop_options, bar.callback())
                   : close_loops(input.frames, input.T_world_initial, loop_options, bar.callback());
    }
    nlohmann::json rejected = nlohmann::json::object();
    for (LoopVerdict v :
         {LoopVerdict::kNotConverged, LoopVerdict::kDegenerate, LoopVerdict::kFewInliers}) {
      std::size_t count = 0;
      for (const LoopCheck& check : closed.checks) count += check.verdict == v;
      rejected[to_string(v)] = count;
    }
    loops_json["candidates"] = closed.candidates.size();
    loops_json["accepted"] = closed.loops.size();
    loops_json["rejected"] = rejected;
    loops_json["sparse_frames"] = closed.sparse_frames.size();
    loops_json["time_s"] = loop_time.elapsed_s();
    nlohmann::json accepted = nlohmann::json::array();
    for (const PairRegistration& loop : closed.loops)
      accepted.push_back({loop.pair.target, loop.pair.source});
    loops_json["pairs"] = accepted;
    if (!closed.loops.empty()) {
      loops_json["pgo"] = {{"termination", to_string(closed.summary.termination)},
                           {"iterations", closed.summary.num_iterations},
                           {"final_cost", closed.summary.final_cost},
                           {"time_s", closed.summary.time.total_s}};
      input.T_world_initial = closed.T_world_frame;
      loops_line = "  loops: " + std::to_string(closed.loops.size()) + " of " +
                   std::to_string(closed.candidates.size()) +
                   " Scan Context candidates accepted by GICP; pose graph " +
                   to_string(closed.summary.termination);
    } else {
      loops_line = "  loops: none found (" + std::to_string(closed.candidates.size()) +
                   " candidates, none validated): the start is left as it is, and a drive "
                   "whose loops are not closed may stay inconsistent";
    }
    if (!closed.sparse_frames.empty()) {
      loops_line += "; " + std::to_string(closed.sparse_frames.size()) +
                    " frames too sparse for a descriptor";
    }
  }

  DenseGraphOptions graph_options;
  graph_options.overlap_threshold = args.overlap;
  graph_options.num_threads = threads;
  const Stopwatch graph_time;
  input.pairs = input.store ? build_dense_graph(*input.store, input.T_world_initial, graph_options)
                            : build_dense_graph(input.frames, input.T_world_initial, graph_options);
  const double graph_s = graph_time.elapsed_s();
  if (args.method == "gre" && sampling == ResidualSampling::kFull) {
    check_full_factor_memory(frame_points, input.pairs);
  }

  if (mpi) mpi->attach({files, read_options, preprocess}, &input);

  MethodResult result;
  if (args.method == "pgo") {
    const auto registrations = register_graph_pairs(input);
    result = run_pose_graph(input, registrations, information);
  } else {
    result = run_registration(input, sampling);
  }
  const bool can_align = reference_poses.size() >= 3;
  AteOptions ate_options;
  ate_options.align = can_align;
  std::optional<AteStatistics> initial_ate;
  if (has_reference) {
    initial_ate = compute_ate(start_poses, reference_poses, ate_options);
    result.ate = compute_ate(result.T_world_frame, reference_poses, ate_options);
    if (run_loops) {
      loops_json["ate_rmse"] =
          compute_ate(input.T_world_initial, reference_poses, ate_options).rmse;
    }
  }

  if (out_file) {
    Trajectory optimized;
    optimized.stamps = start.stamps;
    optimized.ids = start.ids;
    for (const Eigen::Isometry3d& T : result.T_world_frame)
      optimized.poses.push_back(T_world_anchor * T);
    try {
      out_file->stream() << format_trajectory(optimized, out_format);
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
  if (args.json) {
    nlohmann::json j = to_json(result);
    j["frames"] = files.size();
    j["factors"] = input.pairs.size();
    if (input.store) {
      const FrameStoreStats stats = input.store->stats();
      j["frame_store"] = {{"max_bytes", stats.max_bytes}, {"requests", stats.requests},
                          {"hits", stats.hits},           {"loads", stats.loads},
                          {"evictions", stats.evictions}, {"peak_bytes", stats.peak_bytes}};
    }
    j["peak_rss_bytes"] = peak_rss_bytes();
    j["start"] = has_initial ? "initial" : "reference";
    j["loops"] = loops_json;
    if (initial_ate) {
      j["initial_ate_rmse"] = initial_ate->rmse;
      j["initial_ate_mean"] = initial_ate->mean;
      j["initial_ate_rotation_rmse_deg"] = initial_ate->rotation_rmse_deg;
      j["ate_aligned"] = can_align;
    }
    j["preprocess_s"] = preprocess_s;
    j["dense_graph_s"] = graph_s;
    if (!args.out.empty()) j["out"] = args.out;
    if (covariance_file) {
      j["covariance"] = args.covariance.path;
      j["covariance_s"] = result.covariance_s;
    }
    if (mpi) j["mpi"] = mpi->report();
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("carat map: %zu frames from %s, %zu factors in the dense graph\n", files.size(),
                args.frames.c_str(), input.pairs.size());
    if (input.store) {
      const FrameStoreStats stats = input.store->stats();
      std::printf("  frames read on demand under %s: %zu reads for %zu requests, at most %s held\n",
                  format_bytes(static_cast<double>(stats.max_bytes)).c_str(), stats.loads,
                  stats.requests, format_bytes(static_cast<double>(stats.peak_bytes)).c_str());
    }
    if (initial_ate && has_initial) {
      std::printf("  start (%s): ATE RMSE %.4f m, %.3f deg\n", args.initial.c_str(),
                  initial_ate->rmse, initial_ate->rotation_rmse_deg);
    } else if (initial_ate) {
      std::printf("  start (perturbed by %.3g m / %.3g deg): ATE RMSE %.4f m, %.3f deg\n",
                  args.perturb_m, args.perturb_deg, initial_ate->rmse,
                  initial_ate->rotation_rmse_deg);
    } else {
      std::printf("  start: %s (no --poses: no ATE)\n", args.initial.c_str());
    }
    std::printf("%s\n", loops_line.c_str());
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
  flush_standard_output();  // the report is out: now the trajectory goes into place
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
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args, cmd] { return run_map(*cmd, *args); });
}

}  // namespace carat::cli
