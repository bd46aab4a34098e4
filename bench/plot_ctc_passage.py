#!/usr/bin/env python3
"""A CTC through the channel narrowing (paper Sec. 4.4, Fig. 10): the flow rate through the throat, the cell's
and the nucleus's centroid x and shape anisotropy against time, with the throat marked, from a run's
metrics.csv and summary.json.

    python3 bench/plot_ctc_passage.py out/ctc/192x64 [--figure docs/figures/ctc_passage.png]

The run: cellfsi scenes/ctc_narrowing.yaml ... -output_dir DIR (docs/validation.md gives the one used). Needs
python3-matplotlib (scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import csv
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, pyplot, save_figure  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run")
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "ctc_passage.png"))
    args = p.parse_args()
    plt = pyplot("plot_ctc_passage")
    if plt is None:
        sys.exit(1)
    with open(os.path.join(args.run, "metrics.csv")) as f:
        rows = list(csv.DictReader(f))
    with open(os.path.join(args.run, "summary.json")) as f:
        s = json.load(f)
    t = [float(r["time"]) for r in rows]
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    axes[0].plot(t, [float(r["flow_rate"]) * 1e6 for r in rows], color="k")
    axes[0].set_ylabel("flow rate through the throat (1e-6 cm^2/s)")
    for body, colour in (("membrane", "tab:blue"), ("nucleus", "tab:red")):
        axes[1].plot(t, [float(r[body + "_centroid_x"]) * 1e4 for r in rows], color=colour, label=f"{body} x")
        t_in, t_out = s.get(body + "_throat_entry_time"), s.get(body + "_throat_exit_time")
        for ax in axes:
            for tt in (t_in, t_out):
                if tt is not None:
                    ax.axvline(tt, color=colour, lw=0.6, ls="--")
    axes[1].set_ylabel("centroid x (um); dashed: throat entry and exit")
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.grid(True, lw=0.3)
    fig.suptitle(f"CTC through the narrowing: flow rate min {s.get('flow_rate_min', 0) * 1e6:.2f} at "
                 f"t = {s.get('flow_rate_min_time', 0):.3f} s; nucleus most deformed (anisotropy "
                 f"{s.get('nucleus_max_anisotropy', 0):.2f}) at x = {s.get('nucleus_max_anisotropy_x', 0) * 1e4:.1f} um",
                 fontsize=9)
    save_figure(fig, args.figure, "plot_ctc_passage")


if __name__ == "__main__":
    main()
