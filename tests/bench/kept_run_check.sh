#!/bin/sh
# bench/bench_common.py's check_kept_runs through bench/run_rbc_shear_3d.py, on two stand-in runs whose
# summary.json say "completed" (so no cellfsi run is made): one left in box12/ by a 24 um box's run (its command
# line has -domain_size, which the case box12 does not pass) is refused with exit code 1 and a message naming the
# folder and the option, and no table is written; one made with an output option more (-output_every 50) is kept
# and reported.
# Usage: kept_run_check.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -e
src=$1
build=$2
work=$3
rm -rf "$work"
mkdir -p "$work/a/box12" "$work/b/box12"
cd "$work"
line="cellfsi rbc_shear_3d.yaml -output_dir box12 -shear_rate 700 -dt 1e-4 -fluid_space div_conforming"
line="$line -fluid_dc_degree 2 -final_time 0.045"
printf '{"status": "completed", "command_line": "%s -domain_size 0.0024,0.0012,0.0012"}\n' "$line" \
  > a/box12/summary.json
printf '{"status": "completed", "command_line": "%s -output_every 50"}\n' "$line" > b/box12/summary.json
if /usr/bin/python3 "$src/bench/run_rbc_shear_3d.py" --cases box12 --runs a --build "$build" --table a/t.md \
  --figure a/f.png 2> a/refused.txt; then
  echo "the run left by another box was kept"; exit 1
fi
grep -q -- "a/box12: -domain_size 0.0024,0.0012,0.0012 (the run's; not asked now)" a/refused.txt
test ! -e a/t.md
/usr/bin/python3 "$src/bench/run_rbc_shear_3d.py" --cases box12 --runs b --build "$build" --table b/t.md \
  --figure b/f.png > b/out.txt 2>&1
grep -q '^| 12 x 12 x 12 um, 16 x 16 x 16 | completed' b/t.md
