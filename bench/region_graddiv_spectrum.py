#!/usr/bin/env python3
"""The s_I grad-div term of the Fourier solver's region, measured: how many of the region's velocity modes it
leaves soft, how its stiffness is spread, and whether its soft modes are sums of modes local to vertex stars
(the property that patch smoothers of augmented-Lagrangian preconditioners rely on). docs/notes/2026-11-27-perf20-region-graddiv.md and docs/design.md §8.

    python3 bench/region_graddiv_spectrum.py [--mesh 16] [--s 1e9 1e11] [--check 1e10] [--at 1e9 4.5e10]
                                             [--table docs/performance/region_graddiv_16.md] [--reuse]

It runs the 3D compound capsule for one step at N^3 (automatic bodies) once per s_I of --s, saving the region's
first matrix (`-coupling_fourier_region_ksp_view_mat`), and splits the velocity block as A(s) = R + sqrt(s) B:
on the s_I band tau_C grows as s^(1/2), so B is the grad-div term per unit sqrt(s_I) and R the rest (mass,
viscosity, the other stabilisation terms, whose s-dependence is below the round-off at these s). --check runs a
third s_I and reports how far the split predicts its matrix. Then, with R's and B's symmetric parts:
- the generalised eigenvalues lambda of B x = lambda R x: the grad-div term's stiffness against the rest, for
  each s of --at a mode is soft where sqrt(s) lambda < 1 (the rest dominates it);
- for every node, its star (the node and the nodes its functions overlap: 5 x 5 x 5 for quadratic splines) and
  the soft modes of the same problem restricted to the star; how much of the region's soft space the stars'
  soft modes span (the cosines of the principal angles, in R's inner product);
- GMRES iterations on the velocity block R + sqrt(s) B, with no grad-div term and at each s of --at,
  preconditioned by additive Schwarz over the stars (exact star solves) or by block Jacobi over the nodes.
Needs Debian's python3-numpy (with python3-matplotlib: scripts/install-deps.sh) and a build (scripts/build.sh).
"""
import argparse
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, provenance, write_table  # noqa: E402

try:
    import numpy as np
except ImportError:
    sys.exit("region_graddiv_spectrum: needs python3-numpy (scripts/install-deps.sh; Debian's /usr/bin/python3)")

BLOCK = 4  # the region's unknowns per node in 3D: three velocities, then the pressure


def read_first_matrix(path):
    """The first matrix of a PETSc binary file (AIJ, big-endian), as (row pointers, columns, values, n)."""
    with open(path, "rb") as f:
        classid, m, n, nz = np.fromfile(f, dtype=">i4", count=4)
        if classid != 1211216 or m != n:
            sys.exit(f"region_graddiv_spectrum: {path}: not a square PETSc binary matrix")
        lengths = np.fromfile(f, dtype=">i4", count=m)
        cols = np.fromfile(f, dtype=">i4", count=nz).astype(np.int64)
        vals = np.fromfile(f, dtype=">f8", count=nz).astype(float)
    return np.concatenate([[0], np.cumsum(lengths)]), cols, vals, int(n)


def dense(mat):
    ptr, cols, vals, n = mat
    a = np.zeros((n, n))
    rows = np.repeat(np.arange(n), np.diff(ptr))
    a[rows, cols] = vals
    return a


def save_region(args, s):
    """Runs one step with s_I = s and returns the saved region matrix's path."""
    out = os.path.join(args.work, f"s{s:g}")
    mat = os.path.join(args.work, f"region_s{s:g}.bin")
    if os.path.exists(mat):
        if args.reuse:
            return mat
        os.remove(mat)
    n = str(args.mesh)
    scene = os.path.join(ROOT, "scenes", "compound_capsule_shear_3d.yaml")
    cmd = [os.path.join(args.build, "apps", "cellfsi"), scene, "-fluid_elements", f"{n},{n},{n}",
           "-solid_membrane_elements", "1,0,0", "-solid_nucleus_elements", "0,0,0", "-final_time", "5e-4",
           "-output_every", "0", "-checkpoint_every", "0", "-s_interface", f"{s:g}", "-output_dir", out,
           "-output_dir_adopt", "-coupling_fourier_region_ksp_view_mat", f"binary:{mat}", "-fluid_space", "equal_order"]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    with open(out + ".log", "w") as log:
        if subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT, env=env) != 0:
            sys.exit(f"region_graddiv_spectrum: the run with s_I {s:g} failed: see {out}.log")
    return mat


def generalized(b, r):
    """Eigenvalues and R-orthonormal eigenvectors of B x = lambda R x (B symmetric, R symmetric positive)."""
    lo = np.linalg.cholesky(r)
    c = np.linalg.solve(lo, np.linalg.solve(lo, b).T).T
    w, y = np.linalg.eigh(0.5 * (c + c.T))
    return w, np.linalg.solve(lo.T, y)


def gmres_iterations(a, rhs, precondition, rtol=1e-6, max_it=300):
    """Right-preconditioned GMRES without restarts on a x = rhs: (iterations, relative residual)."""
    norm = np.linalg.norm(rhs)
    basis, hess = [rhs / norm], np.zeros((max_it + 1, max_it))
    res = 1.0
    for j in range(max_it):
        w = a @ precondition(basis[j])
        for i in range(j + 1):
            hess[i, j] = w @ basis[i]
            w = w - hess[i, j] * basis[i]
        hess[j + 1, j] = np.linalg.norm(w)
        basis.append(w / hess[j + 1, j])
        e1 = np.zeros(j + 2)
        e1[0] = norm
        y = np.linalg.lstsq(hess[:j + 2, :j + 1], e1, rcond=None)[0]
        res = np.linalg.norm(hess[:j + 2, :j + 1] @ y - e1) / norm
        if res < rtol:
            return j + 1, res
    return max_it, res


def additive(a, blocks):
    """The additive Schwarz preconditioner of a over index blocks, with exact (dense) block solves."""
    inverses = [np.linalg.inv(a[np.ix_(ix, ix)]) for ix in blocks]

    def apply(r):
        z = np.zeros_like(r)
        for ix, inv in zip(blocks, inverses):
            z[ix] += inv @ r[ix]
        return z
    return apply


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mesh", type=int, default=16)
    ap.add_argument("--s", type=float, nargs=2, default=[1e9, 1e11], metavar=("S1", "S2"))
    ap.add_argument("--check", type=float, default=1e10)
    ap.add_argument("--at", type=float, nargs="+", default=[1e9, 4.5e10])
    ap.add_argument("--reuse", action="store_true", help="read the matrices an earlier run saved in --work")
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default=os.path.join(ROOT, "out", "region_graddiv"))
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "performance", "region_graddiv_16.md"))
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    s1, s2 = args.s
    m1, m2, mc = (read_first_matrix(save_region(args, s)) for s in (s1, s2, args.check))
    if not (np.array_equal(m1[0], m2[0]) and np.array_equal(m1[1], m2[1])):
        sys.exit("region_graddiv_spectrum: the two runs' regions differ (another marking): use closer s_I")
    n = m1[3]
    vel = np.array([i for i in range(n) if i % BLOCK != BLOCK - 1])
    a1, a2, ac = (dense(m)[np.ix_(vel, vel)] for m in (m1, m2, mc))
    b = (a2 - a1) / (np.sqrt(s2) - np.sqrt(s1))
    rest = a1 - np.sqrt(s1) * b
    check = np.abs(rest + np.sqrt(args.check) * b - ac).max() / np.abs(ac).max()
    bs, rs = 0.5 * (b + b.T), 0.5 * (rest + rest.T)
    rest_eigs = np.linalg.eigvalsh(rs)
    lam, x = generalized(bs, rs)

    # Node graph and stars, from the matrix's pattern (node i's unknowns are BLOCK i .. BLOCK i + 3).
    ptr, cols = m1[0], m1[1]
    nodes = n // BLOCK
    stars = [np.unique(cols[ptr[BLOCK * i]:ptr[BLOCK * i + 1]] // BLOCK) for i in range(nodes)]
    star_nodes = int(np.median([len(star) for star in stars]))
    lines = [f"The region's velocity block at {args.mesh}^3 (the 3D compound capsule, automatic bodies, first "
             f"step): {len(vel)} velocity unknowns on {nodes} nodes; stars of {star_nodes} "
             f"nodes (median). Split A(s) = R + sqrt(s) B from s_I = {s1:g} and {s2:g}; it predicts the matrix "
             f"at {args.check:g} to {check:.1e} (relative, largest entry). R's symmetric part: eigenvalues "
             f"{rest_eigs.min():.2e} to {rest_eigs.max():.2e}, positive.", "",
             "| s_I | soft modes (sqrt(s) lambda < 1) | lambda < 10 | lambda < 100 | largest sqrt(s) lambda "
             "| stars with a soft mode | soft modes in all stars | region's soft modes the stars span "
             "(cosine > 0.9 / > 0.5) |",
             "|---|---|---|---|---|---|---|---|"]
    lo = np.linalg.cholesky(rs)
    for s in args.at:
        scaled = np.sqrt(s) * lam
        soft = x[:, scaled < 1]
        # The stars' soft modes, embedded and mapped by L^T, where they are orthonormal (R-orthonormal in their
        # star); the span of all of them, in R's inner product.
        columns = []
        with_soft = 0
        for star in stars:
            idx = np.array([3 * k + c for k in star for c in range(3)])
            wl, xl = generalized(bs[np.ix_(idx, idx)], rs[np.ix_(idx, idx)])
            keep = xl[:, np.sqrt(s) * wl < 1]
            if keep.shape[1] == 0:
                continue
            with_soft += 1
            emb = np.zeros((len(vel), keep.shape[1]))
            emb[idx] = keep
            columns.append(lo.T @ emb)
        y = np.hstack(columns) if columns else np.zeros((len(vel), 0))
        count = y.shape[1]
        ew, ev = np.linalg.eigh(y @ y.T)
        basis = ev[:, ew > 1e-8 * max(ew.max(), 1e-300)]
        cosines = np.linalg.svd(basis.T @ (lo.T @ soft), compute_uv=False) if soft.shape[1] else np.array([])
        lines.append(f"| {s:g} | {soft.shape[1]} of {len(vel)} | {(scaled < 10).sum()} | {(scaled < 100).sum()} "
                     f"| {scaled.max():.1e} | {with_soft} of {nodes} | {count} "
                     f"| {(cosines > 0.9).sum()} / {(cosines > 0.5).sum()} of {soft.shape[1]} |")
    # The velocity block's own operator (nonsymmetric: convection) by GMRES to 1e-6 from a random right-hand
    # side, preconditioned by additive Schwarz over the stars (the patch smoother's one-level form) or over the
    # nodes' 3 x 3 blocks.
    star_dofs = [np.array([3 * k + c for k in star for c in range(3)]) for star in stars]
    node_dofs = [np.arange(3 * k, 3 * k + 3) for k in range(nodes)]
    rhs = np.random.default_rng(1).standard_normal(len(vel))
    lines += ["", "The velocity block R + sqrt(s) B by GMRES (no restart) to a relative residual of 1e-6 from a "
              "random right-hand side: iterations (residual where 300 did not reach it):", "",
              "| s_I | additive Schwarz over the stars, exact star solves | block Jacobi over the nodes |",
              "|---|---|---|"]
    for s in [0.0] + list(args.at):
        a = rest + np.sqrt(s) * b
        cells = []
        for blocks in (star_dofs, node_dofs):
            its, res = gmres_iterations(a, rhs, additive(a, blocks))
            cells.append(f"{its}" if res < 1e-6 else f"more than {its} ({res:.1e})")
        lines.append(f"| {s:g}{' (no grad-div term)' if s == 0 else ''} | {cells[0]} | {cells[1]} |")
    lines += ["", provenance(argparse.Namespace(jobs=1, runs=args.work),
                             " ".join(["python3 bench/region_graddiv_spectrum.py"] + sys.argv[1:]))]
    write_table(args.table, lines)


if __name__ == "__main__":
    main()
