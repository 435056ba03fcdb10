#pragma once

// main() for carat's Google Benchmark programs: BENCHMARK_MAIN() after carat's choice of BLAS
// kernels (carat::use_cpu_blas_kernels, as the command-line tool makes it), so that the timings
// are those of `carat`.

#include <benchmark/benchmark.h>

#include "carat/base/blas_kernels.hpp"

/// Defines main(): OpenBLAS's kernels for this CPU, then Google Benchmark's own main.
#define CARAT_BENCHMARK_MAIN()                                        \
  int main(int argc, char** argv) {                                   \
    carat::use_cpu_blas_kernels(argv);                                \
    benchmark::Initialize(&argc, argv);                               \
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1; \
    benchmark::RunSpecifiedBenchmarks();                              \
    benchmark::Shutdown();                                            \
    return 0;                                                         \
  }
