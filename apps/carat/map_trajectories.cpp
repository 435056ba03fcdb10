#include "map_trajectories.hpp"

#include "carat/base/error.hpp"
#include "carat/registration/pose_perturbation.hpp"

namespace carat::cli {
namespace {

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

}  // namespace

MapTrajectories read_map_trajectories(const MapTrajectoryArgs& args,
                                      const std::vector<ScanFile>& files) {
  // A trajectory file with one pose per frame, in scan order.
  const auto read_for_frames = [&](const std::string& option, const std::string& path,
                                   TrajectoryFormat format) {
    const Trajectory given = read_trajectory(path, format);
    if (files.size() != given.poses.size()) {
      throw Error(option + " " + path + " has " + std::to_string(given.poses.size()) +
                  " poses but --frames " + args.frames + " holds " + std::to_string(files.size()) +
                  " frames");
    }
    return poses_in_scan_order(given, format, files, path);
  };
  const TrajectoryFormat format = parse_trajectory_format(args.poses_format);
  const TrajectoryFormat initial_format = parse_trajectory_format(
      args.initial_format.empty() ? args.poses_format : args.initial_format);
  MapTrajectories t;
  if (!args.poses.empty()) t.reference = read_for_frames("--poses", args.poses, format);
  const bool has_initial = !args.initial.empty();
  t.start = has_initial ? read_for_frames("--initial", args.initial, initial_format) : t.reference;
  t.out_format = has_initial ? initial_format : format;
  t.T_world_anchor = t.start.poses.front();
  if (!args.poses.empty()) t.reference_poses = relative_to(t.T_world_anchor, t.reference.poses);
  t.T_world_initial =
      has_initial ? relative_to(t.T_world_anchor, t.start.poses)
                  : perturb_poses(t.reference_poses, args.perturb_m, args.perturb_deg, args.seed);
  return t;
}

}  // namespace carat::cli
