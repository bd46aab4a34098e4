#!/usr/bin/env python3
"""What a 3D membrane's saved states show between the solver's quadrature points: per output of one body
(solid_<body>_*.vts, in solid.pvd's order) the least J = det F on each sample layer through the thickness (the
first and last layers are the shell's faces, where a fold shows first), the mid-surface's local area against the
first output's (its least and largest ratio over the sample grid's cells) and the whole, the shell's own volume
(between its two faces) against the first output's with the J below which 1 % of the samples lie (a shell that
keeps its volume while its J spreads is squeezed here and swollen there), and Taylor's deformation index
(L - B) / (L + B) in the shear plane of the region the mid-surface encloses, as cellfsi's metric
BODY_deformation_index defines it (solid/body_metrics.hpp), here from the sample grid as a closed polyhedron. For
runs made before that metric, and to see where a shell folded. A body of several patches (-solid_NAME_patches 6,
one solid_<body>_p<K>_*.vts a part) is measured as one. Writes a markdown table (--table) or prints it.

  /usr/bin/python3 bench/shell_states.py RUN [--body rbc] [--every N] [--from T] [--plane-dir 1] [--table FILE]

Needs Debian's python3-vtk9 (scripts/install-deps.sh).
"""
import argparse
import datetime
import os
import sys
import xml.etree.ElementTree as ET

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import commit_of_head, write_table  # noqa: E402
from membrane_volume_ratio import read_body  # noqa: E402

TOOL = "shell_states.py"


def cell_areas(mid):
    """The areas of the mid-surface's sample grid cells (two triangles each), shaped (direction 2, direction 1)."""
    import numpy as np
    a, b, c, d = mid[:-1, :-1], mid[1:, :-1], mid[1:, 1:], mid[:-1, 1:]
    return 0.5 * (np.linalg.norm(np.cross(b - a, c - a), axis=-1) + np.linalg.norm(np.cross(c - a, d - a), axis=-1))


def enclosed_moments(mids, second_moment=True):
    """(volume, second moment about the centroid) of the region closed sample grids enclose together (one grid, or
    the parts of one membrane, alike oriented): tetrahedra from the grids' mean point to each of their triangles (a
    pole's row of equal points gives triangles of no volume). second_moment=False: the volume alone (and None)."""
    import numpy as np
    o = np.concatenate([mid.reshape(-1, 3) for mid in mids]).mean(axis=0)
    volume, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    triangles = []
    for mid in mids:
        m = mid - o
        corners = (m[:-1, :-1], m[1:, :-1], m[1:, 1:], m[:-1, 1:])
        triangles += [(corners[0], corners[1], corners[2]), (corners[0], corners[2], corners[3])]
    for a, b, c in triangles:
        a, b, c = a.reshape(-1, 3), b.reshape(-1, 3), c.reshape(-1, 3)
        v = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6
        s = a + b + c
        volume += v.sum()
        if not second_moment:
            continue
        first += (v[:, None] * s).sum(axis=0) / 4
        # (a tetrahedron with one vertex at the origin: int x x^T = V / 20 (sum of v v^T + s s^T))
        for x in (a, b, c, s):
            second += np.einsum("i,ij,ik->jk", v / 20, x, x)
    sign = 1.0 if volume > 0 else -1.0  # (the grid's orientation)
    if not second_moment:
        return sign * volume, None
    volume, first, second = sign * volume, sign * first, sign * second
    centroid = first / volume
    return volume, second - volume * np.outer(centroid, centroid)


def shell_volume(parts, layers):
    """The shell's own volume: what its outer face encloses less what its inner face does (the parts' sample
    grids, shaped (direction 2, direction 1, layer, 3))."""
    inner = enclosed_moments([pts[:, :, 0, :] for pts in parts], False)[0]
    outer = enclosed_moments([pts[:, :, layers - 1, :] for pts in parts], False)[0]
    return abs(outer - inner)


def deformation_index(second, plane_dir):
    """Taylor's (L - B) / (L + B) of the ellipse with the second moments' (x, plane_dir) block."""
    import numpy as np
    block = second[np.ix_([0, plane_dir], [0, plane_dir])]
    small, large = np.sqrt(np.maximum(np.linalg.eigvalsh(block), 0.0))
    return (large - small) / (large + small) if large > 0 else 0.0


class StatesError(Exception):
    """A run folder shell_states cannot read: no solid.pvd, or no output of the body."""


def states(run, body="rbc", start=0.0, every=1, plane_dir=1):
    """The measures of the table's columns, per chosen output of `body` in the run folder `run`: a list of dicts
    (t in s; least_J, one per sample layer; area_min, area_max, area (the whole); shell; J_1pc; volume in cm^3;
    deformation_index; least_part, least_at (two fractions)), with the count of parts and of layers."""
    import numpy as np
    pvd = os.path.join(run, "solid.pvd")
    if not os.path.isfile(pvd):
        raise StatesError(f"{run} has no solid.pvd")
    # Per output time, the body's parts in order (one part, or the six faces of -solid_NAME_patches 6).
    outputs = {}
    for d in ET.parse(pvd).getroot().iter("DataSet"):
        if os.path.basename(d.get("file")).startswith(f"solid_{body}_"):
            outputs.setdefault(float(d.get("timestep")), []).append((int(d.get("part", 0)), d.get("file")))
    if not outputs:
        raise StatesError(f"no output of body '{body}' in {run}")
    outputs = sorted((t, [f for _, f in sorted(parts)]) for t, parts in outputs.items())
    references = [read_body(os.path.join(run, f))[0] for f in outputs[0][1]]
    layers = references[0].shape[2]
    area0 = [cell_areas(r[:, :, layers // 2, :]) for r in references]
    top = max(a.max() for a in area0)
    keep = [a > 1e-12 * top for a in area0]  # (the poles' rows of cells have no area)
    area0 = np.concatenate([a[k] for a, k in zip(area0, keep)])
    shell0 = shell_volume(references, layers)
    chosen = [o for o in outputs if o[0] >= start - 1e-12]
    chosen = [o for i, o in enumerate(chosen) if i % every == 0 or i == len(chosen) - 1]
    rows = []
    for t, files in chosen:
        got = [read_body(os.path.join(run, f)) for f in files]
        mids = [pts[:, :, layers // 2, :] for pts, _ in got]
        areas = np.concatenate([cell_areas(mid)[k] for mid, k in zip(mids, keep)])
        ratio = areas / area0
        volume, second = enclosed_moments(mids)
        part = min(range(len(got)), key=lambda q: got[q][1]["J"].min())
        J = got[part][1]["J"]
        k2, k1, _ = np.unravel_index(np.argmin(J), J.shape)
        rows.append({"t": t,
                     "least_J": [min(a["J"][:, :, k].min() for _, a in got) for k in range(layers)],
                     "area_min": ratio.min(), "area_max": ratio.max(), "area": areas.sum() / area0.sum(),
                     "shell": shell_volume([pts for pts, _ in got], layers) / shell0,
                     "J_1pc": np.percentile(np.concatenate([a["J"].reshape(-1) for _, a in got]), 1),
                     "volume": volume, "deformation_index": deformation_index(second, plane_dir),
                     "least_part": part, "least_at": (k1 / (J.shape[1] - 1), k2 / (J.shape[0] - 1))})
    return rows, len(references), layers


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", help="a run folder (with solid.pvd)")
    ap.add_argument("--body", default="rbc")
    ap.add_argument("--every", type=int, default=1, help="every N-th output (the first and last always)")
    ap.add_argument("--from", dest="start", type=float, default=0.0, help="outputs from this time [s] on")
    ap.add_argument("--plane-dir", type=int, default=1, choices=[1, 2],
                    help="the shear plane's second direction, as cellfsi's (1: y, the default)")
    ap.add_argument("--table", help="markdown file to write (default: print)")
    args = ap.parse_args()
    if args.every < 1:
        sys.exit(f"{TOOL}: --every {args.every} is invalid: give a whole number of 1 or more")
    try:
        rows, parts, layers = states(args.run, args.body, args.start, args.every, args.plane_dir)
    except StatesError as e:
        sys.exit(f"{TOOL}: {e}")
    faces = " | ".join(f"layer {k}" for k in range(layers))
    several = parts > 1
    lines = [f"# The saved states of body '{args.body}' in {os.path.basename(os.path.normpath(args.run))}", "",
             f"Generated by `/usr/bin/python3 bench/{TOOL} {' '.join(sys.argv[1:])}` on "
             f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, git {commit_of_head()}, from the "
             "run's own outputs (its options.yaml says its command).", "",
             f"Per output: the least J on each of the {layers} sample layers through the thickness (layer 0 and "
             f"layer {layers - 1}: the shell's faces), the mid-surface's local area against the first output's "
             "(least and largest over the sample grid's cells) and the whole, the shell's own volume (between its "
             "faces) against the first output's and the J below which 1 % of the samples lie, the volume the "
             "mid-surface encloses, "
             "the deformation index in the shear plane (x and direction "
             f"{'xyz'[args.plane_dir]}) of that region, and where the least J lies: "
             + (f"the part (of {parts}) and " if several else "")
             + "its position along directions 1 and 2 of the sample grid (0 to 1; on the polar shell direction 1 "
             "runs from pole to pole).", "",
             f"| t (ms) | {faces} | local area | whole area | shell's volume | J, 1 % below | volume (um^3) | "
             "deformation index | least J at |",
             "|" + "---|" * (layers + 8)]
    for r in rows:
        least = " | ".join(f"{j:.3f}" for j in r["least_J"])
        where = f"{r['least_at'][0]:.2f}, {r['least_at'][1]:.2f}"
        lines.append(f"| {r['t'] * 1e3:.1f} | {least} | {r['area_min']:.3f}-{r['area_max']:.3f} | "
                     f"{r['area']:.4f} | {r['shell']:.4f} | {r['J_1pc']:.3f} | {r['volume'] * 1e12:.2f} | "
                     f"{r['deformation_index']:.4f} | "
                     + (f"part {r['least_part']}: " if several else "") + f"{where} |")
    write_table(args.table, lines)


if __name__ == "__main__":
    main()
