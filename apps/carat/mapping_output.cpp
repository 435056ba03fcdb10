#include "mapping_output.hpp"

#include "carat/registration/io/trajectory_io.hpp"
#include "svg.hpp"

namespace carat::cli {

std::vector<std::filesystem::path> write_trajectory_pair(const std::filesystem::path& dir,
                                                         const std::string& name,
                                                         std::span<const Eigen::Isometry3d> poses) {
  Trajectory trajectory;
  trajectory.poses.assign(poses.begin(), poses.end());
  for (std::size_t i = 0; i < poses.size(); ++i)
    trajectory.stamps.push_back(static_cast<double>(i));
  const std::filesystem::path kitti = dir / (name + "_kitti.txt");
  const std::filesystem::path tum = dir / (name + "_tum.txt");
  write_trajectory(kitti, trajectory, TrajectoryFormat::kKitti);
  write_trajectory(tum, trajectory, TrajectoryFormat::kTum);
  return {kitti, tum};
}

std::vector<std::filesystem::path> write_mapping_pictures(
    const std::filesystem::path& dir, std::span<const Eigen::Isometry3d> reference,
    std::span<const Eigen::Isometry3d> initial, const std::vector<MethodResult>& results,
    std::span<const FramePair> pairs, const MethodResult* graph_method) {
  static const char* const kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                         "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  std::vector<std::filesystem::path> written;
  const auto aligned = [](std::span<const Eigen::Isometry3d> poses,
                          std::span<const Eigen::Isometry3d> ref) {
    std::vector<Eigen::Isometry3d> out(poses.begin(), poses.end());
    if (ref.size() != poses.size() || poses.size() < 3) return out;
    const AteStatistics ate = compute_ate(poses, ref);
    for (auto& T : out) T = ate.T_reference_estimate * T;
    return out;
  };
  const std::vector<Eigen::Isometry3d> ref(reference.begin(), reference.end());
  {
    std::vector<SvgTrajectory> lines;
    if (!ref.empty()) lines.push_back({ref, "#000000", "reference", true});
    lines.push_back({aligned(initial, reference), "#d62728", "initial guess", false});
    written.push_back(dir / "trajectories_before.svg");
    write_svg(written.back(), trajectories_svg("Initial guess vs reference (aligned)", lines));
  }
  {
    std::vector<SvgTrajectory> lines;
    if (!ref.empty()) lines.push_back({ref, "#000000", "reference", true});
    for (std::size_t k = 0; k < results.size(); ++k) {
      lines.push_back(
          {aligned(results[k].T_world_frame, reference), kColours[k % 8], results[k].label, false});
    }
    written.push_back(dir / "trajectories_after.svg");
    write_svg(written.back(),
              trajectories_svg("Optimized trajectories vs reference (aligned)", lines));
  }
  if (graph_method != nullptr && graph_method->factor_costs.size() == pairs.size()) {
    std::vector<SvgEdge> edges;
    for (std::size_t k = 0; k < pairs.size(); ++k)
      edges.push_back({pairs[k].target, pairs[k].source, graph_method->factor_costs[k]});
    written.push_back(dir / "graph.svg");
    write_svg(written.back(),
              graph_svg("Dense registration graph: " + std::to_string(pairs.size()) + " factors (" +
                            graph_method->label + ")",
                        graph_method->T_world_frame, edges, "error / corr."));
  }
  return written;
}

}  // namespace carat::cli
