#!/usr/bin/env bash
# Configures and builds cellfsi (Release) in $BUILD_DIR (default: build/ in the repository root).
# Extra arguments are passed to the configure step, e.g. -DCELLFSI_BUILD_BENCH=OFF.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

BUILD_DIR="${BUILD_DIR:-build}"
cmake -S . -B "$BUILD_DIR" -G "Unix Makefiles" -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build "$BUILD_DIR" -j"$(nproc)"
