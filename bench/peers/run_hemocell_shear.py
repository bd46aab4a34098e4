#!/usr/bin/env python3
"""Side by side with HemoCell in shear (issue 47, item 4; bench/peers/README.md): one red cell in Couette flow for
5 ms in HemoCell's examples/oneCellShear and in cellfsi, in a box of the same size, each run on one core of this
machine: the cell's bounding box (its "diameters") and deformation index over time, the wall time and the peak
memory.

    python3 bench/peers/run_hemocell_shear.py --hemocell out/peers/hemocell --meshes 27x13x27,40x19x40

HemoCell runs its example as shipped: a 20 x 20 x 10 um lattice (dx 0.5 um, dt 5e-8 s, 100000 steps = 5 ms),
periodic in x and y, walls at z moving at -+ 111 1/s x 9.5 um / 2 (the walls on the first and last lattice
nodes), its own red-cell model (area 129 um^2, volume 81 um^3), the cell's centre 4.5 um above the lower wall and
its axis along z (the velocity gradient): the disc lies in the flow-vorticity plane. Its bounding box and its
deformation index ((L/D0)^2 - 1) / ((L/D0)^2 + 1), L its largest vertex-to-vertex distance and D0 = 7.82 um,
every 0.1 ms (its stretch.log).

cellfsi runs scenes/rbc_shear_3d.yaml in the same box with its axes renamed (x flow, y gradient with the walls
9.5 um apart, z vorticity; periodic in x and z, so that the Fourier bulk solver applies), the shear rate 111 1/s
(the walls move the other way round: the mirror image, the same diameters), the Evans-Fung cell (134 um^2, 94
um^3) 4.5 um above the lower wall with its axis along y, the Skalak membrane at the G h fitted to Mills' D_A
(3.38 uN/m, bench/peers/run_hemocell_side_by_side.py), dt 2.5e-4 s, on each of --meshes (quadratic elements).
Its bounding box: the mid-surface's extent (metrics.csv rbc_extent_x/y/z); its deformation index the same formula
with L the bounding box's largest side (HemoCell's own, from the bounding box, is given too).

Options: --hemocell DIR (out/peers/hemocell; bench/peers/build_hemocell.sh builds it) --meshes NXxNYxNZ,...
(27x13x27,40x19x40) --runs DIR (out/peers/shear) --build DIR (build) --table FILE
(docs/validation/hemocell_shear.md) --figure FILE (docs/figures/hemocell_shear.png; none: no figure) --report
(no runs). A run whose result is kept is not run again."""
import argparse
import csv
import json
import os
import re
import shlex
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)
from bench_common import ROOT, fmt, provenance, pyplot, save_figure, write_table  # noqa: E402
from run_hemocell_side_by_side import (FITTED_GH, THICKNESS, fresh_example, kept_or_none, mpi_env,  # noqa: E402
                                        run_timed_cellfsi, timed)

TOOL = "run_hemocell_shear.py"
D0 = 7.82  # um, HemoCell's reference diameter
SHEAR_RATE = 111.0
FINAL_TIME = 5e-3
DT = 2.5e-4
LAW = "skalak"
REPORT_MS = [1, 2, 3, 4, 5]


def deformation_index(largest):
    r2 = (largest / D0) ** 2
    return 100 * (r2 - 1) / (r2 + 1)


def run_hemocell(args):
    """HemoCell's oneCellShear as shipped in its own folder: its result dict (kept in result.json)."""
    folder = os.path.join(args.runs, "hemocell")
    kept = os.path.join(folder, "result.json")
    done, result = kept_or_none(kept, args)
    if done:
        return result
    exe = fresh_example(args, "oneCellShear", folder, ("RBC.pos", "RBC.xml", "config.xml"))
    rc, wall, mb = timed([exe, "config.xml"], folder, os.path.join(folder, "run.log"), mpi_env())
    log = os.path.join(folder, "stretch.log")  # the example's name for its record
    series = []
    if os.path.isfile(log):
        for line in open(log):
            w = line.split()
            if len(w) >= 8:  # iteration, box x y z, volume %, area %, largest diameter, deformation index %
                series.append({"t_ms": int(w[0]) * 5e-5, "flow": float(w[1]), "vorticity": float(w[2]),
                               "gradient": float(w[3]), "own_di": float(w[7])})
    result = {"code": "HemoCell v2.7", "exit": rc, "wall_s": wall, "peak_MB": mb, "series": series,
              "status": "completed" if rc == 0 and series else f"exit {rc}, {len(series)} records"}
    if rc == 0 and series:
        json.dump(result, open(kept, "w"), indent=1)
    return result


def run_cellfsi(args, mesh):
    """cellfsi in HemoCell's box on mesh NXxNYxNZ: its result dict."""
    tag = f"cellfsi_{mesh}"
    folder = os.path.join(args.runs, tag)
    kept = os.path.join(args.runs, tag + ".json")
    done, result = kept_or_none(kept, args)
    if done:
        return result
    G = FITTED_GH[LAW] * 1e-3 / THICKNESS  # uN/m = 1e-3 dyn/cm
    cmd = [os.path.join(args.build, "apps", "cellfsi"), os.path.join(ROOT, "scenes", "rbc_shear_3d.yaml"),
           "-output_dir", folder, "-output_every", "4", "-domain_size", "0.0020,0.00095,0.0020",
           "-fluid_elements", mesh.replace("x", ","), "-shear_rate", f"{SHEAR_RATE:g}",
           "-solid_rbc_center", "0.0010,0.00045,0.0010", "-solid_rbc_axis", "1,0,0", "-solid_rbc_angle", "90",
           "-solid_rbc_material", LAW, "-solid_rbc_shear_modulus", f"{G:.6g}", "-dt", f"{DT:g}",
           "-final_time", f"{FINAL_TIME:g}"]
    rc, wall, mb, s = run_timed_cellfsi(cmd, os.path.join(args.runs, tag + ".log"))
    try:
        rows = list(csv.DictReader(open(os.path.join(folder, "metrics.csv"))))
    except (OSError, ValueError):
        rows = []
    series = [{"t_ms": float(r["time"]) * 1e3, "flow": float(r["rbc_extent_x"]) * 1e4,
               "gradient": float(r["rbc_extent_y"]) * 1e4, "vorticity": float(r["rbc_extent_z"]) * 1e4}
              for r in rows if "rbc_extent_x" in r]
    result = {"code": f"cellfsi {mesh}", "exit": rc, "wall_s": wall, "peak_MB": mb, "series": series,
              "steps": s.get("steps"), "status": s.get("status"), "max_abs_r_A": s.get("rbc_max_abs_r_A")}
    if rc == 0 and s.get("status") == "completed" and series:
        json.dump(result, open(kept, "w"), indent=1)
    return result


def at(series, t_ms):
    """The record at t_ms (to 1e-6 ms), or None."""
    for r in series:
        if abs(r["t_ms"] - t_ms) < 1e-6:
            return r
    return None


def figure(results, path):
    plt = pyplot(TOOL)
    if plt is None:
        return
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for ax, key, name in zip(axes, ("flow", "gradient", "vorticity"),
                             ("along the flow", "along the velocity gradient", "along the vorticity")):
        for r in results:
            if r and r["series"]:
                ax.plot([p["t_ms"] for p in r["series"]], [p[key] for p in r["series"]],
                        "-" if r["code"].startswith("HemoCell") else "o-", ms=3, label=r["code"])
        ax.set_xlabel("t ms")
        ax.set_ylabel("bounding box um")
        ax.set_title(name)
    axes[0].legend(fontsize=8)
    save_figure(fig, path, TOOL)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--hemocell", default=os.path.join(ROOT, "out", "peers", "hemocell"))
    p.add_argument("--meshes", default="27x13x27,40x19x40")
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "peers", "shear"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "hemocell_shear.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "hemocell_shear.png"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    args.hemocell, args.runs, args.build, args.table = (os.path.abspath(x) for x in
                                                        (args.hemocell, args.runs, args.build, args.table))
    meshes = [m for m in args.meshes.split(",") if m]
    if not meshes or not all(re.fullmatch(r"[1-9]\d*x[1-9]\d*x[1-9]\d*", m) for m in meshes):
        sys.exit(f"{TOOL}: --meshes '{args.meshes}' is invalid: give NXxNYxNZ, comma-separated (e.g. 27x13x27)")
    os.makedirs(args.runs, exist_ok=True)
    results = [run_hemocell(args)]
    print(f"{TOOL}: HemoCell: {results[0] and results[0]['status']}", flush=True)
    for mesh in meshes:
        results.append(run_cellfsi(args, mesh))
        print(f"{TOOL}: cellfsi {mesh}: {results[-1] and results[-1]['status']}", flush=True)
    command = "python3 bench/peers/" + TOOL + " " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    args.jobs = 1
    lines = [provenance(args, command), "",
             "One red cell in Couette flow at 111 1/s for 5 ms, the box 20 um along the flow and the vorticity "
             "(periodic) and 9.5 um between the walls. HemoCell: its oneCellShear example as shipped (dx 0.5 um, "
             "dt 5e-8 s). cellfsi: scenes/rbc_shear_3d.yaml in that box, Skalak membrane at G h "
             f"{FITTED_GH[LAW]} uN/m, dt {DT:g} s, quadratic elements per row. Bounding box sides in um; DI: "
             "((L/D0)^2 - 1)/((L/D0)^2 + 1) in %, D0 = 7.82 um, L the box's largest side (HemoCell's own DI, "
             "from its largest vertex distance, in brackets).", "",
             "| t ms | code | flow | gradient | vorticity | DI % | gradient - HemoCell | vorticity - HemoCell |",
             "|---|---|---|---|---|---|---|---|"]
    hemo = results[0]["series"] if results[0] else []
    for t in REPORT_MS:
        h = at(hemo, t)
        for r in results:
            if not r:
                continue
            x = at(r["series"], t)
            if not x:
                continue
            di = deformation_index(max(x["flow"], x["gradient"], x["vorticity"]))
            own = f" ({x['own_di']:.3f})" if "own_di" in x else ""
            dg = fmt(x["gradient"] - h["gradient"], "+.3f") if h else "-"
            dv = fmt(x["vorticity"] - h["vorticity"], "+.3f") if h else "-"
            lines.append(f"| {t:g} | {r['code']} | {x['flow']:.3f} | {x['gradient']:.3f} | {x['vorticity']:.3f} | "
                         f"{di:.3f}{own} | {dg} | {dv} |")
    lines += ["", "| code | steps | wall s | peak MB | max abs r_A | status |", "|---|---|---|---|---|---|"]
    for r in results:
        if r:
            hemocell = r["code"].startswith("HemoCell")
            steps = (100000 if r.get("exit") == 0 else None) if hemocell else r.get("steps")
            lines.append(f"| {r['code']} | {fmt(steps, 'd')} | {fmt(r.get('wall_s'), '.0f')} | "
                         f"{fmt(r.get('peak_MB'), '.0f')} | {fmt(r.get('max_abs_r_A'), '.1e')} | "
                         f"{r.get('status') or ('exit ' + str(r.get('exit')))} |")
    write_table(args.table, lines)
    if args.figure != "none" and any(r and r["series"] for r in results):
        figure(results, args.figure)


if __name__ == "__main__":
    main()
