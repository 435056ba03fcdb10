// carat map --frames DIR --poses FILE [--poses-format kitti|tum|graph] [--method gre|pgo]
//           [--sampling exact|random|full|lossless] [--residuals M] [--perturb-m X --perturb-deg Y]
//           [--seed S] [--out FILE] [--json]
// Global trajectory optimization on real scans: reads the frames and their poses, optionally
// perturbs the poses (frame 0 stays: it is the gauge), builds the dense graph of overlapping
// pairs at the starting poses and optimizes the registration errors of all pairs (gre) or a
// pose graph of pairwise GICP results (pgo). Reports the ATE of the start and of the result
// against the given poses, and writes the optimized trajectory to --out.
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/kitti_io.hpp"
#include "carat/registration/point_cloud_io.hpp"
#include "carat/registration/pose_perturbation.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/registration/trajectory_io.hpp"
#include "carat/solver/error.hpp"
#include "commands.hpp"
#include "mapping_methods.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

namespace fs = std::filesystem;

struct MapArgs {
  std::string frames;
  std::string poses;
  std::string poses_format = "kitti";
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
  int threads = 0;
  bool drop_non_finite = false;
  bool json = false;
};

/// One scan file of the frame folder and how to read it.
struct FrameFile {
  fs::path path;
  bool xyz_bin = false;  // for .bin: 12-byte records (gtsam_points dumps) instead of 16
};

/// Scans of DIR: DIR/*.bin|*.pcd|*.ply sorted by name (KITTI velodyne/ layout: .bin is
/// x y z intensity), or DIR/<name>/points.bin sorted by <name> (gtsam_points dumps: x y z).
std::vector<FrameFile> list_frames(const std::string& dir, const std::string& bin_format) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir + ": not a folder of frames");
  std::vector<FrameFile> flat, nested;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const fs::path& p = entry.path();
    if (entry.is_directory() && fs::is_regular_file(p / "points.bin")) {
      nested.push_back({p / "points.bin", true});
    } else if (entry.is_regular_file()) {
      const std::string ext = p.extension().string();
      if (ext == ".bin" || ext == ".pcd" || ext == ".ply") flat.push_back({p, false});
    }
  }
  if (ec) throw Error(dir + ": cannot list the folder: " + ec.message());
  if (!flat.empty() && !nested.empty())
    throw Error(dir + ": holds both scan files and <frame>/points.bin folders; keep one layout");
  std::vector<FrameFile> frames = flat.empty() ? nested : flat;
  if (frames.empty())
    throw Error(dir + ": no frames (expected *.bin, *.pcd, *.ply or <frame>/points.bin)");
  std::sort(frames.begin(), frames.end(),
            [](const FrameFile& a, const FrameFile& b) { return a.path < b.path; });
  if (bin_format != "auto")
    for (FrameFile& f : frames) f.xyz_bin = bin_format == "xyz";
  return frames;
}

PointCloud read_frame(const FrameFile& file, bool drop_non_finite) {
  ReadOptions options;
  options.drop_non_finite = drop_non_finite;
  if (file.path.extension() == ".bin")
    return read_kitti_bin(file.path, file.xyz_bin ? KittiFormat::kXyz : KittiFormat::kXyzi,
                          options);
  return read_point_cloud(file.path, KittiFormat::kXyzi, options);
}

int run_map(const MapArgs& args) {
  using Clock = std::chrono::steady_clock;
  const int threads = args.threads > 0 ? args.threads : tbb::info::default_concurrency();
  const TrajectoryFormat format = parse_trajectory_format(args.poses_format);
  const Trajectory reference = read_trajectory(args.poses, format);
  const std::vector<FrameFile> files = list_frames(args.frames, args.bin_format);
  if (files.size() != reference.poses.size()) {
    throw Error(args.frames + " holds " + std::to_string(files.size()) + " frames but " +
                args.poses + " has " + std::to_string(reference.poses.size()) + " poses");
  }
  if (files.size() < 2) throw Error(args.frames + ": at least 2 frames are needed");

  auto t0 = Clock::now();
  MappingInput input;
  input.threads = threads;
  input.seed = args.seed;
  input.residuals = args.residuals;
  input.max_correspondence_distance = args.max_distance;
  input.rounds = args.rounds;
  input.gre_excess_cauchy_scale = args.gre_excess_cauchy;
  PreprocessOptions preprocess;
  preprocess.voxel_size = args.voxel;
  {
    ProgressBar bar("reading and preprocessing", true);
    input.frames = preprocess_frames(
        files.size(), [&](std::size_t k) { return read_frame(files[k], args.drop_non_finite); },
        [&](std::size_t k) { return files[k].path.string(); }, preprocess, threads, bar.callback());
  }
  const double preprocess_s = std::chrono::duration<double>(Clock::now() - t0).count();
  input.T_world_initial =
      perturb_poses(reference.poses, args.perturb_m, args.perturb_deg, args.seed);

  DenseGraphOptions graph_options;
  graph_options.overlap_threshold = args.overlap;
  graph_options.num_threads = threads;
  input.pairs = build_dense_graph(input.frames, input.T_world_initial, graph_options);

  MethodResult result;
  if (args.method == "pgo") {
    const auto registrations = register_graph_pairs(input);
    result = run_pose_graph(input, registrations,
                            args.information == "identity" ? PoseGraphInformation::kIdentity
                                                           : PoseGraphInformation::kHessian);
  } else {
    result = run_registration(input, parse_residual_sampling(args.sampling));
  }
  const bool can_align = reference.poses.size() >= 3;
  AteOptions ate_options;
  ate_options.align = can_align;
  const AteStatistics initial_ate =
      compute_ate(input.T_world_initial, reference.poses, ate_options);
  result.ate = compute_ate(result.T_world_frame, reference.poses, ate_options);

  if (!args.out.empty()) {
    Trajectory optimized;
    optimized.stamps = reference.stamps;
    optimized.poses = result.T_world_frame;
    write_trajectory(args.out, optimized, format);
  }
  if (args.json) {
    nlohmann::json j = to_json(result);
    j["frames"] = input.frames.size();
    j["factors"] = input.pairs.size();
    j["initial_ate_rmse"] = initial_ate.rmse;
    j["initial_ate_mean"] = initial_ate.mean;
    j["initial_ate_rotation_rmse_deg"] = initial_ate.rotation_rmse_deg;
    j["ate_aligned"] = can_align;
    j["preprocess_s"] = preprocess_s;
    if (!args.out.empty()) j["out"] = args.out;
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("carat map: %zu frames from %s, %zu factors in the dense graph\n",
              input.frames.size(), args.frames.c_str(), input.pairs.size());
  std::printf("  start (perturbed by %.3g m / %.3g deg): ATE RMSE %.4f m, %.3f deg\n",
              args.perturb_m, args.perturb_deg, initial_ate.rmse, initial_ate.rotation_rmse_deg);
  std::printf("%s", results_table({result}).c_str());
  std::printf("  rotation ATE RMSE %.4f deg; termination %s\n", result.ate->rotation_rmse_deg,
              result.termination.c_str());
  if (!args.out.empty()) std::printf("  wrote %s\n", args.out.c_str());
  return 0;
}

}  // namespace

void register_map(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<MapArgs>();
  CLI::App* cmd =
      app.add_subcommand("map", "Optimize a trajectory over real scans by dense registration");
  cmd->add_option("--frames", args->frames, "folder of scans (*.bin|*.pcd|*.ply or */points.bin)")
      ->required();
  cmd->add_option("--poses", args->poses, "trajectory file: T_world_frame per frame")->required();
  cmd->add_option("--poses-format", args->poses_format, "format of --poses and --out")
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
      ->check(CLI::Range(29, 100000))
      ->capture_default_str();
  cmd->add_option("--voxel", args->voxel, "downsampling voxel (m)")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--overlap", args->overlap, "overlap threshold of the dense graph")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--max-distance", args->max_distance, "correspondence distance (m)")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--rounds", args->rounds, "gre: correspondence rounds (1: fixed at the start)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--gre-excess-cauchy", args->gre_excess_cauchy,
                  "gre: Cauchy scale on each factor's error above its own minimum (0: none, as "
                  "in the paper)")
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  cmd->add_option("--perturb-m", args->perturb_m, "perturb poses 1.. by this translation (m)")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  cmd->add_option("--perturb-deg", args->perturb_deg, "... and this rotation (degrees)")
      ->check(CLI::Range(0.0, 180.0))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the perturbation and sampling")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "write the optimized trajectory here");
  cmd->add_option("--threads", args->threads, "threads (0: all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--drop-non-finite", args->drop_non_finite,
                "drop NaN / Inf points while reading (default: they are an error)");
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args] { return run_map(*args); });
}

}  // namespace carat::cli
