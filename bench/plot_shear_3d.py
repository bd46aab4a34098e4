#!/usr/bin/env python3
"""The 3D compound capsule in shear (paper Sec. 3.6, Fig. 5b): the inclination theta of the membrane and of the
nucleus against time, for one or more runs (e.g. meshes), and a table of what each run's summary.json reports
(tumbling rates over whole half-turns, regimes, area changes, wall time).

    python3 bench/plot_shear_3d.py RUN [RUN ...] [--figure docs/figures/shear_3d.png]
                                                [--table docs/validation/shear_3d.md] [--window T0 T1 ...]

--window T0 T1 (repeatable) adds a table per window, from metrics.csv alone (so also for a run that stopped
before its end): each body's mean tumbling rate over [T0, T1] (the time average of the per-step omega_tu
column: the long axis's turns per second for the membrane, the material's for the round nucleus), the
nucleus's rate over the membrane's, and the largest |r_A| up to T1. A run that did not reach T1 is listed as
such.

A run: cellfsi scenes/compound_capsule_shear_3d.yaml ... -output_dir RUN (docs/validation.md gives the ones
used), or a kept docs/validation/runs/NAME_metrics.csv (with NAME_summary.json beside it). Needs
python3-matplotlib (scripts/install-deps.sh; Debian's /usr/bin/python3)."""
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


def load_run(path):
    """A run's options, metrics rows and summary ({} if it has none): from its output folder, or from a kept
    NAME_metrics.csv (docs/validation/runs/) with NAME_summary.json beside it, whose command line gives the
    mesh and dt."""
    if os.path.isdir(path):
        opts = options(path)
        metrics, summary = os.path.join(path, "metrics.csv"), os.path.join(path, "summary.json")
    elif path.endswith("_metrics.csv"):
        metrics, summary = path, path[: -len("_metrics.csv")] + "_summary.json"
        opts = {}
    else:
        sys.exit(f"plot_shear_3d: {path}: neither a run folder nor a NAME_metrics.csv")
    with open(metrics) as f:
        rows = list(csv.DictReader(f))
    s = {}
    if os.path.exists(summary):  # (a run stopped with its machine has none)
        with open(summary) as f:
            s = json.load(f)
    if not opts:
        words = s.get("command_line", "").split()
        # What the command line does not set, its scene file does (top-level "name: value" lines).
        scene = next((os.path.join(ROOT, w) for w in words if w.endswith(".yaml")), None)
        if scene and os.path.exists(scene):
            with open(scene) as f:
                opts = {k: v for k, v in (line.split("#")[0].rstrip().split(": ", 1) for line in f
                                          if ": " in line and not line[0].isspace() and not line.startswith("#"))}
        for name in ("fluid_elements", "dt"):
            if "-" + name in words[:-1]:
                opts[name] = words[words.index("-" + name) + 1]
    return opts, rows, s


def describe(opts, s):
    """A run's label: the fluid mesh, with the s_I and the bodies' elements its summary records."""
    text = opts.get("fluid_elements", "?").replace(",", "x")
    if "s_interface" in s:
        text += ", s_I " + f"{s['s_interface']:.2g}".replace("e+0", "e").replace("e+", "e")
    bodies = ["x".join(f"{s[f'{b}_elements_{k}']:.0f}" for k in range(3)) for b in ("membrane", "nucleus")
              if f"{b}_elements_2" in s]
    if bodies:
        text += ", bodies " + " / ".join(bodies)
    return text


def window_row(label, opts, rows, t0, t1):
    """A table row of the mean rates over [t0, t1] (trapezoidal time averages of the per-step omega_tu)."""
    t = [float(r["time"]) for r in rows]
    head = f"| {label} | {opts.get('dt', '?')} | {len(rows)} (t = {t[-1]:g} s) |"
    if t[0] > t0 * (1 + 1e-9):
        return head + f" its first record is at t = {t[0]:g} s, after T0 | | | |"
    if t[-1] < t1 * (1 - 1e-9):
        return head + f" did not reach t = {t1:g} s | | | |"

    def mean(column):
        total = 0.0
        for k in range(1, len(t)):
            a, b = max(t[k - 1], t0), min(t[k], t1)
            if b <= a:
                continue
            # The column's linear interpolant between the records, integrated over [a, b].
            y0, y1 = float(rows[k - 1][column]), float(rows[k][column])
            slope = (y1 - y0) / (t[k] - t[k - 1])
            ya, yb = y0 + slope * (a - t[k - 1]), y0 + slope * (b - t[k - 1])
            total += 0.5 * (ya + yb) * (b - a)
        return total / (t1 - t0)

    wm, wn = mean("membrane_omega_tu"), mean("nucleus_omega_tu")
    upto = [r for r, tk in zip(rows, t) if tk <= t1 * (1 + 1e-9)]
    ra = [max(abs(float(r[b + "_r_A"])) for r in upto) for b in ("membrane", "nucleus")]
    return head + f" {wm:.3f} | {wn:.3f} | {wn / wm:.3f} | {ra[0]:.2e}, {ra[1]:.2e} |"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="+")
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "shear_3d.png"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "shear_3d.md"))
    p.add_argument("--paper", type=float, default=4.68, help="the paper's tumbling frequency (1/s)")
    p.add_argument("--window", type=float, nargs=2, metavar=("T0", "T1"), action="append", default=[],
                   help="also a table of the mean rates over [T0, T1] s, from metrics.csv (repeatable)")
    args = p.parse_args()
    for t0, t1 in args.window:
        if not 0 <= t0 < t1:
            sys.exit(f"plot_shear_3d: --window {t0} {t1}: needs 0 <= T0 < T1")
    plt = pyplot("plot_shear_3d")
    fig, axes = (None, None) if plt is None else plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    lines = ["| run: mesh, s_I, body elements | dt s | steps | membrane omega_TU 1/s (half-turns) | nucleus "
             "omega_TU 1/s | regimes (membrane, nucleus) | max \\|r_A\\| membrane, nucleus | wall time |",
             "|---|---|---|---|---|---|---|---|"]
    windows = [[] for _ in args.window]
    for run in args.runs:
        opts, rows, s = load_run(run)
        label = describe(opts, s)
        for rows_of_window, (t0, t1) in zip(windows, args.window):
            rows_of_window.append(window_row(label, opts, rows, t0, t1))
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
                ax.plot(tt, th, label=f"{label}, dt {opts.get('dt', '?')}")
        minutes = s.get("wall_time_s", float("nan")) / 60
        # A restarted run's summary times only the steps after its checkpoint.
        resumed = f" (steps {s['resumed_from_step'] + 1}-{s['steps']} only)" if "resumed_from_step" in s else ""
        steps = s.get("steps", f"{len(rows)} (stopped, no summary)")
        if s and not str(s.get("status", "")).startswith("completed"):
            # A stopped run's summary averages over the second half of what it ran: not the run's rates.
            s = {k: v for k, v in s.items() if not k.endswith(("omega_tu", "half_turns", "regime"))}
            steps = f"{steps} (stopped at t = {float(rows[-1]['time']):g} s)"
        lines.append(
            f"| {label} | {opts.get('dt', '?')} | {steps} | {fmt(s.get('membrane_omega_tu'), '.3f')} "
            f"({fmt(s.get('membrane_omega_tu_half_turns'), '.0f')}) | {fmt(s.get('nucleus_omega_tu'), '.3f')} | "
            f"{s.get('membrane_regime', '?')}, {s.get('nucleus_regime', '?')} | "
            f"{fmt(s.get('membrane_max_abs_r_A'), '.2e')}, {fmt(s.get('nucleus_max_abs_r_A'), '.2e')} | "
            f"{fmt(minutes, '.1f')} min{resumed} |")
    lines.append("")
    lines.append(f"Paper (64^3 quadratic, s_I 1e9, 3072 membrane and 7168 sphere elements; its 3D dt is not "
                 f"stated): both tumble at {args.paper} 1/s. In the metrics window (the second half of the run) "
                 "the membrane's omega_TU is its long axis's rate over its whole half-turns there (from the window's "
                 "start to the last one), the round nucleus's its material's mean rate over the window; the "
                 "window tables below average both bodies' per-step rates alike.")
    for window, (t0, t1) in zip(windows, args.window):
        lines += ["", f"Mean rates over t = {t0:g}-{t1:g} s (time averages of metrics.csv's per-step omega_tu):", "",
                  "| run | dt s | steps run | membrane omega_TU 1/s | nucleus omega_TU 1/s | nucleus / membrane | "
                  f"max \\|r_A\\| membrane, nucleus to t = {t1:g} s |", "|---|---|---|---|---|---|---|"] + window
    write_table(args.table, lines)
    if axes is None:
        return
    for ax, body in zip(axes, ("membrane", "nucleus")):
        ax.set_title(body if body == "membrane" else "nucleus (a sphere: the axis of its slight deformation)",
                     fontsize=10)
        ax.set_xlabel("t (s)")
        ax.grid(True, lw=0.3)
    axes[0].set_ylabel("theta (deg), long axis from the flow direction")
    axes[1].legend(fontsize=8)  # (the membrane turns through every angle; the nucleus leaves room)
    fig.suptitle("3D compound capsule in shear (paper Fig. 5b)", fontsize=10)
    save_figure(fig, args.figure, "plot_shear_3d")


if __name__ == "__main__":
    main()
