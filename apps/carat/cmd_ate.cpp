// carat ate --estimate FILE --reference FILE [--format kitti|tum|graph]
//           [--reference-format F (default: --format)] [--max-difference 0.01] [--no-align]
//           [--json]
// Absolute trajectory error (evo's APE, translation part) after rigid Umeyama alignment:
// rmse / mean / median / std / min / max in metres, rotation error statistics in degrees.
// Two TUM files are paired by stamp, two graph.txt files by vertex id; any other combination
// pairs pose k with pose k.
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "carat/base/error.hpp"
#include "carat/registration/io/trajectory_io.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace carat::cli {
namespace {

struct AteArgs {
  std::string estimate;
  std::string reference;
  std::string format = "kitti";
  std::string reference_format;  // empty: same as format
  double max_difference = 0.01;
  bool no_align = false;
  bool json = false;
};

int run_ate(const CLI::App& command, const AteArgs& args) {
  const std::string reference_format_name =
      args.reference_format.empty() ? args.format : args.reference_format;
  const TrajectoryFormat estimate_format = parse_trajectory_format(args.format);
  const TrajectoryFormat reference_format = parse_trajectory_format(reference_format_name);
  const bool by_stamp =
      estimate_format == TrajectoryFormat::kTum && reference_format == TrajectoryFormat::kTum;
  const bool by_id =
      estimate_format == TrajectoryFormat::kGraph && reference_format == TrajectoryFormat::kGraph;
  if (!by_stamp && command.count("--max-difference") > 0) {
    throw UsageError("--max-difference does not apply: it pairs two TUM trajectories by stamp");
  }
  const Trajectory estimate = read_trajectory(args.estimate, estimate_format);
  const Trajectory reference = read_trajectory(args.reference, reference_format);

  std::vector<Eigen::Isometry3d> estimate_poses;
  std::vector<Eigen::Isometry3d> reference_poses;
  if (by_id) {  // graph.txt against graph.txt: vertex vN with vertex vN
    std::map<std::uint64_t, std::size_t> reference_of_id;
    for (std::size_t k = 0; k < reference.ids.size(); ++k) {
      reference_of_id.emplace(reference.ids[k], k);
    }
    for (std::size_t k = 0; k < estimate.ids.size(); ++k) {
      const auto match = reference_of_id.find(estimate.ids[k]);
      if (match == reference_of_id.end()) continue;
      estimate_poses.push_back(estimate.poses[k]);
      reference_poses.push_back(reference.poses[match->second]);
    }
    if (estimate_poses.empty()) {
      throw Error(args.estimate + ": none of its " + std::to_string(estimate.poses.size()) +
                  " vertex ids is among the " + std::to_string(reference.poses.size()) + " of " +
                  args.reference);
    }
  } else if (by_stamp) {
    const auto pairs = associate_by_stamp(estimate.stamps, reference.stamps, args.max_difference);
    if (pairs.empty()) {
      throw Error(args.estimate + ": none of its " + std::to_string(estimate.poses.size()) +
                  " stamps is within " + std::to_string(args.max_difference) + " s of one of the " +
                  std::to_string(reference.poses.size()) + " stamps of " + args.reference);
    }
    for (const auto& [e, r] : pairs) {
      estimate_poses.push_back(estimate.poses[static_cast<std::size_t>(e)]);
      reference_poses.push_back(reference.poses[static_cast<std::size_t>(r)]);
    }
  } else {
    if (estimate.poses.size() != reference.poses.size()) {
      throw Error(args.estimate + " has " + std::to_string(estimate.poses.size()) + " poses but " +
                  args.reference + " has " + std::to_string(reference.poses.size()) +
                  " (poses are paired by index)");
    }
    estimate_poses = estimate.poses;
    reference_poses = reference.poses;
  }
  AteOptions options;
  options.align = !args.no_align;
  if (options.align && estimate_poses.size() < 3) {
    throw Error(args.estimate + ": only " + std::to_string(estimate_poses.size()) +
                " poses paired with " + args.reference +
                "; alignment needs at least 3 (use --no-align)");
  }
  AteStatistics s;
  try {
    s = compute_ate(estimate_poses, reference_poses, options);
  } catch (const Error& e) {
    throw Error(args.estimate + " against " + args.reference + ": " + e.what());
  }
  const Eigen::Matrix4d T = s.T_reference_estimate.matrix();
  if (args.json) {
    nlohmann::json j;
    j["estimate"] = args.estimate;
    j["reference"] = args.reference;
    j["format"] = args.format;
    j["reference_format"] = reference_format_name;
    j["association"] = by_stamp ? "stamp" : by_id ? "id" : "index";
    j["aligned"] = options.align;
    j["estimate_poses"] = estimate.poses.size();
    j["reference_poses"] = reference.poses.size();
    j["num_poses"] = s.num_poses;
    j["rmse"] = s.rmse;
    j["mean"] = s.mean;
    j["median"] = s.median;
    j["std"] = s.std;
    j["min"] = s.min;
    j["max"] = s.max;
    j["rotation_rmse_deg"] = s.rotation_rmse_deg;
    j["rotation_mean_deg"] = s.rotation_mean_deg;
    j["rotation_max_deg"] = s.rotation_max_deg;
    j["T_reference_estimate"] = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) {
      j["T_reference_estimate"].push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
    }
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("ATE over %d poses (%s, paired by %s):\n", s.num_poses,
              options.align ? "rigid Umeyama alignment" : "not aligned",
              by_stamp ? "stamp"
              : by_id  ? "id"
                       : "index");
  std::printf(
      "  translation (m):  rmse %.6f  mean %.6f  median %.6f  std %.6f  min %.6f  max %.6f\n",
      s.rmse, s.mean, s.median, s.std, s.min, s.max);
  std::printf("  rotation (deg):   rmse %.6f  mean %.6f  max %.6f\n", s.rotation_rmse_deg,
              s.rotation_mean_deg, s.rotation_max_deg);
  if (options.align) {
    std::printf("T_reference_estimate =\n");
    for (int r = 0; r < 4; ++r) {
      std::printf("  % .9f % .9f % .9f % .9f\n", T(r, 0), T(r, 1), T(r, 2), T(r, 3));
    }
  }
  return 0;
}

}  // namespace

void register_ate(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<AteArgs>();
  CLI::App* cmd =
      app.add_subcommand("ate", "absolute trajectory error of an estimate against a reference");
  cmd->add_option("--estimate", args->estimate, "estimated trajectory")
      ->check(path_value())
      ->required();
  cmd->add_option("--reference", args->reference, "reference (ground-truth) trajectory")
      ->check(path_value())
      ->required();
  cmd->add_option("--format", args->format, "trajectory format of the estimate")
      ->check(CLI::IsMember({"kitti", "tum", "graph"}))
      ->capture_default_str();
  cmd->add_option("--reference-format", args->reference_format,
                  "trajectory format of the reference (default: --format)")
      ->check(CLI::IsMember({"kitti", "tum", "graph"}));
  cmd->add_option("--max-difference", args->max_difference,
                  "largest stamp difference (s) when pairing two TUM trajectories")
      ->check(real_in(0.0, 1e9))
      ->capture_default_str();
  cmd->add_flag("--no-align", args->no_align, "compare without the rigid Umeyama alignment");
  cmd->add_flag("--json", args->json, "print one JSON object");
  registry.add(cmd, [args, cmd] { return run_ate(*cmd, *args); });
}

}  // namespace carat::cli
