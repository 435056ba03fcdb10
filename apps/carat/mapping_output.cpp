#include "mapping_output.hpp"

#include "carat/registration/io/trajectory_io.hpp"
#include "error_plot.hpp"
#include "svg_document.hpp"
#include "svg_top_view.hpp"

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
      lines.push_back({aligned(results[k].T_world_frame, reference), palette_colour(k),
                       results[k].label, false});
    }
    written.push_back(dir / "trajectories_after.svg");
    write_svg(written.back(),
              trajectories_svg("Optimized trajectories vs reference (aligned)", lines));
  }
  if (ref.size() >= 3) {
    // Per-frame errors after the ATE's alignment: each method whose trajectory matches the
    // reference, then the initial guess (dashed, drawn on top).
    std::vector<FrameErrorLine> lines;
    for (std::size_t k = 0; k < results.size(); ++k) {
      if (results[k].T_world_frame.size() != ref.size()) continue;
      lines.push_back({aligned_position_errors(results[k].T_world_frame, ref), palette_colour(k),
                       results[k].label, false});
    }
    if (initial.size() == ref.size())
      lines.push_back({aligned_position_errors(initial, ref), "#7f7f7f", "initial guess", true});
    written.push_back(dir / "frame_errors.svg");
    write_svg(
        written.back(),
        frame_errors_svg("Position error per frame vs reference (aligned as the ATE)", lines));
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
