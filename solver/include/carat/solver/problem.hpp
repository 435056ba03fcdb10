#pragma once

/// A nonlinear least-squares problem: variables on manifolds and residual blocks over them.
/// The problem owns the variable values; solve() updates them in place.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "carat/solver/block_source.hpp"
#include "carat/solver/loss_function.hpp"
#include "carat/solver/manifold.hpp"
#include "carat/solver/residual_block.hpp"
#include "carat/solver/variable_id.hpp"

namespace carat {

/// Variables (with manifolds and values), residual blocks, losses and constant flags.
class Problem {
 public:
  /// One residual block and what it is attached to.
  struct BlockEntry {
    std::shared_ptr<const ResidualBlock> block;  ///< the residual block
    std::shared_ptr<const LossFunction> loss;    ///< robust loss, null for plain least squares
    std::vector<VariableId> variables;           ///< variables in the block's parameter order
  };

  /// Adds a variable on `manifold` with initial value `initial` (ambient_size() doubles).
  /// Throws carat::Error if the size is wrong or the value invalid.
  VariableId add_variable(std::shared_ptr<const Manifold> manifold,
                          std::span<const double> initial);

  /// Adds an SE(3) variable T_world_body (see se3.hpp for the storage). Throws carat::Error
  /// naming the variable when T_world_body is not rigid (se3::rigid_transform_problem()).
  VariableId add_se3(const Eigen::Isometry3d& T_world_body);

  /// Adds an SE(2) variable T_world_body (see se2.hpp for the storage [x, y, theta]). Throws
  /// carat::Error naming the variable when T_world_body is not rigid.
  VariableId add_se2(const Eigen::Isometry2d& T_world_body);

  /// Adds a Euclidean variable.
  VariableId add_euclidean(const Eigen::VectorXd& initial);

  /// Holds a variable fixed (true) or frees it again (false).
  void set_constant(VariableId id, bool constant = true);

  /// Whether the variable is held fixed.
  bool is_constant(VariableId id) const;

  /// Marks a variable for elimination by the Schur complement (true) or not (false), like
  /// the first group of Ceres's ParameterBlockOrdering: landmarks in bundle adjustment. No
  /// residual block may connect two eliminable variables (solve() checks it).
  void set_eliminable(VariableId id, bool eliminable = true);

  /// Whether the variable is marked for elimination.
  bool is_eliminable(VariableId id) const;

  /// Whether any variable is marked for elimination.
  bool has_eliminable() const;

  /// Keeps ambient coordinate `coordinate` of a Euclidean variable (or of a SubsetManifold over
  /// one) at or above `lower` during solve(), which projects every trial point onto the bounds
  /// (as Ceres's bounds constraints do); -infinity removes the bound. Throws carat::Error naming
  /// the variable and coordinate for another manifold, a coordinate out of range, a NaN bound, a
  /// bound above the upper bound, or a current value below it.
  void set_lower_bound(VariableId id, int coordinate, double lower);
  /// The upper bound, as set_lower_bound() (+infinity removes it).
  void set_upper_bound(VariableId id, int coordinate, double upper);
  /// The lower bound of a coordinate (-infinity when none).
  double lower_bound(VariableId id, int coordinate) const;
  /// The upper bound of a coordinate (+infinity when none).
  double upper_bound(VariableId id, int coordinate) const;
  /// Whether any bound is set.
  bool has_bounds() const { return !lower_.empty(); }
  /// Lower bounds of all stored values (the layout of all_values(); empty when no bound is set).
  std::span<const double> all_lower_bounds() const { return lower_; }
  /// Upper bounds of all stored values (the layout of all_values(); empty when no bound is set).
  std::span<const double> all_upper_bounds() const { return upper_; }

  /// Adds a residual block over `variables` (distinct, tangent sizes matching the block's
  /// tangent_dims()); `loss` may be null. Throws carat::Error on any mismatch.
  ResidualBlockId add_residual_block(std::shared_ptr<const ResidualBlock> block,
                                     std::span<const VariableId> variables,
                                     std::shared_ptr<const LossFunction> loss = nullptr);

  /// Same as above with a braced list of variables.
  ResidualBlockId add_residual_block(std::shared_ptr<const ResidualBlock> block,
                                     std::initializer_list<VariableId> variables,
                                     std::shared_ptr<const LossFunction> loss = nullptr);

  /// Number of variables.
  int num_variables() const { return static_cast<int>(manifolds_.size()); }
  /// Number of residual blocks (the problem's own; a block source's come after them).
  int num_residual_blocks() const { return static_cast<int>(blocks_.size()); }

  /// Sets the blocks held outside the problem (block_source.hpp), which solve() adds after the
  /// problem's own blocks; null removes them. Throws carat::Error naming the block when a
  /// block's variables are empty, unknown or listed twice.
  void set_block_source(std::shared_ptr<BlockSource> source);
  /// The block source, or null.
  const std::shared_ptr<BlockSource>& block_source() const { return source_; }
  /// Own blocks plus the block source's.
  std::size_t num_all_blocks() const;
  /// Total number of scalar residual rows over all blocks.
  std::size_t num_residual_rows() const;

  /// The manifold of a variable.
  const Manifold& manifold(VariableId id) const;
  /// Read-only view of a variable's stored value.
  std::span<const double> value(VariableId id) const;
  /// Mutable view of a variable's stored value (keep it valid for its manifold).
  std::span<double> mutable_value(VariableId id);
  /// The stored value of an SE(3) variable as a transform. Throws if it is not SE(3)-sized.
  Eigen::Isometry3d se3(VariableId id) const;
  /// Sets an SE(3) variable.
  void set_se3(VariableId id, const Eigen::Isometry3d& T_world_body);

  /// The stored value of an SE(2) variable as a planar transform. Throws if it is not SE(2).
  Eigen::Isometry2d se2(VariableId id) const;
  /// Sets an SE(2) variable. Throws if it is not SE(2).
  void set_se2(VariableId id, const Eigen::Isometry2d& T_world_body);

  /// A residual block and its attachments.
  const BlockEntry& block(ResidualBlockId id) const;
  /// All residual blocks in insertion order.
  std::span<const BlockEntry> blocks() const { return blocks_; }

  /// Replaces the residual block of `id` by one with the same variables and tangent sizes
  /// (e.g. its compressed form). Throws carat::Error on a mismatch.
  void replace_residual_block(ResidualBlockId id, std::shared_ptr<const ResidualBlock> block);

  /// Total cost 1/2 sum_blocks rho(|r|^2) at the current values (serial; for checks).
  double evaluate_cost() const;

  /// Sum of memory_bytes() over all residual blocks.
  std::size_t residual_memory_bytes() const;

  /// All stored values, concatenated in variable order (ambient storage).
  std::span<const double> all_values() const { return values_; }
  /// Overwrites all stored values at once (same layout as all_values()); throws carat::Error
  /// if the size differs or a value is invalid for its manifold (nothing is changed then).
  void set_all_values(std::span<const double> values);
  /// Offset of a variable's storage inside all_values().
  std::size_t value_offset(VariableId id) const;

 private:
  /// Throws carat::Error when `id` names no variable of this problem.
  void check(VariableId id) const {
    if (id.index < 0 || id.index >= num_variables()) throw_no_variable(id);
  }
  [[noreturn]] void throw_no_variable(VariableId id) const;
  /// Index into values_ of a bounded coordinate; throws for a variable bounds cannot apply to.
  std::size_t bound_index(VariableId id, int coordinate, const char* who) const;
  /// set_lower_bound() (lower) or set_upper_bound().
  void set_bound(VariableId id, int coordinate, double bound, bool lower);

  std::vector<std::shared_ptr<const Manifold>> manifolds_;
  std::vector<std::size_t> offsets_;
  std::vector<char> constant_;
  std::vector<char> eliminable_;
  std::vector<double> values_;
  std::vector<double> lower_, upper_;  // per stored value; empty until a bound is set
  std::vector<BlockEntry> blocks_;
  std::shared_ptr<BlockSource> source_;
};

}  // namespace carat
