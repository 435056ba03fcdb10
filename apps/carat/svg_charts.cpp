#include "svg_charts.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "svg_document.hpp"

namespace carat::cli {

std::string line_plot_svg(const std::string& title, const std::string& x_label,
                          const std::string& y_label, std::span<const SvgSeries> series,
                          const LinePlotOptions& options) {
  const bool log_y = options.log_y;
  // The ordinate as drawn (log10 on a log axis), NaN for a point left out.
  const auto fy = [&](double y) {
    if (log_y && options.y_floor > 0.0 && !(y > options.y_floor) && !std::isnan(y))
      y = options.y_floor;
    if (!std::isfinite(y) || (log_y && !(y > 0.0))) return std::numeric_limits<double>::quiet_NaN();
    return log_y ? std::log10(y) : y;
  };
  double x_lo = std::numeric_limits<double>::max(), x_hi = -x_lo;
  double y_lo = x_lo, y_hi = -x_lo;
  for (const auto& s : series) {
    for (std::size_t k = 0; k < s.x.size() && k < s.y.size(); ++k) {
      if (std::isnan(fy(s.y[k]))) continue;
      x_lo = std::min(x_lo, s.x[k]);
      x_hi = std::max(x_hi, s.x[k]);
      y_lo = std::min(y_lo, fy(s.y[k]));
      y_hi = std::max(y_hi, fy(s.y[k]));
    }
  }
  if (!(x_lo < x_hi)) x_hi = x_lo + 1.0;
  if (!(y_lo < y_hi)) y_hi = y_lo + 1.0;
  if (log_y) {
    y_lo = std::floor(y_lo);
    y_hi = std::ceil(y_hi);
  }
  const double left = 90, right = kSvgWidth - kSvgLegendWidth, top = kSvgMargin,
               bottom = kSvgHeight - 70;
  const auto px = [&](double x) { return left + (x - x_lo) / (x_hi - x_lo) * (right - left); };
  const auto py = [&](double y) {
    return bottom - (fy(y) - y_lo) / (y_hi - y_lo) * (bottom - top);
  };
  std::ostringstream s;
  s << svg_header(title);
  s << "<rect x=\"" << left << "\" y=\"" << top << "\" width=\"" << right - left << "\" height=\""
    << bottom - top << "\" fill=\"none\" stroke=\"black\"/>\n";
  char text[64];
  // x ticks: six evenly spaced, or whole numbers when every abscissa is one (iterations).
  bool whole = true;
  for (const SvgSeries& one : series)
    for (const double x : one.x) whole = whole && x == std::floor(x);
  std::vector<double> x_ticks;
  if (whole) {
    const double step = std::max(1.0, std::ceil((x_hi - x_lo) / 5.0));
    for (double x = std::ceil(x_lo); x <= x_hi; x += step) x_ticks.push_back(x);
  } else {
    for (int k = 0; k <= 5; ++k) x_ticks.push_back(x_lo + (x_hi - x_lo) * k / 5);
  }
  for (const double x : x_ticks) {
    std::snprintf(text, sizeof(text), "%.3g", x);
    s << "<text x=\"" << px(x) << "\" y=\"" << bottom + 18 << "\" text-anchor=\"middle\" "
      << "font-size=\"12\">" << text << "</text>\n";
  }
  const int y_ticks = log_y ? static_cast<int>(y_hi - y_lo) : 5;
  for (int k = 0; k <= y_ticks; ++k) {
    const double t = y_lo + (y_hi - y_lo) * k / std::max(y_ticks, 1);
    if (log_y)
      std::snprintf(text, sizeof(text), "1e%d", static_cast<int>(std::lround(t)));
    else
      std::snprintf(text, sizeof(text), "%.3g", t);
    const double y = bottom - (t - y_lo) / (y_hi - y_lo) * (bottom - top);
    s << "<line x1=\"" << left << "\" y1=\"" << y << "\" x2=\"" << right << "\" y2=\"" << y
      << "\" stroke=\"#dddddd\"/>\n<text x=\"" << left - 6 << "\" y=\"" << y + 4
      << "\" text-anchor=\"end\" font-size=\"12\">" << text << "</text>\n";
  }
  s << "<text x=\"" << (left + right) / 2 << "\" y=\"" << kSvgHeight - 30
    << "\" text-anchor=\"middle\" font-size=\"13\">" << svg_escape(x_label) << "</text>\n"
    << "<text x=\"20\" y=\"" << (top + bottom) / 2 << "\" text-anchor=\"middle\" font-size=\"13\" "
    << "transform=\"rotate(-90 20 " << (top + bottom) / 2 << ")\">" << svg_escape(y_label)
    << "</text>\n";
  if (!options.note.empty())
    s << "<text x=\"" << (left + right) / 2 << "\" y=\"" << kSvgHeight - 10
      << "\" text-anchor=\"middle\" font-size=\"11\" fill=\"#555555\">" << svg_escape(options.note)
      << "</text>\n";
  double legend_y = top + 10;
  for (const auto& series_k : series) {
    const char* dash = series_k.dashed ? " stroke-dasharray=\"6 4\"" : "";
    s << "<polyline fill=\"none\" stroke=\"" << series_k.colour << "\" stroke-width=\""
      << series_k.width << '"' << dash << " points=\"";
    for (std::size_t k = 0; k < series_k.x.size() && k < series_k.y.size(); ++k) {
      if (std::isnan(fy(series_k.y[k]))) continue;
      s << px(series_k.x[k]) << ',' << py(series_k.y[k]) << ' ';
    }
    s << "\"/>\n";
    for (std::size_t k = 0; options.markers && k < series_k.x.size() && k < series_k.y.size();
         ++k) {
      if (std::isnan(fy(series_k.y[k]))) continue;
      s << "<circle cx=\"" << px(series_k.x[k]) << "\" cy=\"" << py(series_k.y[k])
        << "\" r=\"3\" fill=\"" << series_k.colour << "\"/>\n";
    }
    s << "<line x1=\"" << right + 10 << "\" y1=\"" << legend_y << "\" x2=\"" << right + 34
      << "\" y2=\"" << legend_y << "\" stroke=\"" << series_k.colour << "\" stroke-width=\"3\""
      << dash << "/>\n<text x=\"" << right + 40 << "\" y=\"" << legend_y + 4
      << "\" font-size=\"12\">" << svg_escape(series_k.label) << "</text>\n";
    legend_y += 20;
  }
  s << "</svg>\n";
  return s.str();
}

std::string line_plot_svg(const std::string& title, const std::string& x_label,
                          const std::string& y_label, std::span<const SvgSeries> series,
                          bool log_y) {
  LinePlotOptions options;
  options.log_y = log_y;
  return line_plot_svg(title, x_label, y_label, series, options);
}

std::string stacked_bars_svg(const std::string& title, const std::string& y_label,
                             std::span<const std::string> segment_names,
                             std::span<const SvgBar> bars) {
  double y_hi = 0.0;
  for (const auto& bar : bars) {
    double total = 0.0;
    for (double v : bar.values) total += std::max(v, 0.0);
    y_hi = std::max(y_hi, total);
  }
  if (!(y_hi > 0.0)) y_hi = 1.0;
  const double left = 90, right = kSvgWidth - kSvgLegendWidth, top = kSvgMargin,
               bottom = kSvgHeight - 90;
  std::ostringstream s;
  s << svg_header(title);
  char text[64];
  for (int k = 0; k <= 5; ++k) {
    const double v = y_hi * k / 5;
    const double y = bottom - (bottom - top) * k / 5;
    std::snprintf(text, sizeof(text), "%.3g", v);
    s << "<line x1=\"" << left << "\" y1=\"" << y << "\" x2=\"" << right << "\" y2=\"" << y
      << "\" stroke=\"#dddddd\"/>\n<text x=\"" << left - 6 << "\" y=\"" << y + 4
      << "\" text-anchor=\"end\" font-size=\"12\">" << text << "</text>\n";
  }
  s << "<text x=\"20\" y=\"" << (top + bottom) / 2 << "\" text-anchor=\"middle\" font-size=\"13\" "
    << "transform=\"rotate(-90 20 " << (top + bottom) / 2 << ")\">" << svg_escape(y_label)
    << "</text>\n";
  const double slot = (right - left) / static_cast<double>(std::max<std::size_t>(bars.size(), 1));
  for (std::size_t b = 0; b < bars.size(); ++b) {
    double base = 0.0;
    const double x = left + slot * (static_cast<double>(b) + 0.2);
    for (std::size_t k = 0; k < bars[b].values.size(); ++k) {
      const double v = std::max(bars[b].values[k], 0.0);
      const double y0 = bottom - base / y_hi * (bottom - top);
      const double y1 = bottom - (base + v) / y_hi * (bottom - top);
      s << "<rect x=\"" << x << "\" y=\"" << y1 << "\" width=\"" << slot * 0.6 << "\" height=\""
        << y0 - y1 << "\" fill=\"" << palette_colour(k) << "\"/>\n";
      base += v;
    }
    s << "<text x=\"" << x + slot * 0.3 << "\" y=\"" << bottom + 18
      << "\" text-anchor=\"middle\" font-size=\"11\">" << svg_escape(bars[b].label) << "</text>\n";
  }
  double legend_y = top + 10;
  for (std::size_t k = 0; k < segment_names.size(); ++k) {
    s << "<rect x=\"" << right + 10 << "\" y=\"" << legend_y - 8 << "\" width=\"14\" height=\"12\" "
      << "fill=\"" << palette_colour(k) << "\"/>\n<text x=\"" << right + 30 << "\" y=\""
      << legend_y + 3 << "\" font-size=\"12\">" << svg_escape(segment_names[k]) << "</text>\n";
    legend_y += 20;
  }
  s << "</svg>\n";
  return s.str();
}
}  // namespace carat::cli
