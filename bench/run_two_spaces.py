#!/usr/bin/env python3
"""The capsule in shear flow (paper Sec. 3.3, Table 1; scenes/capsule_shear.yaml) on both fluid spaces: the
paper's equal-order VMS with s_I (-fluid_space equal_order, cubic, -s_interface auto) and the
divergence-conforming space without s_I (-fluid_space div_conforming, k' = 2 or 3). Writes two tables:

  table: theta and omega_TT against the converged values of the paper's finest run (26.09 deg, 3.90 1/s), the
         area error, coupling and FGMRES iterations, factorisations and seconds per step, per mesh and space;
  area:  the area error |r_A| over a longer run per mesh (div_conforming only unless --area-spaces says
         otherwise), and its ratio between successive meshes.

    python3 bench/run_two_spaces.py                  # table: 64x32, 128x64, 256x128 at dt 1e-3 to 0.3 s
    python3 bench/run_two_spaces.py --area           # and the area runs to 1 s
    python3 bench/run_two_spaces.py --meshes none --area --jobs 2   # only the area runs, two at a time
    python3 bench/run_two_spaces.py --meshes none --scenes --jobs 2 # the migrating capsule and the six RBCs
    python3 bench/run_two_spaces.py --report         # only the tables, from the runs in --runs

Options: --meshes NXxNY,... (64x32,128x64,256x128) --spaces S,... (equal_order:3,div_conforming:2) --dt S (1e-3)
  --final-time S (0.3) --average-from S (0.15) --area-meshes (64x32,128x64,256x128) --area-final-time S (1.0)
  --area-spaces (div_conforming:2) --area-dt-with-mesh (the area runs' dt halves with h: --dt on the first
  mesh) --jobs N (1) --runs DIR (out/two_spaces) --build DIR (build)
  --table FILE (docs/validation/two_spaces_capsule.md) --area-table FILE (docs/validation/two_spaces_area.md)
  --scenes (the channel scenes, coarse, on --spaces) --scenes-table FILE (docs/validation/two_spaces_scenes.md)
A space is NAME:DEGREE (the patch's degree; for div_conforming also k'). Runs are one rank each; with --jobs 1
(the default) the spaces' seconds per step are measured one after the other on the same machine, so their
ratio is the comparison. A run whose summary.json says "completed" is not run again. Exit code 3 when a run
did not complete."""
import argparse
import concurrent.futures
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_common  # noqa: E402
from bench_common import (ROOT, check_kept_runs, fmt, provenance, run_one, summary_of,  # noqa: E402
                          write_table)

TOOL = "run_two_spaces.py"
THETA_CONVERGED, OMEGA_CONVERGED = 26.09, 3.90  # paper Table 1, 512 x 256 cubic


def mesh_of(text):
    return bench_common.mesh_of(TOOL, text, "mesh")


def space_of(text):
    name, _, degree = text.partition(":")
    if name not in ("equal_order", "div_conforming") or degree not in ("2", "3"):
        sys.exit(f"{TOOL}: space '{text}' is invalid: give equal_order:P or div_conforming:K with P, K in 2, 3")
    return name, int(degree)


def options_of(space, degree, mesh, dt, final_time, average_from):
    nx, ny = mesh_of(mesh)
    o = ["-fluid_elements", f"{nx},{ny}", "-fluid_degree", str(degree), "-dt", str(dt), "-final_time",
         str(final_time), "-metrics_average_from", str(average_from), "-output_every", "0",
         "-solid_membrane_elements", "1,0", "-fluid_space", space]
    if space == "div_conforming":
        o += ["-fluid_dc_degree", str(degree)]
    return o


def runs_of(args):
    out = []
    for mesh in args.meshes:
        for space, degree in args.spaces:
            out.append((f"table_{space}{degree}_{mesh}", "capsule_shear.yaml",
                        options_of(space, degree, mesh, args.dt, args.final_time, args.average_from)))
    if args.area:
        for mesh in args.area_meshes:
            for space, degree in args.area_spaces:
                out.append((area_tag(args, space, degree, mesh), "capsule_shear.yaml",
                            options_of(space, degree, mesh, area_dt(args, mesh), args.area_final_time,
                                       args.area_final_time / 2)))
    return out


def area_dt(args, mesh):
    """The area run's time step: --dt, or with --area-dt-with-mesh --dt on the first mesh, halved with h."""
    if not args.area_dt_with_mesh:
        return args.dt
    return args.dt * mesh_of(args.area_meshes[0])[0] / mesh_of(mesh)[0]


def area_tag(args, space, degree, mesh):
    tag = f"area_{space}{degree}_{mesh}"
    return tag + f"_dt{area_dt(args, mesh):g}" if args.area_dt_with_mesh else tag


# --scenes: the paper's other 2D scenes on both spaces, coarse (scene, mesh, final time, body option, metrics).
# The compound capsule with the paper's largest nucleus (r = 7e-5 cm, 3.2 elements from the membrane at
# 256 x 128): on the equal-order space the two s^h bands lock membrane and nucleus there (docs/validation.md, "The
# compound capsule in 2D"); the divergence-conforming space has no bands.
SCENES = [
    ("capsule_channel_migration.yaml", "128x64", 0.3, "-solid_membrane_elements",
     ["membrane_lateral_offset_final", "membrane_max_abs_r_A", "membrane_r_A"], []),
    ("rbc_channel.yaml", "96x32", 0.2, "-solid_rbc_elements", ["zeta", "eta", "h_cf", "rbc_1_max_abs_r_A"], []),
    ("compound_capsule_shear.yaml", "128x64", 0.3, "-solid_membrane_elements",
     ["membrane_theta_deg", "membrane_omega_tt", "membrane_omega_tu", "nucleus_omega_tu", "membrane_max_abs_r_A"],
     ["-solid_nucleus_semi_axes", "7e-05,7e-05", "-dt", "1e-3", "-metrics_average_from", "0.15"]),
]


def scene_runs(args):
    out = []
    for scene, mesh, final_time, body, _, extra in SCENES:
        nx, ny = mesh_of(mesh)
        for space, degree in args.spaces:
            o = ["-fluid_elements", f"{nx},{ny}", "-fluid_degree", str(degree), "-final_time", str(final_time),
                 "-output_every", "0", body, "1,0", "-fluid_space", space] + extra
            if space == "div_conforming":
                o += ["-fluid_dc_degree", str(degree)]
            out.append((f"scene_{scene[:-5]}_{space}{degree}_{mesh}", scene, o))
    return out


def scene_lines(args):
    lines = ["| scene | mesh | space | degree | T s | metrics | coupling it/step | s/step | status |",
             "|---|---|---|---|---|---|---|---|---|"]
    for scene, mesh, final_time, _, keys, _ in SCENES:
        for space, degree in args.spaces:
            js = summary_of(args, f"scene_{scene[:-5]}_{space}{degree}_{mesh}")
            if js is None:
                continue
            values = ", ".join(f"{k} {fmt(js.get(k), '.4g')}" for k in keys)
            lines.append(f"| {scene} | {mesh} | {space} | {degree} | {final_time:g} | {values} | "
                         f"{fmt(per_step(js, 'coupling_iterations'), '.2f')} | {fmt(per_step(js, 'wall_time_s'), '.3f')} | "
                         f"{js.get('status', '-')} |")
    return lines


def lu_in_steps(js):
    """summary.json's LU factorisations made in steps (the region's, the kept part's, a PETSc PC's), without the
    bulk operator's once-per-run banded LUs. Runs before bulk_factorizations was written counted the bulk's
    only (cellfsi_fourier, cellfsi_bulk): for cellfsi_bulk that is all, so none was made in steps; for
    cellfsi_fourier the region's LU at each refresh was not counted (None)."""
    if "bulk_factorizations" in js:
        return js.get("factorizations")
    if js.get("coupling_pc_type") == "cellfsi_bulk" and js.get("factorizations") is not None:
        return js["factorizations"] - 1
    return None


def per_step(js, key):
    steps = js.get("steps") or 0
    return js[key] / steps if steps and js.get(key) is not None else None


def table_lines(args):
    lines = ["| mesh | space | degree | dt s | theta deg | theta - 26.09 | omega_TT 1/s | omega error % | "
             "max \\|r_A\\| | r_A(T) | averaged over s | coupling it/step | FGMRES it/step | LU in steps | "
             "s/step | wall s | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for mesh in args.meshes:
        for space, degree in args.spaces:
            js = summary_of(args, f"table_{space}{degree}_{mesh}")
            if js is None:
                continue
            th, om = js.get("membrane_theta_deg"), js.get("membrane_omega_tt")
            lines.append(
                f"| {mesh} | {space} | {degree} | {args.dt:g} | {fmt(th, '.2f')} | "
                f"{fmt(None if th is None else th - THETA_CONVERGED, '+.2f')} | {fmt(om, '.3f')} | "
                f"{fmt(None if om is None else 100 * (om - OMEGA_CONVERGED) / OMEGA_CONVERGED, '+.1f')} | "
                f"{fmt(js.get('membrane_max_abs_r_A'), '.2e')} | {fmt(js.get('membrane_r_A'), '.2e')} | "
                f"{fmt(js.get('membrane_average_from'), '.2f')}-{fmt(js.get('membrane_average_to'), '.2f')} | "
                f"{fmt(per_step(js, 'coupling_iterations'), '.2f')} | {fmt(per_step(js, 'linear_iterations'), '.1f')} | "
                f"{fmt(lu_in_steps(js), '.0f')} | {fmt(per_step(js, 'wall_time_s'), '.3f')} | "
                f"{fmt(js.get('wall_time_s'), '.0f')} | {js.get('status', '-')} |")
    return lines


def late_area_error(args, tag, after=0.1):
    """max |r_A| over the steps at t >= after (past the start from rest, whose first-step jump of 5e-4 .. 7e-4
    is the same on every mesh and either space), from the run's metrics.csv; None if there is none."""
    try:
        with open(os.path.join(args.runs, tag, "metrics.csv")) as f:
            rows = list(csv.DictReader(f))
        return max(abs(float(r["membrane_r_A"])) for r in rows if float(r["time"]) >= after)
    except (OSError, KeyError, ValueError):
        return None


def area_lines(args):
    lines = ["| mesh | space | degree | dt s | T s | max \\|r_A\\| | max \\|r_A\\| from 0.1 s | r_A(T) | "
             "ratio to the coarser mesh (from 0.1 s) | coupling it/step | s/step | status |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for space, degree in args.area_spaces:
        previous = None
        for mesh in args.area_meshes:
            tag = area_tag(args, space, degree, mesh)
            js = summary_of(args, tag)
            if js is None:
                continue
            ra, late = js.get("membrane_max_abs_r_A"), late_area_error(args, tag)
            ratio = previous / late if previous and late else None
            previous = late
            lines.append(f"| {mesh} | {space} | {degree} | {area_dt(args, mesh):g} | {args.area_final_time:g} | {fmt(ra, '.2e')} | "
                         f"{fmt(late, '.2e')} | {fmt(js.get('membrane_r_A'), '.2e')} | {fmt(ratio, '.2f')} | "
                         f"{fmt(per_step(js, 'coupling_iterations'), '.2f')} | {fmt(per_step(js, 'wall_time_s'), '.3f')} | "
                         f"{js.get('status', '-')} |")
    return lines


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--meshes", default="64x32,128x64,256x128")
    ap.add_argument("--spaces", default="equal_order:3,div_conforming:2")
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--final-time", type=float, default=0.3)
    ap.add_argument("--average-from", type=float, default=0.15)
    ap.add_argument("--area", action="store_true")
    ap.add_argument("--area-meshes", default="64x32,128x64,256x128")
    ap.add_argument("--area-spaces", default="div_conforming:2")
    ap.add_argument("--area-final-time", type=float, default=1.0)
    ap.add_argument("--area-dt-with-mesh", action="store_true")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--runs", default=os.path.join(ROOT, "out", "two_spaces"))
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "two_spaces_capsule.md"))
    ap.add_argument("--area-table", default=os.path.join(ROOT, "docs", "validation", "two_spaces_area.md"))
    ap.add_argument("--report", action="store_true")
    ap.add_argument("--scenes", action="store_true")
    ap.add_argument("--scenes-table", default=os.path.join(ROOT, "docs", "validation", "two_spaces_scenes.md"))
    args = ap.parse_args()
    args.meshes = [] if args.meshes == "none" else [m for m in args.meshes.split(",") if mesh_of(m)]
    args.area_meshes = [m for m in args.area_meshes.split(",") if mesh_of(m)]
    args.spaces = [space_of(s) for s in args.spaces.split(",")]
    args.area_spaces = [space_of(s) for s in args.area_spaces.split(",")]
    if args.jobs < 1:
        sys.exit(f"{TOOL}: --jobs {args.jobs} is invalid: give at least 1")
    os.makedirs(args.runs, exist_ok=True)
    runs = runs_of(args) + (scene_runs(args) if args.scenes else [])
    failed = []
    if not args.report:
        check_kept_runs(TOOL, args, runs)
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            for tag, result in pool.map(lambda r: run_one(args, r[0], r[1], r[2]), runs):
                print(f"{TOOL}: {tag}: {result}", flush=True)
                if result not in ("kept", "exit 0"):
                    failed.append(tag)
    command = "python3 bench/" + TOOL + " " + " ".join(sys.argv[1:])
    if args.meshes:
        write_table(args.table, [provenance(args, command.strip()), ""] + table_lines(args))
    if args.area:
        write_table(args.area_table, [provenance(args, command.strip()), ""] + area_lines(args))
    if args.scenes:
        write_table(args.scenes_table, [provenance(args, command.strip()), ""] + scene_lines(args))
    if failed:
        print(f"{TOOL}: runs that did not complete: {', '.join(failed)} (logs in {args.runs})", file=sys.stderr)
        sys.exit(3)


if __name__ == "__main__":
    main()
