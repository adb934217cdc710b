#!/usr/bin/env bash
# Install the Debian packages crease needs, when they are missing.
# As root: apt-get update once, then apt-get install -y. Otherwise: print the
# exact command to run and stop with exit 1.
set -euo pipefail

packages=(
  build-essential   # gcc, make, libgomp (OpenMP)
  cmake
  pkg-config
  libpng-dev        # PNG pictures
  zlib1g-dev        # PNG and .npz
  libcjson-dev      # JSON configs and manifests
  libopenblas-openmp-dev  # GEMM for the neural engine, on the OpenMP thread pool
  libsuitesparse-dev      # CHOLMOD: sparse Cholesky for the simulator's Newton solves
  clang             # the clang build of `make check` and the fuzz targets (libFuzzer)
  libclang-rt-dev   # libFuzzer and sanitizer runtimes for clang
  libomp-dev        # OpenMP runtime for the clang build
  libjs-three       # three.js r111 and OrbitControls, copied beside the page `crease view` writes
  libopenmpi-dev    # MPI ranks for `crease dataset` and `crease fit` (docs/mpi.md)
  openmpi-bin       # mpirun, for the 2-rank tests
  chromium          # headless browser for the `crease view` test (tests/view.sh)
  python3-numpy     # python/crease.py (ctypes + numpy) and its test (tests/python_runtime.sh)
)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done
[[ ${#missing[@]} -eq 0 ]] && exit 0

if [[ $(id -u) -ne 0 ]]; then
  echo "crease needs these Debian packages: ${missing[*]}" >&2
  echo "run: sudo apt-get update && sudo apt-get install -y ${missing[*]}" >&2
  exit 1
fi
echo "deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq
apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
