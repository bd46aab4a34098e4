#!/usr/bin/env bash
# Configures and builds cellfsi (Release) in $BUILD_DIR (default: build/ in the repository root).
#   bash scripts/build.sh [TARGET...] [-- CONFIGURE_ARGS...]
# With targets, builds only those (and what they need), e.g. `bash scripts/build.sh cellfsi`; without, all.
# Arguments after `--` go to the configure step, e.g. `-- -DCELLFSI_BUILD_BENCH=OFF`.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

targets=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do
  targets+=(--target "$1")
  shift
done
[ "${1:-}" = "--" ] && shift

BUILD_DIR="${BUILD_DIR:-build}"
cmake -S . -B "$BUILD_DIR" -G "Unix Makefiles" -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build "$BUILD_DIR" -j"$(nproc)" "${targets[@]}"
