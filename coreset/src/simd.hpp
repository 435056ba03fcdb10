#pragma once

// Internal: runtime dispatch of hot loops to an AVX2/FMA build of the same code (x86-64 only;
// the default clone is what the baseline compiler flags produce, so results are identical in
// meaning on every machine, and each machine always runs the same clone).

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__SANITIZE_ADDRESS__)
#define CARAT_MULTIVERSION __attribute__((target_clones("arch=haswell", "default")))
#else
#define CARAT_MULTIVERSION
#endif
