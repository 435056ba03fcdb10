#include "carat/base/blas_kernels.hpp"

#include <dlfcn.h>
#include <strings.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>

namespace carat {
namespace {

/// The kernel set for this CPU's vector units, or nullptr when there is no better one than
/// OpenBLAS's baseline.
const char* core_for_this_cpu() {
#if defined(__x86_64__) && defined(__GNUC__)
  // GCC's and Clang's CPU checks also ask the operating system whether it saves the registers.
  if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl")) {
    return "SkylakeX";
  }
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "Haswell";
#endif
  return nullptr;
}

}  // namespace

BlasKernels blas_kernels() {
  BlasKernels out;
  // OpenBLAS's public query, looked up among the libraries already loaded (CHOLMOD's BLAS is
  // whatever libblas.so.3 points to).
  using CoreName = char* (*)();
  void* symbol = dlsym(RTLD_DEFAULT, "openblas_get_corename");
  if (symbol == nullptr) return out;
  out.library = "OpenBLAS";
  CoreName core_name = nullptr;
  static_assert(sizeof(symbol) == sizeof(core_name));
  std::memcpy(&core_name, &symbol, sizeof(symbol));
  const char* core = core_name();
  out.core = core != nullptr ? core : "";
  // OpenBLAS names its fallback "Prescott" (any letter case, by version).
  if (strcasecmp(out.core.c_str(), "prescott") == 0) {
    if (const char* better = core_for_this_cpu()) out.suggested_core = better;
  }
  return out;
}

void use_cpu_blas_kernels(char** argv) {
  if (argv == nullptr || argv[0] == nullptr || std::getenv("OPENBLAS_CORETYPE") != nullptr) return;
  const BlasKernels kernels = blas_kernels();
  if (kernels.suggested_core.empty()) return;
  if (setenv("OPENBLAS_CORETYPE", kernels.suggested_core.c_str(), 1) != 0) return;
  execv("/proc/self/exe", argv);
  // Only reached when the restart failed: carry on with the kernels already loaded.
  unsetenv("OPENBLAS_CORETYPE");
}

}  // namespace carat
