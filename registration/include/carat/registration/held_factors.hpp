#pragma once

/// Global registration whose factors stay where they were built (e.g. on the processes of an
/// MPI job): each holder keeps its share of a round's factors as a RegistrationShare and serves
/// their linearizations at the poses the solve asks for; the solve (optimize_held_registration())
/// holds only the poses and the reduced system. Blocks are in the order block_order() gives,
/// and a holder's share is a stretch of that order, so the solve is bit for bit the one
/// optimize_registration() makes over the same factors, however the shares are split.

#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "carat/registration/dense_graph.hpp"
#include "carat/registration/global_registration.hpp"
#include "carat/solver/block_source.hpp"
#include "carat/solver/problem.hpp"

namespace carat {

/// The order of the problem's blocks for pairs at the first round's start poses T_world_start:
/// locality_order(), which optimize_registration() uses too. Stretches of it are shares.
std::vector<std::size_t> block_order(std::span<const FramePair> pairs,
                                     std::span<const Eigen::Isometry3d> T_world_start);

/// The factors of one share, kept: their blocks over every frame's pose (frame i is the
/// problem's variable i), linearized as solve() would linearize them.
class RegistrationShare {
 public:
  /// The factors of pairs[indices[q]] (factors parallel to indices, as
  /// build_registration_factors() returns them) at T_world_frame (every frame's pose), with
  /// the robust losses `options` ask for, linearized with options.num_threads threads. Throws
  /// carat::Error for mismatched counts, an index or frame out of range, or a missing block.
  RegistrationShare(std::span<const FramePair> pairs, std::span<const std::size_t> indices,
                    std::vector<RegistrationFactor> factors,
                    std::span<const Eigen::Isometry3d> T_world_frame,
                    const GlobalRegistrationOptions& options);
  ~RegistrationShare();
  RegistrationShare(const RegistrationShare&) = delete;
  RegistrationShare& operator=(const RegistrationShare&) = delete;

  /// Number of factors held.
  std::size_t size() const;
  /// Passes the linearization records of the factors at `values` (every frame's pose, the
  /// layout of Problem::all_values() over SE(3) variables) to `sink` in the order of `indices`,
  /// in runs of at most kRunBlocks factors (BlockLinearizer; block_source.hpp).
  void linearize(std::span<const double> values, const BlockRecordSink& sink);
  /// Passes the cost 1/2 rho(|r|^2) of each factor at `values` to `sink`, in the order of
  /// `indices`, in runs of at most kRunBlocks.
  void costs(std::span<const double> values, const BlockRecordSink& sink);
  /// Factors a run of records holds at most (a run of linearizations: 728 bytes a factor).
  static constexpr std::size_t kRunBlocks = 4096;
  /// Each factor's sum of squared residuals per correspondence at `values`, in the order of
  /// `indices` (GlobalRegistrationResult::factor_costs).
  std::vector<double> factor_costs(std::span<const double> values) const;
  /// What building the share cost (times: the factors' CPU times, summed).
  const RegistrationFactorStats& stats() const;
  /// Per factor, in the order of `indices`: bytes of its full block as built.
  std::span<const std::size_t> correspondence_bytes() const;
  /// Per factor, in the order of `indices`: bytes its kept block holds.
  std::span<const std::size_t> residual_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A round's factors held elsewhere: a BlockSource over them in block order (block k is the
/// factor of pairs[order[k]] over variables {target, source}: frame i is variable i), and what
/// the result reports.
class HeldRegistrationFactors : public BlockSource {
 public:
  /// What building cost, over all factors (times: the build stage's wall time, split as
  /// assemble_registration_problem() splits it).
  virtual RegistrationFactorStats stats() const = 0;
  /// Per pair (parallel to the pairs, not the blocks): bytes of its full block as built.
  virtual std::vector<std::size_t> correspondence_bytes() const = 0;
  /// Per pair: bytes its kept block holds.
  virtual std::vector<std::size_t> residual_bytes() const = 0;
  /// Per pair: the factor's sum of squared residuals per correspondence at `values`.
  virtual std::vector<double> factor_costs(std::span<const double> values) = 0;
};

/// Builds one round's factors at T_world_start where they will stay, and returns them held;
/// `order` is block_order() of the first round (the same every round).
using RegistrationFactorHolder = std::function<std::shared_ptr<HeldRegistrationFactors>(
    std::span<const Eigen::Isometry3d> T_world_start, std::span<const std::size_t> order)>;

/// optimize_registration() with each round's factors from `hold` (called once per round at that
/// round's start poses): the same rounds, solve, covariances and result, bit for bit, as
/// optimize_registration() over the same factors. Throws carat::Error as that does, or when
/// the held factors are not one block per pair in `order` over the pair's frames; what `hold`
/// and the held factors throw passes through.
GlobalRegistrationResult optimize_held_registration(
    const RegistrationFactorHolder& hold, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options);

}  // namespace carat
