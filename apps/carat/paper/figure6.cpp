// carat paper, Fig. 6: the full factors' registration error and the ATE at every LM iteration
// of GRE full, exact and lossless on the synthetic dense sequence.
#include <algorithm>

#include "carat/registration/trajectory_error.hpp"
#include "iteration_trace.hpp"
#include "paper.hpp"
#include "report_table.hpp"
#include "svg.hpp"

namespace carat::cli::paper {
namespace {

GlobalRegistrationOptions lossless_options(const MappingOptions& mapping) {
  GlobalRegistrationOptions options;
  options.sampling = ResidualSampling::kLossless;
  options.max_correspondence_distance = mapping.registration.max_correspondence_distance;
  options.seed = mapping.registration.seed;
  options.num_threads = mapping.num_threads;
  return options;
}

}  // namespace

RegistrationErrorProbe::RegistrationErrorProbe(FrameStore& frames, const MapGraph& graph,
                                               const MappingOptions& options)
    : problem_(build_registration_problem(frames, graph.pairs, graph.T_world_start,
                                          lossless_options(options))) {}

double RegistrationErrorProbe::operator()(std::span<const Eigen::Isometry3d> T_world_frame) {
  for (std::size_t i = 0; i < problem_.frame_variables.size(); ++i)
    problem_.problem.set_se3(problem_.frame_variables[i], T_world_frame[i]);
  return problem_.problem.evaluate_cost();
}

RegistrationIterationCallback RegistrationErrorProbe::recorder(
    std::span<const Eigen::Isometry3d> T_world_truth, IterationTrace* trace) {
  return [this, T_world_truth, trace](const IterationSummary& row,
                                      std::span<const Eigen::Isometry3d> T_world_frame) {
    trace->iteration.push_back(row.iteration);
    trace->cost.push_back(row.cost);
    trace->registration_error.push_back((*this)(T_world_frame));
    trace->ate_rmse.push_back(compute_ate(T_world_frame, T_world_truth).rmse);
    return CallbackResult::kContinue;
  };
}

void figure_six(const std::vector<IterationTrace>& traces, const fs::path& dir, Report* report) {
  std::string& md = report->markdown;
  md +=
      "## Fig. 6: registration error and ATE at every LM iteration (synthetic dense "
      "sequence)\n\n";
  md +=
      "Each Table IV solve, followed iteration by iteration. The registration error is 1/2 the "
      "sum of squared residuals of every full factor (all correspondences, fixed at the initial "
      "poses) at the iterate, whatever rows the method kept; carat evaluates it from the "
      "lossless rows, which have the full factors' cost at every pose. The paper shows KITTI "
      "00; here the synthetic sequence.\n\n";
  ReportTable table({"method", "iterations", "registration error: start", "end",
                     "end minus full's end", "ATE RMSE [m]: start", "end"});
  double full_end = 0.0;
  for (const IterationTrace& t : traces)
    if (t.key == "gre_full" && !t.registration_error.empty())
      full_end = t.registration_error.back();
  nlohmann::json methods = nlohmann::json::array();
  std::vector<SvgSeries> error_series, ate_series;
  static const char* const kColours[] = {"#000000", "#2ca02c", "#1f77b4", "#9467bd", "#d62728"};
  for (std::size_t k = 0; k < traces.size(); ++k) {
    const IterationTrace& t = traces[k];
    if (t.iteration.empty()) continue;
    table.add_row(
        {t.label, std::to_string(t.iteration.back()), fmt("%.6g", t.registration_error.front()),
         fmt("%.9g", t.registration_error.back()),
         fmt("%+.2e", t.registration_error.back() - full_end), fmt("%.4f", t.ate_rmse.front()),
         fmt("%.4f", t.ate_rmse.back())},
        {{"method", t.key}, {"label", t.label}});
    methods.push_back({{"method", t.key},
                       {"label", t.label},
                       {"iteration", t.iteration},
                       {"cost", t.cost},
                       {"registration_error", t.registration_error},
                       {"ate_rmse", t.ate_rmse}});
    const std::vector<double> x(t.iteration.begin(), t.iteration.end());
    const char* colour = kColours[k % std::size(kColours)];
    error_series.push_back({x, t.registration_error, colour, t.label});
    ate_series.push_back({x, t.ate_rmse, colour, t.label});
  }
  md += table.markdown() + "\n";
  report->files.push_back(dir / "fig6_registration_error.svg");
  write_svg(report->files.back(),
            line_plot_svg("Fig. 6: global registration error per iteration", "LM iteration",
                          "registration error (full factors)", error_series, true));
  report->files.push_back(dir / "fig6_ate.svg");
  write_svg(report->files.back(), line_plot_svg("Fig. 6: ATE per iteration", "LM iteration",
                                                "ATE RMSE [m]", ate_series, true));
  md += "![Fig. 6: registration error](fig6_registration_error.svg)\n";
  md += "![Fig. 6: ATE](fig6_ate.svg)\n\n";
  report->json["figure6"] = {{"methods", methods}};
}

}  // namespace carat::cli::paper
