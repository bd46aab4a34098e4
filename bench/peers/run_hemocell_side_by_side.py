#!/usr/bin/env python3
"""Side by side with HemoCell (issue 47, item 4; bench/peers/README.md): the optical-tweezers stretch of one red
cell in HemoCell's examples/stretchCell and in cellfsi, in a box of the same size (26 x 13 x 13 um), at the same
forces, each run on one core of this machine: the axial and transverse diameters D_A,
D_T against Mills et al. (2004), the wall time and the peak memory.

    python3 bench/peers/run_hemocell_side_by_side.py --hemocell out/peers/hemocell --forces 37.9,87,173

HemoCell runs its example as shipped (its own red-cell model and constants, dx 0.5 um, dt 1e-7 s, 40000 steps =
4 ms) with `<stretchForce>` set to each force; its diameters are the cell's bounding box along x and y (the
example's own stretch-F.log; the example pulls 7 membrane vertices at each end). cellfsi runs scenes/rbc_stretch_3d.yaml in that box (-domain_size
0.0026,0.0013,0.0013 -domain_periodic 1,1,1) at --mesh (39x20x20 quadratic: 2/3 um), each --laws law at its G h
fitted to Mills' D_A by bench/run_stretching.py (docs/validation/stretching*.md: skalak 3.38, strain_hardening
7.32 uN/m), the force grown over 5 ms, to equilibrium. Wall time and peak resident memory of every run are read
by GNU time (/usr/bin/time).

The boundaries differ: HemoCell's example has zero-velocity walls on all six faces, cellfsi's box is periodic
(with walls all round cellfsi has no periodic direction for its Fourier solver and factorises the cell region:
the first step at 39 x 20 x 20 had not ended after 4 minutes). At equilibrium the fluid is at rest, so the
boundaries change how fast the cell comes to rest, not where.

Options: --hemocell DIR (out/peers/hemocell; bench/peers/build_hemocell.sh builds it) --forces PN,PN (37.9,87,173,
HemoCell's documented ones) --laws LAW,LAW (skalak,strain_hardening) --mesh NXxNYxNZ (39x20x20) --runs DIR
(out/peers/stretch) --build DIR (build) --table FILE (docs/validation/hemocell_stretch.md) --report (no runs).
A run whose result is kept is not run again."""
import argparse
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
from bench_common import ROOT, fmt, provenance, write_table  # noqa: E402
from run_stretching import MILLS_AXIAL, MILLS_TRANSVERSE, interpolate  # noqa: E402

TOOL = "run_hemocell_side_by_side.py"
PN = 1e-7  # dyn
THICKNESS = 3.1623e-5  # the scene's shell [cm]
# G h [uN/m] fitted to Mills' D_A at 2/3 um elements (docs/validation/stretching_skalak.md, stretching.md).
FITTED_GH = {"skalak": 3.38, "strain_hardening": 7.32, "neo_hookean": 10.49}


def timed(cmd, cwd, log, env):
    """Runs cmd under GNU time in cwd, its output into log: (exit code, wall s, peak resident MB)."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as t, open(log, "w") as out:
        out.write(" ".join(shlex.quote(c) for c in cmd) + "\n")
        out.flush()
        rc = subprocess.call(["/usr/bin/time", "-f", "%e %M", "-o", t.name] + cmd, cwd=cwd, stdout=out,
                             stderr=subprocess.STDOUT, env=env)
        words = t.read().split()
    wall, kb = (float(words[-2]), float(words[-1])) if len(words) >= 2 else (None, None)
    return rc, wall, kb / 1024 if kb else None


def mpi_env():
    return dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1",
                OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_ess_singleton_isolated="1", OMPI_MCA_pml="ob1")


def run_timed_cellfsi(cmd, log):
    """cellfsi's cmd under GNU time from the repository, in a private Open MPI session directory, its output into
    log: (exit code, wall s, peak MB) and its summary.json in the -output_dir it was given (empty if none)."""
    with tempfile.TemporaryDirectory(prefix="cellfsi-ompi-") as session:
        rc, wall, mb = timed(cmd, ROOT, log, dict(mpi_env(), OMPI_MCA_orte_tmpdir_base=session))
    try:
        summary = json.load(open(os.path.join(cmd[cmd.index("-output_dir") + 1], "summary.json")))
    except (OSError, ValueError):
        summary = {}
    return rc, wall, mb, summary


def kept_or_none(path, args):
    """(True, the kept result) if path holds one; (True, None) with --report; (False, None): run it."""
    if os.path.isfile(path):
        return True, json.load(open(path))
    return bool(args.report), None


def fresh_example(args, example_name, folder, files):
    """HemoCell's built examples/NAME/NAME (exits with a message if not built), with `files` of its folder copied
    into a fresh `folder`: the executable's path."""
    example = os.path.join(args.hemocell, "examples", example_name)
    exe = os.path.join(example, example_name)
    if not os.access(exe, os.X_OK):
        sys.exit(f"{os.path.basename(sys.argv[0])}: --hemocell '{args.hemocell}' has no built "
                 f"examples/{example_name}/{example_name} (bash bench/peers/build_hemocell.sh)")
    shutil.rmtree(folder, ignore_errors=True)
    os.makedirs(folder)
    for name in files:
        shutil.copy(os.path.join(example, name), folder)
    return exe


def run_hemocell(args, force):
    """HemoCell's stretchCell at force [pN] in its own folder: its result dict (kept in result.json)."""
    folder = os.path.join(args.runs, f"hemocell_F{force:g}")
    kept = os.path.join(folder, "result.json")
    done, result = kept_or_none(kept, args)
    if done:
        return result
    exe = fresh_example(args, "stretchCell", folder, ("RBC.pos", "RBC.xml"))
    config = open(os.path.join(os.path.dirname(exe), "config.xml")).read()
    config = re.sub(r"<stretchForce>[^<]*</stretchForce>", f"<stretchForce> {force:g} </stretchForce>", config)
    open(os.path.join(folder, "config.xml"), "w").write(config)
    rc, wall, mb = timed([exe, "config.xml"], folder, os.path.join(folder, "run.log"), mpi_env())
    log = os.path.join(folder, f"stretch-{int(force)}.log")  # the example's name for it
    rows = [line.split() for line in open(log)][1:] if os.path.isfile(log) else []
    result = {"code": "HemoCell v2.7", "force_pN": force, "exit": rc, "wall_s": wall, "peak_MB": mb,
              "status": None if rows else f"exit {rc}, no stretch-{int(force)}.log",
              "axial_um": float(rows[-1][1]) if rows else None, "transverse_um": float(rows[-1][2]) if rows else None,
              "time_ms": int(rows[-1][0]) * 1e-4 if rows else None}  # dt 1e-7 s
    if rc == 0 and rows:
        json.dump(result, open(kept, "w"), indent=1)
    return result


def run_cellfsi(args, law, force):
    """cellfsi in HemoCell's box at force [pN] with law at its fitted G h: its result dict."""
    tag = f"cellfsi_{law}_F{force:g}"
    folder = os.path.join(args.runs, tag)
    kept = os.path.join(args.runs, tag + ".json")
    done, result = kept_or_none(kept, args)
    if done:
        return result
    G = FITTED_GH[law] * 1e-3 / THICKNESS  # uN/m = 1e-3 dyn/cm
    cmd = [os.path.join(args.build, "apps", "cellfsi"), os.path.join(ROOT, "scenes", "rbc_stretch_3d.yaml"),
           "-output_dir", folder, "-output_every", "0", "-domain_size", "0.0026,0.0013,0.0013",
           "-domain_periodic", "1,1,1", "-fluid_elements", args.mesh.replace("x", ","),
           "-solid_rbc_material", law, "-solid_rbc_shear_modulus", f"{G:.6g}",
           "-solid_rbc_stretch_force", f"{force * PN:g}", "-solid_rbc_stretch_ramp", "0.005"]
    rc, wall, mb, s = run_timed_cellfsi(cmd, os.path.join(args.runs, tag + ".log"))
    result = {"code": f"cellfsi {law}", "force_pN": force, "exit": rc, "wall_s": wall, "peak_MB": mb,
              "axial_um": s.get("rbc_axial_diameter", 0) * 1e4 or None,
              "transverse_um": s.get("rbc_transverse_diameter", 0) * 1e4 or None,
              "time_ms": (s.get("rbc_equilibrium_time") or 0) * 1e3 or None, "steps": s.get("steps"),
              "status": s.get("status")}
    if rc == 0 and s.get("status") == "completed":
        json.dump(result, open(kept, "w"), indent=1)
    return result


def mills(data, force):
    return interpolate(force, [f for f, *_ in data], [m for _, m, _, _ in data])


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--hemocell", default=os.path.join(ROOT, "out", "peers", "hemocell"))
    p.add_argument("--forces", default="37.9,87,173")
    p.add_argument("--laws", default="skalak,strain_hardening")
    p.add_argument("--mesh", default="39x20x20")
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "peers", "stretch"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "hemocell_stretch.md"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    # The runs change folders (HemoCell writes into its own): every path absolute.
    args.hemocell, args.runs, args.build, args.table = (os.path.abspath(x) for x in
                                                        (args.hemocell, args.runs, args.build, args.table))
    try:
        forces = [float(v) for v in args.forces.split(",") if v]
        if not forces or min(forces) <= 0 or max(forces) > MILLS_AXIAL[-1][0]:
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --forces '{args.forces}' is invalid: give pN in (0, {MILLS_AXIAL[-1][0]}], comma-separated")
    laws = [w for w in args.laws.split(",") if w]
    for law in laws:
        if law not in FITTED_GH:
            sys.exit(f"{TOOL}: --laws '{law}' is invalid: give {', '.join(FITTED_GH)}, comma-separated")
    if not re.fullmatch(r"\d+x\d+x\d+", args.mesh):
        sys.exit(f"{TOOL}: --mesh '{args.mesh}' is invalid: give NXxNYxNZ (e.g. 39x20x20)")
    os.makedirs(args.runs, exist_ok=True)
    results = []
    for force in forces:
        r = run_hemocell(args, force)
        print(f"{TOOL}: HemoCell {force:g} pN: {r}", flush=True)
        results.append(r)
        for law in laws:
            r = run_cellfsi(args, law, force)
            print(f"{TOOL}: cellfsi {law} {force:g} pN: {r}", flush=True)
            results.append(r)
    command = "python3 bench/peers/" + TOOL + " " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    args.jobs = 1
    lines = [provenance(args, command), "",
             f"Box 26 x 13 x 13 um: HemoCell's with zero-velocity walls on all six faces, cellfsi's periodic (at rest "
             f"at equilibrium either way). HemoCell (7 vertices pulled at each end): its stretchCell example as shipped (dx 0.5 um, dt 1e-7 s, "
             f"4 ms). cellfsi: fluid {args.mesh} quadratic elements, dt 1e-3 s, force grown over 5 ms, to "
             "equilibrium, each law at its G h fitted to Mills' D_A (" +
             ", ".join(f"{law} {FITTED_GH[law]} uN/m" for law in laws) + "). Diameters in um; error: against "
             "Mills et al.'s mean at the force (linear between their forces).", "",
             "| F pN | code | D_A | D_T | D_A - Mills | D_T - Mills | simulated ms | wall s | peak MB | status |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        if r is None:
            continue
        ma, mt = mills(MILLS_AXIAL, r["force_pN"]), mills(MILLS_TRANSVERSE, r["force_pN"])
        a, t = r.get("axial_um"), r.get("transverse_um")
        lines.append(f"| {r['force_pN']:g} | {r['code']} | {fmt(a, '.2f')} | {fmt(t, '.2f')} | "
                     f"{fmt(a - ma if a and ma else None, '+.2f')} | {fmt(t - mt if t and mt else None, '+.2f')} | "
                     f"{fmt(r.get('time_ms'), '.1f')} | {fmt(r.get('wall_s'), '.0f')} | "
                     f"{fmt(r.get('peak_MB'), '.0f')} | "
                     f"{r.get('status') or ('exit ' + str(r.get('exit')))} |")
    write_table(args.table, lines)


if __name__ == "__main__":
    main()
