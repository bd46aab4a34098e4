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
ctest --test-dir "$BUILD_DIR" --output-on-failure -j"$(nproc)" "$@" || status=$?
exit "$status"
