// carat odometry --frames DIR --out FILE [--format kitti|tum|graph] [--voxel 0.25]
//                [--max-distance 1.0] [--bin-format auto|xyz|xyzi] [--threads T]
//                [--allow-unconverged] [--json]
// GICP odometry from raw scans: each frame aligned to the one before from the previous motion,
// chained from the identity, written as a trajectory (the --initial of `carat map`). A step that
// did not converge or whose scans fix fewer than 6 directions ends the run with an error naming
// its frames, unless --allow-unconverged.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/io/scan_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/odometry.hpp"
#include "carat/registration/scan_opening.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

struct OdometryArgs {
  std::string frames;
  std::string out;
  std::string format = "kitti";
  std::string bin_format = "auto";
  double voxel = 0.25;
  double max_distance = 1.0;
  int threads = 0;
  bool allow_unconverged = false;
  bool json = false;
};

int run_odometry_command(const OdometryArgs& args) {
  const TrajectoryFormat format = parse_trajectory_format(args.format);
  const std::vector<ScanFile> files =
      list_scan_folder(args.frames, parse_bin_layout(args.bin_format));
  if (files.size() < 2) throw Error(args.frames + ": at least 2 frames are needed");
  std::vector<NamedInput> inputs;
  for (const ScanFile& file : files) inputs.push_back({"--frames", file.path.string()});
  check_output_file("--out", args.out, inputs);
  check_output_outside_folder("--out", args.out, {"--frames", args.frames});
  OutputFile out(args.out);
  const int threads = thread_count(args.threads);
  Stopwatch stage;
  OpenScansOptions scans;
  scans.preprocess.voxel_size = args.voxel;
  scans.num_threads = threads;
  scans.require_constrained = false;  // a degenerate step is reported below
  std::shared_ptr<FrameStore> frames;
  {
    ProgressBar bar("reading and preprocessing", !args.json);
    frames = open_scans(files, scans, bar.callback());
  }
  const double preprocess_s = stage.restart();
  AlignSettings settings;
  settings.max_correspondence_distance = args.max_distance;
  settings.num_threads = threads;
  OdometryResult odometry;
  {
    ProgressBar bar("GICP odometry", !args.json);
    odometry = run_scan_odometry(*frames, settings, bar.callback());
  }
  const double odometry_s = stage.elapsed_s();
  // A step that did not converge (or whose scans fix too few directions) makes every later pose
  // wrong: an error unless asked for, never a trajectory written in silence.
  const std::size_t unreliable = odometry.unreliable_steps();
  const std::string unreliable_text = odometry.describe_unreliable_steps(*frames);
  if (unreliable > 0 && !args.allow_unconverged) {
    throw Error("odometry of --frames " + args.frames + ": " + std::to_string(unreliable) + " of " +
                std::to_string(odometry.steps.size()) +
                " steps cannot be trusted, so every pose after the first of them would be wrong: " +
                unreliable_text + "; nothing was written (--allow-unconverged writes it anyway)");
  }
  Trajectory trajectory;
  trajectory.poses = odometry.T_world_frame;
  for (std::size_t k = 0; k < files.size(); ++k)
    trajectory.stamps.push_back(static_cast<double>(k));
  // Graph ids by the rule `carat map` pairs them with (numbered frames: their number).
  if (format == TrajectoryFormat::kGraph) trajectory.ids = scan_graph_ids(files);
  out.stream() << format_trajectory(trajectory, format);
  int not_converged = 0;
  for (const PairRegistration& step : odometry.steps) not_converged += !step.converged;
  if (args.json) {
    nlohmann::json j;
    j["frames"] = files.size();
    j["out"] = args.out;
    j["format"] = args.format;
    j["steps_not_converged"] = not_converged;
    j["unreliable_steps"] = nlohmann::json::array();
    for (const PairRegistration& step : odometry.steps) {
      if (step.reliable()) continue;
      j["unreliable_steps"].push_back({{"target", step.pair.target},
                                       {"source", step.pair.source},
                                       {"converged", step.converged},
                                       {"constrained_dof", step.constrained_dof}});
    }
    j["preprocess_s"] = preprocess_s;
    j["odometry_s"] = odometry_s;
    j["time_per_frame_ms"] = 1e3 * (preprocess_s + odometry_s) / static_cast<double>(files.size());
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("carat odometry: %zu frames from %s, %d steps not converged\n", files.size(),
                args.frames.c_str(), not_converged);
    if (unreliable > 0) {
      std::printf("  %zu steps cannot be trusted (written as asked): %s\n", unreliable,
                  unreliable_text.c_str());
    }
    std::printf("  time: preprocess %.3f s, odometry %.3f s\n  wrote %s\n", preprocess_s,
                odometry_s, args.out.c_str());
  }
  flush_standard_output();  // the report is out: now the trajectory goes into place
  out.commit();
  return 0;
}

}  // namespace

void register_odometry(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<OdometryArgs>();
  CLI::App* cmd = app.add_subcommand(
      "odometry", "GICP odometry from a folder of scans, written as a trajectory");
  cmd->add_option("--frames", args->frames,
                  "folder of scans (*.bin|*.pcd|*.ply or */points.bin, in natural name order)")
      ->check(path_value())
      ->required();
  cmd->add_option("--out", args->out, "trajectory to write (never one of the inputs)")
      ->check(path_value())
      ->required();
  cmd->add_option("--format", args->format, "trajectory format of --out")
      ->check(CLI::IsMember({"kitti", "tum", "graph"}))
      ->capture_default_str();
  cmd->add_option("--bin-format", args->bin_format,
                  "records of .bin scans (auto: xyz for */points.bin, else xyzi)")
      ->check(CLI::IsMember({"auto", "xyz", "xyzi"}))
      ->capture_default_str();
  cmd->add_option("--voxel", args->voxel, "downsampling voxel (m)")
      ->check(real_in(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--max-distance", args->max_distance,
                  "correspondence distance (m); a first pass uses three times this")
      ->check(real_in(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads (0: all cores)")
      ->check(integer_in(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--allow-unconverged", args->allow_unconverged,
                "write the trajectory even when steps did not converge or fix fewer than 6 "
                "directions (they are listed in the report); without it such a run is an error");
  cmd->add_flag("--json", args->json, "print one JSON object instead of the report");
  registry.add(cmd, [args] { return run_odometry_command(*args); });
}

}  // namespace carat::cli
