// How global registration scales with the size of the map: synthetic drives of F = 100, 300,
// 1000, 3000 frames, each two laps of a circuit that grows with F (around n blocks in a row,
// n = 1 at 100 frames: the demo's drive; 18 blocks, about 2 km, at 1000), frames about 4 m
// apart, so the factors grow about linearly with the frames as a map of new ground does;
// 0.5 m voxels (CARAT_SCALING_VOXEL_M), initial poses the ground truth each moved by 0.1 m and
// 0.5 degrees (a map to refine, as `carat map --perturb-m 0.1 --perturb-deg 0.5`), the dense
// graph built at those poses. Per size:
//
//   BM_BuildExact/F     building and compressing every factor for GRE exact (M = 29)
//   BM_IterationExact/F one LM iteration of GRE exact (summary total / iterations)
//   BM_IterationFull/F  the same for GRE full, skipped when its correspondences would exceed
//                       CARAT_SCALING_FULL_LIMIT_GIB (default 8)
//   BM_SolveExact/F, BM_SolveLossless/F, BM_SolveFull/F
//                       the whole optimization to convergence (the demo's LM settings): its
//                       time as the paper counts it (compressing + solving; the correspondence
//                       search, the same for each, apart as correspondence_s), ATE against the
//                       ground truth, iterations and memory; full skipped as above
//
// Counters: frames, factors, rows, residual_bytes, correspondence_bytes, per_iteration_s and
// the process peak RSS (VmHWM, reset at the start of each benchmark where the kernel allows).
//
// Environment: CARAT_SCALING_MAX_FRAMES (largest size run, default 3000),
// CARAT_SCALING_ITERATIONS (LM iterations per solve, default 3), CARAT_SCALING_THREADS
// (default: all cores), CARAT_SCALING_FULL_LIMIT_GIB (default 8), CARAT_SCALING_VOXEL_M (the
// scans' downsampling voxel, default 0.5 m; smaller voxels give denser scans and more
// correspondences per factor: 2.3x at 0.25 m, ~20,000 rows against the paper's ~30,000).
//
// Each size scans its own drive; the drive, graph and problems of one size are freed before
// the next size starts.
#include <benchmark/benchmark.h>
#include <tbb/info.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "carat/base/blas_kernels.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/registration/pose_perturbation.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/sim/pipeline.hpp"
#include "carat/solver/solve.hpp"

namespace {

constexpr std::array<int, 4> kSizes{100, 300, 1000, 3000};

constexpr double kStartMetres = 0.1;   // start: every pose but the first moved this far ...
constexpr double kStartDegrees = 0.5;  // ... and turned this much

double env_positive(const char* name, double fallback) {
  const char* text = std::getenv(name);
  if (text == nullptr || *text == '\0') return fallback;
  char* end = nullptr;
  const double value = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(value > 0.0)) {
    std::fprintf(stderr, "scaling_bench: ignoring %s=%s (want a positive number)\n", name, text);
    return fallback;
  }
  return value;
}

long env_long(const char* name, long fallback) {
  return static_cast<long>(env_positive(name, static_cast<double>(fallback)));
}

int max_frames() { return static_cast<int>(env_long("CARAT_SCALING_MAX_FRAMES", 3000)); }
int solve_iterations() { return static_cast<int>(env_long("CARAT_SCALING_ITERATIONS", 3)); }
int num_threads() {
  return static_cast<int>(env_long("CARAT_SCALING_THREADS", tbb::info::default_concurrency()));
}
double voxel_metres() {
  return env_positive("CARAT_SCALING_VOXEL_M", carat::PreprocessOptions{}.voxel_size);
}
double full_limit_bytes() {
  return env_positive("CARAT_SCALING_FULL_LIMIT_GIB", 8.0) * 1024.0 * 1024.0 * 1024.0;
}

// ---- process memory (Linux) ----

/// A "VmXXX:   123 kB" field of /proc/self/status in bytes, or 0.
double proc_status_bytes(const std::string& field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::atof(line.c_str() + field.size() + 1) * 1024.0;
  }
  return 0.0;
}

/// Gives freed heap back to the system and resets VmHWM to the current RSS (Linux >= 4.0).
void reset_peak_rss() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
  std::ofstream clear("/proc/self/clear_refs");
  clear << "5";
}

// ---- the drive of one size ----

/// Circuit blocks n for a drive of F frames: two laps around n blocks of 54 m (streets
/// included) with frames about 4 m apart (lap length 108 (n + 1) - 17 m; n = 1 is the demo's
/// circuit at 100 frames).
int circuit_blocks(int frames) {
  return std::clamp(static_cast<int>(std::lround((2.0 * frames - 90.8) / 108.0)), 1, 63);
}

/// The ground truth of a drive of `frames` frames and its scans, preprocessed.
struct Drive {
  int frames = 0;
  std::vector<Eigen::Isometry3d> truth;
  std::vector<std::shared_ptr<const carat::Frame>> scans;  // preprocessed
  double scan_s = 0.0;                                     // scanning + preprocessing
};

Drive make_drive(int frames) {
  Drive d;
  d.frames = frames;
  const int n = circuit_blocks(frames);
  // Scanned and preprocessed frames and the ground truth only: the start is set per size below.
  carat::SyntheticPipelineOptions options;
  options.world.blocks_x = n + 1;
  options.world.blocks_y = 2;
  options.drive.frames = frames;
  options.drive.laps = 2;
  options.drive.circuit_blocks_x = n;
  options.preprocess.voxel_size = voxel_metres();
  options.drift.translation_sigma = 0.0;
  options.drift.rotation_sigma_deg = 0.0;
  options.odometry = false;
  options.dense_graph = false;
  options.threads = num_threads();
  carat::SyntheticPipeline pipeline = carat::simulate_pipeline(options);
  d.truth = std::move(pipeline.T_world_truth);
  d.scans = std::move(pipeline.frames);
  d.scan_s = pipeline.timings.simulate_s + pipeline.timings.preprocess_s;
  return d;
}

// ---- one size: initial poses, graph, problems ----

struct Scene {
  int frames = 0;
  Drive drive;                               // ground truth and scans
  std::unique_ptr<carat::FrameStore> store;  // the scans, resident
  std::vector<Eigen::Isometry3d> initial;
  std::vector<carat::FramePair> pairs;
  double graph_s = 0.0;
  double initial_ate_rmse = 0.0;
  std::size_t points = 0;
  std::optional<std::size_t> correspondences;         // known once exact has been built
  std::unique_ptr<carat::RegistrationProblem> exact;  // built by BM_BuildExact
};

std::unique_ptr<Scene>& scene_slot() {
  static std::unique_ptr<Scene> s;
  return s;
}

Scene& scene(int frames) {
  auto& slot = scene_slot();
  if (slot && slot->frames == frames) return *slot;
  slot.reset();  // free the previous size first
  reset_peak_rss();
  auto s = std::make_unique<Scene>();
  s->frames = frames;
  s->drive = make_drive(frames);
  const std::span<const Eigen::Isometry3d> truth = s->drive.truth;
  // A map to refine, as a SLAM system with loop closure hands it over: every pose but the
  // first moved by 0.1 m and 0.5 degrees in random directions (no drift accumulates, so the
  // dense graph at these poses has every loop closure).
  s->initial = carat::perturb_poses(truth, kStartMetres, kStartDegrees, 1);
  for (const auto& f : s->drive.scans) s->points += f->size();
  s->store = std::make_unique<carat::FrameStore>(s->drive.scans);
  carat::DenseGraphOptions graph;
  graph.num_threads = num_threads();
  const carat::Stopwatch stopwatch;
  s->pairs = carat::build_dense_graph(*s->store, s->initial, graph);
  s->graph_s = stopwatch.elapsed_s();
  s->initial_ate_rmse = carat::compute_ate(s->initial, truth).rmse;
  slot = std::move(s);
  return *slot;
}

carat::FrameStore& frames_of(Scene& s) { return *s.store; }

carat::GlobalRegistrationOptions registration_options(carat::ResidualSampling sampling) {
  carat::GlobalRegistrationOptions options;
  options.sampling = sampling;
  options.residuals = 29;
  options.num_threads = num_threads();
  return options;
}

// ---- counters ----

void scene_counters(benchmark::State& state, const Scene& s) {
  state.counters["frames"] = s.frames;
  state.counters["factors"] = static_cast<double>(s.pairs.size());
  state.counters["points"] = static_cast<double>(s.points);
  state.counters["graph_s"] = s.graph_s;
  state.counters["scan_s"] = s.drive.scan_s;
  state.counters["circuit_blocks"] = circuit_blocks(s.frames);
  state.counters["initial_ate_rmse_m"] = s.initial_ate_rmse;
  state.counters["threads"] = num_threads();
  state.counters["voxel_m"] = voxel_metres();
}

void stats_counters(benchmark::State& state, const carat::RegistrationFactorStats& stats) {
  state.counters["rows"] = static_cast<double>(stats.num_rows);
  state.counters["correspondences"] = static_cast<double>(stats.num_correspondences);
  state.counters["residual_bytes"] = static_cast<double>(stats.residual_bytes);
  state.counters["correspondence_bytes"] = static_cast<double>(stats.correspondence_bytes);
  state.counters["correspondence_s"] = stats.correspondence_s;
  state.counters["compression_s"] = stats.compression_s;
}

void memory_counters(benchmark::State& state, double baseline_rss) {
  state.counters["baseline_rss_bytes"] = baseline_rss;
  state.counters["peak_rss_bytes"] = proc_status_bytes("VmHWM");
}

/// Runs LM for solve_iterations() iterations (tolerances off, so none stops it early) and
/// reports the time per iteration as the benchmark's time.
void solve_and_report(benchmark::State& state, carat::Problem& problem) {
  carat::SolverOptions options;
  options.max_iterations = solve_iterations();
  options.function_tolerance = 0.0;
  options.gradient_tolerance = 0.0;
  options.parameter_tolerance = 0.0;
  options.num_threads = num_threads();
  const carat::SolverSummary summary = carat::solve(options, problem);
  if (!summary.is_solution_usable()) {
    state.SkipWithError(("solve failed: " + summary.message).c_str());
    return;
  }
  const int iterations = std::max(1, summary.num_iterations);
  const double per_iteration = summary.time.total_s / iterations;
  state.SetIterationTime(per_iteration);
  state.counters["per_iteration_s"] = per_iteration;
  state.counters["per_iteration_no_symbolic_s"] =
      (summary.time.total_s - summary.time.symbolic_s) / iterations;
  state.counters["iterations"] = summary.num_iterations;
  state.counters["solve_s"] = summary.time.total_s;
  state.counters["symbolic_s"] = summary.time.symbolic_s;
  state.counters["numeric_s"] = summary.time.numeric_s;
  state.counters["linearize_s"] = summary.time.linearize_s;
  state.counters["factor_nonzeros"] = static_cast<double>(summary.factor_nonzeros);
  state.counters["initial_cost"] = summary.initial_cost;
  state.counters["final_cost"] = summary.final_cost;
}

// ---- benchmarks ----

/// Full's correspondence bytes: 96 B per correspondence (GicpBlock's Point), known from an
/// exact build; if none ran, estimated from the overlaps (fraction of the source's points).
double full_bytes_estimate(const Scene& s) {
  double correspondences = 0.0;
  if (s.correspondences) {
    correspondences = static_cast<double>(*s.correspondences);
  } else {
    const auto& frames = s.drive.scans;
    for (const auto& p : s.pairs)
      correspondences +=
          p.overlap * static_cast<double>(frames[static_cast<std::size_t>(p.source)]->size());
  }
  return correspondences * 96.0;
}

void BM_BuildExact(benchmark::State& state) {
  Scene& s = scene(static_cast<int>(state.range(0)));
  s.exact.reset();
  reset_peak_rss();
  const double baseline = proc_status_bytes("VmRSS");
  for (auto _ : state) {
    const carat::Stopwatch stopwatch;
    s.exact = std::make_unique<carat::RegistrationProblem>(carat::build_registration_problem(
        frames_of(s), s.pairs, s.initial, registration_options(carat::ResidualSampling::kExact)));
    state.SetIterationTime(stopwatch.elapsed_s());
  }
  s.correspondences = s.exact->stats.num_correspondences;
  scene_counters(state, s);
  stats_counters(state, s.exact->stats);
  memory_counters(state, baseline);
}

void BM_IterationExact(benchmark::State& state) {
  Scene& s = scene(static_cast<int>(state.range(0)));
  double build_s = 0.0;
  if (!s.exact) {  // run on its own (a filter): build it here
    const carat::Stopwatch stopwatch;
    s.exact = std::make_unique<carat::RegistrationProblem>(carat::build_registration_problem(
        frames_of(s), s.pairs, s.initial, registration_options(carat::ResidualSampling::kExact)));
    build_s = stopwatch.elapsed_s();
    s.correspondences = s.exact->stats.num_correspondences;
  }
  reset_peak_rss();
  const double baseline = proc_status_bytes("VmRSS");
  for (auto _ : state) solve_and_report(state, s.exact->problem);
  scene_counters(state, s);
  stats_counters(state, s.exact->stats);
  if (build_s > 0.0) state.counters["build_s"] = build_s;
  memory_counters(state, baseline);
  s.exact.reset();
}

void BM_IterationFull(benchmark::State& state) {
  Scene& s = scene(static_cast<int>(state.range(0)));
  s.exact.reset();
  const double estimate = full_bytes_estimate(s);
  state.counters["estimated_correspondence_bytes"] = estimate;
  if (estimate > full_limit_bytes()) {
    scene_counters(state, s);
    char message[160];
    std::snprintf(message, sizeof(message),
                  "full skipped: %.2f GiB of correspondences > limit %.2f GiB",
                  estimate / 1073741824.0, full_limit_bytes() / 1073741824.0);
    state.SkipWithError(message);
    for (auto _ : state) {
    }
    return;
  }
  reset_peak_rss();
  const double baseline = proc_status_bytes("VmRSS");
  for (auto _ : state) {
    const carat::Stopwatch stopwatch;
    auto full = carat::build_registration_problem(
        frames_of(s), s.pairs, s.initial, registration_options(carat::ResidualSampling::kFull));
    state.counters["build_s"] = stopwatch.elapsed_s();
    solve_and_report(state, full.problem);
    stats_counters(state, full.stats);
  }
  scene_counters(state, s);
  memory_counters(state, baseline);
}

/// Optimizes to convergence with `sampling`; reports the optimization time (compression +
/// solve) as the benchmark's time, the ATE and the memory.
void solve_to_convergence(benchmark::State& state, carat::ResidualSampling sampling) {
  Scene& s = scene(static_cast<int>(state.range(0)));
  s.exact.reset();
  if (sampling == carat::ResidualSampling::kFull) {
    const double estimate = full_bytes_estimate(s);
    state.counters["estimated_correspondence_bytes"] = estimate;
    if (estimate > full_limit_bytes()) {
      scene_counters(state, s);
      state.SkipWithError("full skipped: its correspondences exceed the limit");
      for (auto _ : state) {
      }
      return;
    }
  }
  reset_peak_rss();
  const double baseline = proc_status_bytes("VmRSS");
  carat::GlobalRegistrationOptions options = registration_options(sampling);
  options.solver.max_iterations = 100;
  options.solver.num_threads = num_threads();
  for (auto _ : state) {
    const carat::GlobalRegistrationResult result =
        carat::optimize_registration(frames_of(s), s.pairs, s.initial, options);
    const double optimization_s = result.stats.compression_s + result.summary.time.total_s;
    state.SetIterationTime(optimization_s);
    state.counters["optimization_s"] = optimization_s;
    state.counters["solve_s"] = result.summary.time.total_s;
    state.counters["iterations"] = result.summary.num_iterations;
    state.counters["final_cost"] = result.summary.final_cost;
    const std::span<const Eigen::Isometry3d> truth = s.drive.truth;
    state.counters["ate_rmse_m"] = carat::compute_ate(result.T_world_frame, truth).rmse;
    stats_counters(state, result.stats);
    if (sampling == carat::ResidualSampling::kExact)
      s.correspondences = result.stats.num_correspondences;
  }
  scene_counters(state, s);
  memory_counters(state, baseline);
}

void BM_SolveExact(benchmark::State& state) {
  solve_to_convergence(state, carat::ResidualSampling::kExact);
}
void BM_SolveLossless(benchmark::State& state) {
  solve_to_convergence(state, carat::ResidualSampling::kLossless);
}
void BM_SolveFull(benchmark::State& state) {
  solve_to_convergence(state, carat::ResidualSampling::kFull);
}

void register_all() {
  const int largest = max_frames();
  for (const int f : kSizes) {
    if (f > largest) break;
    for (auto* b : {benchmark::RegisterBenchmark("BM_BuildExact", BM_BuildExact),
                    benchmark::RegisterBenchmark("BM_IterationExact", BM_IterationExact),
                    benchmark::RegisterBenchmark("BM_IterationFull", BM_IterationFull),
                    benchmark::RegisterBenchmark("BM_SolveExact", BM_SolveExact),
                    benchmark::RegisterBenchmark("BM_SolveLossless", BM_SolveLossless),
                    benchmark::RegisterBenchmark("BM_SolveFull", BM_SolveFull)}) {
      b->Arg(f)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  carat::use_cpu_blas_kernels(argv);  // OpenBLAS's kernels for this CPU, as `carat` runs them
  register_all();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
