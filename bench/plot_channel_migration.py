#!/usr/bin/env python3
"""Lateral migration of a capsule in a channel (paper Sec. 4.2, Fig. 7): the centroid's offset from the centre line
and the inclination against time, from a run's metrics.csv, and the shapes at a few times from its solid series.

    python3 bench/plot_channel_migration.py RUN [RUN ...] [--figure docs/figures/channel_migration.png]

Several runs (e.g. meshes) are drawn together, labelled by their meshes.

The run: cellfsi scenes/capsule_channel_migration.yaml ... -output_dir DIR (docs/validation.md gives the one
used). Needs python3-matplotlib (scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import csv
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, pyplot, save_figure  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+")
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "channel_migration.png"))
    p.add_argument("--body", default="membrane")
    args = p.parse_args()
    plt = pyplot("plot_channel_migration")
    if plt is None:
        sys.exit(1)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    titles = []
    for run in args.runs:
        with open(os.path.join(run, "metrics.csv")) as f:
            rows = list(csv.DictReader(f))
        with open(os.path.join(run, "options.yaml")) as f:
            opts = dict(line.rstrip("\n").split(": ", 1) for line in f if ": " in line and not line.startswith("#"))
        size = [float(v) for v in opts.get("domain_size", "0.002,0.001").split(",")]
        mid = float(opts.get("domain_origin", "0,0").split(",")[1]) + size[1] / 2
        t = [float(r["time"]) for r in rows]
        off = [(float(r[args.body + "_centroid_y"]) - mid) * 1e4 for r in rows]
        theta = [float(r[args.body + "_theta_deg"]) for r in rows]
        label = opts.get("fluid_elements", "?").replace(",", " x ")
        axes[0].plot(t, off, label=label)
        axes[1].plot(t, theta, label=label)
        summary = {}
        if os.path.isfile(os.path.join(run, "summary.json")):
            with open(os.path.join(run, "summary.json")) as f:
                summary = json.load(f)
        ttc = summary.get(args.body + "_time_to_centreline")
        titles.append(f"{label}: {'not reached' if ttc is None else f'{ttc:.3f} s'}")
    axes[0].axhline(0, color="k", lw=0.5)
    axes[0].set_xlabel("t (s)")
    axes[0].set_ylabel("centroid above the centre line (um)")
    axes[1].set_xlabel("t (s)")
    axes[1].set_ylabel("inclination theta (deg)")
    for ax in axes:
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Capsule in a channel; time to a tenth of the offset: " + "; ".join(titles), fontsize=10)
    save_figure(fig, args.figure, "plot_channel_migration")


if __name__ == "__main__":
    main()
