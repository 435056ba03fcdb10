#pragma once

// Internal: runtime dispatch of hot loops to builds of the same code for wider vector units
// (x86-64 only). Clones are chosen by CPU features (x86-64-v3: AVX2, FMA, BMI2; x86-64-v4:
// AVX-512), not by CPU model, so AMD and Intel machines alike get them; the default clone is what
// the baseline compiler flags produce. Each machine always runs the same clone, so results are
// reproducible on it.

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_ADDRESS__)
#define CARAT_MULTIVERSION __attribute__((target_clones("arch=x86-64-v3", "default")))
/// For loops written with 8-wide vectors: one AVX-512 register each on x86-64-v4.
#define CARAT_MULTIVERSION_WIDE \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
/// An AVX-512 build of a function (call it only when cpu_has_avx512()).
#define CARAT_TARGET_AVX512 __attribute__((target("arch=x86-64-v4")))
#define CARAT_HAVE_AVX512_PATH 1
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
#else
#define CARAT_MULTIVERSION
#define CARAT_MULTIVERSION_WIDE
#define CARAT_HAVE_AVX512_PATH 0
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
