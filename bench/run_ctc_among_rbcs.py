#!/usr/bin/env python3
"""A CTC among red cells through the channel narrowing (the paper's future work, its Sec. 5; issue 46): the
compound-capsule CTC of scenes/ctc_rbc_narrowing.yaml alone and with red cells scattered around it at each asked
haematocrit and seed (scenes/ctc_narrowing.yaml for the CTC alone), run to the end, then per run and per haematocrit (mean and range over the seeds) the CTC's
throat entry, exit and transit time, its membrane's and nucleus's largest anisotropy, its lateral path, the red
cells' cell-free layer in the throat, and the cost; a figure of those against haematocrit and one of snapshots
(the flow's speed and the cells) as the CTC enters, crosses and leaves the throat, one row per haematocrit. The
runs take the scene's fluid space (the divergence-conforming one) and its bodies' element sizes unless --extra
names others; the table's heading says the space and the elements around the CTC's membrane and a red cell's.

    python3 bench/run_ctc_among_rbcs.py --mesh 96x32 --hematocrits 0,15,30 --seeds 3,4,5 --jobs 2

A haematocrit H (per cent of the channel's area, 9.6e-6 cm^2) asks for round(H / 100 * area / a_rbc) red cells
(a_rbc the scene's red cell's area, 1.28e-7 cm^2; 11 cells are 14.7 %, 22 are 29.5 %); the table gives the
haematocrit the run had. The cells are placed at random (-solid_rbc_seed) at least a fluid element from the
walls and each other; a seed with no room for that many is reported and left out. Haematocrit 0 is the CTC alone,
one run (no seed). Runs are kept in --runs (a completed one is not run again; one made with other options is
refused). The cell-free layer in the throat: from each throat wall to the nearest red-cell membrane point inside
the straight throat, averaged over both walls and over the steps after the flow developed (metrics.csv's
throat_cell_free_layer; steps with no red cell in the throat do not count). Early in the run, at --early T (before
the CTC reaches the narrowing), the flow rate through the throat and the distance the CTC travelled, against the
CTC alone on the same mesh: how much the red cells hold the flow back, which is what a mesh study of the
suspension can compare in a short run.

--mesh NXxNY (96x32) --degree P (3) --dt DT (2.5e-4) --final-time T (0.3) --output-every N (20)
--hematocrits LIST (0,15,30) --seeds LIST (3,4,5) --jobs N (1) --runs DIR (out/ctc_among_rbcs) --build DIR (build)
--table FILE (docs/validation/ctc_among_rbcs.md) --figure FILE (docs/figures/ctc_among_rbcs.png)
--snapshots FILE (docs/figures/ctc_among_rbcs_snapshots.png) --snapshot-seed S (the first seed; at a haematocrit where
S did not cross the throat, the first seed that did) --early T (0.04)
--extra "OPTIONS" (more cellfsi options for every run) --report (only the tables and figures, from the runs kept in
--runs: a run stopped and continued by hand with -restart and a later -final_time is reported as it stands). Needs python3-matplotlib and python3-vtk9
(scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import concurrent.futures
import csv
import math
import os
import shlex
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import (ROOT, check_kept_runs, fmt, mesh_of, option_values, provenance, pyplot,  # noqa: E402
                          run_one, same_value, save_figure, summary_of, write_table, yaml_options)

TOOL = "run_ctc_among_rbcs"
SCENE = "ctc_rbc_narrowing.yaml"
ALONE = "ctc_narrowing.yaml"  # the CTC without red cells (haematocrit 0)
DEVELOPED = 1.7e-3  # s: 5 viscous times H^2 / nu of the scene's channel (bench/plot_ctc_passage.py)


def scene_options(name=SCENE):
    """The options a scene file sets, as cellfsi reads them (bench_common.yaml_options)."""
    return yaml_options(os.path.join(ROOT, "scenes", name))


def scene_channel():
    """The scene's channel numbers (cm) and its red cell's area (cm^2), read from the scene file."""
    values = scene_options()
    c = {k: float(values[k]) for k in ("channel_length", "channel_height", "channel_throat_height",
                                        "channel_throat_length", "channel_transition_length")}
    # The walls' offset is (H - h) / 2 over the throat and a step symmetric about its mid-value over each
    # transition: the narrowing takes (H - h) (throat + transition) of the area.
    c["area"] = (c["channel_length"] * c["channel_height"] - (c["channel_height"] - c["channel_throat_height"])
                 * (c["channel_throat_length"] + c["channel_transition_length"]))
    return c


RBC_AREA = 1.2868e-7  # cm^2: the scene's 2D red cell (the area its mid-line encloses, Delta pi R0^2)


def parse_list(text, kind, what, low):
    try:
        vals = [kind(v) for v in text.split(",") if v.strip()]
        if not vals or any(not math.isfinite(v) or v < low for v in vals) or len(set(vals)) != len(vals):
            raise ValueError
        return vals
    except ValueError:
        sys.exit(f"{TOOL}: {what} '{text}' is invalid: give a comma-separated list of distinct numbers >= {low}")


def read_rows(run):
    try:
        with open(os.path.join(run, "metrics.csv")) as f:
            return list(csv.DictReader(f))
    except OSError:
        return []


def start_x(run):
    """The CTC membrane's centre x at the start, from the run's options.yaml (None when it is not there)."""
    try:
        with open(os.path.join(run, "options.yaml")) as f:
            for line in f:
                if line.startswith("solid_membrane_center:"):
                    return float(line.split(":", 1)[1].split(",")[0])
    except (OSError, ValueError):
        pass
    return None


def number(x):
    try:
        v = float(x)
        return v if math.isfinite(v) else None
    except (TypeError, ValueError):
        return None


def measures(args, tag, area):
    """One run's measures (None where not reached), or None when the run has no summary."""
    s = summary_of(args, tag)
    if s is None:
        return None
    rows = read_rows(os.path.join(args.runs, tag))
    rbcs = [k[:-len("_R0")] for k in s if k.startswith("rbc_") and k.endswith("_R0")]
    last = number(rows[-1]["time"]) if rows else None
    m = {"status": f"{s.get('status')}, to {fmt(last, 'g')} s", "steps": s.get("steps"), "wall": s.get("wall_time_s"),
         "cells": len(rbcs), "hct": 100 * sum(s[b + "_Delta"] * math.pi * s[b + "_R0"] ** 2 for b in rbcs) / area}
    for key in ("entry", "exit", "transit"):
        m[key] = number(s.get(f"membrane_throat_{key}_time"))
    for body in ("membrane", "nucleus"):
        m[body + "_anisotropy"] = number(s.get(body + "_max_anisotropy"))
    y = [(number(r["time"]), number(r["membrane_centroid_y"])) for r in rows]
    y = [(t, v) for t, v in y if t is not None and v is not None]
    m["lateral_max"] = max((abs(v) for _, v in y), default=None)  # from the centre line y = 0
    m["lateral_entry"] = next((v for t, v in y if m["entry"] is not None and t >= m["entry"]), None)
    m["lateral_exit"] = next((v for t, v in y if m["exit"] is not None and t >= m["exit"]), None)
    cfl = [number(r.get("throat_cell_free_layer")) for r in rows if (number(r["time"]) or 0) >= DEVELOPED]
    cfl = [v for v in cfl if v is not None]
    m["cfl"] = sum(cfl) / len(cfl) if cfl else None
    m["cfl_steps"] = len(cfl)
    # After a -restart the wall time is that of the steps after resumed_from_step.
    ran = (m["steps"] or 0) - (s.get("resumed_from_step") or 0)
    m["s_per_step"] = m["wall"] / ran if m["wall"] and ran > 0 else None
    m["overlap"] = s.get("contact_overlap_points_max")
    # Early, before the CTC reaches the narrowing: the flow rate and the distance the CTC travelled by --early.
    early = next((r for r in rows if (number(r["time"]) or 0) >= args.early * (1 - 1e-9)), None)
    m["early_flow"] = number(early["flow_rate"]) if early else None
    start = start_x(os.path.join(args.runs, tag))
    x = number(early["membrane_centroid_x"]) if early else None
    m["early_travel"] = x - start if x is not None and start is not None else None
    return m


def spread(vals, f, scale=1.0):
    vals = [v * scale for v in vals if v is not None]
    if not vals:
        return "-"
    mean = sum(vals) / len(vals)
    if len(vals) == 1:
        return format(mean, f)
    return f"{format(mean, f)} ({format(min(vals), f)}-{format(max(vals), f)})"


def fluid_and_membranes(args, runs):
    """The runs' fluid space (from a run's options.yaml) and the elements around the CTC's membrane and a red
    cell's (from their summary.json), as the table's heading says them ("" where no run has them yet)."""
    space, ctc, rbc = None, None, None
    for tag, h, _, _ in runs:
        kept = os.path.join(args.runs, tag, "options.yaml")
        if space is None and os.path.isfile(kept):
            space = yaml_options(kept).get("fluid_space", "equal_order")
        s = summary_of(args, tag) or {}
        ctc = ctc or s.get("membrane_elements_1")
        rbc = rbc or (s.get("rbc_1_elements_1") if h > 0 else None)
    if space is None:
        return ""
    words = {"div_conforming": "the divergence-conforming space", "equal_order": "the equal-order space"}
    counts = ", ".join(f"{what} {n:.0f}" for what, n in (("CTC membrane", ctc), ("red cell", rbc)) if n)
    return f" on {words.get(space, space)}" + (f" (elements around: {counts})" if counts else "")


def table(args, runs, results, channel, command):
    um = 1e4
    lines = [provenance(args, command), "",
             f"Mesh {args.mesh} of degree {args.degree}{fluid_and_membranes(args, runs)}, dt {args.dt:g} s, to "
             f"{args.final_time:g} s; channel area "
             f"{channel['area']:.3g} cm^2, throat {channel['channel_throat_height'] * um:g} um high. Times in s, "
             "lengths in um (lateral: the CTC membrane's centroid from the centre line).", "",
             "| haematocrit asked (%) | seed | red cells | haematocrit (%) | status | throat entry / exit | transit "
             "| membrane anisotropy max | nucleus anisotropy max | lateral at entry / exit, max | cell-free layer in "
             f"the throat (steps) | at {args.early:g} s: flow rate (1e-6 cm^2/s), CTC travel (um); (their ratios to the "
             "CTC alone's) | s/step |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    alone = next((m for (_, h, _, _), m in zip(runs, results) if h == 0 and m is not None), None)
    for (tag, h, seed, _), m in zip(runs, results):
        if m is None:
            lines.append(f"| {h:g} | {seed if h else '-'} | - | - | {results_missing(args, tag)} "
                         "| - | - | - | - | - | - | - | - |")
            continue
        early = "-"
        if m["early_flow"] is not None:
            early = f"{m['early_flow'] * 1e6:.2f}, {m['early_travel'] * um:.2f}"
            if alone is not None and alone["early_flow"] and alone["early_travel"]:
                early += (f" ({m['early_flow'] / alone['early_flow']:.2f}, "
                          f"{m['early_travel'] / alone['early_travel']:.2f})")
        lines.append(
            f"| {h:g} | {seed if h else '-'} | {m['cells']} | {m['hct']:.1f} | {str(m['status']).replace('|', '/')} | "
            f"{fmt(m['entry'], '.4f')} / {fmt(m['exit'], '.4f')} | {fmt(m['transit'], '.4f')} | "
            f"{fmt(m['membrane_anisotropy'], '.2f')} | {fmt(m['nucleus_anisotropy'], '.3f')} | "
            f"{fmt(m['lateral_entry'] and m['lateral_entry'] * um, '+.2f')} / "
            f"{fmt(m['lateral_exit'] and m['lateral_exit'] * um, '+.2f')}, {fmt(m['lateral_max'] and m['lateral_max'] * um, '.2f')} | "
            f"{fmt(m['cfl'] and m['cfl'] * um, '.2f')} ({m['cfl_steps']}) | {early} | {fmt(m['s_per_step'], '.2f')} |")
    lines += ["", "Per haematocrit, over the seeds that ran through the throat: mean (range).", "",
              "| haematocrit asked (%) | runs | haematocrit (%) | throat transit | throat exit | membrane anisotropy "
              "max | nucleus anisotropy max | lateral max | cell-free layer in the throat |",
              "|---|---|---|---|---|---|---|---|---|"]
    for h in args.hematocrits:
        ms = [m for (_, hh, _, _), m in zip(runs, results) if hh == h and m is not None
              and m["transit"] is not None]
        lines.append(f"| {h:g} | {len(ms)} | {spread([m['hct'] for m in ms], '.1f')} | "
                     f"{spread([m['transit'] for m in ms], '.4f')} | {spread([m['exit'] for m in ms], '.4f')} | "
                     f"{spread([m['membrane_anisotropy'] for m in ms], '.2f')} | "
                     f"{spread([m['nucleus_anisotropy'] for m in ms], '.3f')} | "
                     f"{spread([m['lateral_max'] for m in ms], '.2f', um)} | "
                     f"{spread([m['cfl'] for m in ms], '.2f', um)} |")
    return lines


def results_missing(args, tag):
    log = os.path.join(args.runs, tag + ".log")
    if os.path.isfile(log):
        with open(log) as f:
            errors = [line.strip() for line in f if "error" in line]
        if errors:
            return "failed: " + errors[-1].replace("|", "/")[:160]
    return "not run"


def figure(args, runs, results):
    plt = pyplot(TOOL)
    if plt is None:
        return
    panels = [("transit", "throat transit time (s)", 1), ("membrane_anisotropy", "membrane anisotropy, max", 1),
              ("nucleus_anisotropy", "nucleus anisotropy, max", 1), ("lateral_max", "lateral path, max (um)", 1e4),
              ("cfl", "cell-free layer in the throat (um)", 1e4)]
    fig, axes = plt.subplots(1, len(panels), figsize=(3.3 * len(panels), 3.2))
    for ax, (key, label, scale) in zip(axes, panels):
        means = []
        for h in args.hematocrits:
            pts = [(m["hct"], m[key] * scale) for (_, hh, _, _), m in zip(runs, results)
                   if hh == h and m is not None and m[key] is not None and m["transit"] is not None]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], "o", color="tab:blue", ms=4)
            if pts:
                means.append((sum(p[0] for p in pts) / len(pts), sum(p[1] for p in pts) / len(pts)))
        if means:
            ax.plot([p[0] for p in means], [p[1] for p in means], "-", color="k", lw=1)
        ax.set_xlabel("haematocrit (% of the area)")
        ax.set_title(label, fontsize=9)
        ax.grid(True, lw=0.3)
    space = fluid_and_membranes(args, runs).split(" (elements")[0]
    fig.suptitle(f"A CTC among red cells through the narrowing ({args.mesh}, degree {args.degree}{space}): each "
                 "seed a dot, the line their mean", fontsize=9)
    fig.tight_layout()
    save_figure(fig, args.figure, TOOL)


def snapshots(args, runs, results):
    """One row per haematocrit (the --snapshot-seed run, or where that seed did not cross the throat at a
    haematocrit, the first seed that did): the flow's speed and the bodies as the CTC enters, crosses and leaves the
    throat."""
    try:
        import numpy as np
        import vtk  # noqa: F401
        from plot_velocity_snapshot import read_grid, series
    except ImportError:
        print(f"{TOOL}: the snapshots need python3-vtk9 and python3-numpy", file=sys.stderr)
        return
    plt = pyplot(TOOL)
    if plt is None:
        return
    crossed = [(tag, h, seed, m) for (tag, h, seed, _), m in zip(runs, results)
               if m is not None and m["transit"] is not None]
    chosen = []
    for hct in dict.fromkeys(h for _, h, _, _ in crossed):
        at = [c for c in crossed if c[1] == hct]
        tag, h, _, m = next((c for c in at if c[2] == args.snapshot_seed), at[0])
        chosen.append((tag, h, m))
    if not chosen:
        return
    fig, axes = plt.subplots(len(chosen), 3, figsize=(13, 1.9 * len(chosen) + 0.4), squeeze=False)
    for row, (tag, h, m) in zip(axes, chosen):
        run = os.path.join(args.runs, tag)
        fluid, solid = series(os.path.join(run, "fluid.pvd")), series(os.path.join(run, "solid.pvd"))
        for ax, (t_want, what) in zip(row, ((m["entry"], "entry"), (0.5 * (m["entry"] + m["exit"]), "mid-throat"),
                                            (m["exit"], "exit"))):
            t, f, _ = min(fluid, key=lambda e: abs(e[0] - t_want))
            xyz, arrays = read_grid(os.path.join(run, f))
            x0, period = xyz[..., 0].min(), xyz[..., 0].max() - xyz[..., 0].min()
            ax.pcolormesh(xyz[..., 0] * 1e4, xyz[..., 1] * 1e4, np.linalg.norm(arrays["velocity"], axis=-1),
                          shading="gouraud", cmap="viridis")
            for time, sf, name in solid:
                if abs(time - t) > 1e-9 * max(1.0, abs(t)):
                    continue
                s = read_grid(os.path.join(run, sf))[0]
                colour = "w" if name.startswith("rbc") else "r"
                # A body's grid runs along its first parametric direction fastest (a membrane's thickness, a
                # nucleus's radius): its first and last columns are its inner and outer curves.
                # Bodies drift by whole periods (their x is not wrapped): each drawn at its image whose centre
                # is in the channel, and that image's neighbours across the ends.
                shift = period * math.floor((s[..., 0].mean() - x0) / period)
                for curve in (s[:, 0], s[:, -1]):
                    for image in (-period, 0.0, period):
                        ax.plot((curve[:, 0] - shift + image) * 1e4, curve[:, 1] * 1e4, color=colour, lw=0.6)
            ax.set_xlim(x0 * 1e4, (x0 + period) * 1e4)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(f"{m['hct']:.1f} %: CTC at the throat's {what}, t = {t:.3f} s", fontsize=8)
    fig.suptitle(f"A CTC (red) among red cells (white) through the narrowing ({args.mesh}); colour: the flow's "
                 "speed", fontsize=9)
    fig.tight_layout()
    save_figure(fig, args.snapshots, TOOL)


def alone_options(common):
    """The CTC alone's options from the runs' common ones: without the red cells' (-solid_rbc_*, each with its
    value), and every other option the red cells' scene file sets otherwise than the CTC's alone (its fluid space,
    its bodies' element counts and sizes), unless given: the CTC alone is that scene without its red cells."""
    out, i = [], 0
    while i < len(common):
        if common[i].startswith("-solid_rbc_"):
            i += 2
            continue
        out.append(common[i])
        i += 1
    given = option_values(out)
    scene, alone = scene_options(), scene_options(ALONE)
    for key, value in scene.items():
        if key.startswith("solid_rbc_") or key == "solid_bodies" or key in given:
            continue
        if key not in alone or not same_value(alone[key], value):
            out += ["-" + key, value]
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mesh", default="96x32")
    p.add_argument("--degree", type=int, default=3)
    p.add_argument("--dt", type=float, default=2.5e-4)
    p.add_argument("--final-time", type=float, default=0.3)
    p.add_argument("--output-every", type=int, default=20)
    p.add_argument("--hematocrits", default="0,15,30")
    p.add_argument("--seeds", default="3,4,5")
    p.add_argument("--snapshot-seed", type=int, default=None)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "ctc_among_rbcs"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "ctc_among_rbcs.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "ctc_among_rbcs.png"))
    p.add_argument("--snapshots", default=os.path.join(ROOT, "docs", "figures", "ctc_among_rbcs_snapshots.png"))
    p.add_argument("--extra", default="")
    p.add_argument("--early", type=float, default=0.04)
    p.add_argument("--report", action="store_true", help="only the tables and figures, from the runs in --runs")
    args = p.parse_args()
    nx, ny = mesh_of(TOOL, args.mesh, "--mesh")
    args.hematocrits = parse_list(args.hematocrits, float, "--hematocrits", 0)
    args.seeds = parse_list(args.seeds, int, "--seeds", 0)
    if args.snapshot_seed is None:
        args.snapshot_seed = args.seeds[0]
    for name, v, low in (("--jobs", args.jobs, 1), ("--degree", args.degree, 2), ("--output-every",
                                                                                 args.output_every, 1)):
        if v < low:
            sys.exit(f"{TOOL}: {name} {v} is invalid: give {low} or more")
    for name, v in (("--dt", args.dt), ("--final-time", args.final_time), ("--early", args.early)):
        if not v > 0:
            sys.exit(f"{TOOL}: {name} {v:g} is invalid: give a time > 0 in s")
    if not args.report and not os.path.isfile(os.path.join(args.build, "apps", "cellfsi")):
        sys.exit(f"{TOOL}: no {args.build}/apps/cellfsi: build it first (bash scripts/build.sh cellfsi)")
    channel = scene_channel()
    os.makedirs(args.runs, exist_ok=True)
    common = ["-fluid_elements", f"{nx},{ny}", "-fluid_degree", str(args.degree), "-dt", f"{args.dt:g}",
              "-final_time", f"{args.final_time:g}", "-output_every", str(args.output_every)] + shlex.split(args.extra)
    # The scene's own space unless --extra names one (run_one would run the paper's: bench_common.paper_space).
    if "-fluid_space" not in common:
        common += ["-fluid_space", scene_options().get("fluid_space", "equal_order")]
    runs = []
    for h in args.hematocrits:
        count = round(h / 100 * channel["area"] / RBC_AREA)
        # Scattered copies need two or more; the scene's CTC takes two of the 64 bodies a run may have.
        if h > 0 and not 2 <= count <= 62:
            sys.exit(f"{TOOL}: --hematocrits {h:g} is invalid: it asks for {count} red cells; valid: 0 (the CTC "
                     f"alone) or {200 * RBC_AREA / channel['area']:.1f}-{6200 * RBC_AREA / channel['area']:.1f} % "
                     "(2 to 62 cells)")
        if count == 0:
            # The CTC alone: scenes/ctc_narrowing.yaml, whose bodies are this scene's but for the red cells,
            # with the element counts chosen the same way (or as --extra gives them; its red-cell options left
            # out: that scene has none).
            alone = alone_options(common)
            runs.append((f"{args.mesh}_h0", h, None, alone))
            continue
        for seed in args.seeds:
            runs.append((f"{args.mesh}_h{h:g}_s{seed}", h, seed,
                         common + ["-solid_rbc_count", str(count), "-solid_rbc_seed", str(seed)]))
    if not args.report:
        check_kept_runs(TOOL, args, [(tag, SCENE if h > 0 else ALONE, opts) for tag, h, _, opts in runs])
        with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
            for tag, what in pool.map(lambda r: run_one(args, r[0], SCENE if r[1] > 0 else ALONE, r[3]), runs):
                print(f"{TOOL}: {tag}: {what}", flush=True)
    results = [measures(args, tag, channel["area"]) for tag, _, _, _ in runs]
    command = "python3 bench/run_ctc_among_rbcs.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    write_table(args.table, table(args, runs, results, channel, command))
    figure(args, runs, results)
    snapshots(args, runs, results)


if __name__ == "__main__":
    main()
