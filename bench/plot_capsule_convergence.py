#!/usr/bin/env python3
"""Mesh convergence of the capsule in shear flow (paper Table 1): theta and omega_TT against the number of
Eulerian elements, for each series of runs of bench/run_capsule_validation.sh table1 and the paper's rows.

    python3 bench/plot_capsule_convergence.py OUT.png LABEL=RUNS_DIR [LABEL=RUNS_DIR ...]

Each RUNS_DIR holds table1_<NX>x<NY>_p<P>_dt<DT>/summary.json folders (runs that did not complete are left
out), or is a table the script wrote (docs/validation/capsule_table1*.md: rows "| NXxNY | p | dt | theta |
paper | omega |"). Needs python3-matplotlib (scripts/install-deps.sh installs it)."""
import glob
import json
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Paper Table 1 (Casquero et al. 2017), the smallest dt of each mesh: (nx, ny, p) -> (theta deg, omega_TT 1/s).
PAPER = {
    (96, 48, 2): (17.81, 3.20), (96, 48, 3): (23.95, 3.54),
    (128, 64, 2): (22.14, 3.46), (128, 64, 3): (25.22, 3.58),
    (192, 96, 2): (24.45, 3.59), (192, 96, 3): (25.77, 3.78),
    (256, 128, 2): (25.24, 3.72), (256, 128, 3): (25.99, 3.84),
    (384, 192, 2): (25.80, 3.84), (384, 192, 3): (26.06, 3.88),
    (512, 256, 2): (25.87, 3.87), (512, 256, 3): (26.09, 3.90),
}
CONVERGED = PAPER[(512, 256, 3)]


def read_series(runs_dir):
    """{p: [(elements, theta, omega), ...]} from the completed table1 runs in runs_dir (or a table)."""
    out = {}
    if os.path.isfile(runs_dir):
        with open(runs_dir) as f:
            for line in f:
                c = [x.strip() for x in line.strip().strip("|").split("|")]
                m = re.match(r"(\d+)\s*x\s*(\d+)$", c[0]) if len(c) > 5 else None
                if m and re.match(r"^[0-9.]+$", c[3]) and re.match(r"^[0-9.]+$", c[5]):
                    nx, ny, p = int(m.group(1)), int(m.group(2)), int(c[1])
                    out.setdefault(p, []).append((nx * ny, float(c[3]), float(c[5])))
        for p in out:
            out[p].sort()
        return out
    for path in glob.glob(os.path.join(runs_dir, "table1_*", "summary.json")):
        m = re.match(r"table1_(\d+)x(\d+)_p(\d+)_dt", os.path.basename(os.path.dirname(path)))
        if not m:
            continue
        with open(path) as f:
            s = json.load(f)
        if s.get("status") != "completed" or "membrane_theta_deg" not in s:
            continue
        nx, ny, p = int(m.group(1)), int(m.group(2)), int(m.group(3))
        out.setdefault(p, []).append((nx * ny, s["membrane_theta_deg"], s["membrane_omega_tt"]))
    for p in out:
        out[p].sort()
    return out


def main(argv):
    if len(argv) < 3 or any("=" not in a for a in argv[2:]):
        sys.exit(__doc__)
    out_png = argv[1]
    fig, (ax_t, ax_w) = plt.subplots(1, 2, figsize=(11, 4.2))
    colours = {2: "tab:blue", 3: "tab:red"}
    for p in (2, 3):
        rows = sorted((nx * ny, v[0], v[1]) for (nx, ny, q), v in PAPER.items() if q == p)
        e, t, w = zip(*rows)
        ax_t.plot(e, t, "k" + ("--" if p == 2 else "-"), marker="s", mfc="none", lw=1,
                  label=f"paper, p = {p}")
        ax_w.plot(e, w, "k" + ("--" if p == 2 else "-"), marker="s", mfc="none", lw=1,
                  label=f"paper, p = {p}")
    markers = "o^vD"
    labelled = {}  # label -> {p: rows}; several sources may share a label
    for arg in argv[2:]:
        label, runs_dir = arg.split("=", 1)
        series = read_series(runs_dir)
        if not series:
            print(f"plot_capsule_convergence: no completed table1 runs in {runs_dir}", file=sys.stderr)
        for p, rows in series.items():
            labelled.setdefault(label, {}).setdefault(p, []).extend(rows)
    for k, (label, series) in enumerate(labelled.items()):
        for p, rows in sorted(series.items()):
            e, t, w = zip(*sorted(rows))
            style = dict(color=colours.get(p, "tab:green"), marker=markers[k % len(markers)],
                         ls="--" if p == 2 else "-", lw=1.2, label=f"{label}, p = {p}")
            ax_t.plot(e, t, **style)
            ax_w.plot(e, w, **style)
    for ax, ref, name in ((ax_t, CONVERGED[0], "theta (deg)"), (ax_w, CONVERGED[1], "omega_TT (1/s)")):
        ax.axhline(ref, color="grey", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_xlabel("Eulerian elements")
        ax.set_ylabel(name)
        ax.grid(True, which="both", lw=0.3)
    ax_t.set_title("Inclination (dotted: paper's 512 x 256 cubic)")
    ax_w.set_title("Tank-treading frequency")
    ax_w.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    os.makedirs(os.path.dirname(out_png) or ".", exist_ok=True)
    fig.savefig(out_png, dpi=120)
    print(f"plot_capsule_convergence: wrote {out_png}")


if __name__ == "__main__":
    main(sys.argv)
