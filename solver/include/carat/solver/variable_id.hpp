#pragma once

#include <compare>
#include <cstdint>

namespace carat {

/// Handle of a variable in a Problem (its insertion index).
struct VariableId {
  std::int32_t index = -1;  ///< position in the problem; -1 means invalid
  /// True for a handle a Problem handed out.
  constexpr bool valid() const { return index >= 0; }
  /// Ordered and comparable by index.
  friend constexpr auto operator<=>(VariableId, VariableId) = default;
};

/// Handle of a residual block in a Problem (its insertion index).
struct ResidualBlockId {
  std::int32_t index = -1;  ///< position in the problem; -1 means invalid
  /// True for a handle a Problem handed out.
  constexpr bool valid() const { return index >= 0; }
  /// Ordered and comparable by index.
  friend constexpr auto operator<=>(ResidualBlockId, ResidualBlockId) = default;
};

}  // namespace carat
