#include "carat/solver/solver_options.hpp"

#include <cmath>
#include <string>

#include "carat/base/error.hpp"

namespace carat {
namespace {

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

}  // namespace

const char* to_string(LmStart start) {
  switch (start) {
    case LmStart::kAuto:
      return "auto";
    case LmStart::kGaussNewton:
      return "gauss_newton";
    case LmStart::kTrustRegion:
      return "trust_region";
  }
  return "unknown";
}

const char* to_string(Method method) {
  switch (method) {
    case Method::kLevenbergMarquardt:
      return "lm";
    case Method::kGaussNewton:
      return "gn";
  }
  return "unknown";
}

LmStart parse_lm_start(std::string_view name) {
  for (LmStart start : {LmStart::kAuto, LmStart::kGaussNewton, LmStart::kTrustRegion}) {
    if (name == to_string(start)) return start;
  }
  throw Error("unknown LM start " + quote_bytes(name) +
              " (valid: auto, gauss_newton, trust_region)");
}

Method parse_method(std::string_view name) {
  if (name == "lm") return Method::kLevenbergMarquardt;
  if (name == "gn") return Method::kGaussNewton;
  throw Error("unknown method " + quote_bytes(name) + " (valid: lm, gn)");
}

const char* to_string(Ordering ordering) {
  switch (ordering) {
    case Ordering::kAuto:
      return "auto";
    case Ordering::kAmd:
      return "amd";
    case Ordering::kMetis:
      return "metis";
  }
  return "unknown";
}

Ordering parse_ordering(std::string_view name) {
  if (name == "auto") return Ordering::kAuto;
  if (name == "amd") return Ordering::kAmd;
  if (name == "metis") return Ordering::kMetis;
  throw Error("unknown ordering " + quote_bytes(name) + " (valid: auto, amd, metis)");
}

const char* to_string(LinearSolver solver) {
  switch (solver) {
    case LinearSolver::kAuto:
      return "auto";
    case LinearSolver::kSchur:
      return "schur";
    case LinearSolver::kCholesky:
      return "cholesky";
  }
  return "unknown";
}

LinearSolver parse_linear_solver(std::string_view name) {
  if (name == "auto") return LinearSolver::kAuto;
  if (name == "schur") return LinearSolver::kSchur;
  if (name == "cholesky") return LinearSolver::kCholesky;
  throw Error("unknown linear solver " + quote_bytes(name) + " (valid: auto, schur, cholesky)");
}

bool SolverOptions::validate(std::string* error) const {
  if (max_iterations < 0)
    return fail(error, "max_iterations must be >= 0, got " + std::to_string(max_iterations));
  if (num_threads < 1)
    return fail(error, "num_threads must be >= 1, got " + std::to_string(num_threads));
  const struct {
    const char* name;
    double value;
  } non_negative[] = {{"function_tolerance", function_tolerance},
                      {"gradient_tolerance", gradient_tolerance},
                      {"parameter_tolerance", parameter_tolerance},
                      {"min_relative_decrease", min_relative_decrease},
                      {"min_trust_region_radius", min_trust_region_radius},
                      {"min_lm_diagonal", min_lm_diagonal},
                      {"max_linear_system_bytes", max_linear_system_bytes}};
  for (const auto& item : non_negative) {
    if (!(item.value >= 0.0) || !std::isfinite(item.value)) {
      return fail(error, std::string(item.name) + " must be finite and >= 0, got " +
                             std::to_string(item.value));
    }
  }
  if (!(initial_trust_region_radius > 0.0) || !std::isfinite(initial_trust_region_radius)) {
    return fail(error, "initial_trust_region_radius must be finite and > 0");
  }
  if (!(max_trust_region_radius >= initial_trust_region_radius)) {
    return fail(error, "max_trust_region_radius must be >= initial_trust_region_radius");
  }
  if (max_trust_region_growth != 0.0 &&
      (!(max_trust_region_growth >= 1.0) || !std::isfinite(max_trust_region_growth))) {
    return fail(error, "max_trust_region_growth must be 0 (automatic) or finite and >= 1, got " +
                           std::to_string(max_trust_region_growth));
  }
  if (!(max_lm_diagonal >= min_lm_diagonal)) {
    return fail(error, "max_lm_diagonal must be >= min_lm_diagonal");
  }
  if (min_relative_decrease >= 1.0) return fail(error, "min_relative_decrease must be < 1");
  if (!(gauss_newton_phase_radius > 0.0) ||
      !(gauss_newton_phase_radius <= max_trust_region_radius)) {
    return fail(error, "gauss_newton_phase_radius must be > 0 and <= max_trust_region_radius");
  }
  if (!(gauss_newton_phase_min_gain >= 0.0 && gauss_newton_phase_min_gain <= 1.0)) {
    return fail(error, "gauss_newton_phase_min_gain must be in [0, 1], got " +
                           std::to_string(gauss_newton_phase_min_gain));
  }
  if (!(factor_reuse_ratio >= 0.0) || !std::isfinite(factor_reuse_ratio)) {
    return fail(error, "factor_reuse_ratio must be finite and >= 0, got " +
                           std::to_string(factor_reuse_ratio));
  }
  if (anderson_memory < 0 || anderson_memory > 64) {
    return fail(error,
                "anderson_memory must be in [0, 64], got " + std::to_string(anderson_memory));
  }
  return true;
}

}  // namespace carat
