#include "carat/solver/problem.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <typeinfo>

#include "carat/base/error.hpp"
#include "carat/solver/se2.hpp"
#include "carat/solver/se3.hpp"
#include "carat/solver/subset_manifold.hpp"

namespace carat {
namespace {

/// Whether a block differentiating through `assumed` takes its Jacobian in the tangent that
/// `own` steps in: the same object, or one of the same kind (type and sizes; for held
/// coordinates, the same ones held on the same kind of base).
bool same_tangent(const Manifold& assumed, const Manifold& own) {
  if (&assumed == &own) return true;
  if (typeid(assumed) != typeid(own) || assumed.ambient_size() != own.ambient_size() ||
      assumed.tangent_size() != own.tangent_size()) {
    return false;
  }
  const auto* a = dynamic_cast<const SubsetManifold*>(&assumed);
  const auto* b = dynamic_cast<const SubsetManifold*>(&own);
  if (a == nullptr || b == nullptr) return true;
  return a->constant_coordinates() == b->constant_coordinates() &&
         same_tangent(a->base(), b->base());
}

/// A manifold's name, with the coordinates it holds.
std::string describe(const Manifold& manifold) {
  std::string out = manifold.name();
  if (const auto* subset = dynamic_cast<const SubsetManifold*>(&manifold)) {
    out += " holding";
    for (const int c : subset->constant_coordinates()) out += " " + std::to_string(c);
  }
  return out;
}

}  // namespace

VariableId Problem::add_variable(std::shared_ptr<const Manifold> manifold,
                                 std::span<const double> initial) {
  if (!manifold) throw Error("Problem::add_variable: manifold is null");
  if (static_cast<int>(initial.size()) != manifold->ambient_size()) {
    throw Error("Problem::add_variable: a " + std::string(manifold->name()) + " value needs " +
                std::to_string(manifold->ambient_size()) + " numbers, got " +
                std::to_string(initial.size()));
  }
  if (!manifold->is_valid(initial.data())) {
    throw Error("Problem::add_variable: initial value is not a valid " +
                std::string(manifold->name()) + " value (non-finite or not normalized)");
  }
  const VariableId id{static_cast<std::int32_t>(manifolds_.size())};
  offsets_.push_back(values_.size());
  values_.insert(values_.end(), initial.begin(), initial.end());
  if (!lower_.empty()) {
    lower_.resize(values_.size(), -std::numeric_limits<double>::infinity());
    upper_.resize(values_.size(), std::numeric_limits<double>::infinity());
  }
  manifolds_.push_back(std::move(manifold));
  constant_.push_back(0);
  eliminable_.push_back(0);
  return id;
}

VariableId Problem::add_se3(const Eigen::Isometry3d& T_world_body) {
  if (const char* problem = se3::rigid_transform_problem(T_world_body)) {
    throw Error("Problem::add_se3 (variable " + std::to_string(num_variables()) +
                "): T_world_body " + problem);
  }
  double storage[7];
  se3::to_storage(T_world_body, storage);
  return add_variable(se3_manifold(), storage);
}

VariableId Problem::add_se2(const Eigen::Isometry2d& T_world_body) {
  if (const char* problem = se2::rigid_transform_problem(T_world_body)) {
    throw Error("Problem::add_se2 (variable " + std::to_string(num_variables()) +
                "): T_world_body " + problem);
  }
  double storage[3];
  se2::to_storage(T_world_body, storage);
  return add_variable(se2_manifold(), storage);
}

VariableId Problem::add_euclidean(const Eigen::VectorXd& initial) {
  return add_variable(
      euclidean_manifold(static_cast<int>(initial.size())),
      std::span<const double>(initial.data(), static_cast<std::size_t>(initial.size())));
}

void Problem::throw_no_variable(VariableId id) const {
  throw Error("Problem: variable id " + std::to_string(id.index) + " does not exist (" +
              std::to_string(num_variables()) + " variables)");
}

void Problem::set_constant(VariableId id, bool constant) {
  check(id);
  constant_[static_cast<std::size_t>(id.index)] = constant ? 1 : 0;
}

bool Problem::is_constant(VariableId id) const {
  check(id);
  return constant_[static_cast<std::size_t>(id.index)] != 0;
}

void Problem::set_eliminable(VariableId id, bool eliminable) {
  check(id);
  eliminable_[static_cast<std::size_t>(id.index)] = eliminable ? 1 : 0;
}

bool Problem::is_eliminable(VariableId id) const {
  check(id);
  return eliminable_[static_cast<std::size_t>(id.index)] != 0;
}

bool Problem::has_eliminable() const {
  return std::find(eliminable_.begin(), eliminable_.end(), 1) != eliminable_.end();
}

ResidualBlockId Problem::add_residual_block(std::shared_ptr<const ResidualBlock> block,
                                            std::initializer_list<VariableId> variables,
                                            std::shared_ptr<const LossFunction> loss) {
  return add_residual_block(std::move(block),
                            std::span<const VariableId>(variables.begin(), variables.size()),
                            std::move(loss));
}

ResidualBlockId Problem::add_residual_block(std::shared_ptr<const ResidualBlock> block,
                                            std::span<const VariableId> variables,
                                            std::shared_ptr<const LossFunction> loss) {
  // The message prefix, built only on an error (not once per block).
  const auto where = [this] {
    return "Problem::add_residual_block (block " + std::to_string(blocks_.size()) + "): ";
  };
  if (!block) throw Error(where() + "block is null");
  const auto dims = block->tangent_dims();
  if (dims.size() != variables.size()) {
    throw Error(where() + "the block expects " + std::to_string(dims.size()) + " variables, got " +
                std::to_string(variables.size()));
  }
  if (block->num_rows() < 1) throw Error(where() + "the block has no rows");
  for (std::size_t i = 0; i < variables.size(); ++i) {
    check(variables[i]);
    const int tangent = manifolds_[static_cast<std::size_t>(variables[i].index)]->tangent_size();
    if (tangent != dims[i]) {
      throw Error(where() + "variable " + std::to_string(variables[i].index) +
                  " has tangent size " + std::to_string(tangent) + " but the block expects " +
                  std::to_string(dims[i]));
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (variables[j] == variables[i]) {
        throw Error(where() + "variable " + std::to_string(variables[i].index) +
                    " is listed twice");
      }
    }
    // A block that takes its Jacobian through a manifold of its own must take it through the
    // variable's: its columns are then in the tangent the solver steps in.
    const Manifold* assumed = block->jacobian_manifold(static_cast<int>(i));
    const Manifold& own = *manifolds_[static_cast<std::size_t>(variables[i].index)];
    if (assumed != nullptr && !same_tangent(*assumed, own)) {
      throw Error(where() + "variable " + std::to_string(variables[i].index) + " steps on " +
                  describe(own) + " but block '" + block->name() + "' takes its Jacobian through " +
                  describe(*assumed) +
                  "; give the block the variable's manifold (the manifolds argument of "
                  "make_autodiff_block / make_numeric_diff_block)");
    }
  }
  const int r = block->reduced_dim();
  if (r < 1) throw Error(where() + "reduced_dim() must be >= 1");
  blocks_.push_back({std::move(block), std::move(loss),
                     std::vector<VariableId>(variables.begin(), variables.end())});
  return ResidualBlockId{static_cast<std::int32_t>(blocks_.size() - 1)};
}

void Problem::set_block_source(std::shared_ptr<BlockSource> source) {
  if (source) {
    for (std::size_t k = 0; k < source->num_blocks(); ++k) {
      const std::span<const VariableId> variables = source->variables(k);
      const auto where = [k] {
        return "Problem::set_block_source (source block " + std::to_string(k) + "): ";
      };
      if (variables.empty()) throw Error(where() + "the block has no variables");
      for (std::size_t i = 0; i < variables.size(); ++i) {
        if (variables[i].index < 0 || variables[i].index >= num_variables()) {
          throw Error(where() + "variable " + std::to_string(variables[i].index) +
                      " is not in the problem (" + std::to_string(num_variables()) + " variables)");
        }
        for (std::size_t j = 0; j < i; ++j) {
          if (variables[j] == variables[i]) {
            throw Error(where() + "variable " + std::to_string(variables[i].index) +
                        " is listed twice");
          }
        }
      }
    }
  }
  source_ = std::move(source);
}

std::size_t Problem::num_all_blocks() const {
  return blocks_.size() + (source_ ? source_->num_blocks() : 0);
}

std::size_t Problem::num_residual_rows() const {
  std::size_t n = 0;
  for (const auto& entry : blocks_) n += static_cast<std::size_t>(entry.block->num_rows());
  return n;
}

const Manifold& Problem::manifold(VariableId id) const {
  check(id);
  return *manifolds_[static_cast<std::size_t>(id.index)];
}

std::span<const double> Problem::value(VariableId id) const {
  check(id);
  const auto i = static_cast<std::size_t>(id.index);
  return {values_.data() + offsets_[i], static_cast<std::size_t>(manifolds_[i]->ambient_size())};
}

std::span<double> Problem::mutable_value(VariableId id) {
  check(id);
  const auto i = static_cast<std::size_t>(id.index);
  return {values_.data() + offsets_[i], static_cast<std::size_t>(manifolds_[i]->ambient_size())};
}

void Problem::set_all_values(std::span<const double> values) {
  if (values.size() != values_.size()) {
    throw Error("Problem::set_all_values: expected " + std::to_string(values_.size()) +
                " values, got " + std::to_string(values.size()));
  }
  for (std::size_t i = 0; i < manifolds_.size(); ++i) {
    if (!manifolds_[i]->is_valid(values.data() + offsets_[i])) {
      throw Error("Problem::set_all_values: value of variable " + std::to_string(i) +
                  " is not a valid " + manifolds_[i]->name() + " value");
    }
  }
  std::copy(values.begin(), values.end(), values_.begin());
}

std::size_t Problem::value_offset(VariableId id) const {
  check(id);
  return offsets_[static_cast<std::size_t>(id.index)];
}

Eigen::Isometry3d Problem::se3(VariableId id) const {
  const auto v = value(id);
  if (v.size() != 7) {
    throw Error("Problem::se3: variable " + std::to_string(id.index) + " is not an SE(3) variable");
  }
  return se3::from_storage(v.data());
}

void Problem::set_se3(VariableId id, const Eigen::Isometry3d& T_world_body) {
  auto v = mutable_value(id);
  if (v.size() != 7) {
    throw Error("Problem::set_se3: variable " + std::to_string(id.index) +
                " is not an SE(3) variable");
  }
  se3::to_storage(T_world_body, v.data());
}

Eigen::Isometry2d Problem::se2(VariableId id) const {
  if (dynamic_cast<const SE2Manifold*>(&manifold(id)) == nullptr) {
    throw Error("Problem::se2: variable " + std::to_string(id.index) + " is not an SE(2) variable");
  }
  return se2::from_storage(value(id).data());
}

void Problem::set_se2(VariableId id, const Eigen::Isometry2d& T_world_body) {
  if (dynamic_cast<const SE2Manifold*>(&manifold(id)) == nullptr) {
    throw Error("Problem::set_se2: variable " + std::to_string(id.index) +
                " is not an SE(2) variable");
  }
  se2::to_storage(T_world_body, mutable_value(id).data());
}

const Problem::BlockEntry& Problem::block(ResidualBlockId id) const {
  if (id.index < 0 || id.index >= num_residual_blocks()) {
    throw Error("Problem: residual block id " + std::to_string(id.index) + " does not exist");
  }
  return blocks_[static_cast<std::size_t>(id.index)];
}

void Problem::replace_residual_block(ResidualBlockId id,
                                     std::shared_ptr<const ResidualBlock> block) {
  const BlockEntry& old = this->block(id);
  if (!block) throw Error("Problem::replace_residual_block: block is null");
  const auto a = old.block->tangent_dims();
  const auto b = block->tangent_dims();
  if (!std::equal(a.begin(), a.end(), b.begin(), b.end())) {
    throw Error("Problem::replace_residual_block: block " + std::to_string(id.index) +
                ": the new block's variables have different tangent sizes");
  }
  if (block->num_rows() < 1) {
    throw Error("Problem::replace_residual_block: the new block has no rows");
  }
  blocks_[static_cast<std::size_t>(id.index)].block = std::move(block);
}

double Problem::evaluate_cost() const {
  double cost = 0.0;
  std::vector<const double*> params;
  for (const auto& entry : blocks_) {
    params.clear();
    for (VariableId v : entry.variables)
      params.push_back(values_.data() + offsets_[static_cast<std::size_t>(v.index)]);
    const double s = entry.block->squared_norm(params);
    cost += 0.5 * (entry.loss ? entry.loss->evaluate(s).rho : s);
  }
  return cost;
}

std::size_t Problem::residual_memory_bytes() const {
  std::size_t bytes = 0;
  for (const auto& entry : blocks_) bytes += entry.block->memory_bytes();
  return bytes;
}

std::size_t Problem::bound_index(VariableId id, int coordinate, const char* who) const {
  check(id);
  const Manifold& m = manifold(id);
  const auto* subset = dynamic_cast<const SubsetManifold*>(&m);
  const Manifold& base = subset ? subset->base() : m;
  const std::string where =
      std::string(who) + ": variable " + std::to_string(id.index) + " (" + m.name() + ")";
  if (!dynamic_cast<const EuclideanManifold*>(&base)) {
    throw Error(where + ": bounds apply to Euclidean coordinates only");
  }
  if (coordinate < 0 || coordinate >= m.ambient_size()) {
    throw Error(where + ": coordinate " + std::to_string(coordinate) + " is out of range (" +
                std::to_string(m.ambient_size()) + " coordinates)");
  }
  return offsets_[static_cast<std::size_t>(id.index)] + static_cast<std::size_t>(coordinate);
}

void Problem::set_lower_bound(VariableId id, int coordinate, double lower) {
  set_bound(id, coordinate, lower, true);
}

void Problem::set_upper_bound(VariableId id, int coordinate, double upper) {
  set_bound(id, coordinate, upper, false);
}

void Problem::set_bound(VariableId id, int coordinate, double bound, bool lower) {
  const char* who = lower ? "Problem::set_lower_bound" : "Problem::set_upper_bound";
  const std::size_t k = bound_index(id, coordinate, who);
  const std::string where = std::string(who) + ": variable " + std::to_string(id.index) +
                            ", coordinate " + std::to_string(coordinate);
  const double inf = std::numeric_limits<double>::infinity();
  if (std::isnan(bound) || bound == (lower ? inf : -inf)) {
    throw Error(where + ": the bound " + message_number(bound) + " is not a number " +
                (lower ? "below +inf" : "above -inf"));
  }
  const double other = lower_.empty() ? (lower ? inf : -inf) : (lower ? upper_[k] : lower_[k]);
  if (lower ? bound > other : bound < other) {
    throw Error(where + ": the " + (lower ? "lower" : "upper") + " bound " + message_number(bound) +
                " is " + (lower ? "above" : "below") + " the " + (lower ? "upper" : "lower") +
                " bound " + message_number(other));
  }
  if (lower ? values_[k] < bound : values_[k] > bound) {
    throw Error(where + ": the value " + message_number(values_[k]) + " is " +
                (lower ? "below" : "above") + " the bound " + message_number(bound));
  }
  if (lower_.empty()) {
    lower_.assign(values_.size(), -inf);
    upper_.assign(values_.size(), inf);
  }
  (lower ? lower_ : upper_)[k] = bound;
}

double Problem::lower_bound(VariableId id, int coordinate) const {
  const std::size_t k = bound_index(id, coordinate, "Problem::lower_bound");
  return lower_.empty() ? -std::numeric_limits<double>::infinity() : lower_[k];
}

double Problem::upper_bound(VariableId id, int coordinate) const {
  const std::size_t k = bound_index(id, coordinate, "Problem::upper_bound");
  return upper_.empty() ? std::numeric_limits<double>::infinity() : upper_[k];
}

}  // namespace carat
