// carat simulate --out DIR [--frames N] [--laps L] [--circuit-blocks N] [--seed S] [--beams B]:
// simulates a LiDAR drive through the synthetic city and writes it KITTI-style: DIR/NNNNNN.bin (x y
// z float32) and DIR/poses.txt (ground truth T_world_frame, KITTI pose format), for `carat map` and
// for benchmarks of any size.
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "carat/registration/synthetic_world.hpp"
#include "commands.hpp"

namespace carat::cli {
namespace {

struct SimulateArgs {
  std::string out;
  int frames = 100;
  int laps = 2;
  int circuit_blocks = 1;
  int beams = 32;
  std::uint64_t seed = 1;
  int threads = 0;
  bool json = false;
};

int run_simulate(const SimulateArgs& args) {
  const int threads = args.threads > 0 ? args.threads : tbb::info::default_concurrency();
  SyntheticWorldOptions options;
  options.seed = args.seed;
  options.beams = args.beams;
  options.blocks_x = args.circuit_blocks + 1;  // a row of buildings beyond the circuit's end
  const SyntheticWorld world(options);
  SyntheticTrajectoryOptions drive;
  drive.frames = args.frames;
  drive.laps = args.laps;
  drive.circuit_blocks_x = args.circuit_blocks;
  SyntheticSequence sequence;
  tbb::task_arena arena(threads);
  arena.execute([&] { sequence = make_synthetic_sequence(world, drive); });
  write_synthetic_sequence(args.out, sequence);
  std::size_t points = 0;
  for (const auto& scan : sequence.scans) points += scan.size();
  if (args.json) {
    nlohmann::json j;
    j["out"] = args.out;
    j["frames"] = sequence.scans.size();
    j["points"] = points;
    j["seed"] = args.seed;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("wrote %zu frames (%zu points) and poses.txt to %s\n", sequence.scans.size(),
                points, args.out.c_str());
  }
  return 0;
}

}  // namespace

void register_simulate(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<SimulateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Write a simulated LiDAR drive (KITTI-style .bin frames + poses.txt)");
  cmd->add_option("--out", args->out, "output folder")->required();
  cmd->add_option("--frames", args->frames, "frames")
      ->check(CLI::Range(2, 1000000))
      ->capture_default_str();
  cmd->add_option("--laps", args->laps, "laps of the circuit")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--circuit-blocks", args->circuit_blocks,
                  "city blocks in a row that the circuit goes around (1: about 200 m a lap; each "
                  "more adds about 108 m)")
      ->check(CLI::Range(1, 63))
      ->capture_default_str();
  cmd->add_option("--beams", args->beams, "LiDAR channels")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the world and the noise")->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads (0: all cores)")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "print one JSON object");
  registry.add(cmd, [args] { return run_simulate(*args); });
}

}  // namespace carat::cli
