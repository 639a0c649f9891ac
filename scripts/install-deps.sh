#!/usr/bin/env bash
# Installs what csympnet needs to build and test, from Debian 12 packages, and skips what is
# already present. Safe to run any number of times.
#   --bench   accepted for older instructions: what `make bench` needs (PyTorch for the
#             side-by-side) is now in the main list.
set -euo pipefail

bench=0
for arg in "$@"; do
  case "$arg" in
    --bench) bench=1 ;;
    *) echo "install-deps: unknown option '$arg' (expected --bench)" >&2; exit 2 ;;
  esac
done

packages=(
  build-essential cmake pkg-config
  libeigen3-dev        # linear algebra, expm (unsupported/MatrixFunctions)
  libboost-dev         # Boost.Odeint (header-only)
  nlohmann-json3-dev   # configs, reports, model files
  libcli11-dev         # command line
  libgtest-dev         # tests
  libbenchmark-dev     # micro-benchmarks
  python3-dev          # Python module (python/): headers for Debian's /usr/bin/python3
  python3-numpy        # Python module: arrays
  pybind11-dev         # Python module: bindings
  python3-pytest       # Python module: tests
  python3-matplotlib   # csympnet.plot: the paper's figure types
  python3-pandas       # DataFrames as data (identify, CSympNetID.fit) and their tests
  python3-sklearn      # Python tests: CSympNetID under clone and cross_val_score
  python3-tqdm         # CSympNetID(verbose=True): progress bars
  python3-torch        # csympnet.torch and its tests; bench/torch_peer.py (make bench)
  python3-sphinx       # make docs: the documentation site and API reference
  python3-myst-parser  # ... reading the Markdown guide
  python3-pip          # pip install . (docs/install.md; tested by ctest -L install)
  python3-venv         # ... into a venv (python3 -m venv --system-site-packages)
  python3-setuptools   # ... its build backend, offline (pip install --no-build-isolation)
  python3-wheel        # ... and pip wheel
  openmpi-bin          # reproduce: mpirun across ranks (tested in make test)
  libopenmpi-dev       # train: one training over mpirun's ranks (optional: CSYMPNET_MPI)
  libceres-dev         # second-stage optimisers: Levenberg-Marquardt and L-BFGS
  liblapack-dev        # normal-equations Levenberg-Marquardt: dsyrk, dpotrf
  libopenblas0-pthread # ... through OpenBLAS (Debian alternatives), not the reference BLAS
  clang-14             # make test-asan (the sanitizer build) and fuzz/ (make fuzz)
  libclang-rt-14-dev   # the sanitizer and libFuzzer runtimes for clang
)
: "$bench"  # nothing more to add: python3-torch is in the list above

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root or sudo to install ${missing[*]}" >&2; exit 1; }
  sudo="sudo"
fi
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
