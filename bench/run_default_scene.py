#!/usr/bin/env python3
"""The default scene (what `cellfsi` runs with no scene file, scenes/capsule_shear_quick.yaml) on both fluid spaces:
as shipped (the divergence-conforming space, 128 x 64) and on the paper's equal-order space at the mesh it needed
for the same purpose (160 x 80 cubic, the default before issue 45). Each run is the README's command with
`-output_dir`, one rank, one after the other; the table gives theta and omega_TT against the paper's converged
values (26.09 deg, 3.90 1/s; 512 x 256 cubic), the largest membrane area error, the wall time and the peak
resident memory. Writes docs/validation/default_scene.md (or --table).

    python3 bench/run_default_scene.py
    python3 bench/run_default_scene.py --report    # the table from the runs in --runs

Options: --runs DIR (out/default_scene) --build DIR (build) --table FILE --report
A run whose summary.json says "completed" is not run again (its memory is then read from its .mem file).
Exit code 3 when a run did not complete."""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, fmt, launch, provenance, summary_of, write_table  # noqa: E402

TOOL = "run_default_scene.py"
THETA, OMEGA = 26.09, 3.90  # the paper's converged values (512 x 256 cubic)
# tag: (the options after `cellfsi`, mesh, space and degree as the table shows them)
CASES = {
    "as_shipped": ([], "128x64", "div_conforming 2"),
    "equal_order_160x80": (["-fluid_space", "equal_order", "-fluid_elements", "160,80"], "160x80", "equal_order 3"),
}


def run(args, tag, options):
    """Runs `cellfsi OPTIONS -output_dir RUNS/TAG` unless it completed before; writes its peak memory (kB) next to
    it."""
    out_dir = os.path.join(args.runs, tag)
    js = summary_of(args, tag)
    if js and js.get("status") == "completed":
        return
    cmd = [os.path.join(args.build, "apps", "cellfsi")] + options + ["-output_dir", out_dir]
    _, peak_kb = launch(cmd, os.path.join(args.runs, tag + ".log"))
    with open(os.path.join(args.runs, tag + ".mem"), "w") as f:
        f.write(f"{peak_kb}\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", default=os.path.join(ROOT, "out", "default_scene"))
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "default_scene.md"))
    ap.add_argument("--report", action="store_true", help="only the table, from the runs in --runs")
    args = ap.parse_args()
    args.jobs = 1  # (provenance's "runs at a time")
    if not args.report and not os.path.isfile(os.path.join(args.build, "apps", "cellfsi")):
        sys.exit(f"{TOOL}: --build {args.build} has no apps/cellfsi: build first (scripts/build.sh)")
    os.makedirs(args.runs, exist_ok=True)
    rows, failed = [], False
    for tag, (options, mesh, space) in CASES.items():
        if not args.report:
            run(args, tag, options)
        js = summary_of(args, tag)
        if not js or js.get("status") != "completed":
            failed = True
            rows.append(f"| {mesh} | {space} | - | - | - | - | - | - | {js.get('status', 'missing') if js else 'missing'} |")
            continue
        try:
            with open(os.path.join(args.runs, tag + ".mem")) as f:
                memory = f"{int(f.read()) / 1024:.0f} MB"
        except (OSError, ValueError):
            memory = "-"
        theta, omega = js["membrane_theta_deg"], js["membrane_omega_tt"]
        rows.append(f"| {mesh} | {space} | 2e-3 | {theta:.2f}, {omega:.3f} | "
                    f"{theta - THETA:+.2f} deg, {100 * (omega / OMEGA - 1):+.1f} % | "
                    f"{fmt(js.get('membrane_max_abs_r_A'), '.2e')} | {js['wall_time_s']:.1f} | {memory} | "
                    f"`cellfsi{' ' + ' '.join(options) if options else ''}` |")
    lines = [provenance(args, "python3 bench/run_default_scene.py"), "",
             "The default scene to t = 0.25 s (dt 2e-3), theta and omega_TT averaged over 0.126-0.25 s, against the "
             f"paper's converged {THETA} deg and {OMEGA} 1/s (512 x 256 cubic). Wall time: the run's own, set-up "
             "included; memory: peak resident.", "",
             "| mesh | space, degree | dt s | theta deg, omega_TT 1/s | difference | max abs r_A | wall s | memory "
             "| command |", "|---|---|---|---|---|---|---|---|---|"] + rows
    write_table(args.table, lines)
    if failed:
        sys.exit(3)


if __name__ == "__main__":
    main()
