#include "error_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "carat/registration/trajectory_error.hpp"
#include "svg_charts.hpp"

namespace carat::cli {

std::vector<double> aligned_position_errors(std::span<const Eigen::Isometry3d> estimate,
                                            std::span<const Eigen::Isometry3d> reference) {
  const Eigen::Isometry3d T_reference_estimate =
      compute_ate(estimate, reference).T_reference_estimate;
  std::vector<double> errors;
  errors.reserve(estimate.size());
  for (std::size_t k = 0; k < estimate.size(); ++k)
    errors.push_back(
        (reference[k].translation() - T_reference_estimate * estimate[k].translation()).norm());
  return errors;
}

namespace {

/// Lines within this many decades of each other at every frame are drawn as one (about a pixel).
constexpr double kAlikeDecades = 0.01;

/// Whether two lines of per-frame errors are drawn at the same heights (within kAlikeDecades).
bool drawn_alike(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return false;
  const auto level = [](double e) { return std::log10(std::max(e, kErrorPlotFloor)); };
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (std::isfinite(a[k]) != std::isfinite(b[k])) return false;
    if (std::isfinite(a[k]) && std::abs(level(a[k]) - level(b[k])) > kAlikeDecades) return false;
  }
  return true;
}

}  // namespace

std::string frame_errors_svg(const std::string& title, std::span<const FrameErrorLine> lines) {
  // Lines drawn alike form a group; a group's lines are nested, from 6 px wide down to 1.5 px.
  std::vector<std::vector<std::size_t>> groups;
  for (std::size_t k = 0; k < lines.size(); ++k) {
    auto group = std::find_if(groups.begin(), groups.end(), [&](const auto& members) {
      return drawn_alike(lines[members.front()].errors, lines[k].errors);
    });
    if (group == groups.end()) group = groups.insert(groups.end(), std::vector<std::size_t>{});
    group->push_back(k);
  }
  std::vector<SvgSeries> series;
  for (const FrameErrorLine& line : lines) {
    SvgSeries one{{}, line.errors, line.colour, line.label, line.dashed};
    for (std::size_t k = 0; k < line.errors.size(); ++k) one.x.push_back(static_cast<double>(k));
    series.push_back(std::move(one));
  }
  bool nested = false;
  for (const auto& members : groups) {
    if (members.size() < 2) continue;
    nested = true;
    for (std::size_t i = 0; i < members.size(); ++i)
      series[members[i]].width =
          6.0 - 4.5 * static_cast<double>(i) / static_cast<double>(members.size() - 1);
  }
  LinePlotOptions options;
  options.log_y = true;
  options.y_floor = kErrorPlotFloor;
  options.markers = false;
  char note[160];
  const int decade = static_cast<int>(std::lround(std::log10(kErrorPlotFloor)));
  std::snprintf(note, sizeof(note),
                "errors below 1e%d m drawn at 1e%d m; non-finite errors left out%s", decade, decade,
                nested ? "; equal errors drawn as nested lines, widest first" : "");
  options.note = note;
  return line_plot_svg(title, "frame index (drive order)",
                       "position error after ATE alignment [m] (log scale)", series, options);
}

}  // namespace carat::cli
