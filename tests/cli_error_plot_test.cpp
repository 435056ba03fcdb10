// The CLI's per-frame error plot (apps/carat/error_plot): errors after the ATE's alignment, and
// the log-scale picture's lines, decades, legend, floor and nesting, read back from its SVG text.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <regex>
#include <string>
#include <vector>

#include "carat/registration/trajectory_error.hpp"
#include "error_plot.hpp"

namespace carat::cli {
namespace {

/// A planar drive of `n` frames along a curve (not collinear, so the alignment is unique).
std::vector<Eigen::Isometry3d> curved_drive(int n) {
  std::vector<Eigen::Isometry3d> poses;
  for (int k = 0; k < n; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(10.0 * std::sin(0.1 * k), 10.0 * (1 - std::cos(0.1 * k)),
                                      0.05 * k * k * 0.01);
    poses.push_back(T);
  }
  return poses;
}

TEST(ErrorPlot, ErrorsAreThoseOfTheAteAlignment) {
  const std::vector<Eigen::Isometry3d> reference = curved_drive(12);
  // A rigidly moved copy: zero error once aligned.
  const Eigen::Isometry3d T_offset =
      Eigen::Translation3d(5.0, -3.0, 1.0) * Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ());
  std::vector<Eigen::Isometry3d> moved;
  for (const auto& T : reference) moved.push_back(T_offset * T);
  for (const double e : aligned_position_errors(moved, reference)) EXPECT_LT(e, 1e-9);
  // One frame displaced: per-frame errors whose RMS is the ATE's, largest at that frame.
  std::vector<Eigen::Isometry3d> bumped = moved;
  bumped[7].translation() += Eigen::Vector3d(0.0, 0.5, 0.0);
  const std::vector<double> errors = aligned_position_errors(bumped, reference);
  ASSERT_EQ(errors.size(), reference.size());
  double sum = 0.0;
  for (const double e : errors) sum += e * e;
  EXPECT_NEAR(std::sqrt(sum / static_cast<double>(errors.size())),
              compute_ate(bumped, reference).rmse, 1e-12);
  EXPECT_EQ(std::max_element(errors.begin(), errors.end()) - errors.begin(), 7);
}

/// Points "x,y" of every polyline, in drawing order.
std::vector<std::vector<Eigen::Vector2d>> polylines(const std::string& svg) {
  std::vector<std::vector<Eigen::Vector2d>> out;
  const std::regex line("<polyline [^>]*points=\"([^\"]*)\"");
  const std::regex point("([-0-9.e]+),([-0-9.e]+)");
  for (std::sregex_iterator it(svg.begin(), svg.end(), line), end; it != end; ++it) {
    const std::string points = (*it)[1];
    out.emplace_back();
    for (std::sregex_iterator p(points.begin(), points.end(), point); p != end; ++p)
      out.back().emplace_back(std::stod((*p)[1]), std::stod((*p)[2]));
  }
  return out;
}

TEST(ErrorPlot, LinesDecadesLegendAndFloor) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<FrameErrorLine> lines(4);
  lines[0] = {std::vector<double>(10, 1e-3), "#1f77b4", "GRE exact (M=29)", false};
  lines[0].errors[4] = 3e-3;
  lines[1] = {std::vector<double>(10, 1e-2), "#ff7f0e", "PGO (Hessian)", false};
  lines[1].errors[6] = nan;
  lines[2] = {std::vector<double>(10, 0.0), "#7f7f7f", "initial guess", true};
  lines[3] = {lines[0].errors, "#8c564b", "GRE lossless", false};  // drawn alike: nested
  const std::string svg = frame_errors_svg("errors", lines);

  // One polyline per line; the non-finite error left out, the zeros kept (at the floor).
  const auto drawn = polylines(svg);
  ASSERT_EQ(drawn.size(), 4u);
  EXPECT_EQ(drawn[0].size(), 10u);
  EXPECT_EQ(drawn[1].size(), 9u);
  EXPECT_EQ(drawn[2].size(), 10u);
  EXPECT_EQ(drawn[3], drawn[0]);
  EXPECT_NE(svg.find("stroke-dasharray"), std::string::npos);
  // The two equal lines nested (the first widest, drawn under), the others at the plain width.
  std::vector<double> widths;
  const std::regex width("<polyline [^>]*stroke-width=\"([0-9.]+)\"");
  for (std::sregex_iterator it(svg.begin(), svg.end(), width), end; it != end; ++it)
    widths.push_back(std::stod((*it)[1]));
  EXPECT_EQ(widths, (std::vector<double>{6.0, 2.0, 2.0, 1.5}));

  // A gridline and label per decade from the floor (1e-6) to the largest error (1e-2).
  std::map<int, double> decade_y;
  const std::regex grid(
      "<line [^>]*y1=\"([-0-9.e]+)\"[^>]*stroke=\"#dddddd\"/>\\s*<text[^>]*>1e(-?[0-9]+)</text>");
  for (std::sregex_iterator it(svg.begin(), svg.end(), grid), end; it != end; ++it)
    decade_y[std::stoi((*it)[2])] = std::stod((*it)[1]);
  ASSERT_EQ(decade_y.size(), 5u);
  EXPECT_EQ(decade_y.begin()->first, -6);
  EXPECT_EQ(decade_y.rbegin()->first, -2);

  // Points at the heights their log10 maps to: 3e-3 between 1e-3 and 1e-2, zeros at 1e-6.
  const double per_decade = decade_y[-2] - decade_y[-3];
  EXPECT_LT(per_decade, 0.0);  // up is smaller y
  EXPECT_NEAR(drawn[0][0].y(), decade_y[-3], 0.01);
  EXPECT_NEAR(drawn[0][4].y(), decade_y[-3] + std::log10(3.0) * per_decade, 0.01);
  EXPECT_NEAR(drawn[1][0].y(), decade_y[-2], 0.01);
  for (const auto& p : drawn[2]) EXPECT_NEAR(p.y(), decade_y[-6], 0.01);
  // x is the frame index: evenly spaced; the frame after the left-out one is frame 7.
  const double dx = drawn[0][1].x() - drawn[0][0].x();
  EXPECT_GT(dx, 0.0);
  EXPECT_NEAR(drawn[0][9].x() - drawn[0][0].x(), 9 * dx, 0.01);
  EXPECT_NEAR(drawn[1][6].x(), drawn[0][7].x(), 0.01);

  // The legend: every label, right of all the data; the axes' units and the floor stated.
  const std::regex legend(
      "<text x=\"([-0-9.e]+)\"[^>]*>(GRE exact \\(M=29\\)|PGO \\(Hessian\\)|"
      "initial guess|GRE lossless)</text>");
  int labels = 0;
  for (std::sregex_iterator it(svg.begin(), svg.end(), legend), end; it != end; ++it, ++labels)
    for (const auto& line : drawn)
      for (const auto& p : line) EXPECT_GT(std::stod((*it)[1]), p.x());
  EXPECT_EQ(labels, 4);
  EXPECT_NE(svg.find("frame index"), std::string::npos);
  EXPECT_NE(svg.find("[m]"), std::string::npos);
  EXPECT_NE(svg.find("errors below 1e-6 m drawn at 1e-6 m"), std::string::npos);
  EXPECT_NE(svg.find("equal errors drawn as nested lines"), std::string::npos);
}

}  // namespace
}  // namespace carat::cli
