#pragma once

// SVG charts: line plots (linear or log y) and stacked bars.

#include <span>
#include <string>
#include <vector>

namespace carat::cli {

/// One series of a line plot: x and y values, colour and legend label.
struct SvgSeries {
  std::vector<double> x;  // abscissae
  std::vector<double> y;  // ordinates (> 0 on a log axis unless LinePlotOptions::y_floor is set)
  std::string colour;     // SVG colour
  std::string label;      // legend text
  bool dashed = false;    // dashed line (for references)
  double width = 2.0;     // stroke width (pixels)
};

/// How line_plot_svg() draws its axes and series.
struct LinePlotOptions {
  bool log_y = false;    ///< log10 y axis, one gridline and label per decade
  double y_floor = 0.0;  ///< on a log axis, when > 0: values up to it (zero too) drawn at it;
                         ///< when 0 non-positive values are left out
  bool markers = true;   ///< a dot at every point
  std::string note;      ///< one line of small text under the x label (empty: none)
};

/// A line plot with a legend right of the axes; non-finite values are left out of the lines.
std::string line_plot_svg(const std::string& title, const std::string& x_label,
                          const std::string& y_label, std::span<const SvgSeries> series,
                          const LinePlotOptions& options);

/// A line plot with markers; log10 y axis when `log_y` (non-positive values are left out).
std::string line_plot_svg(const std::string& title, const std::string& x_label,
                          const std::string& y_label, std::span<const SvgSeries> series,
                          bool log_y);

/// One stacked bar: a label and its segments' values (same order as the segment names).
struct SvgBar {
  std::string label;           // under the bar
  std::vector<double> values;  // segment heights
};

/// Stacked bars (e.g. time breakdowns), one colour per segment name, with a legend.
std::string stacked_bars_svg(const std::string& title, const std::string& y_label,
                             std::span<const std::string> segment_names,
                             std::span<const SvgBar> bars);

}  // namespace carat::cli
