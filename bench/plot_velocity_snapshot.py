#!/usr/bin/env python3
"""A velocity snapshot of a 2D run (paper Figs. 3c/3d, 4e/4f): the velocity magnitude and, where the run wrote it
(shear flows with cells), the magnitude of the velocity minus the undisturbed shear, with the bodies' outlines, from
the fluid and solid series (fluid.pvd, solid.pvd; one .vts per output or, from several ranks, a .pvts).

    python3 bench/plot_velocity_snapshot.py RUN [--time T[,T2,...]] [--figure docs/figures/shear_velocity.png]

--time picks the output nearest T (default: the last); several times give a panel (or a row of panels) each.
Needs python3-vtk9 and python3-matplotlib (scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import os
import sys
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, pyplot, save_figure  # noqa: E402


def series(pvd):
    """(time, file, name) of each data set of a .pvd collection."""
    root = ET.parse(pvd).getroot()
    return [(float(d.get("timestep")), d.get("file"), d.get("name") or "")
            for d in root.iter("DataSet")]


def read_grid(path):
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
    reader = vtk.vtkXMLPStructuredGridReader() if path.endswith(".pvts") else vtk.vtkXMLStructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    grid = reader.GetOutput()
    nx, ny, nz = grid.GetDimensions()
    xyz = vtk_to_numpy(grid.GetPoints().GetData()).reshape(nz, ny, nx, 3)[0]
    arrays = {}
    pd = grid.GetPointData()
    for i in range(pd.GetNumberOfArrays()):
        a = vtk_to_numpy(pd.GetArray(i))
        arrays[pd.GetArrayName(i)] = a.reshape((nz, ny, nx) + a.shape[1:])[0]
    return xyz, arrays


def draw(np, fig, axes, panels, args, pick, grid, solids, label_time):
    """One output's panels (grid: its read_grid) with the bodies' outlines (and the reversed flow)."""
    t = pick[0]
    xyz, arrays = grid
    x, y = xyz[..., 0] * 1e4, xyz[..., 1] * 1e4  # um
    outlines = [read_grid(os.path.join(args.run, f))[0] for time, f, _ in solids
                if abs(time - t) <= 1e-9 * max(1.0, abs(t))]
    for ax, (name, label) in zip(axes, panels):
        mag = np.linalg.norm(arrays[name], axis=-1)
        m = ax.pcolormesh(x, y, mag, shading="gouraud", cmap="viridis")
        fig.colorbar(m, ax=ax, label=label, shrink=0.85)
        for s in outlines:  # a body's grid: its first and last rows are its outer curves
            for row in (s[0], s[-1]):
                ax.plot(row[:, 0] * 1e4, row[:, 1] * 1e4, color="w", lw=0.8)
            for col in (s[:, 0], s[:, -1]):
                ax.plot(col[:, 0] * 1e4, col[:, 1] * 1e4, color="w", lw=0.8)
        if args.reversed and name == "velocity":
            vx = arrays["velocity"][..., 0]
            if (vx < 0).any():
                ax.contour(x, y, vx, levels=[0.0], colors="r", linewidths=0.8)
            # Area with v_x < 0 (cells of the sample grid whose four corners all have v_x < 0), in um^2.
            neg = (vx[:-1, :-1] < 0) & (vx[1:, :-1] < 0) & (vx[:-1, 1:] < 0) & (vx[1:, 1:] < 0)
            dx1, dy1 = x[:-1, 1:] - x[:-1, :-1], y[:-1, 1:] - y[:-1, :-1]
            dx2, dy2 = x[1:, :-1] - x[:-1, :-1], y[1:, :-1] - y[:-1, :-1]
            area = np.abs(dx1 * dy2 - dy1 * dx2)
            print(f"plot_velocity_snapshot: reversed flow (v_x < 0) over {area[neg].sum():.3g} um^2 of "
                  f"{area.sum():.3g} um^2 at t = {t:g} s")
        ax.set_aspect("equal")
        ax.set_xlabel("x (um)")
        ax.set_ylabel("y (um)")
        if label_time:
            ax.set_title(f"t = {t:g} s", fontsize=9)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run")
    p.add_argument("--time", default=None, help="T or T1,T2,... (one row of panels per time)")
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "shear_velocity.png"))
    p.add_argument("--reversed", action="store_true",
                   help="outline where the flow runs against the mean flow (v_x < 0: recirculation) and print "
                        "its area")
    args = p.parse_args()
    try:
        import numpy as np
        import vtk  # noqa: F401
    except ImportError:
        print("plot_velocity_snapshot: needs python3-vtk9 and python3-numpy (scripts/install-deps.sh)",
              file=sys.stderr)
        sys.exit(1)
    plt = pyplot("plot_velocity_snapshot")
    if plt is None:
        sys.exit(1)
    fluid = series(os.path.join(args.run, "fluid.pvd"))
    if not fluid:
        sys.exit(f"plot_velocity_snapshot: {args.run}/fluid.pvd lists no output (run with -output_every N)")
    times = [] if args.time is None else [t.strip() for t in args.time.split(",") if t.strip()]
    try:
        picks = [min(fluid, key=lambda e: abs(e[0] - float(t))) for t in times] or [fluid[-1]]
    except ValueError:
        sys.exit(f"plot_velocity_snapshot: --time {args.time} is invalid; valid: a time or times T1,T2,... in s")
    solid_pvd = os.path.join(args.run, "solid.pvd")
    solids = series(solid_pvd) if os.path.isfile(solid_pvd) else []
    panels = [("velocity", "|v| (cm/s)")]
    grids = [read_grid(os.path.join(args.run, pick[1])) for pick in picks]
    # The disturbance's panel only when every chosen output has it.
    if all("velocity_disturbance" in arrays for _, arrays in grids):
        panels.append(("velocity_disturbance", "|v - v_shear| (cm/s)"))
    # One row of panels per time; with one panel per time, two times per row.
    per_row = 2 if len(panels) == 1 and len(picks) > 1 else 1
    rows = (len(picks) + per_row - 1) // per_row
    cols = per_row * len(panels)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.2 * rows), squeeze=False)
    flat = [ax for row in axes for ax in row]
    for i, (pick, grid) in enumerate(zip(picks, grids)):
        draw(np, fig, flat[i * len(panels):(i + 1) * len(panels)], panels, args, pick, grid, solids,
             len(picks) > 1)
    for ax in flat[len(picks) * len(panels):]:
        ax.set_visible(False)
    opts = {}
    if os.path.isfile(os.path.join(args.run, "options.yaml")):
        with open(os.path.join(args.run, "options.yaml")) as f:
            opts = dict(line.rstrip("\n").split(": ", 1) for line in f if ": " in line and not line.startswith("#"))
    name = os.path.basename(os.path.normpath(args.run))
    if os.path.isfile(os.path.join(args.run, "summary.json")):
        import json
        with open(os.path.join(args.run, "summary.json")) as f:
            name = json.load(f).get("scene", name)
    when = "" if len(picks) > 1 else f", at t = {picks[0][0]:g} s"
    fig.suptitle(f"{name}, {opts.get('fluid_elements', '?').replace(',', ' x ')} elements{when}", fontsize=10)
    save_figure(fig, args.figure, "plot_velocity_snapshot")


if __name__ == "__main__":
    main()
