#pragma once

// Internal: runtime dispatch of hot loops to an AVX2/FMA build of the same code (x86-64 only).
// The clone is chosen by CPU features (x86-64-v3: AVX2, FMA, BMI2), not by CPU model, so AMD and
// Intel machines alike get it; the default clone is what the baseline compiler flags produce.
// Each machine always runs the same clone, so results are reproducible on it.

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_ADDRESS__)
#define CARAT_MULTIVERSION __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define CARAT_MULTIVERSION
#endif
