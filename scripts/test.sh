#!/usr/bin/env bash
# Installs what is missing, builds everything, and runs the whole test suite. Exits with ctest's status.
# Extra arguments go to ctest, e.g. `bash scripts/test.sh -L quick` (the edit-build-test set, tests/README.md).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

export OPENBLAS_NUM_THREADS=1
BUILD_DIR="${BUILD_DIR:-build}"

bash scripts/install-deps.sh
bash scripts/build.sh -- -DCELLFSI_BUILD_TESTS=ON -DCELLFSI_BUILD_BENCH=ON
status=0
# One more test than cores: many tests wait on MPI's start-up or a subprocess part of the time (measured on 2
# cores: 299 s with -j2, 272 s with -j3; tests/README.md, "Time").
ctest --test-dir "$BUILD_DIR" --output-on-failure -j"$(( $(nproc) + 1 ))" "$@" || status=$?
exit "$status"
