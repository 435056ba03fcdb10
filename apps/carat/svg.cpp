#include "svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <utility>

#include "carat/base/atomic_file.hpp"
#include "carat/base/error.hpp"

namespace carat::cli {
namespace {

constexpr double kWidth = 800.0;
constexpr double kHeight = 640.0;
constexpr double kMargin = 50.0;
constexpr double kLegendWidth = 180.0;

/// Maps world x/y (metres) into the drawing area, keeping the aspect ratio.
class Viewport {
 public:
  explicit Viewport(const std::vector<Eigen::Vector2d>& points) {
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());
    Eigen::Vector2d hi = -lo;
    for (const auto& p : points) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    if (points.empty()) lo = hi = Eigen::Vector2d::Zero();
    const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0});
    const double area_w = kWidth - 2 * kMargin - kLegendWidth;
    const double area_h = kHeight - 2 * kMargin;
    scale_ = std::min(area_w, area_h) / span;
    center_ = 0.5 * (lo + hi);
    origin_ = Eigen::Vector2d(kMargin + area_w / 2, kMargin + area_h / 2);
  }
  Eigen::Vector2d operator()(const Eigen::Vector3d& p) const {
    return {origin_.x() + (p.x() - center_.x()) * scale_,
            origin_.y() - (p.y() - center_.y()) * scale_};
  }
  double scale() const { return scale_; }

 private:
  double scale_ = 1.0;
  Eigen::Vector2d center_, origin_;
};

std::string escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

std::string header(const std::string& title) {
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kWidth << "\" height=\"" << kHeight
    << "\" viewBox=\"0 0 " << kWidth << ' ' << kHeight << "\" font-family=\"sans-serif\">\n"
    << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    << "<text x=\"" << kWidth / 2 << "\" y=\"28\" text-anchor=\"middle\" font-size=\"18\">"
    << escape(title) << "</text>\n";
  return s.str();
}

/// A scale bar of a round length near 1/5 of the drawing.
std::string scale_bar(const Viewport& view) {
  const double target = (kWidth - 2 * kMargin - kLegendWidth) / 5 / view.scale();
  const double magnitude = std::pow(10.0, std::floor(std::log10(target)));
  double length = magnitude;
  for (double m : {2.0, 5.0, 10.0})
    if (m * magnitude <= target) length = m * magnitude;
  const double pixels = length * view.scale();
  const double y = kHeight - 20;
  std::ostringstream s;
  s << "<line x1=\"" << kMargin << "\" y1=\"" << y << "\" x2=\"" << kMargin + pixels << "\" y2=\""
    << y << "\" stroke=\"black\" stroke-width=\"2\"/>\n"
    << "<text x=\"" << kMargin + pixels + 6 << "\" y=\"" << y + 4 << "\" font-size=\"12\">"
    << length << " m</text>\n";
  return s.str();
}

/// Blue -> cyan -> yellow -> red for t in [0, 1].
std::string ramp(double t) {
  t = std::clamp(t, 0.0, 1.0);
  const double stops[4][3] = {{49, 54, 149}, {116, 173, 209}, {253, 174, 97}, {215, 48, 39}};
  const double x = t * 3.0;
  const int k = std::min(static_cast<int>(x), 2);
  const double f = x - k;
  char out[8];
  std::snprintf(out, sizeof(out), "#%02x%02x%02x",
                static_cast<int>(stops[k][0] + f * (stops[k + 1][0] - stops[k][0])),
                static_cast<int>(stops[k][1] + f * (stops[k + 1][1] - stops[k][1])),
                static_cast<int>(stops[k][2] + f * (stops[k + 1][2] - stops[k][2])));
  return out;
}

}  // namespace

std::string trajectories_svg(const std::string& title, std::span<const SvgTrajectory> lines) {
  std::vector<Eigen::Vector2d> all;
  for (const auto& line : lines)
    for (const auto& T : line.poses) all.push_back(T.translation().head<2>());
  const Viewport view(all);
  std::ostringstream s;
  s << header(title);
  double legend_y = kMargin + 10;
  for (const auto& line : lines) {
    s << "<polyline fill=\"none\" stroke=\"" << line.colour << "\" stroke-width=\"1.6\""
      << (line.dashed ? " stroke-dasharray=\"6 4\"" : "") << " points=\"";
    for (const auto& T : line.poses) {
      const Eigen::Vector2d p = view(T.translation());
      s << p.x() << ',' << p.y() << ' ';
    }
    s << "\"/>\n";
    const double x = kWidth - kLegendWidth;
    s << "<line x1=\"" << x << "\" y1=\"" << legend_y << "\" x2=\"" << x + 24 << "\" y2=\""
      << legend_y << "\" stroke=\"" << line.colour << "\" stroke-width=\"3\""
      << (line.dashed ? " stroke-dasharray=\"6 4\"" : "") << "/>\n"
      << "<text x=\"" << x + 30 << "\" y=\"" << legend_y + 4 << "\" font-size=\"12\">"
      << escape(line.label) << "</text>\n";
    legend_y += 20;
  }
  s << scale_bar(view) << "</svg>\n";
  return s.str();
}

std::string graph_svg(const std::string& title, std::span<const Eigen::Isometry3d> poses,
                      std::span<const SvgEdge> edges, const std::string& value_label) {
  std::vector<Eigen::Vector2d> all;
  for (const auto& T : poses) all.push_back(T.translation().head<2>());
  const Viewport view(all);
  double lo = std::numeric_limits<double>::max(), hi = 0.0;
  for (const auto& e : edges) {
    if (e.value > 0.0 && std::isfinite(e.value)) {
      lo = std::min(lo, e.value);
      hi = std::max(hi, e.value);
    }
  }
  if (!(lo <= hi)) lo = hi = 1.0;
  const double log_lo = std::log10(lo), log_hi = std::log10(hi);
  const auto t_of = [&](double v) {
    if (!(v > 0.0) || log_hi <= log_lo) return 0.0;
    return (std::log10(v) - log_lo) / (log_hi - log_lo);
  };
  std::ostringstream s;
  s << header(title);
  std::vector<SvgEdge> sorted(edges.begin(), edges.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const SvgEdge& a, const SvgEdge& b) { return a.value < b.value; });  // red on top
  for (const auto& e : sorted) {
    if (e.from < 0 || e.to < 0 || e.from >= static_cast<int>(poses.size()) ||
        e.to >= static_cast<int>(poses.size()))
      continue;
    const Eigen::Vector2d a = view(poses[static_cast<std::size_t>(e.from)].translation());
    const Eigen::Vector2d b = view(poses[static_cast<std::size_t>(e.to)].translation());
    s << "<line x1=\"" << a.x() << "\" y1=\"" << a.y() << "\" x2=\"" << b.x() << "\" y2=\"" << b.y()
      << "\" stroke=\"" << ramp(t_of(e.value)) << "\" stroke-width=\"1\" opacity=\"0.7\"/>\n";
  }
  for (const auto& T : poses) {
    const Eigen::Vector2d p = view(T.translation());
    s << "<circle cx=\"" << p.x() << "\" cy=\"" << p.y() << "\" r=\"2.2\" fill=\"black\"/>\n";
  }
  // Colour bar.
  const double x = kWidth - kLegendWidth + 10, top = kMargin + 20, height = 200;
  for (int k = 0; k < 50; ++k) {
    s << "<rect x=\"" << x << "\" y=\"" << top + height * (49 - k) / 50
      << "\" width=\"16\" height=\"" << height / 50 + 0.5 << "\" fill=\"" << ramp(k / 49.0)
      << "\"/>\n";
  }
  char lo_text[32], hi_text[32];
  std::snprintf(lo_text, sizeof(lo_text), "%.3g", lo);
  std::snprintf(hi_text, sizeof(hi_text), "%.3g", hi);
  s << "<text x=\"" << x + 22 << "\" y=\"" << top + 10 << "\" font-size=\"12\">" << hi_text
    << "</text>\n<text x=\"" << x + 22 << "\" y=\"" << top + height << "\" font-size=\"12\">"
    << lo_text << "</text>\n<text x=\"" << x << "\" y=\"" << top - 8 << "\" font-size=\"12\">"
    << escape(value_label) << "</text>\n";
  s << scale_bar(view) << "</svg>\n";
  return s.str();
}

std::string line_plot_svg(const std::string& title, const std::string& x_label,
                          const std::string& y_label, std::span<const SvgSeries> series,
                          bool log_y) {
  const auto fy = [&](double y) { return log_y ? std::log10(y) : y; };
  double x_lo = std::numeric_limits<double>::max(), x_hi = -x_lo;
  double y_lo = x_lo, y_hi = -x_lo;
  for (const auto& s : series) {
    for (std::size_t k = 0; k < s.x.size() && k < s.y.size(); ++k) {
      if (log_y && !(s.y[k] > 0.0)) continue;
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
  const double left = 90, right = kWidth - kLegendWidth, top = kMargin, bottom = kHeight - 70;
  const auto px = [&](double x) { return left + (x - x_lo) / (x_hi - x_lo) * (right - left); };
  const auto py = [&](double y) {
    return bottom - (fy(y) - y_lo) / (y_hi - y_lo) * (bottom - top);
  };
  std::ostringstream s;
  s << header(title);
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
  s << "<text x=\"" << (left + right) / 2 << "\" y=\"" << kHeight - 30
    << "\" text-anchor=\"middle\" font-size=\"13\">" << escape(x_label) << "</text>\n"
    << "<text x=\"20\" y=\"" << (top + bottom) / 2 << "\" text-anchor=\"middle\" font-size=\"13\" "
    << "transform=\"rotate(-90 20 " << (top + bottom) / 2 << ")\">" << escape(y_label)
    << "</text>\n";
  double legend_y = top + 10;
  for (const auto& series_k : series) {
    s << "<polyline fill=\"none\" stroke=\"" << series_k.colour
      << "\" stroke-width=\"2\" points=\"";
    for (std::size_t k = 0; k < series_k.x.size() && k < series_k.y.size(); ++k) {
      if (log_y && !(series_k.y[k] > 0.0)) continue;
      s << px(series_k.x[k]) << ',' << py(series_k.y[k]) << ' ';
    }
    s << "\"/>\n";
    for (std::size_t k = 0; k < series_k.x.size() && k < series_k.y.size(); ++k) {
      if (log_y && !(series_k.y[k] > 0.0)) continue;
      s << "<circle cx=\"" << px(series_k.x[k]) << "\" cy=\"" << py(series_k.y[k])
        << "\" r=\"3\" fill=\"" << series_k.colour << "\"/>\n";
    }
    s << "<line x1=\"" << right + 10 << "\" y1=\"" << legend_y << "\" x2=\"" << right + 34
      << "\" y2=\"" << legend_y << "\" stroke=\"" << series_k.colour << "\" stroke-width=\"3\"/>\n"
      << "<text x=\"" << right + 40 << "\" y=\"" << legend_y + 4 << "\" font-size=\"12\">"
      << escape(series_k.label) << "</text>\n";
    legend_y += 20;
  }
  s << "</svg>\n";
  return s.str();
}

std::string stacked_bars_svg(const std::string& title, const std::string& y_label,
                             std::span<const std::string> segment_names,
                             std::span<const SvgBar> bars) {
  static const char* const kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                         "#9467bd", "#8c564b", "#e377c2", "#17becf"};
  double y_hi = 0.0;
  for (const auto& bar : bars) {
    double total = 0.0;
    for (double v : bar.values) total += std::max(v, 0.0);
    y_hi = std::max(y_hi, total);
  }
  if (!(y_hi > 0.0)) y_hi = 1.0;
  const double left = 90, right = kWidth - kLegendWidth, top = kMargin, bottom = kHeight - 90;
  std::ostringstream s;
  s << header(title);
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
    << "transform=\"rotate(-90 20 " << (top + bottom) / 2 << ")\">" << escape(y_label)
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
        << y0 - y1 << "\" fill=\"" << kColours[k % 8] << "\"/>\n";
      base += v;
    }
    s << "<text x=\"" << x + slot * 0.3 << "\" y=\"" << bottom + 18
      << "\" text-anchor=\"middle\" font-size=\"11\">" << escape(bars[b].label) << "</text>\n";
  }
  double legend_y = top + 10;
  for (std::size_t k = 0; k < segment_names.size(); ++k) {
    s << "<rect x=\"" << right + 10 << "\" y=\"" << legend_y - 8 << "\" width=\"14\" height=\"12\" "
      << "fill=\"" << kColours[k % 8] << "\"/>\n<text x=\"" << right + 30 << "\" y=\""
      << legend_y + 3 << "\" font-size=\"12\">" << escape(segment_names[k]) << "</text>\n";
    legend_y += 20;
  }
  s << "</svg>\n";
  return s.str();
}

std::string point_panels_svg(const std::string& title, std::span<const SvgPointPanel> panels,
                             std::span<const std::string> class_labels,
                             std::span<const std::string> class_colours, double half_extent) {
  constexpr double kPanel = 380.0, kGap = 20.0, kTop = 70.0, kBottom = 70.0;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(-half_extent), hi = -lo;
  for (const SvgPointPanel& panel : panels) {
    if (panel.mark_classes.size() != panel.marks.size())
      throw Error("point_panels_svg: " + std::to_string(panel.marks.size()) + " marks but " +
                  std::to_string(panel.mark_classes.size()) + " classes");
    for (std::size_t k = 0; k < panel.marks.size(); ++k) {
      const int c = panel.mark_classes[k];
      if (c < 0 || static_cast<std::size_t>(c) >= class_labels.size() ||
          static_cast<std::size_t>(c) >= class_colours.size())
        throw Error("point_panels_svg: mark class " + std::to_string(c) +
                    " has no label or colour");
      lo = lo.cwiseMin(panel.marks[k].head<2>());
      hi = hi.cwiseMax(panel.marks[k].head<2>());
    }
  }
  const double span = 1.04 * std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0});  // a margin
  const double scale = kPanel / span;                                            // pixels per metre
  const Eigen::Vector2d center = 0.5 * (lo + hi);
  const double width = kGap + static_cast<double>(panels.size()) * (kPanel + kGap);
  const double height = kTop + kPanel + kBottom;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
    << "\" viewBox=\"0 0 " << width << ' ' << height << "\" font-family=\"sans-serif\">\n"
    << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    << "<text x=\"" << width / 2 << "\" y=\"28\" text-anchor=\"middle\" font-size=\"18\">"
    << escape(title) << "</text>\n";
  char text[64];
  for (std::size_t p = 0; p < panels.size(); ++p) {
    const SvgPointPanel& panel = panels[p];
    const double left = kGap + static_cast<double>(p) * (kPanel + kGap);
    const auto px = [&](const Eigen::Vector3d& point) {
      return Eigen::Vector2d(left + kPanel / 2 + (point.x() - center.x()) * scale,
                             kTop + kPanel / 2 - (point.y() - center.y()) * scale);
    };
    s << "<g class=\"panel\">\n<text x=\"" << left + kPanel / 2 << "\" y=\"" << kTop - 12
      << "\" text-anchor=\"middle\" font-size=\"14\">" << escape(panel.title) << "</text>\n"
      << "<rect x=\"" << left << "\" y=\"" << kTop << "\" width=\"" << kPanel << "\" height=\""
      << kPanel << "\" fill=\"none\" stroke=\"black\"/>\n";
    // The cloud: one dot per occupied pixel, as zero-length round-capped strokes of one path.
    std::vector<std::pair<int, int>> pixels;
    for (const Eigen::Vector3d& point : panel.cloud) {
      const Eigen::Vector2d q = px(point);
      if (q.x() < left || q.x() > left + kPanel || q.y() < kTop || q.y() > kTop + kPanel) continue;
      pixels.emplace_back(static_cast<int>(std::lround(q.x())),
                          static_cast<int>(std::lround(q.y())));
    }
    std::sort(pixels.begin(), pixels.end());
    pixels.erase(std::unique(pixels.begin(), pixels.end()), pixels.end());
    s << "<path class=\"cloud\" fill=\"none\" stroke=\"#b0b0b0\" stroke-width=\"1.2\" "
      << "stroke-linecap=\"round\" d=\"";
    for (const auto& [x, y] : pixels) s << 'M' << x << ' ' << y << "h0";
    s << "\"/>\n<g class=\"marks\">\n";
    for (std::size_t k = 0; k < panel.marks.size(); ++k) {
      const Eigen::Vector2d q = px(panel.marks[k]);
      const auto c = static_cast<std::size_t>(panel.mark_classes[k]);
      std::snprintf(text, sizeof(text), "%.1f\" cy=\"%.1f", q.x(), q.y());
      s << "<circle cx=\"" << text << "\" r=\"3.5\" fill=\"" << class_colours[c]
        << "\" data-class=\"" << escape(class_labels[c]) << "\"/>\n";
    }
    s << "</g>\n</g>\n";
  }
  // Legend and a scale bar of a round length near 1/5 of a panel.
  double legend_x = kGap;
  for (std::size_t c = 0; c < class_labels.size() && c < class_colours.size(); ++c) {
    s << "<circle cx=\"" << legend_x + 6 << "\" cy=\"" << height - 30 << "\" r=\"5\" fill=\""
      << class_colours[c] << "\"/>\n<text x=\"" << legend_x + 16 << "\" y=\"" << height - 25
      << "\" font-size=\"13\">" << escape(class_labels[c]) << "</text>\n";
    legend_x += 140;
  }
  const double target = kPanel / 5 / scale;
  const double magnitude = std::pow(10.0, std::floor(std::log10(target)));
  double length = magnitude;
  for (double m : {2.0, 5.0, 10.0})
    if (m * magnitude <= target) length = m * magnitude;
  const double bar_right = width - kGap;
  std::snprintf(text, sizeof(text), "%g m", length);
  s << "<line x1=\"" << bar_right - length * scale << "\" y1=\"" << height - 30 << "\" x2=\""
    << bar_right << "\" y2=\"" << height - 30 << "\" stroke=\"black\" stroke-width=\"2\"/>\n"
    << "<text x=\"" << bar_right - length * scale / 2 << "\" y=\"" << height - 38
    << "\" text-anchor=\"middle\" font-size=\"12\">" << text << "</text>\n</svg>\n";
  return s.str();
}

void write_svg(const std::filesystem::path& path, const std::string& svg) {
  write_file_atomically(path, [&](std::ostream& out) { out << svg; });
}

}  // namespace carat::cli
