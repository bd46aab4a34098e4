#!/usr/bin/env python3
"""Sorting by inertia (scenes/inertial_migration.yaml): a neutrally buoyant stiff disk of diameter W / 4 in a
plane channel of width W, periodic with period W, starting 0.4 W above the lower wall, at several channel Reynolds
numbers and meshes (the rigid limit, against Pan & Glowinski 2002 at the same blockage and period); and capsules
of the same size at capillary numbers Ca = mu gammadot_w a / (G h) (gammadot_w = 6 u / W, the plasma's wall shear
rate; a = W / 8, h = a / 400, the paper's capsule's ratio). Per run: where the body settles (its centre's
distance from the nearer wall over W, averaged over the last tenth of the run), the drift left there, when it came
within 1 % of W of it, its largest deformation, the Reynolds number measured with it, and the cost. Writes a table
and a figure: the trajectories (y / W against the distance travelled x / W) and, with capsules, y_eq / W against
Ca.

--cells chooses the deformable bodies at each Ca: "capsule" (the circle of radius a = W / 8 above), "rbc" (the
scenes' 2D red cell, its long axis along the flow: area 1.2868e-7 cm^2, a = its equivalent radius 2.02 um, 7.6 um
long, h = 5e-7 cm) and "ctc" (the compound capsule of scenes/ctc_narrowing.yaml: the capsule above with a bulky
nucleus of radius 0.4 a whose G is 4 G h / a, the CTC scene's ratio). Ca = mu gammadot_w a / (G h) with each
body's own a and h. The table then gives, per Reynolds number, mesh and Ca, the separation of the settled bodies.

    python3 bench/run_inertial_migration.py                         # Re 13.91, 30.25, 106.1 on 32x32 and 64x64
    python3 bench/run_inertial_migration.py --reynolds 13.91 --meshes 32x32 --jobs 2
    python3 bench/run_inertial_migration.py --meshes 128x128 --starts 0.3,0.25 --travel 10 --cfl 2 --jobs 2
    python3 bench/run_inertial_migration.py --ca 0,0.05,0.2 --reynolds 13.91,106.1 --jobs 2
    python3 bench/run_inertial_migration.py --ca 0.05,0.2 --cells rbc,ctc --reynolds 13.91 --jobs 2
    python3 bench/run_inertial_migration.py --report                # only the table and figure, from --runs

Options: --reynolds RE,... (the plasma's rho u H / mu with u = f H^2 / (12 mu); 13.91,30.25,106.1, the forcing of
the three reference runs) --meshes NXxNY,... (32x32,64x64) --cfl C (2: dt = C h / u_max of the plasma, 3
significant digits; 1 moves the position by 4e-4 W) --travel N (30: run until the plasma's mean velocity has gone
N widths) --starts Y,... (0.4:
the disk's start, its centre's height over W; two starts on either side of the equilibrium bracket it in a short
run) --ca CA,... (0: the stiff disk; above 0, capsules at those capillary numbers) --cells KIND,... (capsule;
also rbc, ctc) --extra "OPTIONS"
--jobs N (1) --runs DIR (out/inertial_migration) --build DIR (build) --table FILE
(docs/validation/inertial_migration.md) --figure FILE (docs/figures/inertial_migration.png). A run whose
summary.json says "completed" with the same options is kept. Exit code 3 when a run did not complete."""
import argparse
import concurrent.futures
import csv
import math
import os
import re
import shlex
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_common  # noqa: E402
from bench_common import ROOT, check_kept_runs, fmt, provenance, run_one, summary_of, write_table  # noqa: E402

TOOL = "run_inertial_migration.py"
SCENE = "inertial_migration.yaml"
# Pan & Glowinski, J. Comput. Phys. 181 (2002) 260-279: d / W = 0.25, the disk's centre settles at y / W from
# the nearer wall, for Re = rho u W / mu with u the mean velocity with the particle (12.78, 27.73, 96.74; the
# forcing of each gives 13.91, 30.25, 106.1 for the plasma alone). Read from the digitised reference of the
# replication in github.com/fradevita/FEN (test/small_test/fsi/Pan_Eulerian) and, for 96.74, a second
# digitisation in github.com/NaokiHori/EllipsesInFlows (0.27231). Inamuro, Maeba & Ogino, Int. J. Multiphase
# Flow 26 (2000), Table 2: 0.2745 at Re about 13 (a rough estimate, as quoted by waLBerla's Segre-Silberberg
# test).
REFERENCES = [(12.78, 0.2732), (27.73, 0.2725), (96.74, 0.2722)]
CELLS = ("capsule", "rbc", "ctc")
# The body's start along the flow, cm: any x serves (the channel is periodic along x); every run so far started
# here.
X_START = 0.0016
RBC_AREA = 1.2868e-7  # geometry/builders.hpp kRbcArea2d
CELL_NAMES = {"capsule": "capsule", "rbc": "red cell", "ctc": "CTC"}


def cell_options(cell, ca, width, mu, u, centre):
    """The options that make the scene's body a deformable cell of kind `cell` at capillary number `ca`."""
    shear = mu * 6 * u / width  # the plasma's wall shear rate times mu
    if cell == "rbc":
        a, h = math.sqrt(RBC_AREA / math.pi), 5e-7
        return ["-solid_disk_shape", "rbc", "-solid_disk_thickness", f"{h:.6g}", "-solid_disk_elements", "1,0",
                "-solid_disk_angle", "0", "-solid_disk_shear_modulus", f"{shear * a / (ca * h):.6g}"]
    a, h = width / 8, width / 3200
    g = shear * a / (ca * h)
    options = ["-solid_disk_shape", "hollow_ellipse", "-solid_disk_thickness", f"{h:.6g}", "-solid_disk_elements",
               "1,0", "-solid_disk_shear_modulus", f"{g:.6g}"]
    if cell == "ctc":
        options += ["-solid_bodies", "disk,nucleus", "-solid_nucleus_shape", "ellipse", "-solid_nucleus_semi_axes",
                    f"{0.4 * a:.6g},{0.4 * a:.6g}", "-solid_nucleus_center", centre, "-solid_nucleus_elements", "0,0",
                    "-solid_nucleus_shear_modulus", f"{4 * g * h / a:.6g}", "-solid_nucleus_density", "1.025"]
    return options


def scene_numbers():
    """W [cm], density and viscosity from the scene file ('key: value' lines)."""
    text = open(os.path.join(ROOT, "scenes", SCENE)).read()

    def value(key):
        m = re.search(rf"^\s*{key}:\s*(\S+)", text, re.M)
        if not m:
            sys.exit(f"{TOOL}: scenes/{SCENE} has no '{key}:'")
        return [float(v) for v in m.group(1).split(",")]

    return value("domain_size")[1], value("density")[0], value("viscosity")[0]


def trajectory(path, width):
    """(x / W travelled, distance from the lower wall / W) of the disk's centroid from metrics.csv."""
    out = []
    with open(path) as f:
        for r in csv.DictReader(f):
            out.append((float(r["disk_centroid_x"]) / width, float(r["disk_centroid_y"]) / width))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--reynolds", default="13.91,30.25,106.1")
    p.add_argument("--meshes", default="32x32,64x64")
    p.add_argument("--cfl", type=float, default=2.0)
    p.add_argument("--travel", type=float, default=30.0)
    p.add_argument("--starts", default="0.4")
    p.add_argument("--ca", default="0")
    p.add_argument("--cells", default="capsule")
    p.add_argument("--extra", default="")
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "inertial_migration"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "inertial_migration.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "inertial_migration.png"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    try:
        reynolds = [float(v) for v in args.reynolds.split(",")]
        if not all(0 < r <= 1000 for r in reynolds):
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --reynolds '{args.reynolds}' is invalid: give plasma Reynolds numbers in (0, 1000], "
                 "e.g. 13.91,30.25")
    if not (0 < args.cfl <= 10):
        sys.exit(f"{TOOL}: --cfl {args.cfl} is invalid: give 0 < C <= 10")
    if not (0 < args.travel <= 1000):
        sys.exit(f"{TOOL}: --travel {args.travel} is invalid: give 0 < N <= 1000 channel widths")
    if args.jobs < 1:
        sys.exit(f"{TOOL}: --jobs {args.jobs} is invalid: give 1 or more")
    try:
        starts = [float(v) for v in args.starts.split(",")]
        if not all(0.15 < y < 0.85 for y in starts):
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --starts '{args.starts}' is invalid: give heights over W in (0.15, 0.85), e.g. 0.3,0.25 "
                 "(the disk of diameter W / 4 must clear the walls)")
    try:
        cas = [float(v) for v in args.ca.split(",")]
        if not all(0 <= c <= 10 for c in cas):
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --ca '{args.ca}' is invalid: give capillary numbers in [0, 10] (0: the stiff disk), "
                 "e.g. 0,0.05,0.2")
    cells = list(dict.fromkeys(args.cells.split(",")))  # (each kind once)
    if not cells or any(c not in CELLS for c in cells):
        sys.exit(f"{TOOL}: --cells '{args.cells}' is invalid: give a list of {', '.join(CELLS)}, e.g. rbc,ctc")
    meshes = [bench_common.mesh_of(TOOL, m, "--meshes") for m in args.meshes.split(",")]
    width, rho, mu = scene_numbers()
    extra = shlex.split(args.extra)
    runs = []
    for re_p in reynolds:
        u = re_p * mu / (rho * width)  # the plasma's mean velocity
        force = 12 * mu * u / width ** 2
        kinds = [(c, k) for c in cas for k in (cells if c > 0 else ["disk"])]
        for (nx, ny), y0, (ca, cell) in ((m, y, c) for c in kinds for m in meshes for y in starts):
            dt = float(f"{args.cfl * width / ny / (1.5 * u):.3g}")
            steps = math.ceil(args.travel * width / u / dt)
            centre = f"{X_START:g},{y0 * width:.6g}"
            options = ["-fluid_elements", f"{nx},{ny}", "-fluid_body_force", f"{force:.6g},0", "-dt", repr(dt),
                       "-final_time", f"{steps * dt:.10g}", "-output_every", "0", "-solid_disk_center", centre]
            if ca > 0:
                options += cell_options(cell, ca, width, mu, u, centre)
            tag = f"re{re_p:g}_{nx}x{ny}" + (f"_y{y0:g}" if y0 != 0.4 else "") + (f"_ca{ca:g}" if ca > 0 else "") + (
                f"_{cell}" if cell in ("rbc", "ctc") else "")
            runs.append((tag, re_p, nx, dt, y0, ca, cell, options + extra))
    os.makedirs(args.runs, exist_ok=True)
    check_kept_runs(TOOL, args, [(tag, SCENE, o) for tag, *_, o in runs])
    if not args.report:
        with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
            for tag, status in pool.map(lambda r: run_one(args, r[0], SCENE, r[7]), runs):
                print(f"{TOOL}: {tag}: {status}")

    rows, curves, points, ends, failed = [], [], [], [], False
    for tag, re_p, nx, dt, y0, ca, cell, _ in runs:
        mesh = tag.split("_")[1]
        body = f"{CELL_NAMES[cell]} Ca {ca:g}" if ca > 0 else "stiff disk"
        js = summary_of(args, tag)
        metrics = os.path.join(args.runs, tag, "metrics.csv")
        if js is None or not os.path.isfile(metrics):
            rows.append(f"| {re_p:g} | {body} | {mesh} | {y0:g} | - | - | - | - | - | - | - | - | - | no run |")
            failed = True
            continue
        traj = trajectory(metrics, width)
        curves.append((tag, traj))
        # Where it went over the second half of the run (a body that tumbles wanders about a band): the distance
        # from the nearer wall over W, its mean and range.
        half = [min(y, 1 - y) for _, y in traj[len(traj) // 2:]]
        band = f"{sum(half) / len(half):.3f} ({min(half):.3f}-{max(half):.3f})" if half else "-"
        steps = js.get("steps") or 0
        status = js.get("status", "?")
        failed = failed or status != "completed"
        u = re_p * mu / (rho * width)  # this run's plasma mean velocity
        settle = js.get("disk_lateral_settle_time")
        # The drift's sign away from the nearer wall: the offset from the centre line grows toward the wall.
        offset = js.get("disk_lateral_offset_equilibrium") or 0.0
        away = -1.0 if offset > 0 else 1.0
        drift = js.get("disk_lateral_drift_final")
        drift_u = away * drift / u if drift is not None else None
        # Settled: within 1 % of W for good and drifting less than 2e-4 W per width travelled.
        settled = settle * u / width if settle is not None and drift_u is not None and abs(drift_u) <= 2e-4 else None
        if status == "completed":
            points.append((re_p, mesh, ca, cell, js.get("disk_wall_distance_over_height")))
            ends.append((re_p, mesh, ca, cell, js.get("disk_wall_distance_over_height"), drift_u))
        rows.append(
            f"| {re_p:g} | {body} | {mesh} | {y0:g} | {fmt(js.get('channel_reynolds'), '.2f')} | {dt:.3g} | "
            f"{fmt(js.get('disk_wall_distance_over_height'), '.4f')} | {fmt(drift_u, '.1e')} | "
            f"{fmt(settled, '.1f') if settled is not None else 'drifting'} | {band} | "
            f"{fmt(js.get('disk_max_anisotropy'), '.3f')} | "
            f"{fmt(js.get('coupling_iterations', 0) / steps if steps else None, '.2f')} | "
            f"{fmt(js.get('wall_time_s', 0) / steps if steps else None, '.3f')} | {status} |")
    # Runs of one case from both sides of the equilibrium, still drifting toward it: where the drift,
    # interpolated linearly in y, vanishes.
    brackets = []
    for case in sorted({e[:4] for e in ends}):
        pts = sorted((y, d) for *c, y, d in ends if tuple(c) == case and y is not None and d is not None)
        for (y0, d0), (y1, d1) in zip(pts, pts[1:]):
            if d0 > 0 > d1:
                re_p, mesh, ca, cell = case
                body = f"{CELL_NAMES[cell]} Ca {ca:g}" if ca else "stiff disk"
                brackets.append(f"Re {re_p:g} (plasma), {mesh}, {body}: "
                                f"between {y0:.4f} and {y1:.4f}, zero drift at {y0 + (y1 - y0) * d0 / (d0 - d1):.4f}")
    # Sorting: at one Reynolds number, mesh and Ca, how far apart the different bodies settle (from start 0.4 W).
    separations = []
    for re_p, mesh, ca in sorted({(r, m, c) for r, m, c, _, _ in points if c > 0}):
        settled = {k: y for r, m, c, k, y in points if (r, m, c) == (re_p, mesh, ca) and y is not None}
        if len(settled) > 1:
            parts = ", ".join(f"{CELL_NAMES[k]} {settled[k]:.4f}" for k in CELLS if k in settled)
            separations.append(f"Re {re_p:g}, {mesh}, Ca {ca:g}: {parts}, apart "
                               f"{max(settled.values()) - min(settled.values()):.4f}")
    lines = ["| Re (plasma) | body | mesh | start y / W | Re (measured) | dt (s) | y_eq / W | drift / u | "
             "settled after (W travelled) | second half: mean (range) | largest anisotropy | coupling it./step | "
             "s/step | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"] + rows + [
        "", "Reference (Pan & Glowinski 2002, d / W = 0.25, period W, start 0.4 W): " +
        ", ".join(f"y_eq / W = {y} at Re {r}" for r, y in REFERENCES) +
        "; Inamuro et al. (2000): 0.2745 at Re about 13.", ""] + (
        ["Bracketed (y_eq / W): " + "; ".join(brackets) + ".", ""] if brackets else []) + (
        ["Separation of the settled bodies (y_eq / W, the distance between them over W): " + "; ".join(separations) +
         ".", ""] if separations else []) + [
        f"y_eq / W: the disk's centre from the nearer wall over W, mean over the last tenth of the run; drift / u: "
        f"its lateral velocity there over the plasma's mean velocity u (signed: > 0 away from the nearer wall; a "
        f"run that ends still drifting brackets the equilibrium with one from the other side); settled: within 1 % "
        f"of W of y_eq for good and drifting by less than 2e-4 W per width travelled, "
        f"as u times that time over W (one width of travel takes " +
        ", ".join(f"{width / (r * mu / (rho * width)) * 1e6:.3g} us at Re {r:g}" for r in reynolds) + "). "
        f"Second half: the distance from the nearer wall over W over the run's second half, its mean and range "
        f"(a body that tumbles wanders about a band). "
        f"Largest anisotropy: the body's largest / smallest second moment - 1 over the run" +
        (" (a red cell's undeformed section alone gives 15.5)" if "rbc" in cells else "") + ". "
        f"Measured Re: rho u H / mu with the mean velocity over the last tenth. "
        f"dt = {args.cfl} h / (1.5 u), to {args.travel:g} widths of travel at u"
        f"{', extra options: ' + args.extra if args.extra else ''}.", "",
        provenance(args, "python3 bench/run_inertial_migration.py " + " ".join(shlex.quote(a) for a in sys.argv[1:]))]
    write_table(args.table, lines)
    plt = bench_common.pyplot(TOOL)
    if plt and curves:
        with_ca = len({c for _, _, c, _, _ in points}) > 1
        fig, axes = plt.subplots(1, 2 if with_ca else 1, figsize=(11 if with_ca else 6.4, 3.8), squeeze=False)
        ax = axes[0][0]
        colours = plt.cm.tab20.colors if len(curves) > 10 else plt.cm.tab10.colors
        for k, (tag, traj) in enumerate(curves):
            ax.plot([x - traj[0][0] for x, _ in traj], [y for _, y in traj], label=tag.replace("_", ", "),
                    color=colours[k % len(colours)])
        for r, y in REFERENCES:
            ax.axhline(y, color="0.5", lw=0.8, ls="--")
        ax.text(0.99, REFERENCES[0][1], " Pan & Glowinski 2002", transform=ax.get_yaxis_transform(), ha="right",
                va="bottom", fontsize=8, color="0.4")
        ax.set_xlabel("x / W travelled")
        ax.set_ylabel("y / W (from the lower wall)")
        ax.set_title("Inertial migration in a plane channel (d = W / 4)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8 if len(curves) <= 8 else 6, ncol=1 if len(curves) <= 8 else 2)
        if with_ca:
            bx = axes[0][1]
            # Capillary numbers over more than a decade on a log axis, where the stiff disk (Ca 0) has no place.
            positive = [c for _, _, c, _, _ in points if c > 0]
            log_ca = bool(positive) and max(positive) >= 20 * min(positive)
            for kind in CELLS:
                for re_p, mesh in sorted({(r, m) for r, m, _, k, _ in points if k == kind}):
                    # The stiff disk (Ca 0) starts each curve on a linear axis.
                    pts = sorted((c, y) for r, m, c, k, y in points
                                 if (r, m) == (re_p, mesh) and (k == kind or (k == "disk" and not log_ca))
                                 and y is not None)
                    bx.plot([c for c, _ in pts], [y for _, y in pts], "o-" if kind == "capsule" else "s--",
                            label=f"{CELL_NAMES[kind]}, Re {re_p:g} (plasma), {mesh}")
            if log_ca:
                bx.set_xscale("log")
            bx.set_xlabel("Ca = mu gammadot_w a / (G h)" + ("" if log_ca else "  (0: the stiff disk)"))
            bx.set_ylabel("y_eq / W (from the nearer wall)")
            bx.set_title("Where it settles, against Ca")
            bx.grid(alpha=0.3)
            bx.legend(fontsize=8)
        bench_common.save_figure(fig, args.figure, TOOL)
    return 3 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
