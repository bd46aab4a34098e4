#!/bin/sh
# bench/scaling_counts_3d.py on -log_view logs written to be exactly F(p) = a + b / p (issue 45's count-based
# model): at 1 and 2 ranks, 2 steps. Per step: FsiLinearSolve 3 s and 100 / 60 flops (a 20, b 80: s = 3 x 20 /
# 100 = 0.6 s, d = 2.4 s), FsiJacobian 1 s and 50 / 25 (s 0, d 1), FsiResidual 1 s and 40 / 20, FsiLocate 0.8 s
# and 10 / 10 with FsiRepulsion 0.3 s inside it, FsiRepulsionSetUp 0.2 s inside that, and FsiLocateSetUp 0.1 s
# and 2 / 2 inside FsiLocate (taken out: FsiLocate 0.4 s and 8 / 8, s 0.4, the repulsion 0.1 s not counted, the
# set-ups left out), FsiSolidUpdate 0.2 s, FsiKinematic 0 s and CellfsiTrack 0.1 s not counted (s all),
# FsiStepEnds only in the one-rank log (0 s: an older log without it is read as 0), the one-rank step 6 s after
# the first (rest 6 - 5.8 = 0.2 s). At 64 ranks the model's step is 1.6 + 4.4 / 64 = 1.66875 s (printed 1.668
# or 1.669: a tie at three digits); FsiLinearSolve's s 36 % of it. A run missing from --runs is refused (a
# non-zero exit, and the message).
# Usage: scaling_counts_exact.sh SOURCE_DIR WORK_DIR
set -e
src=$1
work=$2
rm -rf "$work" && mkdir -p "$work/8cube_1rank" "$work/8cube_2rank"
line() { printf '%-20s 8 1.0 %s 1.0 %s 1.0 0.0e+00 0.0e+00 0.0e+00 1 1 0 0 0 1 1 0 0 0 1\n' "$1" "$2" "$3"; }
for r in 1 2; do
  printf '{"status": "completed", "steps": 2, "commit": "test"}\n' > "$work/8cube_${r}rank/summary.json"
  {
    echo "step 1/2  t=0.0005 s  coupling 4  linear 9  elapsed 1.0 s  left ~1 s"
    echo "step 2/2  t=0.001 s  coupling 4  linear 9  elapsed 7.0 s  left ~0 s"
    if [ $r = 1 ]; then
      line FsiLinearSolve 6.0e+00 2.0e+02; line FsiJacobian 2.0e+00 1.0e+02; line FsiResidual 2.0e+00 8.0e+01
    else
      line FsiLinearSolve 4.0e+00 1.2e+02; line FsiJacobian 1.0e+00 5.0e+01; line FsiResidual 1.0e+00 4.0e+01
    fi
    line FsiLocate 1.6e+00 2.0e+01; line FsiRepulsion 6.0e-01 0.0e+00; line FsiRepulsionSetUp 4.0e-01 0.0e+00
    line FsiLocateSetUp 2.0e-01 4.0e+00
    line FsiSolidUpdate 4.0e-01 0.0e+00; line FsiKinematic 0.0e+00 0.0e+00
    if [ $r = 1 ]; then line FsiStepEnds 0.0e+00 0.0e+00; fi
    line CellfsiTrack 2.0e-01 0.0e+00
  } > "$work/8cube_${r}rank.log"
done
python3 "$src/bench/scaling_counts_3d.py" --runs "$work" --mesh 8 --ranks 1,2 --out "$work/m.md" > /dev/null
grep -Eq '^[|] FsiLinearSolve [|][^|]*[|] 3.000 [|] 100 / 60 [|] [^|]* [|] 0.20 [|] 0.600 [|] 2.400 [|] 3.000 [|] 1.800 [|] 0.63[78] [|] 36% [(]over the limit[)] [|]$' "$work/m.md"
grep -Eq '^[|] FsiJacobian [|].* [|] 0.00 [|] 0.000 [|] 1.000 [|]' "$work/m.md"
grep -Eq '^[|] rest [|].* [|] 0.200 [|]' "$work/m.md"
grep -Eq '^[|] FsiLocate [|].* [|] 8 / 8 [|] [^|]* [|] 1.00 [|] 0.400 [|] 0.000 [|]' "$work/m.md"
grep -Eq '^[|] FsiRepulsion [|].* [|] 1 [(]all[)] [|] 0.100 [|] 0.000 [|]' "$work/m.md"
grep -Eq '^[|] step [|] [|] 6.000 [|].* [|] 1.66[89] [|] [0-9]+% [|]$' "$work/m.md"
if python3 "$src/bench/scaling_counts_3d.py" --runs "$work" --mesh 8 --ranks 1,2,4 --out "$work/x.md" 2> "$work/refused.txt"; then
  exit 1
fi
grep -q 'cannot be read' "$work/refused.txt"
