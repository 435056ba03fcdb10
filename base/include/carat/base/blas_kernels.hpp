#pragma once

/// Which BLAS kernels this process runs (CHOLMOD's supernodal factorization and the sparse inverse
/// spend most of their time in them), and a better choice where OpenBLAS has fallen back to its
/// oldest x86-64 kernels on a CPU it does not recognize.

#include <string>

namespace carat {

/// The BLAS kernels of this process, as the BLAS library reports them.
struct BlasKernels {
  /// "OpenBLAS" when the process has OpenBLAS loaded (it reports its kernels); empty otherwise.
  std::string library;
  /// The kernel set OpenBLAS chose when it loaded (its openblas_get_corename(), e.g. "Haswell",
  /// "SkylakeX", or "Prescott", its fallback for a CPU model it does not know); empty without
  /// OpenBLAS.
  std::string core;
  /// A kernel set for this CPU's vector units when `core` is that fallback on a CPU with AVX2 and
  /// FMA ("Haswell") or AVX-512 ("SkylakeX"): the value for OPENBLAS_CORETYPE, which OpenBLAS reads
  /// when it loads. Empty when OpenBLAS's own choice stands.
  std::string suggested_core;
};

/// The BLAS kernels of this process (see BlasKernels). Cheap; never throws.
BlasKernels blas_kernels();

/// For a program's main(), before it does anything else: when blas_kernels().suggested_core is
/// set and the environment has no OPENBLAS_CORETYPE, sets OPENBLAS_CORETYPE to it and restarts
/// the program (execv of /proc/self/exe with the same arguments), so that OpenBLAS loads those
/// kernels. Returns without doing anything otherwise, or when the restart fails; never prints.
/// An OPENBLAS_CORETYPE set by the user is left as it is.
void use_cpu_blas_kernels(char** argv);

}  // namespace carat
