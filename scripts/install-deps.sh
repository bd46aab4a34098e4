#!/usr/bin/env bash
# Installs the Debian 12 packages cellfsi needs, and nothing else.
#   bash scripts/install-deps.sh run    what building and running the executables needs (scripts/run-default.sh)
#   bash scripts/install-deps.sh        that, and what the tests and the bench/ scripts need (scripts/test.sh)
# Does nothing (and needs no network) when every package is already present.
# Run as root (or with sudo available). Safe to run again.
set -euo pipefail

case "${1:-all}" in
  run | all) ;;
  *)
    echo "install-deps: unknown set '$1'; valid: run (build and run) or nothing (build, run, test, bench)" >&2
    exit 1
    ;;
esac

packages=(
  build-essential cmake pkg-config git
  petsc-dev                  # PETSc 3.18 with MUMPS, SuperLU_DIST, hypre
  libopenblas0-pthread       # otherwise PETSc/MUMPS use the slow reference BLAS
  libopenmpi-dev openmpi-bin
  libeigen3-dev              # (and its FFT module: solvers/fourier_bulk.cpp)
  liblapack-dev              # banded LU of the Fourier bulk solver (zgbtrf)
  libfftw3-dev               # FFTs of the divergence-conforming Fourier solver (fluid/div_conforming/dc_fourier.cpp)
  libscotch-dev              # nested-dissection ordering of the region's LU (solvers/nested_dissection.hpp)
  libmumps-dev               # MUMPS in single precision for the 3D region's LU (solvers/single_precision_lu.hpp)
  libcgal-dev
  libvtk9-dev
  libyaml-cpp-dev            # scene files checked before PETSc reads them
  nlohmann-json3-dev         # summary.json
)
if [ "${1:-all}" = all ]; then
  packages+=(
    libgtest-dev
    libbenchmark-dev
    time python3               # bench/ scripts: /usr/bin/time -v for peak memory, python3 to read -log_view
    python3-matplotlib         # bench/ scripts: the figures in docs/figures/
    python3-yaml               # bench/ scripts: a run continued from its options.yaml, against its scene file
    python3-vtk9               # bench/plot_velocity_snapshot.py reads the VTK output
  )
fi

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
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -q
$SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
echo "install-deps: done"
