#include "svg_top_view.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <utility>

#include "carat/base/error.hpp"
#include "svg_document.hpp"

namespace carat::cli {
namespace {

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
    const double area_w = kSvgWidth - 2 * kSvgMargin - kSvgLegendWidth;
    const double area_h = kSvgHeight - 2 * kSvgMargin;
    scale_ = std::min(area_w, area_h) / span;
    center_ = 0.5 * (lo + hi);
    origin_ = Eigen::Vector2d(kSvgMargin + area_w / 2, kSvgMargin + area_h / 2);
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

/// The largest of 1, 2, 5 times a power of ten that is at most `target` (metres).
double round_length(double target) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(target)));
  double length = magnitude;
  for (double m : {2.0, 5.0, 10.0})
    if (m * magnitude <= target) length = m * magnitude;
  return length;
}

/// A scale bar of a round length near 1/5 of the drawing.
std::string scale_bar(const Viewport& view) {
  const double length =
      round_length((kSvgWidth - 2 * kSvgMargin - kSvgLegendWidth) / 5 / view.scale());
  const double pixels = length * view.scale();
  const double y = kSvgHeight - 20;
  std::ostringstream s;
  s << "<line x1=\"" << kSvgMargin << "\" y1=\"" << y << "\" x2=\"" << kSvgMargin + pixels
    << "\" y2=\"" << y << "\" stroke=\"black\" stroke-width=\"2\"/>\n"
    << "<text x=\"" << kSvgMargin + pixels + 6 << "\" y=\"" << y + 4 << "\" font-size=\"12\">"
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
  s << svg_header(title);
  double legend_y = kSvgMargin + 10;
  for (const auto& line : lines) {
    s << "<polyline fill=\"none\" stroke=\"" << line.colour << "\" stroke-width=\"1.6\""
      << (line.dashed ? " stroke-dasharray=\"6 4\"" : "") << " points=\"";
    for (const auto& T : line.poses) {
      const Eigen::Vector2d p = view(T.translation());
      s << p.x() << ',' << p.y() << ' ';
    }
    s << "\"/>\n";
    const double x = kSvgWidth - kSvgLegendWidth;
    s << "<line x1=\"" << x << "\" y1=\"" << legend_y << "\" x2=\"" << x + 24 << "\" y2=\""
      << legend_y << "\" stroke=\"" << line.colour << "\" stroke-width=\"3\""
      << (line.dashed ? " stroke-dasharray=\"6 4\"" : "") << "/>\n"
      << "<text x=\"" << x + 30 << "\" y=\"" << legend_y + 4 << "\" font-size=\"12\">"
      << svg_escape(line.label) << "</text>\n";
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
  s << svg_header(title);
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
  const double x = kSvgWidth - kSvgLegendWidth + 10, top = kSvgMargin + 20, height = 200;
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
    << svg_escape(value_label) << "</text>\n";
  s << scale_bar(view) << "</svg>\n";
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
    << svg_escape(title) << "</text>\n";
  char text[64];
  for (std::size_t p = 0; p < panels.size(); ++p) {
    const SvgPointPanel& panel = panels[p];
    const double left = kGap + static_cast<double>(p) * (kPanel + kGap);
    const auto px = [&](const Eigen::Vector3d& point) {
      return Eigen::Vector2d(left + kPanel / 2 + (point.x() - center.x()) * scale,
                             kTop + kPanel / 2 - (point.y() - center.y()) * scale);
    };
    s << "<g class=\"panel\">\n<text x=\"" << left + kPanel / 2 << "\" y=\"" << kTop - 12
      << "\" text-anchor=\"middle\" font-size=\"14\">" << svg_escape(panel.title) << "</text>\n"
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
        << "\" data-class=\"" << svg_escape(class_labels[c]) << "\"/>\n";
    }
    s << "</g>\n</g>\n";
  }
  // Legend and a scale bar of a round length near 1/5 of a panel.
  double legend_x = kGap;
  for (std::size_t c = 0; c < class_labels.size() && c < class_colours.size(); ++c) {
    s << "<circle cx=\"" << legend_x + 6 << "\" cy=\"" << height - 30 << "\" r=\"5\" fill=\""
      << class_colours[c] << "\"/>\n<text x=\"" << legend_x + 16 << "\" y=\"" << height - 25
      << "\" font-size=\"13\">" << svg_escape(class_labels[c]) << "</text>\n";
    legend_x += 140;
  }
  const double length = round_length(kPanel / 5 / scale);
  const double bar_right = width - kGap;
  std::snprintf(text, sizeof(text), "%g m", length);
  s << "<line x1=\"" << bar_right - length * scale << "\" y1=\"" << height - 30 << "\" x2=\""
    << bar_right << "\" y2=\"" << height - 30 << "\" stroke=\"black\" stroke-width=\"2\"/>\n"
    << "<text x=\"" << bar_right - length * scale / 2 << "\" y=\"" << height - 38
    << "\" text-anchor=\"middle\" font-size=\"12\">" << text << "</text>\n</svg>\n";
  return s.str();
}

}  // namespace carat::cli
