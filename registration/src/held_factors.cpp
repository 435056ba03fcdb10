#include "carat/registration/held_factors.hpp"

#include <string>
#include <utility>

#include "carat/base/error.hpp"
#include "carat/base/stopwatch.hpp"
#include "factor_losses.hpp"
#include "factor_stats.hpp"
#include "registration_rounds.hpp"

namespace carat {

std::vector<std::size_t> block_order(std::span<const FramePair> pairs,
                                     std::span<const Eigen::Isometry3d> T_world_start) {
  return locality_order(pairs, T_world_start);
}

struct RegistrationShare::Impl {
  Problem problem;  // every frame's pose, the share's blocks
  std::vector<std::size_t> correspondences;
  std::vector<std::size_t> correspondence_bytes;
  std::vector<std::size_t> residual_bytes;
  RegistrationFactorStats stats;
  std::unique_ptr<BlockLinearizer> linearizer;
};

RegistrationShare::RegistrationShare(std::span<const FramePair> pairs,
                                     std::span<const std::size_t> indices,
                                     std::vector<RegistrationFactor> factors,
                                     std::span<const Eigen::Isometry3d> T_world_frame,
                                     const GlobalRegistrationOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (factors.size() != indices.size()) {
    throw Error("registration share: " + std::to_string(factors.size()) + " factors for " +
                std::to_string(indices.size()) + " indices");
  }
  Impl& s = *impl_;
  for (const Eigen::Isometry3d& T : T_world_frame) s.problem.add_se3(T);
  const internal::FactorLosses losses(options);
  for (std::size_t q = 0; q < indices.size(); ++q) {
    if (indices[q] >= pairs.size()) {
      throw Error("registration share: factor index " + std::to_string(indices[q]) + " of " +
                  std::to_string(pairs.size()) + " pairs");
    }
    const FramePair& pair = pairs[indices[q]];
    RegistrationFactor& factor = factors[q];
    const std::string name =
        "pair (" + std::to_string(pair.target) + ", " + std::to_string(pair.source) + ")";
    if (!factor.block) throw Error("registration share: " + name + " has no block");
    for (const int frame : {pair.target, pair.source}) {
      if (frame < 0 || static_cast<std::size_t>(frame) >= T_world_frame.size()) {
        throw Error("registration share: " + name + " names frame " + std::to_string(frame) +
                    " of " + std::to_string(T_world_frame.size()));
      }
    }
    internal::count_factor(factor, &s.stats);
    s.correspondences.push_back(factor.correspondences);
    s.correspondence_bytes.push_back(factor.correspondence_bytes);
    s.residual_bytes.push_back(factor.block->memory_bytes());
    s.problem.add_residual_block(std::move(factor.block),
                                 {VariableId{pair.target}, VariableId{pair.source}},
                                 losses.of(factor));
  }
  s.linearizer = std::make_unique<BlockLinearizer>(s.problem, options.num_threads, kRunBlocks);
}

RegistrationShare::~RegistrationShare() = default;

std::size_t RegistrationShare::size() const { return impl_->correspondences.size(); }

void RegistrationShare::linearize(std::span<const double> values, const BlockRecordSink& sink) {
  impl_->linearizer->linearize(values, sink);
}

void RegistrationShare::costs(std::span<const double> values, const BlockRecordSink& sink) {
  impl_->linearizer->costs(values, sink);
}

std::vector<double> RegistrationShare::factor_costs(std::span<const double> values) const {
  const Problem& problem = impl_->problem;
  if (values.size() != problem.all_values().size()) {
    throw Error("registration share: " + std::to_string(values.size()) + " values for " +
                std::to_string(problem.all_values().size()));
  }
  const auto blocks = problem.blocks();
  std::vector<double> out(blocks.size());
  for (std::size_t q = 0; q < blocks.size(); ++q) {
    const double* at[2] = {values.data() + problem.value_offset(blocks[q].variables[0]),
                           values.data() + problem.value_offset(blocks[q].variables[1])};
    out[q] = blocks[q].block->squared_norm(at) / static_cast<double>(impl_->correspondences[q]);
  }
  return out;
}

const RegistrationFactorStats& RegistrationShare::stats() const { return impl_->stats; }

std::span<const std::size_t> RegistrationShare::correspondence_bytes() const {
  return impl_->correspondence_bytes;
}

std::span<const std::size_t> RegistrationShare::residual_bytes() const {
  return impl_->residual_bytes;
}

GlobalRegistrationResult optimize_held_registration(
    const RegistrationFactorHolder& hold, std::span<const FramePair> pairs,
    std::span<const Eigen::Isometry3d> T_world_frame, const GlobalRegistrationOptions& options) {
  const auto make = [&](std::span<const Eigen::Isometry3d> T_world_start,
                        std::span<const std::size_t> order) {
    std::shared_ptr<HeldRegistrationFactors> held = hold(T_world_start, order);
    if (!held) throw Error("global registration: the factor holder returned no factors");
    if (held->num_blocks() != pairs.size()) {
      throw Error("global registration: " + std::to_string(held->num_blocks()) +
                  " held factors for " + std::to_string(pairs.size()) + " pairs");
    }
    for (std::size_t k = 0; k < order.size(); ++k) {
      const FramePair& pair = pairs[order[k]];
      const std::span<const VariableId> variables = held->variables(k);
      if (variables.size() != 2 || variables[0].index != pair.target ||
          variables[1].index != pair.source) {
        throw Error("global registration: held factor " + std::to_string(k) +
                    " is not over the frames of pair (" + std::to_string(pair.target) + ", " +
                    std::to_string(pair.source) + ")");
      }
    }
    internal::RegistrationRound round;
    for (const Eigen::Isometry3d& T : T_world_start)
      round.frame_variables.push_back(round.problem.add_se3(T));
    round.problem.set_constant(round.frame_variables.front());
    round.problem.set_block_source(held);
    round.stats = held->stats();
    round.correspondence_bytes = held->correspondence_bytes();
    round.residual_bytes = held->residual_bytes();
    round.factor_costs = [held](const Problem& problem) {
      return held->factor_costs(problem.all_values());
    };
    return round;
  };
  return internal::optimize_rounds(make, pairs, T_world_frame, options);
}

}  // namespace carat
