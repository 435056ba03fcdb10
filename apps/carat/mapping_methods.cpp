#include "mapping_methods.hpp"

#include <algorithm>
#include <cstdio>
#include <string>

#include "cli_support.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

SolverOptions mapping_solver(int threads) {
  SolverOptions options;
  options.max_iterations = 100;
  options.num_threads = threads;
  return options;
}

}  // namespace

std::vector<PairRegistration> register_graph_pairs(const MappingInput& input) {
  AlignSettings settings;
  settings.max_correspondence_distance = input.max_correspondence_distance;
  ProgressBar bar("registering pairs (GICP)", input.progress);
  if (input.store) {
    return register_pairs(*input.store, input.pairs, input.T_world_initial, settings, input.threads,
                          bar.callback());
  }
  return register_pairs(input.frames, input.pairs, input.T_world_initial, settings, input.threads,
                        bar.callback());
}

MethodResult run_pose_graph(const MappingInput& input,
                            const std::vector<PairRegistration>& registrations,
                            PoseGraphInformation information) {
  double registration_s = 0.0;
  for (const PairRegistration& r : registrations) registration_s += r.align_s;
  registration_s /= std::max(input.threads, 1);
  PoseGraphBaselineOptions options;
  options.information = information;
  options.cauchy_scale = input.pgo_cauchy_scale;
  options.solver = mapping_solver(input.threads);
  options.covariance = input.covariance;
  const PoseGraphBaselineResult result =
      optimize_pose_graph_baseline(input.T_world_initial, registrations, options);
  MethodResult out;
  const bool hessian = information == PoseGraphInformation::kHessian;
  out.key = hessian ? "pgo_hessian" : "pgo_identity";
  out.label = hessian ? "PGO (Hessian)" : "PGO (identity)";
  out.T_world_frame = result.T_world_frame;
  out.covariance = result.covariance;
  out.covariance_s = result.covariance_s;
  const TimeBreakdown& t = result.summary.time;
  out.breakdown = {{"registration_s", registration_s},
                   {"linearization_s", t.linearize_s},
                   {"cost_evaluation_s", t.cost_s},
                   {"linear_solve_s", t.assembly_s + t.symbolic_s + t.numeric_s + t.solve_s},
                   {"optimization_s", t.total_s}};
  out.time_s = t.total_s;
  out.total_s = registration_s + t.total_s;
  out.memory_bytes = result.summary.residual_memory_bytes;
  // Every edge is one relative-pose block of the same size.
  if (!registrations.empty())
    out.factor_memory_bytes.assign(registrations.size(), out.memory_bytes / registrations.size());
  out.iterations = result.summary.num_iterations;
  out.termination = to_string(result.summary.termination);
  return out;
}

MethodResult run_registration(const MappingInput& input, ResidualSampling sampling,
                              const RegistrationIterationCallback& on_iteration) {
  GlobalRegistrationOptions options;
  options.sampling = sampling;
  options.residuals = input.residuals;
  options.max_correspondence_distance = input.max_correspondence_distance;
  options.seed = input.seed;
  options.num_threads = input.threads;
  options.rounds = input.rounds;
  options.factor_cauchy_scale = input.gre_cauchy_scale;
  options.factor_excess_cauchy_scale = input.gre_excess_cauchy_scale;
  options.solver = mapping_solver(input.threads);
  options.iteration_callback = on_iteration;
  options.covariance = input.covariance;
  MethodResult out;
  out.key = std::string("gre_") + to_string(sampling);
  out.label = sampling == ResidualSampling::kFull ? "GRE full"
              : sampling == ResidualSampling::kLossless
                  ? "GRE lossless"
                  : std::string("GRE ") + to_string(sampling) + " (M=" +
                        std::to_string(sampling == ResidualSampling::kRandom
                                           ? 3 * ((input.residuals + 2) / 3)
                                           : input.residuals) +
                        ")";
  ProgressBar bar("building factors (" + std::string(to_string(sampling)) + ")", input.progress);
  const GlobalRegistrationResult result =
      input.build_factors ? optimize_registration(
                                [&](std::span<const Eigen::Isometry3d> T_world_frame) {
                                  return input.build_factors(input.pairs, T_world_frame, options);
                                },
                                input.pairs, input.T_world_initial, options)
      : input.store ? optimize_registration(*input.store, input.pairs, input.T_world_initial,
                                            options, bar.callback())
                    : optimize_registration(input.frames, input.pairs, input.T_world_initial,
                                            options, bar.callback());
  bar.finish();
  out.T_world_frame = result.T_world_frame;
  out.covariance = result.covariance;
  out.covariance_s = result.covariance_s;
  const TimeBreakdown& t = result.summary.time;
  out.breakdown = {{"correspondences_s", result.stats.correspondence_s},
                   {"compression_s", result.stats.compression_s},
                   {"factor_minimum_s", result.stats.minimum_s},
                   {"linearization_s", t.linearize_s},
                   {"cost_evaluation_s", t.cost_s},
                   {"linear_solve_s", t.assembly_s + t.symbolic_s + t.numeric_s + t.solve_s},
                   {"optimization_s", t.total_s}};
  // Optimization time as in the paper's Fig. 7: compressing the factors (and, with the excess
  // kernel, each factor's model minimum) plus the LM solve; the correspondence search is the
  // same for every sampling and is reported on its own.
  out.time_s = result.stats.compression_s + result.stats.minimum_s + t.total_s;
  out.total_s = result.stats.correspondence_s + out.time_s;
  out.memory_bytes = result.stats.residual_bytes;
  out.correspondence_bytes = result.stats.correspondence_bytes;
  out.iterations = result.summary.num_iterations;
  out.termination = to_string(result.summary.termination);
  out.factor_costs = result.factor_costs;
  out.factor_memory_bytes = result.factor_residual_bytes;
  out.factor_correspondence_bytes = result.factor_correspondence_bytes;
  return out;
}

nlohmann::json to_json(const MethodResult& result) {
  nlohmann::json j;
  j["method"] = result.key;
  j["label"] = result.label;
  if (result.ate) {
    j["ate_rmse"] = result.ate->rmse;
    j["ate_mean"] = result.ate->mean;
    j["ate_std"] = result.ate->std;
    j["ate_median"] = result.ate->median;
    j["ate_max"] = result.ate->max;
    j["ate_rotation_rmse_deg"] = result.ate->rotation_rmse_deg;
  }
  j["time_s"] = result.time_s;
  j["total_s"] = result.total_s;
  nlohmann::json breakdown = nlohmann::json::object();
  for (const auto& [stage, seconds] : result.breakdown) breakdown[stage] = seconds;
  j["time_breakdown"] = breakdown;
  j["memory_bytes"] = result.memory_bytes;
  j["correspondence_bytes"] = result.correspondence_bytes;
  // Per factor: mean, smallest and largest.
  const auto per_factor = [](const std::vector<std::size_t>& bytes) {
    nlohmann::json summary = nlohmann::json::object();
    if (bytes.empty()) return summary;
    std::size_t total = 0;
    for (std::size_t b : bytes) total += b;
    summary["mean"] = static_cast<double>(total) / static_cast<double>(bytes.size());
    summary["min"] = *std::min_element(bytes.begin(), bytes.end());
    summary["max"] = *std::max_element(bytes.begin(), bytes.end());
    return summary;
  };
  j["memory_bytes_per_factor"] = per_factor(result.factor_memory_bytes);
  j["correspondence_bytes_per_factor"] = per_factor(result.factor_correspondence_bytes);
  j["iterations"] = result.iterations;
  j["termination"] = result.termination;
  return j;
}

std::string results_table(const std::vector<MethodResult>& results) {
  // Padding by hand: "±" is two bytes in UTF-8, which printf's widths would count as two.
  const auto pad = [](std::string text, std::size_t width) {
    std::size_t shown = 0;
    for (unsigned char c : text) shown += (c & 0xC0) != 0x80 ? 1 : 0;
    return std::string(width > shown ? width - shown : 0, ' ') + text;
  };
  std::string out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-22s", "method");
  out += line + pad("ATE mean ± std [m]", 21) + pad("RMSE [m]", 10) + pad("iters", 7) +
         pad("optimize [s]", 13) + pad("total [s]", 11) + pad("residuals", 12) + "\n";
  for (const MethodResult& r : results) {
    char ate[64] = "-", rmse[32] = "-", time[32], total[32];
    if (r.ate) {
      std::snprintf(ate, sizeof(ate), "%.4f ± %.4f", r.ate->mean, r.ate->std);
      std::snprintf(rmse, sizeof(rmse), "%.4f", r.ate->rmse);
    }
    std::snprintf(time, sizeof(time), "%.3f", r.time_s);
    std::snprintf(total, sizeof(total), "%.3f", r.total_s);
    std::snprintf(line, sizeof(line), "%-22s", r.label.c_str());
    out += line + pad(ate, 21) + pad(rmse, 10) + pad(std::to_string(r.iterations), 7) +
           pad(time, 13) + pad(total, 11) +
           pad(format_bytes(static_cast<double>(r.memory_bytes)), 12) + "\n";
  }
  return out;
}

}  // namespace carat::cli
