#include "mapping_methods.hpp"

#include <algorithm>
#include <cstdio>
#include <string>

#include "cli_support.hpp"
#include "progress.hpp"

namespace carat::cli {
namespace {

/// The seconds of a solve's linear algebra.
double linear_solve_s(const TimeBreakdown& t) {
  return t.assembly_s + t.symbolic_s + t.numeric_s + t.solve_s;
}

}  // namespace

std::string mapping_stage_label(MappingStage stage) {
  switch (stage) {
    case MappingStage::kLoops:
      return "closing loops";
    case MappingStage::kDenseGraph:
      return "overlap assessment";
    case MappingStage::kPairRegistration:
      return "registering pairs (GICP)";
    case MappingStage::kFactors:
      return "building factors";
  }
  return "";
}

void check_full_factor_memory(std::span<const std::size_t> points, std::span<const FramePair> pairs,
                              const std::string& advice) {
  double bytes = 0.0;
  for (const FramePair& pair : pairs)
    bytes += 96.0 * static_cast<double>(points[static_cast<std::size_t>(pair.source)]);
  const double available = static_cast<double>(available_memory_bytes());
  if (bytes > 0.8 * available) {
    throw UsageError("the " + std::to_string(pairs.size()) +
                     " full GRE factors of the dense graph would take up to " +
                     format_bytes(bytes) + "; " + format_bytes(available) + " are available (" +
                     advice + ")");
  }
}

MappingOptions registration_method(MappingOptions options, ResidualSampling sampling) {
  options.method = MappingMethod::kRegistration;
  options.registration.sampling = sampling;
  return options;
}

MappingOptions pose_graph_method(MappingOptions options, PoseGraphInformation information) {
  options.method = MappingMethod::kPoseGraph;
  options.pose_graph.information = information;
  return options;
}

MethodResult describe_method(const MappingResult& result, const MappingOptions& options) {
  MethodResult out;
  out.T_world_frame = result.T_world_frame;
  out.covariance = result.covariance;
  out.covariance_s = result.covariance_s;
  out.memory_bytes = result.summary.residual_memory_bytes;
  out.factor_memory_bytes = result.factor_residual_bytes;
  out.iterations = result.summary.num_iterations;
  out.termination = to_string(result.summary.termination);
  const TimeBreakdown& t = result.summary.time;
  if (result.method == MappingMethod::kPoseGraph) {
    const bool hessian = options.pose_graph.information == PoseGraphInformation::kHessian;
    out.key = hessian ? "pgo_hessian" : "pgo_identity";
    out.label = hessian ? "PGO (Hessian)" : "PGO (identity)";
    double registration_s = 0.0;
    for (const PairRegistration& r : result.registrations) registration_s += r.align_s;
    registration_s /= std::max(options.num_threads, 1);
    out.breakdown = {{"registration_s", registration_s},
                     {"linearization_s", t.linearize_s},
                     {"cost_evaluation_s", t.cost_s},
                     {"linear_solve_s", linear_solve_s(t)},
                     {"optimization_s", t.total_s}};
    out.time_s = t.total_s;
    out.total_s = registration_s + t.total_s;
    return out;
  }
  const ResidualSampling sampling = options.registration.sampling;
  const int residuals = options.registration.residuals;
  out.key = std::string("gre_") + to_string(sampling);
  out.label =
      sampling == ResidualSampling::kFull ? "GRE full"
      : sampling == ResidualSampling::kLossless
          ? "GRE lossless"
          : std::string("GRE ") + to_string(sampling) + " (M=" +
                std::to_string(sampling == ResidualSampling::kRandom ? 3 * ((residuals + 2) / 3)
                                                                     : residuals) +
                ")";
  const RegistrationFactorStats& s = result.factor_stats;
  out.breakdown = {{"correspondences_s", s.correspondence_s},
                   {"compression_s", s.compression_s},
                   {"factor_minimum_s", s.minimum_s},
                   {"linearization_s", t.linearize_s},
                   {"cost_evaluation_s", t.cost_s},
                   {"linear_solve_s", linear_solve_s(t)},
                   {"optimization_s", t.total_s}};
  // Optimization time as in the paper's Fig. 7: compressing the factors (and, with the excess
  // kernel, each factor's model minimum) plus the LM solve; the correspondence search is the
  // same for every sampling and is reported on its own.
  out.time_s = s.compression_s + s.minimum_s + t.total_s;
  out.total_s = s.correspondence_s + out.time_s;
  out.memory_bytes = s.residual_bytes;
  out.correspondence_bytes = s.correspondence_bytes;
  out.factor_costs = result.factor_costs;
  out.factor_correspondence_bytes = result.factor_correspondence_bytes;
  return out;
}

MethodResult run_method(FrameStore& frames, const MapGraph& graph, const MappingOptions& options,
                        bool progress, std::vector<PairRegistration>* registrations) {
  StageBars<MappingStage> bars(mapping_stage_label, progress);
  const bool reuse = registrations != nullptr && !registrations->empty();
  MappingResult result = optimize_map(frames, graph, options, bars.callback(),
                                      reuse ? std::span<const PairRegistration>(*registrations)
                                            : std::span<const PairRegistration>());
  bars.finish();
  if (registrations != nullptr && !reuse) *registrations = result.registrations;
  return describe_method(result, options);
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
