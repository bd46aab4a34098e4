#!/usr/bin/env bash
# Installs what is missing, builds, and runs the whole test suite. Exits with ctest's status.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

export OPENBLAS_NUM_THREADS=1
BUILD_DIR="${BUILD_DIR:-build}"

bash scripts/install-deps.sh
bash scripts/build.sh
status=0
ctest --test-dir "$BUILD_DIR" --output-on-failure -j2 || status=$?
exit "$status"
