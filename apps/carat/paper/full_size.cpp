// carat paper --full-size: Tables IV and V at the paper's problem size. A synthetic drive of
// 4,540 frames (two laps of a 10-block circuit, frames about half a metre apart) whose dense
// graph has more factors than the paper's KITTI 00 graph, frames scanned and preprocessed on
// demand under a memory cap, then GRE exact M = 29 / 256 / 1024 and lossless from a perturbed
// start, each solved when its factors fit in memory (a sample of its factors tells how much
// they take), and full's memory from its factors' bytes as built.
#include <algorithm>
#include <cmath>
#include <optional>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/registration/mapping.hpp"
#include "carat/registration/pose_perturbation.hpp"
#include "carat/registration/trajectory_error.hpp"
#include "carat/sim/sequence.hpp"
#include "carat/sim/world.hpp"
#include "cli_support.hpp"
#include "mapping_methods.hpp"
#include "paper.hpp"
#include "progress.hpp"
#include "published.hpp"
#include "report_table.hpp"

namespace carat::cli::paper {
namespace {

constexpr double kVoxel = 0.25;          // metres: about 6,800 correspondences a factor
constexpr double kPerturbMetres = 0.1;   // start: every pose but the first moved this far
constexpr double kPerturbDegrees = 0.5;  // and turned this much
constexpr std::size_t kFrameCapBytes = std::size_t{1} << 30;  // frames held at once: 1 GiB
constexpr std::size_t kSampleFactors = 64;  // factors built to project a method's memory
constexpr double kMemoryShare = 0.8;        // of the memory free at the start, for the factors
constexpr int kPaperBlocks = 10;            // circuit blocks at the paper's 4,540 frames

/// One method of the full-size tables and what became of it.
struct FullSizeRow {
  ResidualSampling sampling = ResidualSampling::kExact;
  int residuals = 0;                   // M (exact); 0 otherwise
  double projected_bytes = 0.0;        // residual memory of every factor, from the sample
  std::optional<MethodResult> result;  // when it was solved
  double wall_s = 0.0;                 // factors built and solved, frames read included
};

/// A row of the tables before its method runs.
FullSizeRow planned(ResidualSampling sampling, int residuals, double projected_bytes = 0.0) {
  FullSizeRow row;
  row.sampling = sampling;
  row.residuals = residuals;
  row.projected_bytes = projected_bytes;
  return row;
}

/// Circuit blocks of a drive of `frames` frames: the paper-size drive's spacing (10 blocks at
/// 4,540 frames), at least one block.
int circuit_blocks(int frames) {
  return std::max(1, static_cast<int>(
                         std::lround(kPaperBlocks * frames / double(published::kSequence00Poses))));
}

/// "GRE exact (M=29)", "GRE lossless", "GRE full".
std::string label_of(ResidualSampling sampling, int residuals) {
  if (sampling == ResidualSampling::kExact)
    return "GRE exact (M=" + std::to_string(residuals) + ")";
  return std::string("GRE ") + to_string(sampling);
}

}  // namespace

void full_size_tables(const PaperArgs& args, int threads, Report* report) {
  const int frames = args.full_size_frames;
  const int blocks = circuit_blocks(frames);
  const Stopwatch section_time;
  SyntheticWorldOptions world_options;
  world_options.seed = args.seed;
  world_options.blocks_x = blocks + 1;  // a row of buildings beyond the circuit's end
  const SyntheticWorld world(world_options);
  SyntheticTrajectoryOptions drive;
  drive.frames = frames;
  drive.laps = 2;
  drive.circuit_blocks_x = blocks;
  const std::vector<Eigen::Isometry3d> T_world_sensor = world.trajectory(drive);
  // Poses relative to the first, as `carat map` reads a drive.
  std::vector<Eigen::Isometry3d> truth;
  truth.reserve(T_world_sensor.size());
  for (const auto& T : T_world_sensor) truth.push_back(T_world_sensor.front().inverse() * T);

  PreprocessOptions preprocess;
  preprocess.voxel_size = kVoxel;
  preprocess.num_threads = 1;  // frames load in parallel already
  FrameStore store(
      truth.size(),
      [&](std::size_t k) {
        const std::string name = "synthetic frame " + std::to_string(k);
        return preprocess_frame(
            world.scan(T_world_sensor[k], synthetic_frame_noise_seed(world_options.seed, k)),
            preprocess, name);
      },
      [&](std::size_t k) {  // the dense graph's overlap tests need the points alone
        return downsample_frame_points(
            world.scan(T_world_sensor[k], synthetic_frame_noise_seed(world_options.seed, k)),
            preprocess, "synthetic frame " + std::to_string(k));
      },
      kFrameCapBytes);
  const std::vector<Eigen::Isometry3d> T_world_initial =
      perturb_poses(truth, kPerturbMetres, kPerturbDegrees, args.seed);
  const AteStatistics initial = compute_ate(T_world_initial, truth);

  const double available = static_cast<double>(available_memory_bytes());
  const double limit = args.full_size_memory_gb > 0.0
                           ? args.full_size_memory_gb * 1e9
                           : std::max(0.0, kMemoryShare * available - double(kFrameCapBytes));
  MappingOptions mapping;
  mapping.num_threads = threads;
  mapping.registration.seed = args.seed;
  MapGraph graph;
  {
    StageBars<MappingStage> bars(
        [](MappingStage stage) { return "full size: " + mapping_stage_label(stage); }, !args.json);
    graph = build_map_graph(store, T_world_initial, mapping, bars.callback());
  }
  const double graph_s = graph.times.seconds("dense_graph");
  const std::vector<FramePair>& pairs = graph.pairs;
  if (pairs.empty()) {
    throw Error("carat paper --full-size: the " + std::to_string(frames) +
                "-frame drive has no dense factors");
  }

  // The factors whose bytes project each method's memory: spread evenly over the graph.
  std::vector<std::size_t> sample(std::min(kSampleFactors, pairs.size()));
  for (std::size_t k = 0; k < sample.size(); ++k) sample[k] = k * pairs.size() / sample.size();
  std::vector<FullSizeRow> rows;
  for (int m : {29, 256, 1024}) rows.push_back(planned(ResidualSampling::kExact, m));
  rows.push_back(planned(ResidualSampling::kLossless, 0));
  // What full would hold, every factor's correspondences: projected from the first sample, and
  // as built once a method has built every factor.
  double full_projected = 0.0, full_built = 0.0;
  for (FullSizeRow& row : rows) {
    GlobalRegistrationOptions options;
    options.sampling = row.sampling;
    options.residuals = row.sampling == ResidualSampling::kExact ? row.residuals : 29;
    options.seed = args.seed;
    options.num_threads = threads;
    double sample_bytes = 0.0, sample_correspondence_bytes = 0.0;
    for (const RegistrationFactor& f :
         build_registration_factors(store, pairs, sample, T_world_initial, options)) {
      sample_bytes += static_cast<double>(f.block->memory_bytes());
      sample_correspondence_bytes += static_cast<double>(f.correspondence_bytes);
    }
    const double scale = double(pairs.size()) / double(sample.size());
    row.projected_bytes = sample_bytes * scale;
    if (full_projected == 0.0) full_projected = sample_correspondence_bytes * scale;
    if (row.projected_bytes > limit) continue;
    MappingOptions method = registration_method(mapping, row.sampling);
    method.registration.residuals = options.residuals;
    const Stopwatch wall;
    row.result = run_method(store, graph, method, !args.json);
    row.wall_s = wall.elapsed_s();
    row.result->ate = compute_ate(row.result->T_world_frame, truth);
    row.result->T_world_frame.clear();
    // Every factor was built: full's memory is their correspondences' bytes, not a projection.
    full_built = static_cast<double>(row.result->correspondence_bytes);
  }
  rows.push_back(planned(ResidualSampling::kFull, 0, full_projected));
  const bool any_solved =
      std::any_of(rows.begin(), rows.end(), [](const FullSizeRow& row) { return row.result; });

  const FullSizeRow* lossless = nullptr;
  const FullSizeRow* smallest = nullptr;  // exact M = 29, when solved
  for (const FullSizeRow& row : rows) {
    if (!row.result) continue;
    if (row.sampling == ResidualSampling::kLossless) lossless = &row;
    if (row.sampling == ResidualSampling::kExact && row.residuals == 29) smallest = &row;
  }
  const published::SamplingRow& paper_29 = published::kTables4And5.front();
  ReportTable t4({"method", "solved", "ATE RMSE [m]", "ATE mean ± std [m]", "ATE vs lossless",
                  "iterations", "time [s]", "time vs M=29", "paper ATE 00 [m]", "paper time [h]",
                  "paper time vs M=29"});
  ReportTable t5({"method", "residual memory", "per factor", "paper corresp. [GB]",
                  "paper residuals [GB]", "paper per factor", "per factor / paper"});
  for (const FullSizeRow& row : rows) {
    const std::string label = label_of(row.sampling, row.residuals);
    const std::string key = std::string("gre_") + to_string(row.sampling);
    nlohmann::json j4{{"method", key}, {"label", label}, {"solved", row.result.has_value()}};
    nlohmann::json j5{{"method", key}, {"label", label}};
    if (row.sampling == ResidualSampling::kExact) j4["residuals"] = j5["residuals"] = row.residuals;
    std::vector<std::string> c4{label}, c5{label};
    const double bytes = row.result ? static_cast<double>(row.result->memory_bytes)
                         : row.sampling == ResidualSampling::kFull && any_solved
                             ? full_built
                             : row.projected_bytes;
    const double per_factor = bytes / double(pairs.size());
    j5["memory_bytes"] = bytes;
    // Measured when solved; projected from the sample; full's: its correspondences as built by
    // a solved method (projected when none was solved).
    const char* source = row.result                                              ? "measured"
                         : row.sampling == ResidualSampling::kFull && any_solved ? "as built"
                                                                                 : "projected";
    j5["memory_source"] = source;
    j5["projected_bytes"] = row.projected_bytes;
    j5["memory_bytes_per_factor"] = per_factor;
    if (row.result) {
      const MethodResult& r = *row.result;
      const nlohmann::json measured = to_json(r);
      for (const char* k : {"ate_rmse", "ate_mean", "ate_std", "ate_max", "time_s", "total_s",
                            "time_breakdown", "correspondence_bytes", "iterations", "termination"})
        j4[k] = measured[k];
      j4["wall_s"] = row.wall_s;
      c4.insert(c4.end(), {"yes", fmt("%.4f", r.ate->rmse),
                           fmt("%.4f", r.ate->mean) + " ± " + fmt("%.4f", r.ate->std)});
      if (lossless != nullptr) {
        const double change = 100.0 * (r.ate->rmse / lossless->result->ate->rmse - 1.0);
        j4["ate_change_vs_lossless_percent"] = change;
        c4.push_back(fmt("%+.3f %%", change));
      } else {
        c4.push_back("—");
      }
      c4.insert(c4.end(),
                {std::to_string(r.iterations), fmt(r.time_s < 10.0 ? "%.3f" : "%.1f", r.time_s)});
      if (smallest != nullptr) {
        const double ratio = r.time_s / smallest->result->time_s;
        j4["time_vs_m29"] = ratio;
        c4.push_back(fmt("%.2f", ratio));
      } else {
        c4.push_back("—");
      }
    } else {
      const std::string why =
          row.sampling == ResidualSampling::kFull
              ? "full is not solved at this size (the paper took 13.2 h on 128 threads); its "
                "memory is its factors' correspondences as built"
              : "its factors would hold " + format_bytes(row.projected_bytes) +
                    " (projected from " + std::to_string(sample.size()) +
                    " of them), over the limit of " + format_bytes(limit);
      j4["why_not_solved"] = why;
      c4.insert(c4.end(), {"no", "—", "—", "—", "—", "—", "—"});
    }
    const int paper_residuals = row.sampling == ResidualSampling::kFull    ? 0
                                : row.sampling == ResidualSampling::kExact ? row.residuals
                                                                           : -1;
    c5.insert(c5.end(), {format_bytes(bytes) + (row.result ? "" : " (" + std::string(source) + ")"),
                         format_bytes(per_factor)});
    if (const auto paper = published_sampling_row(paper_residuals)) {
      const double paper_vs_29 = paper->hours / paper_29.hours;
      add_paper_table4(*paper, &j4);
      j4["paper_time_vs_m29"] = paper_vs_29;
      add_paper_table5(*paper, per_factor, &j5, &c5);
      c4.insert(c4.end(),
                {mean_std(paper->ate), fmt("%.2f", paper->hours), fmt("%.2f", paper_vs_29)});
    } else {
      c4.insert(c4.end(), {"—", "—", "—"});
      c5.insert(c5.end(), {"—", "—", "—", "—"});
    }
    t4.add_row(c4, j4);
    t5.add_row(c5, j5);
  }

  const FrameStoreStats store_stats = store.stats();
  const double section_s = section_time.elapsed_s();
  std::string& md = report->markdown;
  md += "## Tables IV and V at the paper's size (`--full-size`)\n\n";
  md += thousands(frames) + " synthetic frames (two laps of a " + std::to_string(blocks) +
        "-block circuit), scanned and preprocessed on demand (" + fmt("%g", kVoxel) +
        " m voxels) with at most " + format_bytes(double(kFrameCapBytes)) + " of frames held; " +
        thousands(static_cast<long long>(pairs.size())) +
        " dense factors (the paper's KITTI 00: " + thousands(published::kSequence00Poses) +
        " poses, " + thousands(published::kSequence00Factors) +
        " factors). Start: the ground truth with every pose but the first moved by " +
        fmt("%g", kPerturbMetres) + " m and " + fmt("%g", kPerturbDegrees) + "° (ATE RMSE " +
        fmt("%.4f", initial.rmse) + " m); correspondences fixed there, as in the paper. " +
        std::to_string(threads) + " threads (the paper: " + std::to_string(published::kThreads) +
        "). Dense graph " + fmt("%.0f", graph_s) + " s; section " + fmt("%.0f", section_s) +
        " s; peak RSS of the process " + format_bytes(static_cast<double>(peak_rss_bytes())) +
        "; " + std::to_string(store_stats.loads) + " frame scans for " + std::to_string(frames) +
        " frames (and " + std::to_string(store_stats.point_loads) +
        " scans of their points alone, for the overlap tests).\n\n";
  md += "### Table IV at the paper's size\n\n" + t4.markdown();
  md +=
      "\nSettings differ: a synthetic drive from a perturbed ground truth instead of KITTI 00 "
      "from odometry, and " +
      std::to_string(threads) + " threads instead of " + std::to_string(published::kThreads) +
      ", so compare the ratios (time against M = 29, ATE against lossless, whose cost is full's "
      "at every pose, so its optimum is full's), not metres or hours. Time is compressing plus "
      "the LM solve; the correspondence search, the same for every method, is in the JSON. A "
      "method is solved when its factors, projected from " +
      std::to_string(sample.size()) + " of them, fit in " + format_bytes(limit) +
      (args.full_size_memory_gb > 0.0 ? " (`--full-size-memory`)"
                                      : " (80 % of the memory free at the start, less the "
                                        "frames' cap; `--full-size-memory` sets it)") +
      ".\n";
  md += "\n### Table V at the paper's size\n\n" + t5.markdown();
  md +=
      "\nResidual memory: the bytes the kept factors hold during the solve (measured when "
      "solved, else projected); full's is every factor's correspondences as built. Paper per "
      "factor: its memory held during the optimization (sampled residuals; all residuals: the "
      "correspondences) over " +
      thousands(published::kSequence00Factors) +
      " factors, GB read as 10^9 bytes. carat's rows are self-contained (56 bytes each: the "
      "whitening row, its offset and the source point), where the paper's sampled residuals "
      "index correspondences held apart.\n\n";
  report->json["full_size"] = {{"frames", frames},
                               {"laps", drive.laps},
                               {"circuit_blocks", blocks},
                               {"voxel_m", kVoxel},
                               {"factors", pairs.size()},
                               {"threads", threads},
                               {"initial_ate_rmse", initial.rmse},
                               {"dense_graph_s", graph_s},
                               {"section_s", section_s},
                               {"memory_limit_bytes", limit},
                               {"sample_factors", sample.size()},
                               {"peak_rss_bytes", peak_rss_bytes()},
                               {"frame_store",
                                {{"loads", store_stats.loads},
                                 {"point_loads", store_stats.point_loads},
                                 {"evictions", store_stats.evictions},
                                 {"peak_bytes", store_stats.peak_bytes},
                                 {"max_bytes", store_stats.max_bytes}}},
                               {"table4", t4.json()},
                               {"table5", t5.json()}};
}

}  // namespace carat::cli::paper
