#pragma once

/// Global registration error minimization (Koide et al. 2023, Sec. IV-C): a GICP block with
/// correspondences fixed at the initial poses for every frame pair of the dense graph, each
/// kept whole, compressed exactly (coreset) or randomly sampled, and all poses optimized
/// together with LM (the first pose held constant).

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/registration/frame.hpp"
#include "carat/registration/frame_store.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/problem.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/solver_options.hpp"
#include "carat/solver/solver_summary.hpp"

namespace carat {

/// How each factor's rows are kept.
enum class ResidualSampling {
  kFull,      ///< every row of every correspondence
  kExact,     ///< an exact coreset of M weighted rows (same H, b, c at the initial poses)
  kRandom,    ///< ceil(M/3) random correspondences (3 rows each), weighted N/M
  kLossless,  ///< at most 13 rows with the same cost as the full factor at every pose
              ///< (its Gram matrix in the relative pose's entries; lossless_block.hpp)
};

/// Name of a sampling mode: "full", "exact", "random", "lossless".
const char* to_string(ResidualSampling sampling);
/// Parses "full", "exact", "random" or "lossless"; throws carat::Error listing the valid names
/// otherwise.
ResidualSampling parse_residual_sampling(std::string_view name);

/// Called after every LM iteration of every round with the iteration's row and the frames'
/// poses T_world_frame (parallel to the frames) at the current iterate, the last accepted one;
/// kAbort ends the solve as SolverOptions::iteration_callback does, and with it the rounds.
using RegistrationIterationCallback =
    std::function<CallbackResult(const IterationSummary&, std::span<const Eigen::Isometry3d>)>;

/// Settings of the global registration problem and its solve.
struct GlobalRegistrationOptions {
  ResidualSampling sampling = ResidualSampling::kExact;  ///< rows kept per factor
  int residuals = 29;                        ///< M: rows per factor for exact and random sampling
  double max_correspondence_distance = 1.0;  ///< metres, at the initial poses
  int min_correspondences = 29;              ///< a factor with fewer is an error
  std::uint64_t seed = 1;                    ///< seed of the coreset shuffle / random draw
  int num_threads = 1;                       ///< threads for building, compressing, solving
  double factor_cauchy_scale = 0.0;          ///< Cauchy kernel on each factor's whole squared error
                                             ///< (exactness is kept); 0: none, as in the paper
  double factor_excess_cauchy_scale = 0.0;   ///< Cauchy kernel on each factor's squared error
                                             ///< above the factor's own least squared norm over
                                             ///< its relative pose (Gauss-Newton on the kept
                                             ///< rows from the initial poses; ExcessLoss): the
                                             ///< GRE analogue of a PGO edge's Cauchy kernel on
                                             ///< its Mahalanobis error. 0: none, as in the
                                             ///< paper. At most one of the two kernels is set.
  int rounds = 1;  ///< 1: correspondences fixed at the initial poses (the paper); more: search
                   ///< again at each round's result and solve again, until a round moves no
                   ///< pose more than the tolerances below
  double round_translation_tolerance = 1e-3;  ///< metres
  double round_rotation_tolerance = 1e-4;     ///< radians
  SolverOptions solver;                       ///< LM settings
  /// After the last round: every pose's marginal covariance at the solution, from the problem
  /// as solved (carat::Covariance over its kept rows; see carat/solver/covariance.hpp).
  bool covariance = false;
  /// Per-iteration poses (e.g. an error against a reference at every iteration); it runs after
  /// solver.iteration_callback when both are set. Empty: none.
  RegistrationIterationCallback iteration_callback;
};

/// Bytes and times of building the factors.
struct RegistrationFactorStats {
  std::size_t num_factors = 0;           ///< residual blocks
  std::size_t num_correspondences = 0;   ///< correspondences found over all factors
  std::size_t num_rows = 0;              ///< rows kept over all factors
  std::size_t correspondence_bytes = 0;  ///< bytes of the full GICP blocks as built
  std::size_t residual_bytes = 0;        ///< bytes the kept blocks hold during the solve
  double correspondence_s = 0.0;  ///< wall time of the searches and full blocks (share of stage)
  double compression_s = 0.0;     ///< wall time of compressing (share of the same stage)
  double minimum_s = 0.0;         ///< wall time of the factors' model minima for the excess kernel
                                  ///< (share of the same stage; 0 without that kernel)
};

/// The assembled problem: one SE(3) variable per frame, one block per pair.
struct RegistrationProblem {
  Problem problem;                                       ///< variables and blocks
  std::vector<VariableId> frame_variables;               ///< parallel to the frames
  std::vector<FramePair> pairs;                          ///< parallel to the blocks
  std::vector<std::size_t> factor_correspondences;       ///< per block: correspondences found
  std::vector<std::size_t> factor_correspondence_bytes;  ///< per block: bytes of its full block
  std::vector<std::size_t> factor_residual_bytes;        ///< per block: bytes the kept block holds
  RegistrationFactorStats stats;                         ///< what building cost
};

/// One factor of the dense graph as built: its kept block and what building it cost.
struct RegistrationFactor {
  std::shared_ptr<const ResidualBlock> block;  ///< the kept rows (full, exact, random, lossless)
  std::size_t correspondences = 0;             ///< correspondences found
  std::size_t correspondence_bytes = 0;        ///< bytes of the full GICP block as built
  double correspondence_s = 0.0;               ///< CPU time of the search and the full block
  double compression_s = 0.0;                  ///< CPU time of compressing
  double minimum_s = 0.0;                      ///< CPU time of the model minimum (excess kernel)
  double minimum = 0.0;  ///< the block's least squared norm over T_ij (excess kernel only)
};

/// Builds the factors of pairs[k] for every k in `indices` (every pair when empty), returned
/// parallel to `indices` (to the pairs when empty), at T_world_frame. Frames come from the
/// store: a store that loads on demand is walked in locality_order(), so a bounded cache reads
/// each frame a few times only. Factors do not depend on the thread count, the order or the
/// other indices (each factor's seed is options.seed + k). Throws carat::Error as
/// build_registration_problem() does; `progress` gets (factors done, factors).
std::vector<RegistrationFactor> build_registration_factors(
    FrameStore& frames, std::span<const FramePair> pairs, std::span<const std::size_t> indices,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

/// The problem from built factors (parallel to `pairs`), at T_world_frame, the first pose held
/// constant; blocks (and the result's per-block lists) in `order` (indices into the pairs, each
/// once; empty: the pairs' order). Stats' times are the factors' CPU times scaled so that they
/// add up to `build_s` (the build stage's wall time; 0 keeps the CPU times). Throws
/// carat::Error for mismatched counts, an order that is not a permutation, a missing block or
/// a non-finite pose.
RegistrationProblem assemble_registration_problem(std::span<const FramePair> pairs,
                                                  std::vector<RegistrationFactor> factors,
                                                  std::span<const Eigen::Isometry3d> T_world_frame,
                                                  const GlobalRegistrationOptions& options,
                                                  double build_s = 0.0,
                                                  std::span<const std::size_t> order = {});

/// Builds the problem at T_world_frame (the first frame's pose held constant). Factors are
/// built and compressed in parallel (see build_registration_factors()); results do not depend
/// on the thread count. Throws carat::Error for mismatched counts, bad options, non-finite
/// poses, a frame after the first whose own geometry fixes fewer than 6 directions
/// (Frame::constrained_dof(), e.g. a plane; every frame of a resident store is checked before
/// any factor is built), or a pair with fewer than min_correspondences correspondences (naming
/// the pair). `progress` gets (factors done, factors).
RegistrationProblem build_registration_problem(
    FrameStore& frames, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

/// What optimize_registration() found.
struct GlobalRegistrationResult {
  std::vector<Eigen::Isometry3d> T_world_frame;  ///< optimized poses
  SolverSummary summary;                         ///< the LM solve
  RegistrationFactorStats stats;                 ///< building the factors
  std::vector<double> factor_costs;  ///< per factor: sum of squared residuals / correspondences
  std::vector<std::size_t> factor_correspondence_bytes;  ///< per factor: its full block's bytes
  std::vector<std::size_t> factor_residual_bytes;  ///< per factor: bytes held during the solve
  int rounds = 0;                                  ///< correspondence rounds run
  /// With GlobalRegistrationOptions::covariance: per frame, the covariance of its pose's right
  /// perturbation xi = [omega (rad), v (m)], T_world_frame <- T_world_frame Exp(xi); zero for
  /// the first frame, which is held constant.
  std::vector<se3::Matrix6d> covariance;
  double covariance_s = 0.0;  ///< wall time of the covariances
};

/// Builds the problem and solves it, `options.rounds` times at most. Over the rounds: the
/// summary's iterations, steps and times add up, its initial_cost is the first round's and its
/// final_cost the last round's (each round has its own correspondences, so the two are costs of
/// different objectives); the stats' times add up, their counts are the last round's and their
/// byte counts the largest of any round; factor_costs and the per-factor bytes are the last
/// round's (all per-factor lists parallel to the pairs). The problem's blocks are in
/// block_order() of the start poses (held_factors.hpp). A store that reads frames on demand
/// reads them again each round. Throws carat::Error as build_registration_problem() does, or
/// when a solve fails.
GlobalRegistrationResult optimize_registration(
    FrameStore& frames, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options,
    const std::function<void(std::size_t, std::size_t)>& progress = {});

/// Builds the factors of every pair at T_world_frame, parallel to the pairs: one round's build
/// stage in optimize_registration() (e.g. shards built by other processes and gathered).
using RegistrationFactorBuilder =
    std::function<std::vector<RegistrationFactor>(std::span<const Eigen::Isometry3d>)>;

/// The same with the factors of each round from `build` (called once per round at that round's
/// start poses); `pairs` and T_world_frame give the problem's shape. Throws carat::Error as
/// assemble_registration_problem() does, for a factor count that is not the pair count, or when
/// a solve fails; what `build` throws passes through.
GlobalRegistrationResult optimize_registration(const RegistrationFactorBuilder& build,
                                               std::span<const FramePair> pairs,
                                               std::span<const Eigen::Isometry3d> T_world_frame,
                                               const GlobalRegistrationOptions& options);

/// Deprecated: build_registration_problem() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline RegistrationProblem
build_registration_problem(std::span<const std::shared_ptr<const Frame>> frames,
                           std::span<const FramePair> pairs,
                           std::span<const Eigen::Isometry3d> T_world_frame,
                           const GlobalRegistrationOptions& options,
                           const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return build_registration_problem(store, pairs, T_world_frame, options, progress);
}

/// Deprecated: optimize_registration() from frames in memory.
[[deprecated("wrap the frames in a carat::FrameStore")]] inline GlobalRegistrationResult
optimize_registration(std::span<const std::shared_ptr<const Frame>> frames,
                      std::span<const FramePair> pairs,
                      std::span<const Eigen::Isometry3d> T_world_frame,
                      const GlobalRegistrationOptions& options,
                      const std::function<void(std::size_t, std::size_t)>& progress = {}) {
  FrameStore store = resident_store(frames);
  return optimize_registration(store, pairs, T_world_frame, options, progress);
}

}  // namespace carat
