#!/usr/bin/env bash
# Fluid assembly cost per element (residual, Jacobian) for p = 2, 3 in 2D (128 x 64) and 3D (16^3), on 1 and 2
# ranks, and the immersed tangent per solid point (one rank); writes docs/performance/fluid_assembly.md and
# prints it. Run from anywhere after scripts/build.sh.
#   bash bench/run_fluid_assembly.sh            # N2D=128 N3D=16 REPEAT=5 by default
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD_DIR="${BUILD_DIR:-build}"
N2D="${N2D:-128}"; N3D="${N3D:-16}"; REPEAT="${REPEAT:-5}"
export OPENBLAS_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
exe="$BUILD_DIR/bench/fluid_assembly"
[ -x "$exe" ] || { echo "run scripts/build.sh first ($exe missing)" >&2; exit 1; }
mkdir -p docs/performance
out=docs/performance/fluid_assembly.md
{
  echo "<!-- written by bench/run_fluid_assembly.sh; $(date -u +%Y-%m-%dT%H:%MZ), $(git rev-parse --short HEAD 2>/dev/null || echo unknown), $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs) -->"
  one=$("$exe" -n2d "$N2D" -n3d "$N3D" -repeat "$REPEAT")
  # The assembly table (up to the first blank line), its two-rank rows, then the immersed points' table.
  printf '%s\n' "$one" | sed '/^$/,$d'
  mpirun --oversubscribe -np 2 "$exe" -n2d "$N2D" -n3d "$N3D" -repeat "$REPEAT" -immersed false | tail -n +3
  printf '%s\n' "$one" | sed -n '/^$/,$p'
} > "$out"
cat "$out"
