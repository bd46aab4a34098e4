#!/usr/bin/env python3
"""The paper's shear-flow sweeps (Sec. 3.5-3.6): runs `cellfsi` on a scene for each value of a parameter,
collects every run's summary.json, and writes a markdown table and a figure.

    python3 bench/run_shear_sweeps.py swelling   # capsules a = 1e-4 ... 5.5e-4 cm + the biconcave capsule: Fig. 3a/b
    python3 bench/run_shear_sweeps.py bulky      # bulky ellipses a = 1e-4 ... 5.5e-4 cm: Fig. 4a
    python3 bench/run_shear_sweeps.py compound   # compound capsules, nucleus r = 1e-5 ... 7e-5 cm: Fig. 4b-d
    python3 bench/run_shear_sweeps.py viscosity  # the Sec. 3.3 capsule, inner/outer viscosity 1 ... 10 (issue 27)
    python3 bench/run_shear_sweeps.py viscosity --scene biconcave_capsule_shear.yaml --values 1,5  # the RBC

Options (all have defaults; the paper's resolution is 384x192 cubic, dt 5e-4, which -- mesh and --dt select):
  --mesh NXxNY (256x128)  --degree P (3)  --dt S (1e-3)  --final-time S (0.3)  --average-from S (0.15)
  --values V,V,...  (the sweep's values: cm; viscosity: the ratio lambda)  --jobs N (2)  --runs DIR (out/sweeps)  --build DIR (build)
  --table FILE (docs/validation/shear_<sweep>.md)  --figure FILE (docs/figures/shear_<sweep>.png)
  --report  (no runs: only the table and figure from the runs in --runs)  --extra "OPTIONS" (to every run)
  --scene FILE  (viscosity only: another scene of scenes/ whose cell is the body 'membrane'; table and figure
                 get the scene's name: docs/validation/shear_viscosity_<scene>.md)
A run whose summary.json says "completed" is not run again. Exit code 3 when a run did not complete (it is in
the table with its status). Figures need python3-matplotlib (installed by
scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import concurrent.futures
import json
import os
import shlex
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import (ROOT, check_kept_runs, fmt, provenance, pyplot, run_one, save_figure,  # noqa: E402
                          write_table)

SWEEPS = {
    # name: scene, default values [cm], the option a value sets, the x quantity of the figure
    "swelling": ("capsule_shear.yaml", [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 5.5e-4], "membrane", "Delta"),
    "bulky": ("bulky_ellipse_shear.yaml", [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 5.5e-4], "body", "Delta"),
    "compound": ("compound_capsule_shear.yaml", [1e-5, 2e-5, 3e-5, 4e-5, 5e-5, 6e-5, 7e-5], "nucleus", "phi"),
    # the ratio lambda of the membrane's inner viscosity to the plasma's (the scene's 0.012 g/(cm s))
    "viscosity": ("capsule_shear.yaml", [1, 2, 3, 5, 8, 10], "membrane", "lambda"),
}
PLASMA_VISCOSITY = 0.012  # g/(cm s), scenes/capsule_shear.yaml


def value_options(sweep, v):
    if sweep == "viscosity":
        return ["-solid_membrane_inner_viscosity", f"{v * PLASMA_VISCOSITY:g}"]
    if sweep == "compound":
        return ["-solid_nucleus_semi_axes", f"{v:g},{v:g}"]
    body = SWEEPS[sweep][2]
    return [f"-solid_{body}_semi_axes", f"{v:g},1e-4"]


def scene_stem(args):
    """The --scene file's name without .yaml ("" for the sweep's own scene)."""
    return os.path.splitext(os.path.basename(args.scene))[0] if args.scene else ""


def runs_of(args):
    """(tag, scene, options) of every run of the sweep."""
    scene, values, _, _ = SWEEPS[args.sweep]
    scene = args.scene or scene
    nx, ny = args.mesh.split("x")
    common = ["-fluid_elements", f"{nx},{ny}", "-fluid_degree", str(args.degree), "-dt", str(args.dt),
              "-final_time", str(args.final_time), "-metrics_average_from", str(args.average_from),
              "-output_every", "0"] + shlex.split(args.extra)
    values = [float(v) for v in args.values.split(",")] if args.values else values
    name = args.sweep + (f"_{scene_stem(args)}" if args.scene else "")
    out = [(f"{name}_{args.mesh}_p{args.degree}_{v:g}", scene, value_options(args.sweep, v) + common)
           for v in values]
    if args.sweep == "swelling":  # the paper's red star: the biconcave capsule
        out.append((f"{args.sweep}_{args.mesh}_p{args.degree}_biconcave", "biconcave_capsule_shear.yaml", common))
    return out


def collect(args):
    rows = []
    for tag, scene, options in runs_of(args):
        path = os.path.join(args.runs, tag, "summary.json")
        if not os.path.isfile(path):
            continue
        with open(path) as f:
            s = json.load(f)
        s["_tag"], s["_scene"] = tag, scene
        rows.append(s)
    return rows


def write_sweep_table(args, rows, command):
    sweep = args.sweep
    lines = [provenance(args, command), ""]
    if sweep == "compound":
        lines += ["| r cm | phi | membrane theta deg | membrane omega_TT 1/s | membrane regime | nucleus omega_TU 1/s |"
                  " nucleus regime | steps | wall s | status |", "|---|---|---|---|---|---|---|---|---|---|"]
        for s in rows:
            lines.append(f"| {s['_tag'].rsplit('_', 1)[1]} | {fmt(s.get('nucleus_phi'), '.3f')} |"
                         f" {fmt(s.get('membrane_theta_deg'), '.2f')} | {fmt(s.get('membrane_omega_tt'), '.3f')} |"
                         f" {s.get('membrane_regime', '-')} | {fmt(s.get('nucleus_omega_tu'), '.3f')} |"
                         f" {s.get('nucleus_regime', '-')} | {s.get('steps')} | {fmt(s.get('wall_time_s'), '.0f')} |"
                         f" {s.get('status')} |")
    else:
        body = SWEEPS[sweep][2]
        first = "lambda" if sweep == "viscosity" else "a cm"
        lines += [f"| {first} | Delta | theta deg | omega_TT 1/s | omega_TU 1/s | half-turns | regime | steps | wall s |"
                  " status |", "|---|---|---|---|---|---|---|---|---|---|"]
        for s in rows:
            b = "membrane" if s["_scene"].startswith("biconcave") else body
            lines.append(f"| {s['_tag'].rsplit('_', 1)[1]} | {fmt(s.get(b + '_Delta'), '.3f')} |"
                         f" {fmt(s.get(b + '_theta_deg'), '.2f')} | {fmt(s.get(b + '_omega_tt'), '.3f')} |"
                         f" {fmt(s.get(b + '_omega_tu'), '.3f')} | {fmt(s.get(b + '_omega_tu_half_turns'), '.0f')} |"
                         f" {s.get(b + '_regime', '-')} | {s.get('steps')} | {fmt(s.get('wall_time_s'), '.0f')} |"
                         f" {s.get('status')} |")
    write_table(args.table, lines)


def write_figure(args, rows):
    plt = pyplot("run_shear_sweeps")
    if plt is None:
        return
    done = [s for s in rows if s.get("status") == "completed"]
    if not done:
        print("run_shear_sweeps: no completed runs: figure skipped", file=sys.stderr)
        return
    label = f"{args.mesh}, p = {args.degree}, dt = {args.dt:g} s"
    if args.sweep == "compound":
        xs = [s["nucleus_phi"] for s in done]
        panels = [("membrane_theta_deg", "membrane theta (deg)"), ("membrane_omega_tt", "membrane omega_TT (1/s)"),
                  ("nucleus_omega_tu", "nucleus omega_TU (1/s)")]
        fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
        for ax, (key, name) in zip(axes, panels):
            tt = [s.get("membrane_regime") == "tank-treading" for s in done]
            ax.plot(xs, [s.get(key) for s in done], "-", color="tab:red", lw=1)
            for x, s, t in zip(xs, done, tt):
                ax.plot(x, s.get(key), "o" if t else "x", color="tab:red", ms=6)
            ax.set_xlabel("filling fraction phi")
            ax.set_ylabel(name)
            ax.grid(True, lw=0.3)
        fig.suptitle(f"Compound capsules ({label}); x: membrane not tank-treading", fontsize=10)
    elif args.sweep == "viscosity":
        xs = [s.get("membrane_viscosity_ratio", 1.0) for s in done]
        panels = [("membrane_theta_deg", "theta (deg)"), ("membrane_omega_tt", "omega_TT (1/s)"),
                  ("membrane_omega_tu", "omega_TU (1/s)")]
        fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
        for ax, (key, name) in zip(axes, panels):
            # A tumbling capsule's mean inclination means nothing: theta only where the axis stays.
            pts = [(x, s) for x, s in zip(xs, done)
                   if key != "membrane_theta_deg" or s.get("membrane_regime") != "tumbling"]
            ax.plot([x for x, _ in pts], [s.get(key) for _, s in pts], "-", color="tab:blue", lw=1)
            for x, s in pts:
                ax.plot(x, s.get(key), "o" if s.get("membrane_regime") == "tank-treading" else "x",
                        color="tab:blue", ms=6)
            ax.set_xlabel("viscosity ratio lambda")
            ax.set_ylabel(name)
            ax.grid(True, lw=0.3)
        who = scene_stem(args).replace("_", " ") if args.scene else "The Sec. 3.3 capsule"
        fig.suptitle(f"{who} with an inner viscosity ({label}); x: not tank-treading", fontsize=10)
    else:
        body = SWEEPS[args.sweep][2]
        ell = [s for s in done if not s["_scene"].startswith("biconcave")]
        star = [s for s in done if s["_scene"].startswith("biconcave")]
        keys = ([("theta_deg", "theta (deg)"), ("omega_tt", "omega_TT (1/s)")] if args.sweep == "swelling"
                else [("omega_tu", "omega_TU (1/s)")])
        fig, axes = plt.subplots(1, len(keys), figsize=(5.5 * len(keys), 3.8), squeeze=False)
        for ax, (key, name) in zip(axes[0], keys):
            ax.plot([s[body + "_Delta"] for s in ell], [s.get(body + "_" + key) for s in ell], "o-",
                    color="tab:blue", label="ellipses")
            for s in star:
                ax.plot(s["membrane_Delta"], s.get("membrane_" + key), "*", color="tab:red", ms=14,
                        label="biconcave")
            ax.set_xlabel("swelling degree Delta")
            ax.set_ylabel(name)
            ax.grid(True, lw=0.3)
            ax.legend(fontsize=8)
        axes[0][0].set_title(("Capsules" if args.sweep == "swelling" else "Bulky ellipses") + f" ({label})",
                             fontsize=9)
    save_figure(fig, args.figure, "run_shear_sweeps")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("sweep", choices=sorted(SWEEPS))
    p.add_argument("--mesh", default="256x128")
    p.add_argument("--degree", type=int, default=3)
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--final-time", type=float, default=0.3)
    p.add_argument("--average-from", type=float, default=0.15)
    p.add_argument("--values", default="")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "sweeps"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default="")
    p.add_argument("--figure", default="")
    p.add_argument("--extra", default="")
    p.add_argument("--report", action="store_true")
    p.add_argument("--scene", default="")
    args = p.parse_args()
    if "x" not in args.mesh:
        p.error(f"--mesh {args.mesh} is invalid; valid: NXxNY, e.g. 256x128")
    if args.scene and (args.sweep != "viscosity" or not os.path.isfile(os.path.join(ROOT, "scenes", args.scene))):
        p.error(f"--scene {args.scene} is invalid; valid: with the viscosity sweep, a 2D shear scene file of "
                "scenes/ whose cell is the body 'membrane', e.g. biconcave_capsule_shear.yaml")
    suffix = f"_{scene_stem(args)}" if args.scene else ""
    args.table = args.table or os.path.join(ROOT, "docs", "validation", f"shear_{args.sweep}{suffix}.md")
    args.figure = args.figure or os.path.join(ROOT, "docs", "figures", f"shear_{args.sweep}{suffix}.png")
    exe = os.path.join(args.build, "apps", "cellfsi")
    if not args.report and not os.access(exe, os.X_OK):
        sys.exit(f"run_shear_sweeps: {exe} not found; build first (scripts/build.sh)")
    os.makedirs(args.runs, exist_ok=True)
    command = "bench/run_shear_sweeps.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    check_kept_runs("run_shear_sweeps", args, runs_of(args))
    if not args.report:
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            for tag, how in pool.map(lambda r: run_one(args, *r), runs_of(args)):
                print(f"run_shear_sweeps: {tag}: {how}", flush=True)
    rows = collect(args)
    write_sweep_table(args, rows, command)
    write_figure(args, rows)
    missing = len(runs_of(args)) - sum(1 for s in rows if s.get("status") == "completed")
    if missing:
        print(f"run_shear_sweeps: {missing} run(s) did not complete (see the table and the .log files in "
              f"{args.runs})", file=sys.stderr)
        sys.exit(3)


if __name__ == "__main__":
    main()
