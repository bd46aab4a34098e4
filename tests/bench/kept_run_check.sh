#!/bin/sh
# bench/bench_common.py's check_kept_runs through bench/run_rbc_shear_3d.py, on two stand-in runs whose
# summary.json say "completed" (so no cellfsi run is made): one left in box12/ by a 24 um box's run (its command
# line has -domain_size, which the case box12 does not pass) is refused with exit code 1 and a message naming the
# folder and the option, and no table is written; one made with an output option more (-output_every 50) is kept
# and reported. A run continued from its own options.yaml (`cellfsi DIR/options.yaml -restart ...`, whose command
# line has only that launch's options) is judged by its options.yaml against the scene file: kept when it holds the
# scene's values and the asked ones; refused, naming them, when it has another angle than the scene's and a law
# that was not asked.
# Usage: kept_run_check.sh SOURCE_DIR BUILD_DIR WORK_DIR
set -e
src=$1
build=$2
work=$3
rm -rf "$work"
mkdir -p "$work/a/box12" "$work/b/box12" "$work/c/box12" "$work/d/box12"
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
# Continued from its options.yaml: the scene's options (a few, as cellfsi flattens them), the driver's, the
# output's and the scene's name.
for r in c d; do
  printf '{"status": "completed", "command_line": "cellfsi %s/box12/options.yaml -restart -final_time 0.045 %s"}\n' \
    "$r" "-checkpoint_every 40" > $r/box12/summary.json
  { echo "# the options this run was given"; echo "dim: 3"; echo "domain_size: 0.0012,0.0012,0.0012"
    echo "shear_rate: 700"; echo "dt: 1e-4"; echo "fluid_density: 1.025"; echo "solid_rbc_shape: rbc_3d"
    echo "output_dir: $r/box12"; echo "fluid_space: div_conforming"; echo "fluid_dc_degree: 2"
    echo "final_time: 0.045"; echo "scene: rbc_shear_3d"; echo "checkpoint_every: 40"; } > $r/box12/options.yaml
done
echo "solid_rbc_angle: 45" >> d/box12/options.yaml
echo "solid_rbc_material: skalak" >> d/box12/options.yaml
/usr/bin/python3 "$src/bench/run_rbc_shear_3d.py" --cases box12 --runs c --build "$build" --table c/t.md \
  --figure c/f.png > c/out.txt 2>&1
grep -q '^| 12 x 12 x 12 um, 16 x 16 x 16 | completed' c/t.md
if /usr/bin/python3 "$src/bench/run_rbc_shear_3d.py" --cases box12 --runs d --build "$build" --table d/t.md \
  --figure d/f.png 2> d/refused.txt; then
  echo "the run continued with another angle and law was kept"; exit 1
fi
refused="d/box12: -solid_rbc_angle 45 (the run's; not asked now), -solid_rbc_material skalak (the run's;"
grep -q -- "$refused not asked now)" d/refused.txt
test ! -e d/t.md
