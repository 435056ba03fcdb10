#!/usr/bin/env bash
# Installs carat's build and test dependencies from Debian 12 packages.
# Idempotent and non-interactive; needs root (or sudo) and apt.
set -euo pipefail

packages=(
  build-essential cmake git pkg-config
  libeigen3-dev libsuitesparse-dev libtbb-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev nlohmann-json3-dev libnanoflann-dev
  # The Python module (pybind11) and its tests and examples: Debian's interpreter, numpy, pytest,
  # matplotlib, scipy (the examples against scipy.optimize.least_squares).
  python3-dev pybind11-dev python3-numpy python3-pytest python3-matplotlib python3-scipy
  # BLAS/LAPACK for CHOLMOD's supernodal factorization: OpenBLAS, single-threaded
  # (measured faster than ATLAS and reference BLAS on carat's pose-graph benchmark; see README).
  libopenblas0-serial
  # OpenMPI, for `mpirun -np N carat map` and its test (CARAT_MPI=AUTO builds it when found):
  # about 90 MB installed with what it pulls in (gfortran among it).
  libopenmpi-dev openmpi-bin
)
if [[ "${CARAT_WITH_CERES:-0}" == "1" ]]; then
  packages+=(libceres-dev)
fi
# Clang and its sanitizer runtimes, for the sanitizer and fuzzer builds (scripts/test-sanitize.sh,
# scripts/fuzz.sh).
if [[ "${CARAT_WITH_CLANG:-0}" == "1" ]]; then
  packages+=(clang libclang-rt-14-dev)
fi

SUDO=""
if [[ "$(id -u)" != "0" ]]; then SUDO="sudo"; fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# Which BLAS CHOLMOD gets is a system-wide choice (Debian's alternatives): left as it is unless
# CARAT_SET_BLAS=1 asks for OpenBLAS serial, the setup carat's figures were measured with (a
# fresh install picks it anyway: it has the highest priority of what is installed here).
arch_dir="/usr/lib/$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || echo x86_64-linux-gnu)"
for lib in libblas.so.3 liblapack.so.3; do
  target="${arch_dir}/openblas-serial/${lib}"
  name="${lib}-$(basename "${arch_dir}")"
  if [[ -e "$target" ]] && update-alternatives --query "$name" >/dev/null 2>&1; then
    current=$(update-alternatives --query "$name" | awk '/^Value:/ {print $2}')
    if [[ "$current" != "$target" ]]; then
      if [[ "${CARAT_SET_BLAS:-0}" == "1" ]]; then
        $SUDO update-alternatives --quiet --set "$name" "$target"
      else
        echo "note: ${lib} is ${current}; CARAT_SET_BLAS=1 $0 selects OpenBLAS serial" >&2
      fi
    fi
  fi
done
