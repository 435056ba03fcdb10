#pragma once

// Internal: the coreset's vector types and the AVX-512 check; the multiversioning macros are in
// carat/base/multiversion.hpp.

#include "carat/base/multiversion.hpp"

#if CARAT_HAVE_AVX512_PATH
#include <cstdlib>
namespace carat::internal {
/// Whether this CPU runs x86-64-v4 code (AVX-512 F, BW, CD, DQ, VL) and the environment does
/// not set CARAT_DISABLE_AVX512 (which runs the narrower kernels, e.g. to test them here).
inline bool cpu_has_avx512() {
  static const bool has =
      __builtin_cpu_supports("x86-64-v4") > 0 && std::getenv("CARAT_DISABLE_AVX512") == nullptr;
  return has;
}
}  // namespace carat::internal
#endif

#include <cstddef>
#include <new>
#include <vector>

namespace carat::internal {
/// Allocator of 64-byte aligned storage: a vector of eight doubles from the start of such a
/// buffer then never straddles two cache lines (plain heap blocks are 16-byte aligned).
template <class T>
struct CacheAligned {
  using value_type = T;
  static constexpr std::align_val_t kAlignment{64};
  CacheAligned() = default;
  template <class U>
  CacheAligned(const CacheAligned<U>&) {}
  /// Storage for n values.
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlignment)); }
  /// Frees storage from allocate.
  void deallocate(T* p, std::size_t) { ::operator delete(p, kAlignment); }
  template <class U>
  bool operator==(const CacheAligned<U>&) const {
    return true;
  }
};

/// A vector of doubles whose data start on a cache line.
using AlignedDoubles = std::vector<double, CacheAligned<double>>;

/// Whether the eight-wide lift kernels (and rows kept packed) pay off: with AVX-512, whose 32
/// registers hold their accumulators; under AddressSanitizer too, to check them; elsewhere the
/// accumulators would spill and the four-wide kernels over lifted rows are faster.
inline bool wide_kernels() {
#if CARAT_HAVE_AVX512_PATH
  return cpu_has_avx512();
#elif defined(__SANITIZE_ADDRESS__)
  return true;
#else
  return false;
#endif
}

/// Four doubles in one vector (GCC vector extension; lowered to what the target has).
typedef double v4d __attribute__((vector_size(32)));
/// Eight doubles in one vector.
typedef double v8d __attribute__((vector_size(64)));
/// Eight 64-bit integers in one vector (lane masks of v8d comparisons, shuffle indices).
typedef long v8l __attribute__((vector_size(64)));
}  // namespace carat::internal
