#pragma once

// Internal: the rounds of global registration (build, solve, search again at the result) over
// problems made one round at a time, either of the factors' own blocks or of factors held
// elsewhere (a block source): optimize_registration() and optimize_held_registration().

#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <span>
#include <vector>

#include "carat/registration/global_registration.hpp"
#include "carat/solver/problem.hpp"

namespace carat::internal {

/// One round's problem and what the result reports of it.
struct RegistrationRound {
  Problem problem;                                ///< frame i is variable i, the first constant
  std::vector<VariableId> frame_variables;        ///< parallel to the frames
  RegistrationFactorStats stats;                  ///< building the round's factors
  std::vector<std::size_t> correspondence_bytes;  ///< per pair: its full block's bytes
  std::vector<std::size_t> residual_bytes;        ///< per pair: its kept block's bytes
  /// Per pair: sum of squared residuals per correspondence at the problem's values.
  std::function<std::vector<double>(const Problem&)> factor_costs;
};

/// Makes one round's problem at the round's start poses; `order` is the block order.
using RegistrationRoundMaker = std::function<RegistrationRound(
    std::span<const Eigen::Isometry3d> T_world_start, std::span<const std::size_t> order)>;

/// The rounds of optimize_registration() over problems from `make` (block order: block_order()
/// of T_world_frame, kept for every round).
GlobalRegistrationResult optimize_rounds(const RegistrationRoundMaker& make,
                                         std::span<const FramePair> pairs,
                                         std::span<const Eigen::Isometry3d> T_world_frame,
                                         const GlobalRegistrationOptions& options);

}  // namespace carat::internal
