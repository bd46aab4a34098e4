#!/usr/bin/env python3
"""The 3D compound capsule in shear (paper Sec. 3.6, Fig. 5b): the inclination theta of the membrane and of the
nucleus against time, for one or more runs (e.g. meshes), and a table of what each run's summary.json reports
(tumbling rates over whole half-turns, regimes, area changes, wall time).

    python3 bench/plot_shear_3d.py RUN [RUN ...] [--figure docs/figures/shear_3d.png]
                                                [--table docs/validation/shear_3d.md]

A run: cellfsi scenes/compound_capsule_shear_3d.yaml ... -output_dir RUN (docs/validation.md gives the ones
used). Needs python3-matplotlib (scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import csv
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, fmt, pyplot, save_figure, write_table  # noqa: E402


def options(run):
    with open(os.path.join(run, "options.yaml")) as f:
        return dict(line.rstrip("\n").split(": ", 1) for line in f if ": " in line and not line.startswith("#"))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+")
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "shear_3d.png"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "shear_3d.md"))
    p.add_argument("--paper", type=float, default=4.68, help="the paper's tumbling frequency (1/s)")
    args = p.parse_args()
    plt = pyplot("plot_shear_3d")
    fig, axes = (None, None) if plt is None else plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    lines = ["| mesh | dt s | steps | membrane omega_TU 1/s (half-turns) | nucleus omega_TU 1/s | regimes "
             "(membrane, nucleus) | max \\|r_A\\| membrane, nucleus | wall time |",
             "|---|---|---|---|---|---|---|---|"]
    for run in args.runs:
        opts = options(run)
        with open(os.path.join(run, "metrics.csv")) as f:
            rows = list(csv.DictReader(f))
        with open(os.path.join(run, "summary.json")) as f:
            s = json.load(f)
        mesh = opts.get("fluid_elements", "?").replace(",", "x")
        t = [float(r["time"]) for r in rows]
        if axes is not None:
            for ax, body in zip(axes, ("membrane", "nucleus")):
                theta = [float(r[body + "_theta_deg"]) for r in rows]
                # theta lives in (-90, 90]: no line across the jump where the axis passes the vertical.
                tt, th = [t[0]], [theta[0]]
                for k in range(1, len(t)):
                    if abs(theta[k] - theta[k - 1]) > 90:
                        tt.append(float("nan"))
                        th.append(float("nan"))
                    tt.append(t[k])
                    th.append(theta[k])
                ax.plot(tt, th, label=f"{mesh} quadratic")
        minutes = s.get("wall_time_s", float("nan")) / 60
        lines.append(
            f"| {mesh} | {opts.get('dt', '?')} | {s.get('steps')} | {fmt(s.get('membrane_omega_tu'), '.3f')} "
            f"({fmt(s.get('membrane_omega_tu_half_turns'), '.0f')}) | {fmt(s.get('nucleus_omega_tu'), '.3f')} | "
            f"{s.get('membrane_regime', '?')}, {s.get('nucleus_regime', '?')} | "
            f"{fmt(s.get('membrane_max_abs_r_A'), '.2e')}, {fmt(s.get('nucleus_max_abs_r_A'), '.2e')} | "
            f"{minutes:.1f} min |")
    lines.append("")
    lines.append(f"Paper (64^3 quadratic, dt 5e-4): both tumble at {args.paper} 1/s. omega_TU is averaged over the "
                 "whole half-turns of the long axis in the metrics window (the second half of the run).")
    write_table(args.table, lines)
    if axes is None:
        return
    for ax, body in zip(axes, ("membrane", "nucleus")):
        ax.set_title(body if body == "membrane" else "nucleus (a sphere: the axis of its slight deformation)",
                     fontsize=10)
        ax.set_xlabel("t (s)")
        ax.grid(True, lw=0.3)
    axes[0].set_ylabel("theta (deg), long axis from the flow direction")
    axes[0].legend(fontsize=8)
    fig.suptitle("3D compound capsule in shear (paper Fig. 5b)", fontsize=10)
    save_figure(fig, args.figure, "plot_shear_3d")


if __name__ == "__main__":
    main()
