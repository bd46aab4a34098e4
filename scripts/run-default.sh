#!/usr/bin/env bash
# Installs what is missing, builds the cellfsi executable (and nothing else: no tests, no benchmarks), and
# runs the default scene: the elliptic capsule in shear flow of paper Sec. 3.3 at 128 x 64 elements of the
# divergence-conforming space to t = 0.25 s, output in out/capsule_shear_quick/.
# Exits with the program's status.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

export OPENBLAS_NUM_THREADS=1
BUILD_DIR="${BUILD_DIR:-build}"

bash scripts/install-deps.sh run
# Tests and benchmarks off here (their packages need not be present); scripts/test.sh turns them on again.
bash scripts/build.sh cellfsi -- -DCELLFSI_BUILD_TESTS=OFF -DCELLFSI_BUILD_BENCH=OFF
exec "$BUILD_DIR/apps/cellfsi"
