#!/usr/bin/env python3
"""The 3D red blood cell in shear at Ca 0.46 (issue 47, item 3; docs/validation.md, "A red blood cell in 3D"):
scenes/rbc_shear_3d.yaml at 700 1/s on the divergence-conforming space with its automatic membrane, in the
scene's 12 um box, in a box twice as long along the flow (24 um, the same 0.75 um elements), and in one also
twice as high (walls 24 um apart, to 25 ms); in the 12 um box with a cytosol 5 times as viscous as the plasma
(to 20 ms), with Skalak's law (to 25 ms), and started with its axis of symmetry 45 deg out of the shear plane
(asked to 150 ms), the latter also with the walls 24 um apart (to 40 ms), started 10 deg out of the plane (asked
to 100 ms), both tilted starts with Skalak's law (to 100 and 60 ms), and an oblate spheroid of the cell's volume
(aspect 0.5) started 45 deg out of the plane (to 80 ms); one rank each, one after the other. Writes a table
(docs/validation/rbc_shear_3d_ca046.md) of the
motion each run shows: the times theta (the long axis's inclination in the shear plane, metrics.csv) crosses
zero downward and flips through +-90 deg, the half turns between them against Jeffery's rigid oblate spheroid
(r = 0.328: pi (r + 1/r) / gammadot = 15.2 ms), the mean membrane rotation rate omega_TT, the cell's extents
along the flow, the gradient and the vorticity, the short axis's angle to the vorticity (at the start, and its
range over the last third), |r_A| and the cost; and a figure (docs/figures/rbc_shear_3d_ca046.png) of theta,
the extents along the flow and the vorticity, and that angle against time.

    python3 bench/run_rbc_shear_3d.py              # the thirteen runs (35 min to 5.5 h each on one core)
    python3 bench/run_rbc_shear_3d.py --report     # the table and figure from the runs in --runs

Options: --runs DIR (out/rbc_shear_3d_ca046) --build DIR (build) --table FILE --figure FILE --report
--cases box12,box24,tall24,box12_ratio5,box12_skalak,box12_tilt45,tall24_tilt45,box12_tilt10,box12_skalak_tilt45,
box12_skalak_tilt10,box12_oblate_tilt45,box12_skalak_tilt10_faces,box12_skalak_tilt10_faces_cubic,
box12_skalak_tilt10_faces_thick3,box12_skalak_tilt10_faces_thin,box24_skalak_faces_thick3 (the runs to make or report; the cubic membrane and the
membrane cubic through its thickness only, about 5.5 and 3 h; the last, in the plane in the 24 um box, about 1.5 h). A run whose summary.json says "completed" is not
run again (one made with other options is refused). Exit code 3 when a run did not complete. Needs
python3-matplotlib for the figure (scripts/install-deps.sh)."""
import argparse
import csv
import itertools
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import (ROOT, check_kept_runs, fmt, provenance, pyplot, run_one, save_figure,  # noqa: E402
                          summary_of, write_table)

TOOL = "run_rbc_shear_3d.py"
SCENE = "rbc_shear_3d.yaml"
RATE = 700.0  # 1/s: Ca = mu gammadot R0 / (G h) = 0.012 * 700 * 3.27e-4 / 6e-3 = 0.46
ASPECT = 0.328  # the Evans-Fung cell's thickness over its diameter, as a rigid oblate spheroid
JEFFERY_HALF_TURN = math.pi * (ASPECT + 1 / ASPECT) / RATE
COMMON = ["-shear_rate", f"{RATE:g}", "-dt", "1e-4", "-fluid_space", "div_conforming", "-fluid_dc_degree", "2"]
# tag: (the box, its options after the common ones)
CASES = {
    "box12": ("12 x 12 x 12 um, 16 x 16 x 16", ["-final_time", "0.045"]),
    "box24": ("24 x 12 x 12 um, 32 x 16 x 16", ["-final_time", "0.04", "-domain_size", "0.0024,0.0012,0.0012",
                                                 "-fluid_elements", "32,16,16"]),
    # (the walls twice as far apart: the cell spans 0.65 of the 12 um gap)
    "tall24": ("24 x 24 x 12 um, 32 x 32 x 16", ["-final_time", "0.025", "-domain_size", "0.0024,0.0024,0.0012",
                                                  "-fluid_elements", "32,32,16"]),
    # (a cytosol 5 times as viscous as the plasma, the physiological ratio; in the 24 um box a step took 25 s)
    "box12_ratio5": ("12 x 12 x 12 um, 16 x 16 x 16, viscosity ratio 5",
                     ["-final_time", "0.02", "-solid_rbc_inner_viscosity", "0.06"]),
    # (Skalak's law with its area term, C = 10: the area-dilation modulus 21 G h; the same G h)
    "box12_skalak": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10)",
                     ["-final_time", "0.025", "-solid_rbc_material", "skalak"]),
    # (the axis of symmetry 45 deg out of the shear plane at the start, where the others have it in the plane:
    # does the cell drift to rolling, its axis along the vorticity, or back to tumbling? It stops at 86.6 ms: a
    # shell element at a pole of the membrane's parametrisation inverts.)
    "box12_tilt45": ("12 x 12 x 12 um, 16 x 16 x 16, axis 45 deg out of the shear plane",
                     ["-final_time", "0.15", "-solid_rbc_angle", "45"]),
    # (the same start with the walls 24 um apart: do the walls turn it towards rolling?)
    "tall24_tilt45": ("24 x 24 x 12 um, 32 x 32 x 16, axis 45 deg out of the shear plane",
                      ["-final_time", "0.04", "-domain_size", "0.0024,0.0024,0.0012", "-fluid_elements", "32,32,16",
                       "-solid_rbc_angle", "45"]),
    # (a start 10 deg out of the plane: does a small tilt leave the in-plane tumbling too? -solid_rbc_angle turns
    # the axis from the vorticity, z, about y: 90 is in the plane, 80 is 10 deg out of it)
    "box12_tilt10": ("12 x 12 x 12 um, 16 x 16 x 16, axis 10 deg out of the shear plane",
                     ["-final_time", "0.1", "-solid_rbc_angle", "80"]),
    # (the 45 deg start with Skalak's law, whose area term keeps each piece of the membrane's area: the neo-Hookean
    # shell's local area ranged 0.58-1.87 of its reference at 86 ms, the largest next to the poles, where an
    # element folded; does the cell still head for rolling, and does it pass 86.6 ms? It does both, and from 100
    # to 200 ms its axis stays within 1.3-9.2 deg of the vorticity: it rolls. Its faces fold between the
    # quadrature points near the poles from 152 ms.)
    "box12_skalak_tilt45": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10), axis 45 deg out of the shear "
                            "plane",
                            ["-final_time", "0.2", "-solid_rbc_material", "skalak", "-solid_rbc_angle", "45"]),
    # (the 10 deg start with Skalak's law: the neo-Hookean shell's run folds an element near a pole at 47 ms. This
    # one tumbles twice, then swings while its axis leaves the plane, and stops at 61.9 ms: an element in the
    # second row from a pole inverts. With -solid_rbc_elements 1,100,200 it stops at 62.3 ms, in the same row.)
    "box12_skalak_tilt10": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10), axis 10 deg out of the shear "
                            "plane",
                            ["-final_time", "0.15", "-solid_rbc_material", "skalak", "-solid_rbc_angle", "80"]),
    # (not a red cell: an oblate spheroid of the cell's volume, 94.2 um^3 against 94.09, aspect 0.5, semi-axes
    # 3.556 and 1.778 um, with the same shell, started 45 deg out of the plane. Dupont et al. (JFM 791, 2016)
    # find such a capsule at viscosity ratio 1 and Ca <~ 1 in the shear plane from any start: is the red cell's
    # drift towards rolling its shape's, or the method's? Its shape's: the spheroid turns to the plane.)
    "box12_oblate_tilt45": ("12 x 12 x 12 um, 16 x 16 x 16, oblate spheroid (aspect 0.5), axis 45 deg out of the "
                            "shear plane",
                            ["-final_time", "0.08", "-solid_rbc_shape", "hollow_ellipsoid", "-solid_rbc_semi_axes",
                             "3.556e-4,3.556e-4,1.778e-4", "-solid_rbc_angle", "45"]),
    # (the same start on the shell without poles, -solid_rbc_patches 6: the polar shell's run stops at 61.9 ms,
    # an element next to a pole inverted)
    "box12_skalak_tilt10_faces": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10), axis 10 deg out of the "
                                  "shear plane, six patches (no poles)",
                                  ["-final_time", "0.1", "-solid_rbc_material", "skalak", "-solid_rbc_angle", "80",
                                   "-solid_rbc_patches", "6"]),
    # (the same with a cubic membrane: four collocation points through the thickness instead of three, which held
    # the shell's J three times better over the first 4 ms, bench/run_shell_j_spread.py; 19.4 s a step)
    "box12_skalak_tilt10_faces_cubic": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10), axis 10 deg out of "
                                        "the shear plane, six patches, cubic membrane",
                                        ["-final_time", "0.1", "-solid_rbc_material", "skalak", "-solid_rbc_angle",
                                         "80", "-solid_rbc_patches", "6", "-solid_rbc_degree", "3"]),
    # (cubic through the thickness only: the same four points across it, quadratic in-plane; it held J as well as
    # the cubic membrane over the first 4 ms at about half its cost, bench/run_shell_j_spread.py)
    "box12_skalak_tilt10_faces_thick3": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10), axis 10 deg out of "
                                         "the shear plane, six patches, cubic through the thickness",
                                         ["-final_time", "0.1", "-solid_rbc_material", "skalak", "-solid_rbc_angle",
                                          "80", "-solid_rbc_patches", "6", "-solid_rbc_thickness_degree", "3"]),
    # (the tilted start on the thin shell, -solid_rbc_thin_shell: the mid-surface alone, the thickness not an
    # unknown; the solid shells fold at a dimple's inner face from 48-60 ms)
    "box12_skalak_tilt10_faces_thin": ("12 x 12 x 12 um, 16 x 16 x 16, Skalak's law (C = 10), axis 10 deg out of "
                                       "the shear plane, six patches, thin shell",
                                       ["-final_time", "0.1", "-solid_rbc_material", "skalak", "-solid_rbc_angle",
                                        "80", "-solid_rbc_patches", "6", "-solid_rbc_thin_shell", "true"]),
    # (in the shear plane with that shell, in the box twice as long along the flow: the mirror symmetry keeps the
    # cell in the plane, where it tumbles; does the tumbling settle to a periodic state on a shell that holds, in
    # a box the stretched cell does not fill (up to 10.7 um along the flow in the 24 um box)?)
    "box24_skalak_faces_thick3": ("24 x 12 x 12 um, 32 x 16 x 16, Skalak's law (C = 10), six patches, cubic "
                                  "through the thickness",
                                  ["-final_time", "0.07", "-domain_size", "0.0024,0.0012,0.0012", "-fluid_elements",
                                   "32,16,16", "-solid_rbc_material", "skalak", "-solid_rbc_patches", "6",
                                   "-solid_rbc_thickness_degree", "3"]),
}


def metrics(args, tag):
    try:
        with open(os.path.join(args.runs, tag, "metrics.csv")) as f:
            return [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    except (OSError, ValueError):
        return []


# A flip: theta rises through zero by more than FLIP_RISE deg from its lowest over FLIP_WINDOW s up to the
# crossing to its highest over FLIP_WINDOW s after it. At 700 1/s the kept runs' flips rise by 34-176 deg so, and
# their swings about zero by at most 4 (docs/notes/2026-11-30-tilted-skalak-cell-rolls.md).
FLIP_WINDOW = 3e-4
FLIP_RISE = 20.0


def crossings(rows):
    """(downward zero crossings of theta, flips) [s]: a downward crossing by linear interpolation; a flip where
    theta goes from negative to positive and rises by more than FLIP_RISE, at the step's midpoint. A cell in the
    shear plane jumps from -90 to 90 deg; one tilted out of it from about -30 to 70 (its long axis's projection
    turning over), or rises from -15 to 41 deg in 0.5 ms, or from -9 to 45 in 1.8 ms; a swing about zero rises
    by a few degrees over the window. The window is in time, so the test does not depend on the output's
    interval."""
    down, flips = [], []
    theta = [r["rbc_theta_deg"] for r in rows]
    times = [r["time"] for r in rows]
    for i, (a, b) in enumerate(zip(rows, rows[1:])):
        ta, tb = theta[i], theta[i + 1]
        if ta > 0 >= tb and ta - tb < 45:
            down.append(a["time"] + (b["time"] - a["time"]) * ta / (ta - tb))
        if ta < 0 < tb:
            eps = 1e-9 * FLIP_WINDOW
            low = min(th for t, th in zip(times, theta) if a["time"] - FLIP_WINDOW - eps <= t <= a["time"])
            high = max(th for t, th in zip(times, theta) if b["time"] <= t <= b["time"] + FLIP_WINDOW + eps)
            if high - low > FLIP_RISE:
                flips.append(0.5 * (a["time"] + b["time"]))
    return down, flips


# A swing's peak: theta the largest within SWING_WINDOW s either side (the in-plane swings of the 24 um box have a
# period of about 20 ms and rise by 15 deg from their dips: docs/validation.md, "A red blood cell in 3D").
SWING_WINDOW = 2e-3


def swing_row(box, rows):
    """A row of the swinging table for a cell started in the shear plane that never flips: theta's peaks (after the start's transient, the
    first SWING_WINDOW s), the swing period (their mean spacing), and over the last whole swing (between the last
    two peaks) theta's mean and range, the deformation index's range and the mean omega_TT (turns per second:
    solid/body_metrics.hpp), with the tank-treading period 1 / omega_TT against the swing's. None without two
    peaks."""
    # (started in the shear plane: a tilted start's axis leaves it, and its theta is a projection's)
    if not rows or crossings(rows)[1] or rows[0].get("rbc_short_axis_to_vorticity_deg", 90.0) != 90.0:
        return None
    times = [r["time"] for r in rows]
    theta = [r["rbc_theta_deg"] for r in rows]
    eps = 1e-9 * SWING_WINDOW
    peaks = [i for i, t in enumerate(times)
             if times[0] + SWING_WINDOW < t < times[-1] - SWING_WINDOW
             and theta[i] == max(th for u, th in zip(times, theta) if abs(u - t) <= SWING_WINDOW + eps)
             and theta[i - 1] < theta[i]]  # (a flat top counts once: its first sample)
    if len(peaks) < 2:
        return None
    period = (times[peaks[-1]] - times[peaks[0]]) / (len(peaks) - 1)
    last = rows[peaks[-2]:peaks[-1] + 1]
    mean = sum(r["rbc_theta_deg"] for r in last) / len(last)
    omega = sum(r["rbc_omega_tt"] for r in last) / len(last)
    di = [r["rbc_deformation_index"] for r in last] if "rbc_deformation_index" in last[0] else []
    tt = 1 / omega if omega > 0 else float("nan")
    return (f"| {box} | {', '.join(f'{times[i] * 1e3:.1f} ({theta[i]:.1f})' for i in peaks)} | {period * 1e3:.1f} | "
            f"{mean:.1f}; {min(r['rbc_theta_deg'] for r in last):.1f}-{max(r['rbc_theta_deg'] for r in last):.1f} | "
            f"{(f'{min(di):.3f}-{max(di):.3f}' if di else '-')} | {omega:.1f} | {tt * 1e3:.1f} | "
            f"{period / tt:.2f} |")


def seconds_per_step(log):
    """The wall time per step from a run's log (one launch's: `launch` writes it afresh), between its first and
    last "step N/M ... elapsed E s" lines; summary.json's wall time would be a restarted run's last launch's."""
    steps = []
    try:
        with open(log) as f:
            for line in f:
                m = re.match(r"step (\d+)/\d+ .* elapsed ([\d.]+) s", line)
                if m:
                    steps.append((int(m.group(1)), float(m.group(2))))
    except OSError:
        return float("nan")
    if len(steps) < 2 or steps[-1][0] == steps[0][0]:
        return float("nan")
    return (steps[-1][1] - steps[0][1]) / (steps[-1][0] - steps[0][0])


def short_status(status):
    """A failed run's status cut to its error's first clause and where it stopped ("failed: inverted solid
    element: det F = ... <= 0 in step 866 at t = 0.0866 s"); others as they are."""
    if not status.startswith("failed: "):
        return status
    where = re.search(r" (in|after) step \d+.* at t = \S+ s", status)
    return status.split(";", 1)[0] + (where.group(0) if where and where.group(0) not in status.split(";", 1)[0]
                                      else "")


def row_of(args, tag, box, rows):
    js = summary_of(args, tag) or {}
    if not rows:
        return f"| {box} | {js.get('status', 'not run')} | - | - | - | - | - | - | - | - | - | - |"
    down, flips = crossings(rows)
    # A half turn: between two downward zero crossings with a flip between them (a swing about zero is none).
    half = [b - a for a, b in zip(down, down[1:]) if any(a < f < b for f in flips)]
    # The last whole turn (between the last two flips, or the whole run): its mean rate and extents.
    t0, t1 = (flips[-2], flips[-1]) if len(flips) >= 2 else (rows[0]["time"], rows[-1]["time"])
    last = [r for r in rows if t0 <= r["time"] <= t1]
    omega = sum(r["rbc_omega_tt"] for r in last) / len(last)
    ext = {k: (min(r[f"rbc_extent_{k}"] for r in last) * 1e4, max(r[f"rbc_extent_{k}"] for r in last) * 1e4)
           for k in "xyz"}
    # Taylor's deformation index in the shear plane over the same turn (runs made before the metric: none).
    di = (f"{min(r['rbc_deformation_index'] for r in last):.3f}-{max(r['rbc_deformation_index'] for r in last):.3f}"
          if "rbc_deformation_index" in last[0] else "-")
    status = short_status(js.get("status", "running or stopped"))
    # The first output whose samples found J <= 0 (the shell folded between the solver's quadrature points;
    # summary.json's rbc_fold_time, null: none; runs made before it was recorded: not known).
    if js.get("rbc_fold_time") is not None:
        status += f" (folded between quadrature points from {js['rbc_fold_time'] * 1e3:.1f} ms)"
    # (A failed run's summary has not the membrane's elements; its error names them when a shell element failed.)
    shell = re.search(r" of (?:1 x )?(\d+) x (\d+)", js.get("status", ""))
    elements = [js.get("rbc_elements_1", shell and float(shell.group(1))),
                js.get("rbc_elements_2", shell and float(shell.group(2)))]
    # (A failed run's summary has no run-wide maximum: the largest in its metrics.csv.)
    r_a = js.get("rbc_max_abs_r_A")
    if r_a is None and rows and "rbc_r_A" in rows[0]:
        r_a = max(abs(r["rbc_r_A"]) for r in rows)
    s_step = seconds_per_step(os.path.join(args.runs, tag + ".log"))
    # The short axis's angle to the vorticity at the start, and its range over the run's last third (it swings
    # as the cell turns; runs made before the metric: none).
    tilt = "-"
    if "rbc_short_axis_to_vorticity_deg" in rows[0]:
        t_end = rows[0]["time"] + 2 / 3 * (rows[-1]["time"] - rows[0]["time"])
        late = [r["rbc_short_axis_to_vorticity_deg"] for r in rows if r["time"] >= t_end]
        tilt = f"{rows[0]['rbc_short_axis_to_vorticity_deg']:.1f}; {min(late):.1f}-{max(late):.1f}"
    return (f"| {box} | {status}, to {rows[-1]['time'] * 1e3:.1f} ms | "
            f"{', '.join(f'{t * 1e3:.2f}' for t in down) or '-'} | "
            f"{', '.join(f'{t * 1e3:.2f}' for t in flips) or '-'} "
            f"| {', '.join(f'{h * 1e3:.1f}' for h in half) or '-'} | {omega:.1f} | "
            f"{ext['x'][0]:.2f}-{ext['x'][1]:.2f}, {ext['y'][0]:.2f}-{ext['y'][1]:.2f}, "
            f"{ext['z'][0]:.2f}-{ext['z'][1]:.2f} | {di} | {tilt} | {fmt(r_a, '.1e')} | "
            f"{fmt(elements[0], '.0f')} x {fmt(elements[1], '.0f')} | "
            f"{fmt(s_step, '.1f')} |")


def figure(args, runs):
    plt = pyplot(TOOL)
    if plt is None:
        return
    # (The legend in a row of its own below the panels: eleven cases' names are wider than a panel.)
    fig = plt.figure(figsize=(15, 6))
    grid = fig.add_gridspec(2, 3, height_ratios=[4, 1.3])
    ax = [fig.add_subplot(grid[0, i]) for i in range(3)]
    for k, ((tag, (box, _)), style) in enumerate(zip(CASES.items(), itertools.cycle(["-", "--", ":", "-."]))):
        rows = runs.get(tag)
        if not rows:
            continue
        t = [r["time"] * 1e3 for r in rows]
        ax[0].plot(t, [r["rbc_theta_deg"] for r in rows], style, color=f"C{k}", label=box)
        ax[1].plot(t, [r["rbc_extent_x"] * 1e4 for r in rows], style, color=f"C{k}")
        ax[1].plot(t, [r["rbc_extent_z"] * 1e4 for r in rows], style, color=f"C{k}", lw=0.6)
        if "rbc_short_axis_to_vorticity_deg" in rows[0]:
            ax[2].plot(t, [r["rbc_short_axis_to_vorticity_deg"] for r in rows], style, color=f"C{k}")
    ax[0].set_ylabel("theta (deg)")
    ax[0].set_title(f"inclination (Jeffery's half turn {JEFFERY_HALF_TURN * 1e3:.1f} ms)", fontsize=9)
    ax[1].set_ylabel("extent (um)")
    ax[1].set_title("extent along the flow (thick) and the vorticity (thin)", fontsize=9)
    ax[2].set_ylabel("angle (deg)")
    ax[2].set_title("short axis to the vorticity (90: in the plane; 0: rolling)", fontsize=9)
    for a in ax:
        a.set_xlabel("t (ms)")
        a.grid(alpha=0.3)
    legend = fig.add_subplot(grid[1, :])
    legend.axis("off")
    legend.legend(*ax[0].get_legend_handles_labels(), loc="center", ncol=2, fontsize=7, frameon=False)
    save_figure(fig, args.figure, TOOL)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", default=os.path.join(ROOT, "out", "rbc_shear_3d_ca046"))
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "rbc_shear_3d_ca046.md"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "rbc_shear_3d_ca046.png"))
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--report", action="store_true", help="only the table and figure, from the runs in --runs")
    args = ap.parse_args()
    args.jobs = 1  # (provenance's "runs at a time")
    cases = [c for c in args.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            sys.exit(f"{TOOL}: --cases '{c}' is invalid: give {', '.join(CASES)}, comma-separated")
    if not args.report and not os.path.isfile(os.path.join(args.build, "apps", "cellfsi")):
        sys.exit(f"{TOOL}: --build {args.build} has no apps/cellfsi: build first (scripts/build.sh)")
    os.makedirs(args.runs, exist_ok=True)
    if not args.report:
        check_kept_runs(TOOL, args, [(c, SCENE, COMMON + CASES[c][1]) for c in cases])
    runs, lines, failed = {}, [], False
    for c in cases:
        if not args.report:
            run_one(args, c, SCENE, COMMON + CASES[c][1])
        runs[c] = metrics(args, c)
        js = summary_of(args, c)
        failed = failed or not js or js.get("status") != "completed"
        lines.append(row_of(args, c, CASES[c][0], runs[c]))
    every = ",".join(CASES)
    command = "python3 bench/run_rbc_shear_3d.py" + (f" --cases {args.cases}" if args.cases != every else "") + (
        " --report" if args.report else "")
    out = [provenance(args, command), "",
           f"`cellfsi scenes/{SCENE} {' '.join(COMMON)}` with each box's options (the membrane from the mesh); Ca "
           "0.46, viscosity ratio 1 unless said, walls 12 um apart (24 in the tall box). Times in ms; theta's "
           "downward zero crossings and its flips (a fast rise through zero: a jump through +-90 deg in the shear "
           "plane); half turns between zero crossings with a flip "
           f"between them (Jeffery: {JEFFERY_HALF_TURN * 1e3:.1f} ms); omega_TT (the membrane's rotation rate, 1/s) "
           "and the extents (um; flow x, gradient y, vorticity z) and Taylor's deformation index (L - B) / (L + B) "
           "in the shear plane (of the enclosed region's second moments; runs made before the metric: -) over the "
           "last whole turn (between the last two flips; the whole run before two flips); the short axis's angle to "
           "the vorticity (deg; 90: in the shear plane, 0: rolling) at the start and its range over the run's last "
           "third.", "",
           "| box, fluid elements | status | theta = 0 (down) | flips | half turns | omega_TT | extents x, y, z "
           "| DI | short axis to vorticity | max abs r_A | membrane | s/step |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"] + lines
    swinging = [row for row in (swing_row(CASES[c][0], runs[c]) for c in cases) if row]
    if swinging:
        out += ["", "The cells that never flip but swing: theta's peaks (time ms, theta deg; after the first "
                f"{SWING_WINDOW * 1e3:g} ms), the swing period (their mean spacing, ms), and over the last whole swing "
                "theta's mean and range (deg), the deformation index's range, the mean omega_TT (turns per second) and "
                "the tank-treading period 1 / omega_TT (ms) against the swing's.", "",
                "| box, fluid elements | peaks | swing period | theta mean; range | DI | omega_TT | 1 / omega_TT | "
                "swing / tank-treading period |", "|---|---|---|---|---|---|---|---|"] + swinging
    write_table(args.table, out)
    figure(args, runs)
    if failed:
        sys.exit(3)


if __name__ == "__main__":
    main()
