#!/usr/bin/env bash
# Installs what is missing, builds, and runs the default scene. For now that is the geometry demo, which
# writes the paper's cell and channel patches to VTK in out/geometry/. Exits with the program's status.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

export OPENBLAS_NUM_THREADS=1
BUILD_DIR="${BUILD_DIR:-build}"

bash scripts/install-deps.sh
bash scripts/build.sh
exec "$BUILD_DIR/apps/cellfsi-geometry" -output_dir out/geometry
