#!/usr/bin/env python3
"""What a 3D coupled step costs (issue 26): the paper's compound capsule (scenes/compound_capsule_shear_3d.yaml,
Sec. 3.6) at N^3 quadratic fluid elements on 1 or more ranks, a few steps from the initial state, with -log_view.
Writes one row per case: seconds per step after the first, the first step with the set-up, the step's split
by the coupling's log events, the coupling and GMRES iterations, the corrected region and the peak memory per
rank (/usr/bin/time -v). The table goes to docs/performance/coupled_steps_3d.md (or --table).

  python3 bench/run_3d_steps.py                          # 16^3 to 64^3, 1 and 2 ranks (64^3: ~15 GB, ~10 min)
  python3 bench/run_3d_steps.py --cases 16:1:3,32:2:3    # N:RANKS:STEPS

Bodies: --elements paper (default) scales the paper's 64^3 discretisation with N (membrane 1 x N/2 x 3N/2,
nucleus 7 x N/4 x N: the paper's 1 x 32 x 96 and 7 x 16 x 64 at N = 64, mesh ratio 1.52); --elements auto takes
them from the fluid mesh (-solid_NAME_elements 1,0,0 and 0,0,0); a -solid_NAME_elements in --extra replaces
either. Runs one case at a time (64^3 needs most of
a 24 GB machine); OPENBLAS_NUM_THREADS=1. Needs /usr/bin/time (Debian package time).
"""
import argparse
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, fmt, paper_space, provenance, write_table  # noqa: E402

TOOL = "run_3d_steps.py"
# The coupling's log events (coupling/coupling_events.hpp), per step; FsiFactor (the Fourier bulk's banded
# factors) is once per run and reported apart.
EVENTS = ["FsiPCSetUp", "FsiLinearSolve", "FsiJacobian", "FsiResidual", "FsiLocate", "FsiSolidUpdate", "CellfsiTrack"]


def parse_cases(text):
    cases = []
    for c in text.split(","):
        m = re.fullmatch(r"(\d+):(\d+):(\d+)", c.strip())
        if not m or int(m.group(1)) < 4 or int(m.group(2)) < 1 or int(m.group(3)) < 2:
            sys.exit(f"{TOOL}: --cases item '{c}' is invalid: give N:RANKS:STEPS with N >= 4, RANKS >= 1, "
                     "STEPS >= 2 (e.g. 32:2:3)")
        cases.append(tuple(int(g) for g in m.groups()))
    return cases


def log_events(text):
    """-log_view's event lines: name -> (count, max time over ranks in s)."""
    ev = {}
    for line in text.splitlines():
        f = line.split()
        if len(f) > 4 and re.match(r"^[A-Za-z]\w*$", f[0]) and re.match(r"^\d+$", f[1]):
            try:
                ev[f[0]] = (int(f[1]), float(f[3]))
            except ValueError:
                pass
    return ev


def step_times(text):
    """(step, elapsed s) of the progress lines (one per step in 3D: each takes more than their 2 s spacing)."""
    return [(int(m.group(1)), float(m.group(2)))
            for m in re.finditer(r"^step (\d+)/\d+ .*elapsed ([0-9.]+) s", text, re.M)]


def run_case(args, n, ranks, steps):
    tag = f"{n}cube_{ranks}rank"
    out_dir = os.path.join(args.runs, tag)
    shutil.rmtree(out_dir, ignore_errors=True)
    os.makedirs(args.runs, exist_ok=True)
    bodies = (["-solid_membrane_elements", "1,0,0", "-solid_nucleus_elements", "0,0,0"] if args.elements == "auto"
              else ["-solid_membrane_elements", f"1,{n // 2},{3 * n // 2}",
                    "-solid_nucleus_elements", f"7,{max(n // 4, 2)},{n}"])
    # A body's elements given in --extra replace these (an option may be given once).
    extra = args.extra.split()
    for name in ("-solid_membrane_elements", "-solid_nucleus_elements"):
        if name in extra:
            i = bodies.index(name)
            del bodies[i:i + 2]
    cmd = [os.path.join(args.build, "apps", "cellfsi"), os.path.join(ROOT, "scenes", "compound_capsule_shear_3d.yaml"),
           "-fluid_elements", f"{n},{n},{n}", "-final_time", repr(steps * 5e-4), "-output_every", "0",
           "-log_view", "-output_dir", out_dir] + bodies + paper_space(extra)
    time_base = os.path.join(args.runs, tag + ".time")
    for old in glob.glob(time_base + ".*"):
        os.remove(old)
    # One /usr/bin/time per rank, each writing its own file (the rank from Open MPI's environment).
    timed = ["bash", "-c", '/usr/bin/time -v -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"', time_base] + cmd
    launch = ["mpirun", "-np", str(ranks), "--oversubscribe"] if ranks > 1 else []
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1",
               OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    log_path = os.path.join(args.runs, tag + ".log")
    # (A private Open MPI session directory, as bench_common.run_one's.)
    with tempfile.TemporaryDirectory(prefix="cellfsi-ompi-") as session, open(log_path, "w") as log:
        env["OMPI_MCA_orte_tmpdir_base"] = session
        rc = subprocess.call(launch + timed, stdout=log, stderr=subprocess.STDOUT, env=env)
    text = open(log_path).read()
    try:
        with open(os.path.join(out_dir, "summary.json")) as f:
            s = json.load(f)
    except (OSError, ValueError):
        s = {}
    if rc != 0 or s.get("status") != "completed":
        why = [line for line in text.splitlines() if "cellfsi: error:" in line] or [s.get("status", "no summary")]
        return f"| {n}^3 | {ranks} | failed (exit {rc}): {why[0].replace('cellfsi: error: ', '')[:150]} |"
    times = step_times(text)
    per = (times[-1][1] - times[0][1]) / (times[-1][0] - times[0][0]) if len(times) > 1 else float("nan")
    ev = log_events(text)
    split = [ev.get(e, (0, 0.0))[1] / s["steps"] for e in EVENTS]
    # The solids' step: the velocity at their collocation points (FsiSolidUpdate) and their kinematic update
    # (FsiKinematic; older logs hold both in the first).
    split[EVENTS.index("FsiSolidUpdate")] += ev.get("FsiKinematic", (0, 0.0))[1] / s["steps"]
    rss = []
    for p in glob.glob(time_base + ".*"):
        m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", open(p).read())
        if m:
            rss.append(int(m.group(1)) / 2**20)
    iterations = s.get("coupling_iterations", 0)
    return (f"| {n}^3 | {ranks} | {s['steps']} | {fmt(per, '.1f')} | {fmt(times[0][1], '.1f')} | "
            + " | ".join(fmt(x, ".2f") for x in split)
            + f" | {fmt(ev.get('FsiFactor', (0, float('nan')))[1], '.1f')} | {iterations / s['steps']:.2f} | "
            f"{s['linear_iterations'] / max(1, iterations):.1f} | {int(s.get('corrected_unknowns', 0))} | "
            f"{fmt(max(rss) if rss else float('nan'), '.2f')} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default="16:1:4,16:2:4,32:1:4,32:2:4,48:1:3,48:2:3,64:1:2,64:2:2",
                    help="N:RANKS:STEPS, comma-separated")
    ap.add_argument("--elements", default="paper", choices=["paper", "auto"])
    ap.add_argument("--extra", default="", help="more cellfsi options for every run")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--runs", default=os.path.join(ROOT, "out", "bench_3d_steps"))
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "performance", "coupled_steps_3d.md"))
    args = ap.parse_args()
    cases = parse_cases(args.cases)
    if not os.access(os.path.join(args.build, "apps", "cellfsi"), os.X_OK):
        sys.exit(f"{TOOL}: {args.build}/apps/cellfsi not found: build first (scripts/build.sh) or give --build")
    if not os.access("/usr/bin/time", os.X_OK):
        sys.exit(f"{TOOL}: /usr/bin/time not found (apt-get install time)")
    args.jobs = 1
    head = provenance(args, "python3 bench/run_3d_steps.py " + " ".join(sys.argv[1:])).replace(
        "(one rank each)", "(each on the ranks of its row)")
    lines = ["# A 3D coupled step: cost per step and where it goes", "",
             head, "",
             "The compound capsule of scenes/compound_capsule_shear_3d.yaml (dt 5e-4) at N^3 quadratic elements, "
             f"bodies `--elements {args.elements}`{', extra options `' + args.extra + '`' if args.extra else ''}. "
             "s/step: wall time per step after the first (progress lines); step 1: wall time to the end of step 1, "
             "set-up included. The events (-log_view, the slowest rank's time) are per step over all steps: "
             "PCSetUp is the region's LU, LinearSolve the FGMRES solves, Jacobian and Residual their assembly, "
             "Locate the point location, SolidUpdate the solids' step, Track the bodies' metrics of the step; Factor is the Fourier bulk's banded "
             "factorisation, once per run. Peak GB: the largest resident set of one rank.", "",
             "| mesh | ranks | steps | s/step | step 1 (s) | PCSetUp | LinearSolve | Jacobian | Residual | Locate | "
             "SolidUpdate | Track | Factor (once) | coupling/step | GMRES/coupling | corrected unknowns | peak GB |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for n, ranks, steps in cases:
        row = run_case(args, n, ranks, steps)
        print(row, flush=True)
        lines.append(row)
    write_table(args.table, lines)


if __name__ == "__main__":
    main()
