#!/usr/bin/env bash
# Installs what is missing, builds, and runs the default scene: the elliptic capsule in shear flow of paper
# Sec. 3.3 at 160 x 80 cubic elements to t = 0.25 s (about 1.5 minutes on 2 cores), output in
# out/capsule_shear_quick/.
# Exits with the program's status.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

export OPENBLAS_NUM_THREADS=1
BUILD_DIR="${BUILD_DIR:-build}"

bash scripts/install-deps.sh
bash scripts/build.sh
exec "$BUILD_DIR/apps/cellfsi"
