#pragma once

// SVG top views in metres (x right, y up): trajectories, registration graphs and point clouds.

#include <Eigen/Geometry>
#include <span>
#include <string>
#include <vector>

namespace carat::cli {

/// One trajectory to draw: its poses, colour (SVG colour string) and legend label.
struct SvgTrajectory {
  std::vector<Eigen::Isometry3d> poses;  // T_world_frame
  std::string colour;                    // e.g. "#1f77b4"
  std::string label;                     // legend text
  bool dashed = false;                   // dashed line (for references)
};

/// Top view of several trajectories with a legend and a metre scale; returns the SVG text.
std::string trajectories_svg(const std::string& title, std::span<const SvgTrajectory> lines);

/// One edge of a graph picture: frame indices and the value that colours it.
struct SvgEdge {
  int from = 0;        // frame index
  int to = 0;          // frame index
  double value = 0.0;  // e.g. the factor's error; coloured on a log scale
};

/// Top view of a graph: frames as dots at their positions, edges coloured from blue (small
/// value) to red (large value) on a log scale, with a colour bar labelled `value_label`.
std::string graph_svg(const std::string& title, std::span<const Eigen::Isometry3d> poses,
                      std::span<const SvgEdge> edges, const std::string& value_label);

/// One panel of a top-view point picture: a cloud drawn as small grey dots, marked points on top.
struct SvgPointPanel {
  std::string title;                   // above the panel
  std::vector<Eigen::Vector3d> cloud;  // metres (x right, y up); outside the view: not drawn
  std::vector<Eigen::Vector3d> marks;  // metres; the view always holds every mark
  std::vector<int> mark_classes;       // per mark: index into the classes' labels and colours
};

/// Panels side by side over one shared view (the square of half-width `half_extent` metres
/// around the origin, widened to hold every mark), each cloud deduplicated to one dot per pixel
/// and each mark a circle of its class's colour inside `<g class="marks">`; a legend of the
/// classes and a metre scale. Throws carat::Error when a mark's class has no label or colour.
std::string point_panels_svg(const std::string& title, std::span<const SvgPointPanel> panels,
                             std::span<const std::string> class_labels,
                             std::span<const std::string> class_colours, double half_extent);

}  // namespace carat::cli
