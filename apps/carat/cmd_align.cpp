// carat align --target FILE --source FILE [--voxel 0.25]
//             [--method gicp|point-to-plane|point-to-point] [--max-distance 1.0]
//             [--bin-format xyz|xyzi] [--threads T] [--json]
// GICP scan matching of two scans (KITTI .bin, .pcd or .ply): prints T_target_source (4 x 4),
// iterations, error, convergence and a time breakdown.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/align.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/io/kitti_io.hpp"
#include "carat/registration/io/point_cloud_io.hpp"
#include "cli_support.hpp"
#include "commands.hpp"

namespace carat::cli {
namespace {

struct AlignArgs {
  std::string target;
  std::string source;
  double voxel = 0.25;
  double max_distance = 1.0;
  std::string bin_format = "xyzi";
  std::string method = "gicp";
  int threads = 1;
  bool json = false;
};

int run_align(const AlignArgs& args) {
  const KittiFormat format = parse_kitti_format(args.bin_format);
  Stopwatch stage;
  const PointCloud target_raw = read_point_cloud(args.target, format);
  const PointCloud source_raw = read_point_cloud(args.source, format);
  const double read_s = stage.restart();
  PreprocessOptions preprocess;
  preprocess.voxel_size = args.voxel;
  preprocess.num_threads = args.threads;
  const auto target = preprocess_frame(target_raw, preprocess, args.target);
  const auto source = preprocess_frame(source_raw, preprocess, args.source);
  const double preprocess_s = stage.elapsed_s();
  AlignSettings settings;
  settings.max_correspondence_distance = args.max_distance;
  settings.num_threads = args.threads;
  settings.method = parse_registration_method(args.method);
  stage.restart();
  const AlignResult result = align(target->cloud(), target->tree(), source->cloud(),
                                   Eigen::Isometry3d::Identity(), settings);
  const double align_s = stage.elapsed_s();
  if (result.constrained_dof < 6) {
    throw Error(args.source + " onto " + args.target + ": the scans constrain only " +
                std::to_string(result.constrained_dof) +
                " of 6 degrees of freedom (a degenerate scene, e.g. a single plane), so the "
                "alignment is not unique");
  }
  const Eigen::Matrix4d T = result.T_target_source.matrix();
  if (args.json) {
    nlohmann::json j;
    j["target"] = args.target;
    j["source"] = args.source;
    j["T_target_source"] = nlohmann::json::array();
    for (int r = 0; r < 4; ++r)
      j["T_target_source"].push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
    j["iterations"] = result.iterations;
    j["error"] = result.error;
    j["converged"] = result.converged;
    j["constrained_dof"] = result.constrained_dof;
    j["min_eigenvalue_ratio"] = result.min_eigenvalue_ratio;
    j["correspondences"] = result.num_correspondences;
    j["points_target"] = target->size();
    j["points_source"] = source->size();
    j["time_breakdown"] = {{"read_s", read_s},
                           {"preprocess_s", preprocess_s},
                           {"align_s", align_s},
                           {"search_s", result.search_s},
                           {"optimize_s", result.optimize_s}};
    j["time_s"] = read_s + preprocess_s + align_s;
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }
  std::printf("T_target_source =\n");
  for (int r = 0; r < 4; ++r)
    std::printf("  % .9f % .9f % .9f % .9f\n", T(r, 0), T(r, 1), T(r, 2), T(r, 3));
  std::printf("iterations %d (%s), error %.6e, %d correspondences\n", result.iterations,
              result.converged ? "converged" : "NOT converged", result.error,
              result.num_correspondences);
  std::printf("points after %.2f m voxels: target %zu, source %zu\n", args.voxel, target->size(),
              source->size());
  std::printf(
      "time: read %.3f s, preprocess %.3f s, align %.3f s (search %.3f s, optimize %.3f s)\n",
      read_s, preprocess_s, align_s, result.search_s, result.optimize_s);
  return 0;
}

}  // namespace

void register_align(CLI::App& app, CommandRegistry& registry) {
  auto args = std::make_shared<AlignArgs>();
  CLI::App* cmd =
      app.add_subcommand("align", "GICP scan matching of two scans (KITTI .bin, .pcd or .ply)");
  cmd->add_option("--target", args->target, "target scan (.bin, .pcd or .ply)")
      ->check(path_value())
      ->required();
  cmd->add_option("--source", args->source, "source scan (.bin, .pcd or .ply)")
      ->check(path_value())
      ->required();
  cmd->add_option("--voxel", args->voxel, "voxel size (m)")
      ->check(real_in(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--max-distance", args->max_distance, "max correspondence distance (m)")
      ->check(real_in(0.01, 100.0))
      ->capture_default_str();
  cmd->add_option("--method", args->method, "registration error")
      ->check(CLI::IsMember({"gicp", "point-to-plane", "point-to-point"}))
      ->capture_default_str();
  cmd->add_option("--bin-format", args->bin_format,
                  "records of .bin scans: xyzi (16 bytes/point, KITTI) or xyz (12 bytes/point)")
      ->check(CLI::IsMember({"xyz", "xyzi"}))
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads")
      ->check(integer_in(1, 1024))
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "print one JSON object");
  registry.add(cmd, [args] { return run_align(*args); });
}

}  // namespace carat::cli
