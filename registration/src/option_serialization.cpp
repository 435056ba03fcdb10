#include "carat/registration/option_serialization.hpp"

#include <cstdint>
#include <string>

#include "carat/base/field_count.hpp"

namespace carat {
namespace {

// The writers and readers below are written for these members: a new one must be written and
// read there, and the count here raised (callbacks are counted and deliberately not sent).
static_assert(field_count<ReadOptions>() == 2, "option_serialization: write the new field");
static_assert(field_count<PreprocessOptions>() == 4, "option_serialization: write the new field");
static_assert(field_count<OpenScansOptions>() == 5, "option_serialization: write the new field");
static_assert(field_count<SolverOptions>() == 27, "option_serialization: write the new field");
static_assert(field_count<GlobalRegistrationOptions>() == 14,
              "option_serialization: write the new field");
static_assert(field_count<DenseGraphOptions>() == 5, "option_serialization: write the new field");

void put_bool(ByteWriter& out, bool value) { out.put(static_cast<std::uint8_t>(value ? 1 : 0)); }

bool get_bool(ByteReader& in, const char* name) {
  const auto value = in.get<std::uint8_t>();
  if (value > 1) in.garbled(std::string(name) + " is " + std::to_string(value) + ", not 0 or 1");
  return value == 1;
}

template <class Enum>
void put_enum(ByteWriter& out, Enum value) {
  out.put(static_cast<std::uint8_t>(value));
}

/// An enum written by put_enum() whose values run from 0 to `last`.
template <class Enum>
Enum get_enum(ByteReader& in, Enum last, const char* name) {
  const auto value = in.get<std::uint8_t>();
  if (value > static_cast<std::uint8_t>(last)) {
    in.garbled(std::string(name) + " " + std::to_string(value) + " is out of range");
  }
  return static_cast<Enum>(value);
}

}  // namespace

void write_options(ByteWriter& out, const ReadOptions& options) {
  put_bool(out, options.drop_non_finite);
  out.put(static_cast<std::uint64_t>(options.max_points));
}

void write_options(ByteWriter& out, const PreprocessOptions& options) {
  out.put(options.voxel_size);
  out.put(options.covariance_neighbors);
  out.put(options.min_points);
  out.put(options.num_threads);
}

void write_options(ByteWriter& out, const OpenScansOptions& options) {
  write_options(out, options.read);
  write_options(out, options.preprocess);
  out.put(static_cast<std::uint64_t>(options.max_bytes));
  put_bool(out, options.require_constrained);
  out.put(options.num_threads);
}

void write_options(ByteWriter& out, const SolverOptions& options) {
  put_enum(out, options.method);
  put_enum(out, options.ordering);
  put_enum(out, options.linear_solver);
  out.put(options.max_linear_system_bytes);
  out.put(options.max_iterations);
  out.put(options.function_tolerance);
  out.put(options.gradient_tolerance);
  out.put(options.parameter_tolerance);
  out.put(options.initial_trust_region_radius);
  put_enum(out, options.lm_start);
  out.put(options.gauss_newton_phase_radius);
  out.put(options.gauss_newton_phase_min_gain);
  out.put(options.max_trust_region_radius);
  out.put(options.max_trust_region_growth);
  out.put(options.min_trust_region_radius);
  out.put(options.min_relative_decrease);
  out.put(options.min_lm_diagonal);
  out.put(options.max_lm_diagonal);
  put_bool(out, options.reuse_factorization);
  out.put(options.factor_reuse_ratio);
  out.put(options.anderson_memory);
  out.put(options.num_threads);
  put_bool(out, options.record_iterations);
  // iteration_callback and evaluation_callback stay in their process.
  put_bool(out, options.update_state_every_iteration);
  put_bool(out, options.check_blocks);
}

void write_options(ByteWriter& out, const GlobalRegistrationOptions& options) {
  put_enum(out, options.sampling);
  out.put(options.residuals);
  out.put(options.max_correspondence_distance);
  out.put(options.min_correspondences);
  out.put(options.seed);
  out.put(options.num_threads);
  out.put(options.factor_cauchy_scale);
  out.put(options.factor_excess_cauchy_scale);
  out.put(options.rounds);
  out.put(options.round_translation_tolerance);
  out.put(options.round_rotation_tolerance);
  write_options(out, options.solver);
  put_bool(out, options.covariance);
  // iteration_callback stays in its process.
}

ReadOptions read_read_options(ByteReader& in) {
  ReadOptions options;
  options.drop_non_finite = get_bool(in, "drop_non_finite");
  options.max_points = static_cast<std::size_t>(in.get<std::uint64_t>());
  return options;
}

void write_options(ByteWriter& out, const DenseGraphOptions& options) {
  out.put(options.overlap_threshold);
  out.put(options.voxel_size);
  out.put(options.max_distance);
  out.put(options.overlap_stride);
  out.put(options.num_threads);
}

DenseGraphOptions read_dense_graph_options(ByteReader& in) {
  DenseGraphOptions options;
  options.overlap_threshold = in.get<double>();
  options.voxel_size = in.get<double>();
  options.max_distance = in.get<double>();
  options.overlap_stride = in.get<int>();
  options.num_threads = in.get<int>();
  return options;
}

PreprocessOptions read_preprocess_options(ByteReader& in) {
  PreprocessOptions options;
  options.voxel_size = in.get<double>();
  options.covariance_neighbors = in.get<int>();
  options.min_points = in.get<int>();
  options.num_threads = in.get<int>();
  return options;
}

OpenScansOptions read_open_scans_options(ByteReader& in) {
  OpenScansOptions options;
  options.read = read_read_options(in);
  options.preprocess = read_preprocess_options(in);
  options.max_bytes = static_cast<std::size_t>(in.get<std::uint64_t>());
  options.require_constrained = get_bool(in, "require_constrained");
  options.num_threads = in.get<int>();
  return options;
}

SolverOptions read_solver_options(ByteReader& in) {
  SolverOptions options;
  options.method = get_enum(in, Method::kGaussNewton, "method");
  options.ordering = get_enum(in, Ordering::kMetis, "ordering");
  options.linear_solver = get_enum(in, LinearSolver::kCholesky, "linear solver");
  options.max_linear_system_bytes = in.get<double>();
  options.max_iterations = in.get<int>();
  options.function_tolerance = in.get<double>();
  options.gradient_tolerance = in.get<double>();
  options.parameter_tolerance = in.get<double>();
  options.initial_trust_region_radius = in.get<double>();
  options.lm_start = get_enum(in, LmStart::kTrustRegion, "lm start");
  options.gauss_newton_phase_radius = in.get<double>();
  options.gauss_newton_phase_min_gain = in.get<double>();
  options.max_trust_region_radius = in.get<double>();
  options.max_trust_region_growth = in.get<double>();
  options.min_trust_region_radius = in.get<double>();
  options.min_relative_decrease = in.get<double>();
  options.min_lm_diagonal = in.get<double>();
  options.max_lm_diagonal = in.get<double>();
  options.reuse_factorization = get_bool(in, "reuse_factorization");
  options.factor_reuse_ratio = in.get<double>();
  options.anderson_memory = in.get<int>();
  options.num_threads = in.get<int>();
  options.record_iterations = get_bool(in, "record_iterations");
  options.update_state_every_iteration = get_bool(in, "update_state_every_iteration");
  options.check_blocks = get_bool(in, "check_blocks");
  return options;
}

GlobalRegistrationOptions read_global_registration_options(ByteReader& in) {
  GlobalRegistrationOptions options;
  options.sampling = get_enum(in, ResidualSampling::kLossless, "sampling");
  options.residuals = in.get<int>();
  options.max_correspondence_distance = in.get<double>();
  options.min_correspondences = in.get<int>();
  options.seed = in.get<std::uint64_t>();
  options.num_threads = in.get<int>();
  options.factor_cauchy_scale = in.get<double>();
  options.factor_excess_cauchy_scale = in.get<double>();
  options.rounds = in.get<int>();
  options.round_translation_tolerance = in.get<double>();
  options.round_rotation_tolerance = in.get<double>();
  options.solver = read_solver_options(in);
  options.covariance = get_bool(in, "covariance");
  return options;
}

}  // namespace carat
