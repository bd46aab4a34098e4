#!/usr/bin/env python3
"""Why the migrating capsule's area error is larger on the finer mesh (issue 12; docs/validation.md,
"The migrating capsule (Sec. 4.2)"): short runs of scenes/capsule_channel_migration.yaml (the paper's Sec. 4.2 capsule,
Poiseuille flow) to T that vary one thing at a time against 256 x 128 with dt 5e-4, s_I 1e9 and the automatic
membrane mesh: the time step, the membrane mesh, s_I, and the Eulerian mesh. Writes r_A (paper Eq. (21): the
relative change of the membrane's own area, the thin band) at T/2 and T, and each run's wall time.

  bench/run_area_error_study.py                       # every case, one run at a time
  bench/run_area_error_study.py --report              # the table from the runs already there

A run whose summary.json says completed is kept. Needs a built cellfsi (scripts/build.sh)."""
import argparse
import csv
import json
import os
import sys

from bench_common import ROOT, check_kept_runs, fmt, provenance, run_one, write_table

# tag: (what differs, cellfsi options)
CASES = [
    ("256x128", "reference: 256 x 128, dt 5e-4, s_I 1e9, membrane automatic", []),
    ("256x128_dt2.5e-4", "dt 2.5e-4 (the paper's)", ["-dt", "2.5e-4"]),
    ("256x128_membrane360", "membrane 1 x 360 (the paper's)", ["-solid_membrane_elements", "1,360"]),
    ("256x128_sI1e5", "s_I 1e5", ["-s_interface", "1e5"]),
    ("256x128_sI1e7", "s_I 1e7", ["-s_interface", "1e7"]),
    ("256x128_sI1e11", "s_I 1e11", ["-s_interface", "1e11"]),
    ("128x64", "128 x 64", ["-fluid_elements", "128,64"]),
    ("128x64_dt2.5e-4", "128 x 64, dt 2.5e-4", ["-fluid_elements", "128,64", "-dt", "2.5e-4"]),
    ("128x64_membrane360", "128 x 64, membrane 1 x 360", ["-fluid_elements", "128,64", "-solid_membrane_elements",
                                                         "1,360"]),
]
BASE = ["-fluid_elements", "256,128", "-solid_membrane_elements", "1,0", "-dt", "5e-4", "-output_every", "0"]


def merged(base, changes):
    """base with each option of changes replacing its value (cellfsi refuses an option given twice)."""
    options = dict(zip(base[::2], base[1::2]))
    options.update(zip(changes[::2], changes[1::2]))
    return [x for kv in options.items() for x in kv]


def r_a_at(rows, t):
    row = min(rows, key=lambda r: abs(float(r["time"]) - t))
    return float(row["membrane_r_A"])


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--final-time", type=float, default=0.1)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "area_error"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "area_error_study.md"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    args.jobs = 1
    os.makedirs(args.runs, exist_ok=True)
    runs = [(tag, "capsule_channel_migration.yaml", merged(BASE + ["-final_time", str(args.final_time)], options))
            for tag, _, options in CASES]
    check_kept_runs("run_area_error_study", args, runs)
    if not args.report:
        for run in runs:
            print(*run_one(args, *run), flush=True)
    T = args.final_time
    lines = [f"| case | r_A(t = {T / 2:g} s) | r_A(t = {T:g} s) | steps | wall s |", "|---|---|---|---|---|"]
    missing = False
    for tag, what, _ in CASES:
        path = os.path.join(args.runs, tag)
        try:
            with open(os.path.join(path, "summary.json")) as f:
                summary = json.load(f)
            with open(os.path.join(path, "metrics.csv")) as f:
                rows = list(csv.DictReader(f))
        except (OSError, ValueError):
            lines.append(f"| {what} | - | - | - | not run |")
            missing = True
            continue
        lines.append(f"| {what} | {r_a_at(rows, T / 2):.2e} | {r_a_at(rows, T):.2e} | {summary.get('steps', '-')} "
                     f"| {fmt(summary.get('wall_time_s'), '.0f')} |")
    command = "bench/run_area_error_study.py" + (" --report" if args.report else "")
    write_table(args.table, ["# The migrating capsule's area error: what it depends on", "",
                             provenance(args, command), "",
                             "`cellfsi scenes/capsule_channel_migration.yaml " + " ".join(BASE) +
                             f" -final_time {T:g}` plus each case's change.", ""] + lines)
    return 3 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
