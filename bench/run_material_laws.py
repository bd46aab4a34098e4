#!/usr/bin/env python3
"""The membrane laws compared in flow (issue 28, item 2; docs/materials.md): the paper's capsule in shear
(scenes/capsule_shear.yaml, Sec. 3.3) and, with --channel, its six-RBC channel (scenes/rbc_channel.yaml, Sec. 4.1),
each run once per law at the same small-strain shear modulus G. Writes a markdown table (theta, omega_TT, r_P, the
largest stretch; zeta and eta for the channel) and a figure of theta and r_P against time.

    python3 bench/run_material_laws.py                       # capsule, G = 7500 and 750, every law
    python3 bench/run_material_laws.py --channel             # and the six-RBC channel at G = 7500

Options: --mesh NXxNY (128x64, cubic) --dt S (1e-3) --final-time S (0.5) --average-from S (0.25)
  --moduli G,G (7500,750) --channel-mesh NXxNY (96x32) --channel-final-time S (0.4) --jobs N (1)
  --runs DIR (out/material_laws) --build DIR (build) --table FILE (docs/validation/material_laws.md)
  --figure FILE (docs/figures/material_laws.png) --report (no runs: the table and figure from --runs)
A run whose summary.json says "completed" is not run again. Exit code 3 when a run did not complete."""
import argparse
import concurrent.futures
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_common  # noqa: E402
from bench_common import (ROOT, check_kept_runs, fmt, provenance, pyplot, run_one, save_figure,  # noqa: E402
                          summary_of, write_table)

TOOL = "run_material_laws.py"
# name in the table: the body's options (the body is "membrane" in the capsule, "rbc" in the channel)
LAWS = [
    ("neo_hookean", ["material", "neo_hookean"]),
    ("mooney_rivlin (a = 0.5)", ["material", "mooney_rivlin"]),
    ("strain_hardening (C3 = G/30)", ["material", "strain_hardening"]),
    ("strain_hardening (C3 = G)", ["material", "strain_hardening", "hardening_c3", "1"]),
]


def law_options(body, words):
    return [w if i % 2 else f"-solid_{body}_{w}" for i, w in enumerate(words)]


def mesh_of(text, what):
    return bench_common.mesh_of(TOOL, text, what)


def runs_of(args):
    """(tag, scene, options, row label fields) of every run."""
    out = []
    nx, ny = mesh_of(args.mesh, "--mesh")
    common = ["-fluid_elements", f"{nx},{ny}", "-fluid_degree", "3", "-dt", str(args.dt), "-final_time",
              str(args.final_time), "-metrics_average_from", str(args.average_from), "-output_every", "0",
              "-solid_membrane_elements", "1,0"]
    for g in args.moduli:
        for i, (name, words) in enumerate(LAWS):
            out.append((f"capsule_{args.mesh}_G{g:g}_law{i}", "capsule_shear.yaml",
                        common + ["-solid_membrane_shear_modulus", f"{g:g}"] + law_options("membrane", words),
                        ("capsule", name, g)))
    if args.channel:
        cx, cy = mesh_of(args.channel_mesh, "--channel-mesh")
        for i, (name, words) in enumerate(LAWS):
            if words[1] == "mooney_rivlin":
                continue  # the neo-Hookean law in 2D (docs/materials.md): no run of its own
            out.append((f"channel_{args.channel_mesh}_law{i}", "rbc_channel.yaml",
                        ["-fluid_elements", f"{cx},{cy}", "-dt", "5e-4", "-final_time", str(args.channel_final_time),
                         "-metrics_average_from", str(args.channel_final_time / 2), "-output_every", "0",
                         "-solid_rbc_elements", "1,0"] + law_options("rbc", words),
                        ("channel", name, 7500.0)))
    return out


def series(args, tag, key):
    """(time, value) of a metrics.csv column."""
    try:
        with open(os.path.join(args.runs, tag, "metrics.csv")) as f:
            rows = list(csv.DictReader(f))
    except OSError:
        return [], []
    t = [float(r["time"]) for r in rows if r.get(key) not in (None, "", "nan")]
    v = [float(r[key]) for r in rows if r.get(key) not in (None, "", "nan")]
    return t, v


def table(args, runs, command):
    lines = [provenance(args, command), "",
             "| case | law | G dyn/cm^2 | Ca | theta deg | omega_TT 1/s | r_P (end) | max stretch | zeta | eta | "
             "coupling it./step | wall s | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    complete = True
    for tag, _, _, (case, name, g) in runs:
        s = summary_of(args, tag)
        if s is None:
            lines.append(f"| {case} | {name} | {g:g} | - | - | - | - | - | - | - | - | - | not run |")
            complete = False
            continue
        complete = complete and s.get("status") == "completed"
        if case == "capsule":
            b, theta, omega = "membrane", s.get("membrane_theta_deg"), s.get("membrane_omega_tt")
            stretch, r_p, ca = s.get("membrane_max_stretch"), s.get("membrane_r_P"), s.get("membrane_Ca")
            zeta = eta = None
        else:  # six cells rbc_0 ... rbc_5: the largest stretch of any, the mean theta
            cells = [k[:-len("_max_stretch")] for k in s if k.endswith("_max_stretch")]
            stretch = max((s[c + "_max_stretch"] for c in cells), default=None)
            r_p = max((abs(s.get(c + "_r_P", 0.0)) for c in cells), default=None)
            thetas = [s[c + "_theta_deg"] for c in cells if c + "_theta_deg" in s]
            theta = sum(thetas) / len(thetas) if thetas else None
            omega, ca, zeta, eta = None, None, s.get("zeta"), s.get("eta")
        steps = max(1, s.get("steps", 1))
        lines.append(f"| {case} | {name} | {g:g} | {fmt(ca, '.3f')} | {fmt(theta, '.3f')} | {fmt(omega, '.4f')} | "
                     f"{fmt(r_p, '.5f')} | {fmt(stretch, '.4f')} | {fmt(zeta, '.4f')} | {fmt(eta, '.4f')} | "
                     f"{s.get('coupling_iterations', 0) / steps:.2f} | {fmt(s.get('wall_time_s'), '.0f')} | "
                     f"{s.get('status')} |")
    write_table(args.table, lines)
    return complete


def figure(args, runs):
    plt = pyplot(TOOL)
    if plt is None:
        return
    capsule = [r for r in runs if r[3][0] == "capsule"]
    moduli = sorted({r[3][2] for r in capsule}, reverse=True)
    fig, axes = plt.subplots(2, len(moduli), figsize=(5.2 * len(moduli), 6.4), squeeze=False)
    for j, g in enumerate(moduli):
        for tag, _, _, (_, name, gg) in capsule:
            if gg != g:
                continue
            for i, key in enumerate(["membrane_theta_deg", "membrane_r_P"]):
                t, v = series(args, tag, key)
                axes[i][j].plot(t, v, label=name, lw=1.2, ls="--" if "mooney" in name else "-")
        axes[0][j].set_title(f"capsule in shear, G = {g:g} dyn/cm$^2$")
        axes[0][j].set_ylabel("theta (deg)")
        axes[1][j].set_ylabel("r_P (perimeter change)")
        axes[1][j].set_xlabel("t (s)")
        axes[0][j].legend(fontsize=7)
    save_figure(fig, args.figure, TOOL)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--mesh", default="128x64")
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--final-time", type=float, default=0.5)
    p.add_argument("--average-from", type=float, default=0.25)
    p.add_argument("--moduli", default="7500,750")
    p.add_argument("--channel", action="store_true")
    p.add_argument("--channel-mesh", default="96x32")
    p.add_argument("--channel-final-time", type=float, default=0.4)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "material_laws"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "material_laws.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "material_laws.png"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    try:
        args.moduli = [float(v) for v in args.moduli.split(",")]
        if not args.moduli or min(args.moduli) <= 0:
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --moduli '{args.moduli}' is invalid: give shear moduli > 0, comma-separated (e.g. 7500,750)")
    runs = runs_of(args)
    os.makedirs(args.runs, exist_ok=True)
    check_kept_runs(TOOL, args, [(tag, scene, options) for tag, scene, options, _ in runs])
    if not args.report:
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            for tag, status in pool.map(lambda r: run_one(args, r[0], r[1], r[2]), runs):
                print(f"{TOOL}: {tag}: {status}", flush=True)
    complete = table(args, runs, "python3 bench/run_material_laws.py " + " ".join(sys.argv[1:]))
    figure(args, runs)
    sys.exit(0 if complete else 3)


if __name__ == "__main__":
    main()
