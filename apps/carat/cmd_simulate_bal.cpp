// carat simulate-bal --layout ring|street|random --cameras N --points N
//                    --observations-per-point K [--noise PX] [--outliers F] [--seed S]
//                    --out FILE [--truth FILE] [--json]
// writes a synthetic bundle-adjustment problem in the BAL format: the perturbed start with noisy
// observations to --out and, optionally, the true cameras and points with noise-free
// observations to --truth. Both files go into place only when everything was written.
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "carat/base/atomic_file.hpp"
#include "carat/residuals/bal_problem.hpp"
#include "carat/residuals/io/bal_io.hpp"
#include "carat/sim/bal_scene.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace carat::cli {
namespace {

struct SimulateBalArgs {
  std::string layout = "ring";
  int cameras = 16;
  int points = 1000;
  int observations_per_point = 4;
  double noise = 1.0;
  double outliers = 0.0;
  double start_noise = 1.0;
  std::uint64_t seed = 1;
  std::string out;
  std::string truth;
  bool json = false;
};

/// Refuses combinations the option ranges let through: too few points for the cameras, more
/// observations per point than cameras or than the layout can place, a scene larger than the
/// format or the memory.
void check_sizes(const SimulateBalArgs& args) {
  if (args.points < args.cameras) {
    throw UsageError("--points " + std::to_string(args.points) + " must be at least --cameras " +
                     std::to_string(args.cameras) + " (every camera observes a point)");
  }
  if (args.observations_per_point > args.cameras) {
    throw UsageError("--observations-per-point " + std::to_string(args.observations_per_point) +
                     " must be at most --cameras " + std::to_string(args.cameras));
  }
  const int most = max_observations_per_point(parse_bal_layout(args.layout), args.cameras);
  if (args.observations_per_point > most) {
    throw UsageError("--observations-per-point " + std::to_string(args.observations_per_point) +
                     " cannot be placed with --layout " + args.layout + ": at most " +
                     std::to_string(most) +
                     " consecutive cameras have one facade point in front of them (use "
                     "--layout ring or random for more observers per point)");
  }
  const auto observations = static_cast<std::uint64_t>(args.points) *
                            static_cast<std::uint64_t>(args.observations_per_point);
  if (observations > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) {
    throw UsageError("--points * --observations-per-point is " + std::to_string(observations) +
                     " observations; the BAL format holds at most 2147483647");
  }
  // Two copies of the scene (truth and start) and the text of one file at a time.
  const double bytes = static_cast<double>(observations) * (2.0 * sizeof(BalObservation) + 1.0) +
                       static_cast<double>(args.points) * 2.0 * 24.0 +
                       static_cast<double>(args.cameras) * 2.0 * 72.0;
  const auto available = static_cast<double>(available_memory_bytes());
  if (bytes > available) {
    throw UsageError("--points " + std::to_string(args.points) + " with --observations-per-point " +
                     std::to_string(args.observations_per_point) + " needs about " +
                     format_bytes(bytes) + " of memory; " + format_bytes(available) +
                     " are available");
  }
}

int run_simulate_bal(const SimulateBalArgs& args) {
  check_output_file("--out", args.out, {});
  if (!args.truth.empty()) {
    check_output_file("--truth", args.truth, {});
    if (args.truth == args.out || same_file(args.truth, args.out)) {
      throw UsageError("--truth and --out name the same file " + args.out);
    }
  }
  check_sizes(args);

  BalSimulationOptions options;
  options.layout = parse_bal_layout(args.layout);
  options.cameras = args.cameras;
  options.points = args.points;
  options.observations_per_point = args.observations_per_point;
  options.pixel_noise_sigma = args.noise;
  options.outlier_fraction = args.outliers;
  options.seed = args.seed;
  options.camera_rotation_sigma_rad *= args.start_noise;
  options.camera_position_sigma_m *= args.start_noise;
  options.focal_sigma_relative *= args.start_noise;
  options.point_sigma_m *= args.start_noise;
  const BalScene scene = simulate_bal(options);

  std::size_t outliers = 0;
  for (char o : scene.outlier) outliers += o ? 1 : 0;
  BalProblem noisy_truth = scene.truth;  // the truth against the noisy observations
  noisy_truth.observations = scene.problem.observations;
  const double initial_cost = bal_cost(scene.problem);
  const double truth_cost = bal_cost(noisy_truth);
  noisy_truth = {};

  OutputFile out(args.out);
  write_bal(out.stream(), scene.problem);
  std::unique_ptr<OutputFile> truth;
  if (!args.truth.empty()) {
    truth = std::make_unique<OutputFile>(args.truth);
    write_bal(truth->stream(), scene.truth);
  }

  if (args.json) {
    nlohmann::json j;
    j["layout"] = args.layout;
    j["cameras"] = scene.problem.cameras.size();
    j["points"] = scene.problem.points.size();
    j["observations"] = scene.problem.observations.size();
    j["outliers"] = outliers;
    j["noise_px"] = args.noise;
    j["outlier_fraction"] = args.outliers;
    j["seed"] = args.seed;
    j["initial_cost"] = initial_cost;
    j["truth_cost"] = truth_cost;
    j["out"] = args.out;
    if (!args.truth.empty()) j["truth"] = args.truth;
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("%s scene: %zu cameras, %zu points, %zu observations (%zu outliers), seed %llu\n",
                args.layout.c_str(), scene.problem.cameras.size(), scene.problem.points.size(),
                scene.problem.observations.size(), outliers,
                static_cast<unsigned long long>(args.seed));
    std::printf("cost (1/2 sum of squared pixel errors): %.6g at the start, %.6g at the truth\n",
                initial_cost, truth_cost);
    std::printf("wrote %s%s%s\n", args.out.c_str(), args.truth.empty() ? "" : " and the truth to ",
                args.truth.c_str());
  }
  flush_standard_output();  // the report is out: now the files go into place
  out.commit();
  if (truth) truth->commit();
  return 0;
}

}  // namespace

void register_simulate_bal(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<SimulateBalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "simulate-bal", "Write a synthetic bundle-adjustment problem (BAL format) and its truth");
  cmd->add_option("--layout", args->layout,
                  "ring: cameras on a circle looking inward; street: cameras along a line looking "
                  "at a facade; random: cameras around a ball of points")
      ->check(CLI::IsMember({"ring", "street", "random"}))
      ->capture_default_str();
  cmd->add_option("--cameras", args->cameras, "cameras")
      ->check(integer_in(2, 1000000))
      ->capture_default_str();
  cmd->add_option("--points", args->points, "points (at least --cameras)")
      ->check(integer_in(2, 100000000))
      ->capture_default_str();
  cmd->add_option("--observations-per-point", args->observations_per_point,
                  "cameras observing each point (at most --cameras)")
      ->check(integer_in(2, 10000))
      ->capture_default_str();
  cmd->add_option("--noise", args->noise, "Gaussian pixel noise per coordinate, pixels")
      ->check(real_in(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--outliers", args->outliers,
                  "fraction of observations moved 50-100 pixels away (outliers)")
      ->check(real_in(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--start-noise", args->start_noise,
                  "scale of the start's perturbation (1: rotations 0.01 rad, camera centres and "
                  "points 0.1 m, focal lengths 1 %, one sigma each)")
      ->check(real_in(0.0, 100.0))
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "seed of the scene and the noise")
      ->check(seed_value())
      ->capture_default_str();
  cmd->add_option("--out", args->out,
                  "BAL file of the problem: perturbed start, noisy observations")
      ->check(path_value())
      ->required();
  cmd->add_option("--truth", args->truth,
                  "BAL file of the truth: true cameras and points, noise-free observations")
      ->check(path_value());
  cmd->add_flag("--json", args->json, "print one JSON object");
  registry.add(cmd, [args] { return run_simulate_bal(*args); });
}

}  // namespace carat::cli
