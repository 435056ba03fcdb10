#pragma once

/// The number of members of an aggregate struct, at compile time: code that must handle every
/// field of a struct (serializing it, merging two of it) asserts the count it was written for, so
/// that a field added later fails the build there instead of being silently dropped.

#include <cstddef>

namespace carat {
namespace internal {

/// Converts to any type; only named in unevaluated contexts.
struct AnyField {
  template <class T>
  operator T() const;  // NOLINT(google-explicit-constructor): converts implicitly by design
};

/// Counts by trying `T{AnyField, ...}` with one more initializer until it no longer compiles.
template <class T, class... Fields>
constexpr std::size_t count_fields() {
  if constexpr (requires { T{Fields{}..., AnyField{}}; }) {
    return count_fields<T, Fields..., AnyField>();
  } else {
    return sizeof...(Fields);
  }
}

}  // namespace internal

/// Members of the aggregate `T` (no base classes, no array members: each member is one field).
template <class T>
constexpr std::size_t field_count() {
  return internal::count_fields<T>();
}

}  // namespace carat
