// carat simulate --out DIR [--frames N] [--laps L] [--circuit-blocks N] [--seed S] [--beams B]
//                [--drift-heading D]:
// simulates a LiDAR drive through the synthetic city and writes it KITTI-style: DIR/NNNNNN.bin (x y
// z intensity float32, intensity 0) and DIR/poses.txt (ground truth T_world_frame, KITTI pose
// format), for `carat map` and for benchmarks of any size. Frames are written as they are
// simulated (memory does not grow with the drive), into a temporary folder that becomes DIR only
// when the drive is complete.
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "carat/base/output_folder.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/sim/drift.hpp"
#include "carat/sim/kitti_writer.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"
#include "cli_support.hpp"
#include "commands.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

struct SimulateArgs {
  std::string out;
  int frames = 100;
  int laps = 2;
  int circuit_blocks = 1;
  int beams = 32;
  std::uint64_t seed = 1;
  double drift_heading = -1.0;  // < 0: no initial.txt
  int threads = 0;
  bool json = false;
};

int run_simulate(const SimulateArgs& args) {
  check_output_folder("--out", args.out, {});
  OutputFolder folder(args.out, "carat simulate");  // fails here if --out cannot be written
  const int threads = thread_count(args.threads);
  SyntheticWorldOptions options;
  options.seed = args.seed;
  options.beams = args.beams;
  options.blocks_x = args.circuit_blocks + 1;  // a row of buildings beyond the circuit's end
  const SyntheticWorld world(options);
  SyntheticTrajectoryOptions drive;
  drive.frames = args.frames;
  drive.laps = args.laps;
  drive.circuit_blocks_x = args.circuit_blocks;

  // The disk the drive needs, from its first frame, against what is free where it goes.
  const double frame_bytes = 16.0 * static_cast<double>(first_scan(world, drive).size());
  const double drive_bytes = static_cast<double>(args.frames) * (1.2 * frame_bytes + 200.0);
  const double free_bytes = static_cast<double>(available_disk_bytes(args.out));
  if (drive_bytes > free_bytes) {
    throw UsageError("--frames " + std::to_string(args.frames) + ": the drive would take about " +
                     format_bytes(drive_bytes) + " on disk (" + format_bytes(frame_bytes) +
                     " per frame); " + format_bytes(free_bytes) + " are free where --out " +
                     args.out + " goes");
  }

  std::size_t points = 0;
  {
    ProgressBar bar("simulating frames", !args.json);
    tbb::task_arena arena(threads);
    arena.execute(
        [&] { points = write_synthetic_drive(folder.path(), world, drive, bar.callback()); });
  }
  if (args.drift_heading >= 0.0) {
    // A drifting odometry guess beside the ground truth: the drift model of `carat demo` plus a
    // systematic heading drift, for `carat map --initial`.
    DriftOptions drift;
    drift.seed = args.seed;
    drift.translation_sigma = 0.005;
    drift.rotation_sigma_deg = 0.02;
    drift.heading_bias_deg = args.drift_heading;
    Trajectory initial;
    initial.poses = apply_drift(world.trajectory(drive), drift);
    for (std::size_t k = 0; k < initial.poses.size(); ++k)
      initial.stamps.push_back(static_cast<double>(k));
    write_trajectory(folder.path() / "initial.txt", initial, TrajectoryFormat::kKitti);
  }
  if (args.json) {
    nlohmann::json j;
    j["out"] = args.out;
    if (args.drift_heading >= 0.0)
      j["initial"] = (std::filesystem::path(args.out) / "initial.txt").string();
    j["frames"] = args.frames;
    j["points"] = points;
    j["seed"] = args.seed;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("wrote %d frames (%zu points) and poses.txt to %s\n", args.frames, points,
                args.out.c_str());
  }
  flush_standard_output();  // the report is out: now the drive goes into place
  folder.commit();
  return 0;
}

}  // namespace

void register_simulate(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Write a simulated LiDAR drive (KITTI-style .bin frames + poses.txt)");
  cmd->add_option("--out", args->out,
                  "output folder (created; an earlier carat output there is replaced whole)")
      ->check(path_value())
      ->required();
  cmd->add_option("--frames", args->frames, "frames")
      ->check(integer_in(2, 1000000))
      ->capture_default_str();
  cmd->add_option("--laps", args->laps, "laps of the circuit")
      ->check(integer_in(1, 1000))
      ->capture_default_str();
  cmd->add_option("--circuit-blocks", args->circuit_blocks,
                  "city blocks in a row that the circuit goes around (1: about 200 m a lap; each "
                  "more adds about 108 m)")
      ->check(integer_in(1, 63))
      ->capture_default_str();
  cmd->add_option("--beams", args->beams, "LiDAR channels")
      ->check(integer_in(1, 256))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the world and the noise")
      ->check(seed_value())
      ->capture_default_str();
  cmd->add_option("--drift-heading", args->drift_heading,
                  "also write initial.txt: a drifting odometry guess whose heading drifts by this "
                  "many degrees per metre (0.1: 10 degrees per 100 m), for `carat map --initial`")
      ->check(real_in(0.0, 10.0));
  cmd->add_option("--threads", args->threads, "threads (0: all cores)")
      ->check(integer_in(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "print one JSON object");
  registry.add(cmd, [args] { return run_simulate(*args); });
}

}  // namespace carat::cli
