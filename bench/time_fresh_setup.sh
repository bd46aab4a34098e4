#!/usr/bin/env bash
# Times the README's first command on a fresh Debian 12 system: a minimal Debian 12 root made by debootstrap
# (the packages a container or cloud image starts with, from Debian's mirror), this commit's files copied in,
# then, inside it as root, the packages of `scripts/install-deps.sh run` and `scripts/run-default.sh` (build
# cellfsi, run the default scene), each timed. Needs root and Debian's mirror; installs debootstrap if missing.
#   bash bench/time_fresh_setup.sh [DIR]     (DIR: where the root goes, default /var/tmp/cellfsi-fresh; removed
#                                             first if it exists, kept afterwards for a look)
# Prints one line per phase and a markdown row for README.md's set-up figure. Take it on an idle machine: the
# build and the scene use both cores.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

ROOTDIR="${1:-/var/tmp/cellfsi-fresh}"
if [ "$(id -u)" -ne 0 ]; then
  echo "time_fresh_setup: run as root (debootstrap and chroot need it)" >&2
  exit 1
fi
command -v debootstrap >/dev/null || { apt-get update -q >/dev/null && apt-get install -y -q debootstrap >/dev/null; }

mounted=()
cleanup() {
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount -l "${mounted[i]}" 2>/dev/null || true; done
}
trap cleanup EXIT

rm -rf "$ROOTDIR"
t0=$(date +%s)
debootstrap --variant=minbase bookworm "$ROOTDIR" http://deb.debian.org/debian >"$ROOTDIR.debootstrap.log" 2>&1
cat >"$ROOTDIR/etc/apt/sources.list" <<'EOF'
deb http://deb.debian.org/debian bookworm main
deb http://deb.debian.org/debian bookworm-updates main
deb http://deb.debian.org/debian-security bookworm-security main
EOF
cp /etc/resolv.conf "$ROOTDIR/etc/resolv.conf"
mkdir -p "$ROOTDIR/repo"
git archive HEAD | tar -x -C "$ROOTDIR/repo"
for m in proc sys dev dev/pts; do
  mount --bind "/$m" "$ROOTDIR/$m"
  mounted+=("$ROOTDIR/$m")
done
echo "time_fresh_setup: fresh root in $ROOTDIR ($(($(date +%s) - t0)) s)"

phase() {  # phase NAME COMMAND: runs COMMAND in the fresh root, as root, from the clone; prints its seconds
  local name=$1 start end
  shift
  start=$(date +%s.%N)
  chroot "$ROOTDIR" /usr/bin/env -i HOME=/root PATH=/usr/sbin:/usr/bin:/sbin:/bin bash -c "cd /repo && $*" \
    >"$ROOTDIR.$name.log" 2>&1
  end=$(date +%s.%N)
  python3 -c "print(f'{$end - $start:.0f}')"
}
packages=$(phase packages bash scripts/install-deps.sh run)
count=$(grep -o "[0-9]* newly installed" "$ROOTDIR.packages.log" | cut -d' ' -f1)
echo "time_fresh_setup: packages of 'install-deps.sh run': $packages s ($count packages)"
default=$(phase default bash scripts/run-default.sh)
scene=$(grep -o "completed [0-9]* steps in [0-9.]* s" "$ROOTDIR.default.log" | awk '{print $5}')
echo "time_fresh_setup: scripts/run-default.sh: $default s (the scene $scene s of it)"
echo "| $(git rev-parse --short HEAD) | $(nproc) cores | $packages s ($count packages) | $default s (scene $scene s) |" \
  "$((packages + ${default%.*})) s |"
