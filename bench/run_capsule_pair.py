#!/usr/bin/env python3
"""Two capsules passing each other in shear flow (scenes/capsule_pair_shear.yaml; the 2D analogue of Lac, Morel &
Barthes-Biesel, JFM 2007): per mesh, their relative trajectory (Delta y against Delta x, in radii a), the lateral
shift it leaves (Delta y once they are again as far apart along the flow as they started, Delta x = +8a), the
least membrane-membrane distance against the repulsion's cut-off, the overlapping points (0: the membranes never
crossed), and the cost. Writes a table and a figure of the trajectories.

    python3 bench/run_capsule_pair.py                          # 64x64 and 128x128, dt 5e-4, to 0.5 s
    python3 bench/run_capsule_pair.py --meshes 64x64 --jobs 2 --extra "-coupling_repulsion false"
    python3 bench/run_capsule_pair.py --report                 # only the table and figure, from --runs

Options: --meshes NXxNY,... (64x64,128x128) --dt S (5e-4) --final-time S (0.5) --extra "OPTIONS" (added to every
run) --jobs N (1) --runs DIR (out/capsule_pair) --build DIR (build) --table FILE
(docs/validation/capsule_pair.md) --figure FILE (docs/figures/capsule_pair.png). A run whose summary.json says
"completed" with the same options is kept. Exit code 3 when a run did not complete."""
import argparse
import concurrent.futures
import csv
import os
import shlex
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_common  # noqa: E402
from bench_common import ROOT, check_kept_runs, fmt, provenance, run_one, summary_of, write_table  # noqa: E402

TOOL = "run_capsule_pair.py"
SCENE = "capsule_pair_shear.yaml"
RADIUS = 1e-4          # the scene's capsules [cm]
START_APART = 8.0      # their initial distance along the flow, in radii


def trajectory(path, period):
    """(time, dx / a, dy / a) of upper minus lower from metrics.csv, dx wrapped into (-period/2, period/2]."""
    out = []
    with open(path) as f:
        for r in csv.DictReader(f):
            dx = float(r["upper_centroid_x"]) - float(r["lower_centroid_x"])
            dx -= period * round(dx / period)
            dy = float(r["upper_centroid_y"]) - float(r["lower_centroid_y"])
            out.append((float(r["time"]), dx / RADIUS, dy / RADIUS, r.get("contact_cell_gap"),
                        r.get("contact_overlap_points")))
    return out


def shift_after_passing(traj):
    """Delta y / a where Delta x / a first reaches +START_APART after the two have passed (dx > 0), linearly
    interpolated; None if they never get there (they turned back, or the run ended first)."""
    passed = False
    for (t0, x0, y0, *_), (t1, x1, y1, *_) in zip(traj, traj[1:]):
        passed = passed or x1 > 0
        if passed and x0 < START_APART <= x1:
            return y0 + (y1 - y0) * (START_APART - x0) / (x1 - x0)
    return None


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--meshes", default="64x64,128x128")
    p.add_argument("--dt", type=float, default=5e-4)
    p.add_argument("--final-time", type=float, default=0.5)
    p.add_argument("--extra", default="")
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "capsule_pair"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "capsule_pair.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "capsule_pair.png"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    if not (args.dt > 0 and args.final_time > args.dt):
        sys.exit(f"{TOOL}: --dt {args.dt} and --final-time {args.final_time} are invalid: give 0 < dt < final time")
    if args.jobs < 1:
        sys.exit(f"{TOOL}: --jobs {args.jobs} is invalid: give 1 or more")
    meshes = [bench_common.mesh_of(TOOL, m, "--meshes") for m in args.meshes.split(",")]
    extra = shlex.split(args.extra)
    runs = []
    for nx, ny in meshes:
        options = ["-fluid_elements", f"{nx},{ny}", "-dt", str(args.dt), "-final_time", str(args.final_time),
                   "-output_every", "0"] + extra
        runs.append((f"{nx}x{ny}", nx, options))
    os.makedirs(args.runs, exist_ok=True)
    check_kept_runs(TOOL, args, [(tag, SCENE, o) for tag, _, o in runs])
    if not args.report:
        with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
            for tag, status in pool.map(lambda r: run_one(args, r[0], SCENE, r[2]), runs):
                print(f"{TOOL}: {tag}: {status}")

    rows, curves, failed = [], [], False
    for tag, nx, _ in runs:
        js = summary_of(args, tag)
        metrics = os.path.join(args.runs, tag, "metrics.csv")
        if js is None or not os.path.isfile(metrics):
            rows.append(f"| {tag} | - | - | - | - | - | - | no run |")
            failed = True
            continue
        traj = trajectory(metrics, 0.0032)
        curves.append((tag, traj))
        shift = shift_after_passing(traj)
        gaps = [float(g) for *_, g, _ in traj if g not in (None, "", "inf")]
        overlaps = [float(o) for *_, o in traj if o not in (None, "")]
        cutoff = js.get("repulsion_cutoff")
        steps = js.get("steps") or 0
        status = js.get("status", "?")
        failed = failed or status != "completed"
        rows.append(
            f"| {tag} | {fmt(0.0032 / nx / RADIUS, '.3f')} | {fmt(traj[0][2], '.3f')} | {fmt(shift, '.3f')} | "
            f"{fmt(min(gaps) / cutoff if gaps and cutoff else None, '.2f') if gaps else 'none within r_c'} | "
            f"{int(max(overlaps)) if overlaps else '-'} | "
            f"{fmt(js.get('coupling_iterations', 0) / steps if steps else None, '.2f')} | "
            f"{fmt(js.get('wall_time_s', 0) / steps if steps else None, '.3f')} | {status} |")
    lines = ["| mesh | element / a | Delta y / a at the start | Delta y / a after passing (Delta x = +8a) | "
             "least membrane distance / r_c | overlapping points (most) | coupling it./step | s/step | status |",
             "|---|---|---|---|---|---|---|---|---|"] + rows + [
        "", f"Capsules of radius a = 1e-4 cm, Ca = 0.1, 8a apart along the flow and 0.5a across it at the start; "
        f"walls 32a apart, period 32a; dt {args.dt}, to t = {args.final_time} s"
        f"{', extra options: ' + args.extra if args.extra else ''}. "
        "\"none within r_c\": the membranes never came within the repulsion's cut-off (one fluid element), so "
        "it never acted.", "",
        provenance(args, "python3 bench/run_capsule_pair.py " + " ".join(shlex.quote(a) for a in sys.argv[1:]))]
    write_table(args.table, lines)
    plt = bench_common.pyplot(TOOL)
    if plt and curves:
        fig, ax = plt.subplots(figsize=(6.4, 3.6))
        for tag, traj in curves:
            # Up to the first wrap of Delta x around the period (the pair then meets the other's image).
            end = next((k for k in range(1, len(traj)) if abs(traj[k][1] - traj[k - 1][1]) > 16), len(traj))
            ax.plot([x for _, x, *_ in traj[:end]], [y for _, _, y, *_ in traj[:end]], label=tag)
        ax.axvline(START_APART, color="0.6", lw=0.8, ls="--")
        ax.set_xlabel("Delta x / a (upper minus lower capsule)")
        ax.set_ylabel("Delta y / a")
        ax.set_title("Two capsules passing in shear (Ca 0.1)")
        ax.grid(alpha=0.3)
        ax.legend()
        bench_common.save_figure(fig, args.figure, TOOL)
    return 3 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
