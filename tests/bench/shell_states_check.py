#!/usr/bin/env python3
"""bench/shell_states.py on a stand-in run: an ellipsoidal shell (mid-surface semi-axes 4, 2 and 1.5 um, 5 sample
layers, 60 x 120 grid cells with a pole's row of equal points at each end, as cellfsi's output has), then the
same shell's mid-surface scaled by 1.1 about its centre (its faces the same 0.3 um from it), with J given per
layer and, in the second, one sample (the first, on layer 0) at -0.9. The table must give the layers' least J as
written, the local and whole area ratios 1 and 1.21, the shell's own volume (between its faces) 1 and 1.21
times the first output's (the exact 4/3 pi ((a+h)(b+h)(c+h) - (a-h)(b-h)(c-h)), h = 0.15 um, within 0.1 %), the
J below which 1 % of the samples lie (the least layer's, 0.8 then -0.2: the one sample at -0.9 is the least J,
not the 1 %), the enclosed volume (4/3 pi a b c, 50.27 um^3, within the grid's 0.2 %) times 1 and 1.331, and
the deformation index (a - b) / (a + b) = 1/3 in the x-y plane and (a - c) / (a + c) = 0.4545 in the x-z plane
(--plane-dir 2), within 0.2 %, and where the least J lies; the same
shell written as two parts (its two halves along the azimuth, as -solid_NAME_patches writes a body's faces) must
give the same numbers, the least J in a part; --every 0 is refused.

  /usr/bin/python3 tests/bench/shell_states_check.py SOURCE_DIR WORK_DIR
"""
import math
import os
import shutil
import subprocess
import sys

import numpy as np
import vtk
from vtk.util.numpy_support import numpy_to_vtk

SRC, WORK = sys.argv[1], sys.argv[2]
A, B, C, H = 4e-4, 2e-4, 1.5e-4, 3e-5
CENTRE = np.array([6e-4, 6e-4, 6e-4])


def write_shell(path, scale, j_per_layer, azimuths=slice(0, 121), first=None):
    layers, polar = 5, 61
    phi = np.linspace(0, math.pi, polar)[None, :, None]
    theta = np.linspace(0, 2 * math.pi, 121)[azimuths, None, None]
    azim = theta.shape[0]
    off = (np.linspace(-0.5, 0.5, layers) * H)[None, None, :]
    pts = np.stack(np.broadcast_arrays((scale * A + off) * np.sin(phi) * np.cos(theta), (scale * B + off) *
                                       np.sin(phi) * np.sin(theta), (scale * C + off) * np.cos(phi)), axis=-1)
    pts = CENTRE + pts  # shaped (azimuth, polar, layer, 3): VTK's (k, j, i)
    grid = vtk.vtkStructuredGrid()
    grid.SetDimensions(layers, polar, azim)
    points = vtk.vtkPoints()
    points.SetData(numpy_to_vtk(np.ascontiguousarray(pts.reshape(-1, 3)), deep=True))
    grid.SetPoints(points)
    J = np.broadcast_to(np.array(j_per_layer)[None, None, :], (azim, polar, layers)).reshape(-1).copy()
    if first is not None:
        J[0] = first  # (the first sample: azimuth 0, the pole, layer 0)
    arr = numpy_to_vtk(J, deep=True)
    arr.SetName("J")
    grid.GetPointData().AddArray(arr)
    writer = vtk.vtkXMLStructuredGridWriter()
    writer.SetFileName(path)
    writer.SetInputData(grid)
    writer.Write()


def table(work, *extra):
    out = subprocess.run(["/usr/bin/python3", os.path.join(SRC, "bench", "shell_states.py"), work, *extra],
                         capture_output=True, text=True)
    return out.returncode, out.stdout, out.stderr


def rows(text):
    return [[c.strip() for c in line.strip("|").split("|")] for line in text.splitlines()
            if line.startswith("| ") and line[2].isdigit()]


def write_run(work, halves):
    """The stand-in run in work: the whole shell (part 0), or its two halves along the azimuth (parts 0, 1)."""
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    parts = [slice(0, 61), slice(60, 121)] if halves else [slice(0, 121)]
    entries = []
    for step, (t, scale, J) in enumerate(((0, 1.0, [0.9, 1.0, 1.0, 1.0, 0.8]),
                                          (0.002, 1.1, [-0.2, 0.7, 1.0, 0.6, 0.5]))):
        for k, azimuths in enumerate(parts):
            name = f"solid_rbc_p{k}_{step:06d}.vts" if halves else f"solid_rbc_{step:06d}.vts"
            write_shell(os.path.join(work, name), scale, J, azimuths, -0.9 if step == 1 and k == 0 else None)
            entries.append(f'<DataSet timestep="{t}" part="{k}" name="rbc" file="{name}"/>\n')
    with open(os.path.join(work, "solid.pvd"), "w") as f:
        f.write('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1"><Collection>\n' + "".join(entries)
                + '</Collection></VTKFile>\n')


failures = []


def check(what, ok):
    if not ok:
        failures.append(what)


volume = 4 / 3 * math.pi * A * B * C * 1e12
P, h = A * B + B * C + C * A, H / 2
SHELL = (1.21 * P + h * h) / (P + h * h)  # (the shell's volume, 8/3 pi h (s^2 P + h^2), at s = 1.1 against s = 1)
for halves in (False, True):
    work = os.path.join(WORK, "parts" if halves else "whole")
    write_run(work, halves)
    for plane, di in ((1, (A - B) / (A + B)), (2, (A - C) / (A + C))):
        code, out, err = table(work, "--plane-dir", str(plane))
        check(f"exit code {code}: {err}", code == 0)
        r = rows(out)
        check(f"two rows in\n{out}", len(r) == 2)
        if len(r) != 2:
            continue
        check(f"layers at 0 ms: {r[0][1:6]}", r[0][1:6] == ["0.900", "1.000", "1.000", "1.000", "0.800"])
        check(f"layers at 2 ms: {r[1][1:6]}", r[1][1:6] == ["-0.900", "0.700", "1.000", "0.600", "0.500"])
        check(f"local area at 0 ms: {r[0][6]}", r[0][6] == "1.000-1.000")
        check(f"local area at 2 ms: {r[1][6]}", r[1][6] == "1.210-1.210")
        check(f"whole area: {r[0][7]}, {r[1][7]}", (r[0][7], r[1][7]) == ("1.0000", "1.2100"))
        check(f"shell's volume: {r[0][8]}, {r[1][8]}", r[0][8] == "1.0000" and abs(float(r[1][8]) / SHELL - 1) < 1e-3)
        check(f"J, 1 % below: {r[0][9]}, {r[1][9]}", (r[0][9], r[1][9]) == ("0.800", "-0.200"))
        check(f"volume {r[0][10]} against {volume:.2f}", abs(float(r[0][10]) / volume - 1) < 2e-3)
        check(f"volume ratio {r[1][10]} / {r[0][10]}", abs(float(r[1][10]) / float(r[0][10]) - 1.331) < 1e-3)
        for row in r:
            check(f"plane {plane}: deformation index {row[11]} against {di:.4f}", abs(float(row[11]) / di - 1) < 2e-3)
        # (the least J: the one sample at -0.9, the first of the first part, on layer 0)
        where = "part 0: 0.00, 0.00" if halves else "0.00, 0.00"
        check(f"least J at {r[1][12]}, not {where}", r[1][12] == where)
code, out, err = table(os.path.join(WORK, "whole"), "--every", "0")
check(f"--every 0: exit code {code}, {err}", code == 1 and "--every 0 is invalid" in err)
if failures:
    sys.exit("shell_states_check: " + "\n".join(failures))
print("shell_states_check: passed")
