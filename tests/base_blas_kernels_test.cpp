// BLAS kernels: what the loaded BLAS reports, the suggestion only for OpenBLAS's fallback on a CPU
// with wider vector units, and no restart when the user chose the kernels.
#include <gtest/gtest.h>
#include <strings.h>

#include <cstdlib>
#include <string>

#include "carat/base/blas_kernels.hpp"

namespace carat {
namespace {

TEST(BlasKernelsTest, SuggestsKernelsOnlyForOpenBlasFallbackOnAWiderCpu) {
  // Test programs link CHOLMOD, and with it the BLAS libblas.so.3 points to.
  const BlasKernels kernels = blas_kernels();
  if (kernels.library.empty()) {
    EXPECT_TRUE(kernels.core.empty());
    EXPECT_TRUE(kernels.suggested_core.empty());
    GTEST_SKIP() << "the BLAS of this process is not OpenBLAS";
  }
  EXPECT_EQ(kernels.library, "OpenBLAS");
  EXPECT_FALSE(kernels.core.empty());
  const bool fallback = strcasecmp(kernels.core.c_str(), "prescott") == 0;
#if defined(__x86_64__)
  const bool wider = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
                      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl");
#else
  const bool wider = false;
  const bool avx512 = false;
#endif
  if (fallback && wider) {
    EXPECT_EQ(kernels.suggested_core, avx512 ? "SkylakeX" : "Haswell");
  } else {
    EXPECT_EQ(kernels.suggested_core, "") << "core " << kernels.core;
  }
}

TEST(BlasKernelsTest, KernelsTheUserChoseAreLeftAlone) {
  // With OPENBLAS_CORETYPE set there is no restart: the call returns and the variable keeps its
  // value (a restart would run this program again from its start).
  const char* before = std::getenv("OPENBLAS_CORETYPE");
  const std::string saved = before != nullptr ? before : "";
  ASSERT_EQ(setenv("OPENBLAS_CORETYPE", "Prescott", 1), 0);
  char name[] = "base_blas_kernels_test";
  char* argv[] = {name, nullptr};
  use_cpu_blas_kernels(argv);
  EXPECT_STREQ(std::getenv("OPENBLAS_CORETYPE"), "Prescott");
  use_cpu_blas_kernels(nullptr);  // no arguments: nothing to restart with
  if (before != nullptr) {
    setenv("OPENBLAS_CORETYPE", saved.c_str(), 1);
  } else {
    unsetenv("OPENBLAS_CORETYPE");
  }
}

}  // namespace
}  // namespace carat
