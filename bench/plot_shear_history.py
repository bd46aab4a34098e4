#!/usr/bin/env python3
"""A membrane's inclination theta and area change r_A (Eq. 21) against time, for one or more shear runs (e.g. two
meshes, two viscosity ratios of one cell): the figure that tells a steady state from a drift, which the sweeps'
averages alone do not.

    python3 bench/plot_shear_history.py RUN[=LABEL] [RUN[=LABEL] ...] [--body membrane]
                                        [--figure docs/figures/shear_history.png]

A run: any cellfsi output folder with metrics.csv and options.yaml (docs/validation.md names the runs used).
Needs python3-matplotlib (scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, pyplot, save_figure  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+", help="RUN or RUN=LABEL")
    p.add_argument("--body", default="membrane", help="the body whose metrics are drawn (default membrane)")
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "shear_history.png"))
    args = p.parse_args()
    plt = pyplot("plot_shear_history")
    if plt is None:
        sys.exit(1)
    fig, (ax_t, ax_a) = plt.subplots(1, 2, figsize=(11, 3.8))
    for item in args.runs:
        run, _, label = item.partition("=")
        path = os.path.join(run, "metrics.csv")
        if not os.path.isfile(path):
            sys.exit(f"plot_shear_history: {path} does not exist: give a cellfsi output folder")
        with open(path) as f:
            rows = list(csv.DictReader(f))
        key = f"{args.body}_theta_deg"
        if not rows or key not in rows[0]:
            sys.exit(f"plot_shear_history: {path} has no column {key}: is the body called '{args.body}'?")
        t = [float(r["time"]) for r in rows]
        ax_t.plot(t, [float(r[key]) for r in rows], label=label or os.path.basename(run))
        ax_a.plot(t, [float(r[f"{args.body}_r_A"]) for r in rows], label=label or os.path.basename(run))
    ax_t.set_xlabel("t (s)")
    ax_t.set_ylabel("theta (deg)")
    ax_t.set_ylim(-5, 30)
    ax_a.set_xlabel("t (s)")
    ax_a.set_ylabel("r_A")
    for ax in (ax_t, ax_a):
        ax.grid(alpha=0.3)
    ax_a.legend(fontsize=8)
    save_figure(fig, args.figure, "plot_shear_history")


if __name__ == "__main__":
    main()
