#!/usr/bin/env python3
"""Why the 3D red cell's shell folds through its thickness (docs/validation.md, "A red blood cell in 3D"): the
tilted Skalak cell of bench/run_rbc_shear_3d.py's case box12_skalak_tilt10_faces (Ca 0.46, 700 1/s, axis 10 deg out
of the shear plane, six patches) run to 4 ms as it is and with one thing changed at a time: the step halved, the
fluid mesh 1.5 times finer (the membrane's automatic elements with it), the membrane 1.5 times finer on the same
fluid, the cubic instead of the quadratic divergence-conforming space, and a cubic membrane (its one element
through the thickness then holds four collocation points, not three), and cubic or quartic through the thickness
only (-solid_rbc_thickness_degree). Per run, from its saved states at 4 ms
(bench/shell_states.py): the least J on the shell's two faces and at its middle, the J below which 1 % of the
samples lie, the shell's own volume (between its faces) against its first, and the cost. If the spread of J
shrinks with the step or a mesh, the fold is a discretisation error that converges; if it does not, it is not.

    python3 bench/run_shell_j_spread.py              # the eight runs (5-20 min each on one core)
    python3 bench/run_shell_j_spread.py --report     # the table from the runs in --runs

Options: --runs DIR (out/shell_j_spread) --build DIR (build) --table FILE
(docs/validation/rbc_shell_j_spread.md) --cases base,dt5e-5,fluid24,membrane60,dc3,membrane_cubic,
thickness_cubic,thickness_quartic --report.
A run whose summary.json says "completed" is not run again (one made with other options is refused). Needs
Debian's python3-vtk9 (scripts/install-deps.sh)."""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, check_kept_runs, provenance, run_one, write_table  # noqa: E402
from shell_states import StatesError, states  # noqa: E402

TOOL = "run_shell_j_spread.py"
BASE = {"shear_rate": "700", "fluid_space": "div_conforming", "fluid_dc_degree": "2", "solid_rbc_material": "skalak",
        "solid_rbc_angle": "80", "solid_rbc_patches": "6", "final_time": "0.004", "dt": "1e-4", "output_every": "10"}
# tag: (what changes, the options that change it)
CASES = {
    "base": ("as box12_skalak_tilt10_faces: 16^3 quadratic, dt 1e-4, membrane 1 x 40 x 40 a face", {}),
    "dt5e-5": ("the step halved: dt 5e-5", {"dt": "5e-5", "output_every": "20"}),
    "fluid24": ("the fluid 24^3 (the membrane's automatic elements finer with it)", {"fluid_elements": "24,24,24"}),
    "membrane60": ("the membrane 1 x 60 x 60 a face on the same fluid", {"solid_rbc_elements": "1,60,60"}),
    "dc3": ("the cubic divergence-conforming space", {"fluid_dc_degree": "3"}),
    "membrane_cubic": ("the membrane cubic (4 points through the thickness, not 3)", {"solid_rbc_degree": "3"}),
    "thickness_cubic": ("the membrane cubic through the thickness only (4 points across it, quadratic in-plane)",
                        {"solid_rbc_thickness_degree": "3"}),
    "thickness_quartic": ("the membrane quartic through the thickness only (5 points across it)",
                          {"solid_rbc_thickness_degree": "4"}),
}


def options(tag):
    merged = dict(BASE, **CASES[tag][1])
    return [w for k, v in merged.items() for w in (f"-{k}", v)]


def states_at_end(args, tag):
    """bench/shell_states.py's measures of the run's last saved state (a dict), or None when it has none."""
    try:
        rows, _, _ = states(os.path.join(args.runs, tag))
    except StatesError:
        return None
    return rows[-1] if rows else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", default=os.path.join(ROOT, "out", "shell_j_spread"))
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "rbc_shell_j_spread.md"))
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--report", action="store_true", help="only the table, from the runs in --runs")
    args = ap.parse_args()
    args.jobs = 1
    cases = [c for c in args.cases.split(",") if c]
    bad = [c for c in cases if c not in CASES]
    if bad or not cases:
        sys.exit(f"{TOOL}: --cases '{args.cases}' is invalid: give a comma-separated list of {', '.join(CASES)}")
    os.makedirs(args.runs, exist_ok=True)
    check_kept_runs(TOOL, args, [(tag, "rbc_shear_3d.yaml", options(tag)) for tag in cases])
    if not args.report:
        exe = os.path.join(args.build, "apps", "cellfsi")
        if not os.access(exe, os.X_OK):
            sys.exit(f"{TOOL}: no {exe}: build first (scripts/build.sh) or give --build")
        for tag in cases:
            print(f"{TOOL}: {tag}: {run_one(args, tag, 'rbc_shear_3d.yaml', options(tag))[1]}", flush=True)
    lines = ["# Where the red cell's shell loses its J: the step, the meshes and the space", "",
             provenance(args, "python3 bench/" + TOOL + " " + " ".join(sys.argv[1:])), "",
             "scenes/rbc_shear_3d.yaml with " + " ".join(options("base")) + " and, per row, what changes. At 4 ms "
             "(bench/shell_states.py on the run's saved states, 5 sample layers through the thickness): the least "
             "J on the inner face, the middle and the outer face, the J below which 1 % of the samples lie, the "
             "shell's own volume (between its faces) against its first; s/step over the run on one core.", "",
             "| run | what changes | least J: face, middle, face | J, 1 % below | shell's volume | status | s/step |",
             "|---|---|---|---|---|---|---|"]
    for tag in cases:
        try:
            with open(os.path.join(args.runs, tag, "summary.json")) as f:
                js = json.load(f)
        except (OSError, ValueError):
            lines.append(f"| {tag} | {CASES[tag][0]} | - | - | - | not run | - |")
            continue
        row = states_at_end(args, tag)
        cost = js["wall_time_s"] / js["steps"] if js.get("steps") else float("nan")
        if row is None:
            lines.append(f"| {tag} | {CASES[tag][0]} | - | - | - | {js.get('status')} (no saved states) | "
                         f"{cost:.1f} |")
            continue
        least = row["least_J"]
        faces = f"{least[0]:.3f}, {least[len(least) // 2]:.3f}, {least[-1]:.3f}"
        lines.append(f"| {tag} | {CASES[tag][0]} | {faces} | {row['J_1pc']:.3f} | {row['shell']:.4f} | "
                     f"{js.get('status')} to {row['t'] * 1e3:.1f} ms | {cost:.1f} |")
    write_table(args.table, lines)


if __name__ == "__main__":
    main()
