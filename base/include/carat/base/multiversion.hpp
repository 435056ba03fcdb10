#pragma once

/// Runtime dispatch of hot loops to builds of the same code for wider vector units (GCC on
/// x86-64; elsewhere, and under AddressSanitizer, the macros are empty). Clones are chosen by CPU
/// features (x86-64-v3: AVX2, FMA, BMI2; x86-64-v4: AVX-512), not by CPU model; the default clone
/// is what the baseline compiler flags produce. Each machine always runs the same clone, so
/// results are reproducible on it. A lambda or a callee inside a cloned function gets the clone's
/// target only when it is inlined: mark such helpers always_inline.

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_ADDRESS__)
/// Builds a function for x86-64-v3 (AVX2, FMA) and the baseline; picks one at load time.
#define CARAT_MULTIVERSION __attribute__((target_clones("arch=x86-64-v3", "default")))
/// For loops written with 8-wide vectors: one AVX-512 register each on x86-64-v4.
#define CARAT_MULTIVERSION_WIDE \
  __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
/// An AVX-512 build of a function (call it only when the CPU runs x86-64-v4 code).
#define CARAT_TARGET_AVX512 __attribute__((target("arch=x86-64-v4")))
/// Whether CARAT_TARGET_AVX512 builds exist in this build.
#define CARAT_HAVE_AVX512_PATH 1
#else
#define CARAT_MULTIVERSION
#define CARAT_MULTIVERSION_WIDE
#define CARAT_HAVE_AVX512_PATH 0
#endif
