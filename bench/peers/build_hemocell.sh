#!/usr/bin/env bash
# Brings and builds the peer code HemoCell (lattice Boltzmann + immersed boundary; github UvaCsl/HemoCell, tag
# v2.7) on Palabos v2.3.0 (github omalaspinas/palabos, tag v2.3.0), for the side-by-side runs of
# bench/peers/README.md. Nothing of either code is kept in this repository: both are cloned into --dest.
#
#   bash bench/peers/build_hemocell.sh [--hemocell URL|DIR] [--palabos URL|DIR] [--dest DIR] [--jobs N]
#
# --hemocell, --palabos: a git URL or a local clone (default the github URLs above); --dest (the repository's
# out/peers/hemocell; a tree a failed run of this script left is made again, any other non-empty folder refused);
# --jobs (2). HemoCell's own setup.sh downloads Palabos from gitlab.com; this script takes Palabos' src and
# externalLibraries from the git repository instead, applies HemoCell's patch (patch/patchPLB.sh), configures
# with -DBUILD_TESTING=OFF and builds the targets hemocell, stretchCell and oneCellShear. Needs Debian's
# libhdf5-openmpi-dev (installed here when missing, as root).
set -euo pipefail
HEMOCELL=https://github.com/UvaCsl/HemoCell
PALABOS=https://github.com/omalaspinas/palabos
DEST=$(cd "$(dirname "$0")/../.." && pwd)/out/peers/hemocell  # the repository's out/, as the bench script's default
JOBS=2
while [ $# -gt 0 ]; do
  case "$1" in
    --hemocell) HEMOCELL=$2; shift 2 ;;
    --palabos) PALABOS=$2; shift 2 ;;
    --dest) DEST=$2; shift 2 ;;
    --jobs) JOBS=$2; shift 2 ;;
    *) echo "build_hemocell.sh: unknown argument '$1'; valid: --hemocell, --palabos, --dest, --jobs" >&2; exit 1 ;;
  esac
done
case "$JOBS" in
  '' | *[!0-9]* | 0)
    echo "build_hemocell.sh: --jobs '$JOBS' is invalid; valid: a whole number >= 1" >&2
    exit 1 ;;
esac

if ! dpkg -s libhdf5-openmpi-dev >/dev/null 2>&1; then
  if [ "$(id -u)" != 0 ]; then
    echo "build_hemocell.sh: libhdf5-openmpi-dev is missing (install it as root)" >&2
    exit 1
  fi
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libhdf5-openmpi-dev
fi

# The tree is complete once Palabos is in and patched (.cellfsi-patched); a tree a failed run left is made again.
if [ -e "$DEST/.cellfsi-patched" ]; then
  echo "build_hemocell.sh: $DEST holds a patched HemoCell tree already; building it"
else
  if [ -n "$(ls -A "$DEST" 2>/dev/null)" ]; then
    # Only a tree this script began (HemoCell's files in it) is removed; any other folder is refused.
    if [ ! -e "$DEST/hemocell.h" ]; then
      echo "build_hemocell.sh: --dest '$DEST' holds other files; valid: an empty or new folder" >&2
      exit 1
    fi
    rm -rf "$DEST"
  fi
  mkdir -p "$DEST"
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  git clone --quiet --no-checkout "$HEMOCELL" "$tmp/hemocell"
  git -C "$tmp/hemocell" archive v2.7 | tar -x -C "$DEST"
  git clone --quiet --no-checkout "$PALABOS" "$tmp/palabos"
  mkdir -p "$DEST/palabos"
  git -C "$tmp/palabos" archive v2.3.0 src externalLibraries | tar -x -C "$DEST/palabos"
  (cd "$DEST/patch" && ./patchPLB.sh)
  touch "$DEST/.cellfsi-patched"
fi
cmake -S "$DEST" -B "$DEST/build" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release
cmake --build "$DEST/build" -j "$JOBS" --target hemocell stretchCell oneCellShear
for exe in "$DEST"/examples/stretchCell/stretchCell "$DEST"/examples/oneCellShear/oneCellShear; do
  [ -x "$exe" ] || { echo "build_hemocell.sh: $exe was not built" >&2; exit 2; }
  echo "build_hemocell.sh: built $exe"
done
