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

namespace carat::internal {
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
