#!/usr/bin/env bash
# Cost of inserting element matrices into the fluid Jacobian (one rank), per element: the SeqBAIJ inserter
# against PETSc's public insertion and COO assembly (issue 11), next to the whole Jacobian assembly of the same
# mesh; writes docs/performance/fluid_insertion.md and prints it. Run from anywhere after scripts/build.sh.
#   bash bench/run_fluid_insertion.sh            # REPEAT=5 by default
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD_DIR="${BUILD_DIR:-build}"
REPEAT="${REPEAT:-5}"
export OPENBLAS_NUM_THREADS=1
ins="$BUILD_DIR/bench/fluid_insertion"; asm="$BUILD_DIR/bench/fluid_assembly"
for exe in "$ins" "$asm"; do [ -x "$exe" ] || { echo "run scripts/build.sh first ($exe missing)" >&2; exit 1; }; done
mkdir -p docs/performance
out=docs/performance/fluid_insertion.md
{
  echo "<!-- written by bench/run_fluid_insertion.sh; $(date -u +%Y-%m-%dT%H:%MZ), $(git rev-parse --short HEAD 2>/dev/null || echo unknown), $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs) -->"
  echo "Insertion, us per element (best of $REPEAT; the pattern is set once and not timed; last column: MatSetPreallocationCOO on AIJ, ms, once):"
  echo
  echo "| dim | p | mesh | direct (SeqBAIJ inserter) | MatSetValuesBlockedLocal (BAIJ) | COO (AIJ) | COO (BAIJ, PETSc's fallback) | COO pattern ms |"
  echo "|---|---|---|---|---|---|---|---|"
  "$ins" -dim 2 -p 2 -n 128 -repeat "$REPEAT"
  "$ins" -dim 2 -p 3 -n 128 -repeat "$REPEAT"
  "$ins" -dim 3 -p 2 -n 16 -repeat "$REPEAT"
  echo
  echo "The whole Jacobian assembly of the same meshes (element kernels and direct insertion), us per element:"
  echo
  "$asm" -n2d 128 -three_d false -repeat "$REPEAT"
  "$asm" -n2d 8 -n3d 16 -repeat "$REPEAT" | grep '^| 3 | 2 '
} > "$out"
cat "$out"
