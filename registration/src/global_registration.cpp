#include "carat/registration/global_registration.hpp"

#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/base/field_count.hpp"
#include "carat/base/stopwatch.hpp"
#include "carat/coreset/compress.hpp"
#include "carat/coreset/row_coreset.hpp"
#include "carat/registration/correspondences.hpp"
#include "carat/registration/held_factors.hpp"
#include "carat/residuals/gicp_block.hpp"
#include "carat/residuals/lossless_block.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solve.hpp"
#include "factor_losses.hpp"
#include "factor_stats.hpp"
#include "parallel.hpp"
#include "pose_covariances.hpp"
#include "registration_rounds.hpp"

namespace carat {
namespace {

std::string pair_name(const FramePair& pair) {
  return "pair (" + std::to_string(pair.target) + ", " + std::to_string(pair.source) + ")";
}

void check_options(const GlobalRegistrationOptions& options) {
  if (options.residuals < 1)
    throw Error("global registration: residuals (M) must be >= 1, got " +
                std::to_string(options.residuals));
  if (options.sampling == ResidualSampling::kExact && options.residuals < minimum_coreset_rows(6))
    throw Error("global registration: exact sampling needs residuals (M) >= " +
                std::to_string(minimum_coreset_rows(6)) + ", got " +
                std::to_string(options.residuals));
  if (!(options.max_correspondence_distance > 0.0))
    throw Error("global registration: max_correspondence_distance must be > 0");
  if (options.min_correspondences < 1)
    throw Error("global registration: min_correspondences must be >= 1");
  for (const auto& [name, scale] :
       {std::pair{"factor_cauchy_scale", options.factor_cauchy_scale},
        std::pair{"factor_excess_cauchy_scale", options.factor_excess_cauchy_scale}}) {
    if (!(scale >= 0.0) || !std::isfinite(scale))
      throw Error(std::string("global registration: ") + name +
                  " must be finite and >= 0 (0: no kernel), got " + std::to_string(scale));
  }
  if (options.factor_cauchy_scale > 0.0 && options.factor_excess_cauchy_scale > 0.0)
    throw Error(
        "global registration: factor_cauchy_scale and factor_excess_cauchy_scale are both set; "
        "a factor takes one kernel");
  std::string why;
  if (!options.solver.validate(&why)) throw Error("global registration: " + why);
}

/// The least squared norm of a binary registration block over its relative pose T_ij, by
/// Gauss-Newton steps from `values` (the source pose moves: T_j <- T_j Exp(delta) moves T_ij by
/// the same right perturbation, the block's reduced tangent). Steps use the pseudo-inverse over
/// eigenvalues above 1e-12 of the largest; it stops when a step no longer lowers the norm or
/// lowers it by less than 1e-12 relative. Returns the lowest norm met (<= the starting one).
double block_minimum(const ResidualBlock& block, ParameterPointers values) {
  const int r = block.reduced_dim();
  std::array<double, 7> source{};
  std::copy(values[1], values[1] + 7, source.begin());
  const double* current[2] = {values[0], source.data()};
  Eigen::MatrixXd H(r, r);
  Eigen::VectorXd b(r);
  H.setZero();
  b.setZero();
  double best = block.accumulate(current, H, b);
  constexpr int kMaxSteps = 20;
  for (int step = 0; step < kMaxSteps; ++step) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(H);
    const Eigen::VectorXd lambda = eigen.eigenvalues();
    const Eigen::VectorXd projected = eigen.eigenvectors().transpose() * b;
    const double floor = 1e-12 * lambda.cwiseAbs().maxCoeff();
    Eigen::VectorXd scaled = Eigen::VectorXd::Zero(r);
    for (int k = 0; k < r; ++k) {
      if (lambda[k] > floor) scaled[k] = -projected[k] / lambda[k];
    }
    const se3::Vector6d delta = eigen.eigenvectors() * scaled;
    std::array<double, 7> trial{};
    se3::to_storage(se3::from_storage(source.data()) * se3::exp(delta), trial.data());
    const double* moved[2] = {values[0], trial.data()};
    H.setZero();
    b.setZero();
    const double cost = block.accumulate(moved, H, b);
    if (!(cost < best)) break;
    const bool converged = best - cost <= 1e-12 * best;
    best = cost;
    source = trial;
    if (converged) break;
  }
  return best;
}

/// Throws unless `order` lists every index below n once.
void check_order(std::span<const std::size_t> order, std::size_t n) {
  if (order.size() != n) {
    throw Error("global registration: a block order of " + std::to_string(order.size()) +
                " indices for " + std::to_string(n) + " pairs");
  }
  std::vector<char> seen(n, 0);
  for (const std::size_t k : order) {
    if (k >= n || seen[k]) {
      throw Error("global registration: the block order lists pair " + std::to_string(k) +
                  (k >= n ? " of " + std::to_string(n) : std::string(" twice")));
    }
    seen[k] = 1;
  }
}

/// Adds one round's solve and build statistics to the running result.
void accumulate_round(const SolverSummary& summary, const RegistrationFactorStats& stats,
                      bool first, GlobalRegistrationResult* out) {
  if (first) {
    out->summary = summary;
    out->stats = stats;
    return;
  }
  merge_later_solve(out->summary, summary);
  static_assert(field_count<RegistrationFactorStats>() == 8,
                "accumulate_round: merge the new field");
  out->stats.num_factors = stats.num_factors;
  out->stats.correspondence_s += stats.correspondence_s;
  out->stats.compression_s += stats.compression_s;
  out->stats.minimum_s += stats.minimum_s;
  out->stats.num_correspondences = stats.num_correspondences;
  out->stats.num_rows = stats.num_rows;
  out->stats.correspondence_bytes =
      std::max(out->stats.correspondence_bytes, stats.correspondence_bytes);
  out->stats.residual_bytes = std::max(out->stats.residual_bytes, stats.residual_bytes);
}

}  // namespace

const char* to_string(ResidualSampling sampling) {
  switch (sampling) {
    case ResidualSampling::kFull:
      return "full";
    case ResidualSampling::kExact:
      return "exact";
    case ResidualSampling::kRandom:
      return "random";
    case ResidualSampling::kLossless:
      return "lossless";
  }
  return "unknown";
}

ResidualSampling parse_residual_sampling(std::string_view name) {
  if (name == "full") return ResidualSampling::kFull;
  if (name == "exact") return ResidualSampling::kExact;
  if (name == "random") return ResidualSampling::kRandom;
  if (name == "lossless") return ResidualSampling::kLossless;
  throw Error("unknown sampling " + quote_bytes(name) + " (valid: full, exact, random, lossless)");
}

namespace {

/// The degenerate-frame error (frames after the first must fix all 6 directions).
void check_frame(const Frame& frame, std::size_t index) {
  if (index > 0 && frame.constrained_dof() < 6) {
    throw Error("global registration: frame " + std::to_string(index) +
                (frame.name().empty() ? std::string() : " (" + frame.name() + ")") +
                " is degenerate: its scan fixes only " + std::to_string(frame.constrained_dof()) +
                " of 6 degrees of freedom (e.g. a single plane), so its pose is not determined");
  }
}

/// Checks the counts, pairs and poses shared by the builders.
void check_inputs(std::size_t frames, std::span<const FramePair> pairs,
                  std::span<const Eigen::Isometry3d> T_world_frame) {
  if (frames != T_world_frame.size()) {
    throw Error("global registration: " + std::to_string(frames) + " frames but " +
                std::to_string(T_world_frame.size()) + " poses");
  }
  if (frames < 2)
    throw Error("global registration: at least 2 frames are needed, got " + std::to_string(frames));
  const int n = static_cast<int>(frames);
  for (const FramePair& pair : pairs) {
    if (pair.target < 0 || pair.target >= n || pair.source < 0 || pair.source >= n ||
        pair.target == pair.source)
      throw Error("global registration: " + pair_name(pair) + " does not name two distinct frames");
  }
  for (std::size_t i = 0; i < frames; ++i) {
    if (!T_world_frame[i].matrix().allFinite())
      throw Error("global registration: pose " + std::to_string(i) + " is not finite");
  }
}

/// Throws unless the pairs tie every frame to frame 0 (the gauge, held constant): a frame or a
/// group of frames that no pair links to it would keep its start pose while the solve reports
/// convergence.
void check_connected(std::size_t frames, std::span<const FramePair> pairs) {
  std::vector<std::size_t> parent(frames);
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  const auto find = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (const FramePair& pair : pairs) {
    parent[find(static_cast<std::size_t>(pair.target))] =
        find(static_cast<std::size_t>(pair.source));
  }
  std::size_t loose = 0, example = 0;
  for (std::size_t i = frames; i-- > 1;) {
    if (find(i) == find(0)) continue;
    ++loose;
    example = i;
  }
  if (loose > 0) {
    throw Error("global registration: " + std::to_string(loose) + " of " + std::to_string(frames) +
                " frames are tied to frame 0 by no chain of pairs (e.g. frame " +
                std::to_string(example) + "; " + std::to_string(pairs.size()) +
                " pairs given), so their poses are undetermined; add pairs that link them");
  }
}

/// One factor: correspondences at the initial relative pose, the full block, its kept form.
RegistrationFactor build_factor(const Frame& target, const Frame& source, const FramePair& pair,
                                std::size_t k, const Eigen::Isometry3d& T_world_target,
                                const Eigen::Isometry3d& T_world_source,
                                const GlobalRegistrationOptions& options) {
  RegistrationFactor factor;
  Stopwatch step;
  const Eigen::Isometry3d T_ij = T_world_target.inverse() * T_world_source;
  const std::vector<std::array<std::uint32_t, 2>> correspondences = find_nearest_pairs(
      target.cloud(), target.tree(), source.cloud(), T_ij, options.max_correspondence_distance);
  if (static_cast<int>(correspondences.size()) < options.min_correspondences) {
    char distance[32];
    std::snprintf(distance, sizeof(distance), "%g", options.max_correspondence_distance);
    const std::string names = target.name().empty() || source.name().empty()
                                  ? std::string()
                                  : " (" + target.name() + ", " + source.name() + ")";
    throw Error("global registration: " + pair_name(pair) + " has only " +
                std::to_string(correspondences.size()) + " correspondences within " + distance +
                " m (need " + std::to_string(options.min_correspondences) +
                "); the frames do not overlap at the initial poses" + names);
  }
  auto full = std::make_shared<const GicpBlock>(target.cloud().points, target.cloud().covariances,
                                                source.cloud().points, source.cloud().covariances,
                                                correspondences, T_ij);
  factor.correspondences = correspondences.size();
  factor.correspondence_bytes = full->memory_bytes();
  factor.correspondence_s = step.restart();
  std::array<double, 7> target_storage{}, source_storage{};
  se3::to_storage(T_world_target, target_storage.data());
  se3::to_storage(T_world_source, source_storage.data());
  const double* values[2] = {target_storage.data(), source_storage.data()};
  switch (options.sampling) {
    case ResidualSampling::kFull:
      factor.block = full;
      break;
    case ResidualSampling::kExact: {
      CompressionOptions compression;
      compression.target_rows = options.residuals;
      compression.seed = options.seed + k;
      factor.block = compress(full, values, compression);
      break;
    }
    case ResidualSampling::kRandom: {
      RandomSamplingOptions sampling;
      sampling.group_size = 3;
      sampling.target_rows = 3 * ((options.residuals + 2) / 3);
      sampling.seed = options.seed + k;
      if (sampling.target_rows >= full->num_rows()) {
        factor.block = full;
      } else {
        factor.block = compress_random(full, sampling);
      }
      break;
    }
    case ResidualSampling::kLossless:
      factor.block = make_lossless_block(*full, T_ij);
      break;
  }
  factor.compression_s = step.restart();
  if (options.factor_excess_cauchy_scale > 0.0) {
    factor.minimum = block_minimum(*factor.block, values);
    factor.minimum_s = step.elapsed_s();
  }
  return factor;
}

}  // namespace

std::vector<RegistrationFactor> build_registration_factors(
    FrameStore& frames, std::span<const FramePair> pairs, std::span<const std::size_t> indices,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress) {
  check_options(options);
  check_inputs(frames.size(), pairs, T_world_frame);
  std::vector<std::size_t> all;
  if (indices.empty()) {
    all.resize(pairs.size());
    std::iota(all.begin(), all.end(), std::size_t{0});
    indices = all;
  }
  for (const std::size_t k : indices) {
    if (k >= pairs.size())
      throw Error("global registration: factor index " + std::to_string(k) + " of " +
                  std::to_string(pairs.size()) + " pairs");
  }
  std::vector<RegistrationFactor> out(indices.size());
  const int threads = std::clamp(options.num_threads, 1, tbb::info::default_concurrency());
  tbb::task_arena arena(threads);
  std::atomic<std::size_t> done{0};
  const auto build_one = [&](std::size_t p) {
    const FramePair& pair = pairs[indices[p]];
    const auto i = static_cast<std::size_t>(pair.target);
    const auto j = static_cast<std::size_t>(pair.source);
    const std::shared_ptr<const Frame> target = frames.get(i);
    const std::shared_ptr<const Frame> source = frames.get(j);
    check_frame(*target, i);
    check_frame(*source, j);
    out[p] = build_factor(*target, *source, pair, indices[p], T_world_frame[i], T_world_frame[j],
                          options);
    if (progress) progress(done.fetch_add(1) + 1, indices.size());
  };
  arena.execute([&] {
    if (frames.resident()) {
      internal::parallel_for_each_index(indices.size(), build_one);
      return;
    }
    std::vector<FramePair> chosen;
    chosen.reserve(indices.size());
    for (const std::size_t k : indices) chosen.push_back(pairs[k]);
    const std::vector<std::size_t> order = locality_order(chosen, T_world_frame);
    // Each worker first reads the frames of the factor kFramesAhead positions on, unless they
    // are cached or being read: frames are then read while the other workers build factors,
    // not while they wait for the same frame.
    constexpr std::size_t kFramesAhead = 64;
    std::vector<std::size_t> positions(order.size());
    std::iota(positions.begin(), positions.end(), std::size_t{0});
    internal::parallel_for_in_order(positions, threads, [&](std::size_t position) {
      if (position + kFramesAhead < order.size()) {
        const FramePair& ahead = chosen[order[position + kFramesAhead]];
        frames.prefetch(static_cast<std::size_t>(ahead.target));
        frames.prefetch(static_cast<std::size_t>(ahead.source));
      }
      build_one(order[position]);
    });
  });
  return out;
}

RegistrationProblem assemble_registration_problem(std::span<const FramePair> pairs,
                                                  std::vector<RegistrationFactor> factors,
                                                  std::span<const Eigen::Isometry3d> T_world_frame,
                                                  const GlobalRegistrationOptions& options,
                                                  double build_s,
                                                  std::span<const std::size_t> order) {
  check_options(options);
  check_inputs(T_world_frame.size(), pairs, T_world_frame);
  check_connected(T_world_frame.size(), pairs);
  if (factors.size() != pairs.size()) {
    throw Error("global registration: " + std::to_string(factors.size()) + " factors for " +
                std::to_string(pairs.size()) + " pairs");
  }
  if (!order.empty()) check_order(order, pairs.size());
  RegistrationProblem out;
  for (const Eigen::Isometry3d& T : T_world_frame)
    out.frame_variables.push_back(out.problem.add_se3(T));
  out.problem.set_constant(out.frame_variables.front());
  const internal::FactorLosses losses(options);
  for (std::size_t q = 0; q < pairs.size(); ++q) {
    const std::size_t k = order.empty() ? q : order[q];
    const FramePair& pair = pairs[k];
    out.pairs.push_back(pair);
    RegistrationFactor& factor = factors[k];
    if (!factor.block) throw Error("global registration: " + pair_name(pair) + " has no block");
    std::shared_ptr<const LossFunction> factor_loss = losses.of(factor);
    internal::count_factor(factor, &out.stats);
    out.factor_correspondences.push_back(factor.correspondences);
    out.factor_correspondence_bytes.push_back(factor.correspondence_bytes);
    out.factor_residual_bytes.push_back(factor.block->memory_bytes());
    out.problem.add_residual_block(std::move(factor.block),
                                   {out.frame_variables[static_cast<std::size_t>(pair.target)],
                                    out.frame_variables[static_cast<std::size_t>(pair.source)]},
                                   std::move(factor_loss));
  }
  // The stage ran in parallel: split its wall time in proportion to the per-factor CPU times.
  const double cpu = out.stats.correspondence_s + out.stats.compression_s + out.stats.minimum_s;
  if (build_s > 0.0 && cpu > 0.0) {
    out.stats.correspondence_s *= build_s / cpu;
    out.stats.compression_s *= build_s / cpu;
    out.stats.minimum_s *= build_s / cpu;
  }
  return out;
}

namespace {

/// Checks the frames of a resident store up front (every frame, degenerate ones by name, before
/// any factor is built); a store that reads on demand checks each frame as its factors are built.
void check_resident(FrameStore& frames, std::span<const FramePair> pairs,
                    std::span<const Eigen::Isometry3d> T_world_frame,
                    const GlobalRegistrationOptions& options) {
  if (!frames.resident()) return;
  check_options(options);
  check_inputs(frames.size(), pairs, T_world_frame);
  check_connected(frames.size(), pairs);
  for (std::size_t i = 0; i < frames.size(); ++i) check_frame(*frames.get(i), i);
}

}  // namespace

RegistrationProblem build_registration_problem(
    FrameStore& frames, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress) {
  check_resident(frames, pairs, T_world_frame, options);
  const Stopwatch stage_time;
  std::vector<RegistrationFactor> factors =
      build_registration_factors(frames, pairs, {}, T_world_frame, options, progress);
  return assemble_registration_problem(pairs, std::move(factors), T_world_frame, options,
                                       stage_time.elapsed_s());
}

GlobalRegistrationResult optimize_registration(
    FrameStore& frames, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress) {
  check_resident(frames, pairs, T_world_frame, options);
  int rounds_built = 0;
  return optimize_registration(
      [&](std::span<const Eigen::Isometry3d> T_world_start) {
        std::vector<RegistrationFactor> factors =
            build_registration_factors(frames, pairs, {}, T_world_start, options, progress);
        // The last round's solve needs no frame: free the cache for the solver's memory.
        if (++rounds_built == options.rounds) frames.release_cached();
        return factors;
      },
      pairs, T_world_frame, options);
}

GlobalRegistrationResult optimize_registration(const RegistrationFactorBuilder& build,
                                               std::span<const FramePair> pairs,
                                               std::span<const Eigen::Isometry3d> T_world_frame,
                                               const GlobalRegistrationOptions& options) {
  const auto make = [&](std::span<const Eigen::Isometry3d> T_world_start,
                        std::span<const std::size_t> order) {
    const Stopwatch stage_time;
    std::vector<RegistrationFactor> factors = build(T_world_start);
    RegistrationProblem built = assemble_registration_problem(
        pairs, std::move(factors), T_world_start, options, stage_time.elapsed_s(), order);
    internal::RegistrationRound round;
    round.stats = built.stats;
    round.correspondence_bytes.resize(pairs.size());
    round.residual_bytes.resize(pairs.size());
    for (std::size_t q = 0; q < order.size(); ++q) {
      round.correspondence_bytes[order[q]] = built.factor_correspondence_bytes[q];
      round.residual_bytes[order[q]] = built.factor_residual_bytes[q];
    }
    round.problem = std::move(built.problem);
    round.frame_variables = std::move(built.frame_variables);
    round.factor_costs = [order = std::vector<std::size_t>(order.begin(), order.end()),
                          correspondences =
                              std::move(built.factor_correspondences)](const Problem& problem) {
      std::vector<double> costs(order.size());
      const auto blocks = problem.blocks();
      for (std::size_t q = 0; q < blocks.size(); ++q) {
        const double* values[2] = {problem.value(blocks[q].variables[0]).data(),
                                   problem.value(blocks[q].variables[1]).data()};
        costs[order[q]] =
            blocks[q].block->squared_norm(values) / static_cast<double>(correspondences[q]);
      }
      return costs;
    };
    return round;
  };
  return internal::optimize_rounds(make, pairs, T_world_frame, options);
}

namespace internal {

GlobalRegistrationResult optimize_rounds(const RegistrationRoundMaker& make,
                                         std::span<const FramePair> pairs,
                                         std::span<const Eigen::Isometry3d> T_world_frame,
                                         const GlobalRegistrationOptions& options) {
  if (options.rounds < 1)
    throw Error("global registration: rounds must be >= 1, got " + std::to_string(options.rounds));
  check_inputs(T_world_frame.size(), pairs, T_world_frame);
  check_connected(T_world_frame.size(), pairs);
  const std::vector<std::size_t> order = block_order(pairs, T_world_frame);
  GlobalRegistrationResult out;
  out.T_world_frame.assign(T_world_frame.begin(), T_world_frame.end());
  SolverOptions solver = options.solver;
  solver.num_threads = options.num_threads;
  for (int round = 0; round < options.rounds; ++round) {
    RegistrationRound built = make(out.T_world_frame, order);
    if (options.iteration_callback) {
      solver.update_state_every_iteration = true;
      solver.iteration_callback =
          [&options, &built, poses = std::vector<Eigen::Isometry3d>(built.frame_variables.size())](
              const IterationSummary& row) mutable {
            if (options.solver.iteration_callback &&
                options.solver.iteration_callback(row) == CallbackResult::kAbort)
              return CallbackResult::kAbort;
            for (std::size_t i = 0; i < poses.size(); ++i)
              poses[i] = built.problem.se3(built.frame_variables[i]);
            return options.iteration_callback(row, poses);
          };
    }
    const SolverSummary summary = solve(solver, built.problem);
    if (!summary.is_solution_usable())
      throw Error("global registration: the solve failed: " + summary.message);
    accumulate_round(summary, built.stats, round == 0, &out);
    double max_translation = 0.0, max_rotation = 0.0;
    for (std::size_t i = 0; i < built.frame_variables.size(); ++i) {
      const Eigen::Isometry3d T = built.problem.se3(built.frame_variables[i]);
      const se3::Vector6d step = se3::log(out.T_world_frame[i].inverse() * T);
      max_rotation = std::max(max_rotation, step.head<3>().norm());
      max_translation = std::max(max_translation, step.tail<3>().norm());
      out.T_world_frame[i] = T;
    }
    out.rounds = round + 1;
    out.factor_correspondence_bytes = std::move(built.correspondence_bytes);
    out.factor_residual_bytes = std::move(built.residual_bytes);
    out.factor_costs = built.factor_costs(built.problem);
    const bool last = summary.termination == TerminationType::kUserAbort ||
                      round + 1 == options.rounds ||
                      (max_translation < options.round_translation_tolerance &&
                       max_rotation < options.round_rotation_tolerance);
    if (!last) continue;
    if (options.covariance) {
      out.covariance = internal::pose_covariances(built.problem, built.frame_variables,
                                                  options.num_threads, &out.covariance_s);
    }
    break;
  }
  return out;
}

}  // namespace internal

}  // namespace carat
