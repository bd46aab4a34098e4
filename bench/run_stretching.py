#!/usr/bin/env python3
"""The optical-tweezers stretching test of a 3D red blood cell (issue 28, item 4; docs/validation.md): runs
scenes/rbc_stretch_3d.yaml once per membrane law and force, each to equilibrium (-equilibrium_stop), fits the
surface shear modulus G h of each law to the experimental means of Mills et al. (2004), and writes a markdown table
and a figure of the axial and transverse diameters D_A, D_T against the force with the data's spread.

    python3 bench/run_stretching.py                  # both laws, the default forces, the scene's mesh and dt
    python3 bench/run_stretching.py --mesh 24x8x12   # into docs/validation/stretching_24x8x12.md
    python3 bench/run_stretching.py --laws skalak --extra '-solid_rbc_stretch_ramp 0.005'   # stretching_skalak.md

The fit. At a fixed thickness h every stress of a law scales with G (strain_hardening: with C3 / G fixed;
skalak and strain_hardening_membrane: with C fixed), and the fluid changes only how fast the cell comes to rest,
so the equilibrium diameters depend on F / (G h) alone: the runs at the scene's G h (6 uN/m) and forces F give
D(F) at any other G h' as D(F G h / G h'), read off the runs' curve by linear interpolation. The fitted G h' of a
law minimises the squared differences from Mills' means of D_A (and, in a second fit, of D_A and D_T together)
over their forces (a search over G h' on a grid 0.01 uN/m fine); only the G h' for which every data force maps
inside the simulated range are considered. The figure draws each law at its G h fitted to D_A.

Options: --forces PN,PN (every law; default per law, FORCES below) --laws LAW,LAW (neo_hookean,strain_hardening;
  or skalak; or strain_hardening_membrane) --mesh NXxNYxNZ (36x12x18, the scene's) --dt S (the scene's, 1e-3; a
  run whose membrane inverts or whose coupling diverges runs again at dt / 2, then dt / 4) --final-time S (the
  scene's) --extra 'OPTIONS' (to every run; e.g. '-solid_rbc_stretch_ramp 0.005', the force grown over 5 ms)
  --runs DIR (out/STEM) --build DIR (build) --results FILE (docs/validation/STEM.json)
  --table FILE (docs/validation/STEM.md) --figure FILE (docs/figures/STEM.png) --report (no runs); STEM is
  stretching, with _skalak when --laws has skalak, _hardening_membrane when it has strain_hardening_membrane,
  and _MESH for a mesh other than the scene's
A run whose summary.json says "completed", or that inverted or whose coupling diverged (then the next dt runs: a
sudden pull's first steps are the hard ones), is not run again (one made with other options is refused). Exit
code 3 when a run did not complete."""
import argparse
import json
import os
import shlex
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import (ROOT, check_kept_runs, fmt, provenance, pyplot, run_one, save_figure,  # noqa: E402
                          summary_of, write_table)

TOOL = "run_stretching.py"
SCENE = "rbc_stretch_3d.yaml"
PN = 1e-7  # dyn
UN_PER_M = 1e-3  # dyn/cm
# strain_hardening with the scene's C3 = G/30 (Mills et al.), skalak with its default C = 10, and
# strain_hardening_membrane (Mills' hardening of the shape with the area term of skalak's C = 10;
# docs/materials.md)
LAWS = {"neo_hookean": [], "strain_hardening": [], "skalak": [], "strain_hardening_membrane": []}
SURFACE_LAWS = ("skalak", "strain_hardening_membrane")  # their bending modulus is G (1 + C) h^3 / 6
# The default forces [pN] per law at the scene's G h = 6 uN/m: the neo-Hookean cell is 22.5 um long at 190 pN,
# near the box's 24 um (its periodic image), so its sweep ends there; the strain-hardening one goes on to 250 pN
# so that its fit may take G h down to 4.6 uN/m.
# Skalak's law keeps the area and stiffens fast: at G h = 6 uN/m 190 pN stretches the cell to only 13.8 um (1 um
# elements), Mills' 16.3 needs about twice the force, so its sweep goes on to 400 pN.
# strain_hardening_membrane is softer at large strains (17.0 um at 190 pN, 1 um elements): to 250 pN, and from 8 pN
# so that its fit may take G h above 6 uN/m.
FORCES = {"neo_hookean": "15,30,50,80,120,190", "strain_hardening": "15,30,50,80,120,190,250",
          "skalak": "15,30,50,80,120,190,250,320,400",
          "strain_hardening_membrane": "8,15,30,50,80,120,190,250"}

# Mills et al. (2004), the experimental diameters against the force: mean, lowest and highest [um], at force F
# [pN], as digitised in HemoCell's stretchCell validation file (github.com/UvaCsl/HemoCell,
# examples/stretchCell/validation/reference-bounds.dat, commit fc7497d2; the two values at each force are the
# ends of the spread drawn in Mills et al.'s figure, the third the mean). Rest diameter there: 7.92 (7.18-8.58).
MILLS_AXIAL = [  # F, mean, low, high
    (15.9, 9.26, 8.35, 10.10), (19.2, 9.58, 8.70, 10.45), (30.6, 10.53, 9.62, 11.39), (38.0, 11.14, 10.08, 12.29),
    (46.6, 11.86, 10.82, 12.97), (67.4, 12.87, 11.88, 13.87), (87.6, 13.77, 12.58, 14.98),
    (108.6, 14.35, 12.87, 15.82), (129.7, 15.19, 13.89, 16.62), (150.9, 15.60, 14.43, 16.87),
    (173.1, 16.07, 14.26, 17.88), (192.8, 16.30, 14.49, 18.02)]
MILLS_TRANSVERSE = [
    (16.1, 6.20, 5.58, 6.81), (19.8, 6.28, 5.64, 6.92), (30.7, 5.72, 5.13, 6.32), (37.7, 5.44, 4.82, 5.99),
    (46.9, 5.07, 4.29, 5.83), (67.7, 4.64, 3.94, 5.36), (87.6, 4.64, 4.00, 5.27), (109.2, 4.60, 3.98, 5.23),
    (130.0, 4.53, 3.88, 5.19), (151.0, 4.35, 3.78, 4.99), (172.9, 4.60, 4.08, 5.05), (193.0, 4.39, 3.75, 4.94)]
MILLS_REST = (7.92, 7.18, 8.58)


def numbers(text, what, cast=float, positive=True):
    try:
        values = [cast(v) for v in text.split(",") if v != ""]
        if not values or (positive and min(values) <= 0):
            raise ValueError
        return values
    except ValueError:
        sys.exit(f"{TOOL}: {what} '{text}' is invalid: give {'positive ' if positive else ''}numbers, "
                 "comma-separated")


RETRIES = 2  # a run whose membrane inverted or coupling diverged is run again with dt halved, at most this often


def runs_of(args):
    """(law, force in pN, [(tag, scene, options) of each attempt: dt, dt / 2, dt / 4]) of every case."""
    common = ["-output_every", "0"]
    if args.mesh:
        try:
            n = [int(v) for v in args.mesh.split("x")]
            if len(n) != 3 or min(n) < 2:
                raise ValueError
        except ValueError:
            sys.exit(f"{TOOL}: --mesh '{args.mesh}' is invalid: give NXxNYxNZ (e.g. 24x8x12)")
        common += ["-fluid_elements", ",".join(map(str, n))]
    if args.final_time:
        common += ["-final_time", f"{args.final_time:g}"]
    common += shlex.split(args.extra)
    mesh = args.mesh or "scene"
    out = []
    for law in args.laws:
        for f in args.forces or sorted(numbers(FORCES[law], "FORCES")):
            attempts = []
            for k in range(RETRIES + 1):
                dt = (args.dt or scene_dt()) / 2 ** k
                attempts.append((f"{law}_{mesh}_F{f:g}" + (f"_dt{dt:g}" if k else ""), SCENE,
                                 common + (["-dt", f"{dt:g}"] if k or args.dt else []) +
                                 ["-solid_rbc_material", law, "-solid_rbc_stretch_force", f"{f * PN:g}"] + LAWS[law]))
            out.append((law, f, attempts))
    return out


def scene_dt():
    with open(os.path.join(ROOT, "scenes", SCENE)) as f:
        for line in f:
            if line.startswith("dt:"):
                return float(line.split(":")[1])
    sys.exit(f"{TOOL}: scenes/{SCENE} has no dt")


def scene_mesh():
    with open(os.path.join(ROOT, "scenes", SCENE)) as f:
        for line in f:
            if line.startswith("fluid_elements:"):
                return line.split(":")[1].strip().replace(",", "x")
    return "the scene's"


def inverted(args, tag):
    """The run failed in a way a smaller step cures: an inverted element or a diverged coupling iteration."""
    s = summary_of(args, tag)
    return bool(s) and any(w in str(s.get("status")) for w in ("inverted", "diverged"))


def chosen(args, attempts):
    """The attempt that stands for a case: the first that completed, else the last one run (None: not run)."""
    last = None
    for tag, _, options in attempts:
        s = summary_of(args, tag)
        if s is None:
            break
        last = (tag, s, options)
        if s.get("status") == "completed":
            break
    return last


def interpolate(x, xs, ys):
    for i in range(1, len(xs)):
        if x <= xs[i]:
            return ys[i - 1] + (ys[i] - ys[i - 1]) * (x - xs[i - 1]) / (xs[i] - xs[i - 1])
    return None


def curve(points, key):
    """(forces [pN], diameters [um]) of one law's completed runs at equilibrium, with the rest shape at F = 0."""
    done = sorted((f, s) for f, s, _ in points if s and s.get("status") == "completed" and
                  s.get("rbc_equilibrium_time") is not None)
    if not done:
        return [], []
    rest = 2 * 3.91  # the Evans-Fung mid-surface diameter; replaced by the measured one when a run gives it
    fs, ds = [0.0], [rest]
    for f, s in done:
        fs.append(f)
        ds.append(s[key] * 1e4)
    return fs, ds


def fit(fs, da, dt, gh0, with_transverse):
    """The G h [uN/m] minimising the squared differences from Mills' means of D_A (and of D_T, with_transverse),
    with the RMS differences of each and the residuals; None when the runs do not span the data at any G h in
    1 ... 50 uN/m. `edge`: the best G h is the smallest the runs' largest force allows (a smaller one might fit
    better)."""
    best = None
    fmax = fs[-1] if fs else 0
    lowest = None
    for k in range(100, 5001):
        gh = k * 0.01
        if max(MILLS_AXIAL[-1][0], MILLS_TRANSVERSE[-1][0]) * gh0 / gh > fmax:
            continue
        lowest = gh if lowest is None else lowest
        ra = [interpolate(F * gh0 / gh, fs, da) - m for F, m, _, _ in MILLS_AXIAL]
        rt = [interpolate(F * gh0 / gh, fs, dt) - m for F, m, _, _ in MILLS_TRANSVERSE]
        cost = sum(r * r for r in ra + (rt if with_transverse else []))
        if best is None or cost < best["cost"]:
            best = {"G_h_uN_per_m": gh, "cost": cost, "rms_axial_um": (sum(r * r for r in ra) / len(ra)) ** 0.5,
                    "rms_transverse_um": (sum(r * r for r in rt) / len(rt)) ** 0.5, "residual_axial_um": ra,
                    "residual_transverse_um": rt}
    if best:
        best["edge"] = best["G_h_uN_per_m"] == lowest
    return best


def results(args, runs):
    by_law = {law: [] for law in args.laws}
    for law, f, attempts in runs:
        c = chosen(args, attempts)
        dt = (c[2][c[2].index("-dt") + 1] if "-dt" in c[2] else f"{scene_dt():g}") if c else None
        by_law[law].append((f, c[1] if c else None, dt))
    out = {}
    for law, points in by_law.items():
        fs, da = curve(points, "rbc_axial_diameter")
        _, dt = curve(points, "rbc_transverse_diameter")
        any_s = next((s for _, s, _ in points if s), None)
        gh0 = None
        if any_s:
            g = any_s["rbc_shear_modulus"]
            # The shell's bending modulus: G h^3 / 3, the surface laws' G (1 + C) h^3 / 6 (docs/materials.md).
            k = (1 + any_s["rbc_area_dilation"]) / 6 if any_s.get("rbc_material") in SURFACE_LAWS else 1 / 3
            h = (any_s["rbc_bending_modulus"] / (k * g)) ** (1 / 3)
            gh0 = g * h / UN_PER_M
        out[law] = {"forces_pN": fs, "axial_um": da, "transverse_um": dt, "G_h_run_uN_per_m": gh0,
                    "fit": None, "fit_both": None, "runs": []}
        for f, s, dt_used in sorted(points, key=lambda p: p[0]):
            row = {"force_pN": f, "status": s.get("status") if s else "not run", "dt": dt_used}
            if s:
                row.update({k: s.get("rbc_" + k) for k in ("axial_diameter", "transverse_diameter", "equilibrium_time",
                                                           "centroid_shift", "r_P", "max_abs_r_A",
                                                           "enclosed_change", "max_stretch")})
                row.update({"steps": s.get("steps"), "wall_time_s": s.get("wall_time_s"),
                            "coupling_iterations": s.get("coupling_iterations"),
                            "elements": [s.get(f"rbc_elements_{d}") for d in range(3)]})
            out[law]["runs"].append(row)
        if gh0 and len(fs) > 2:
            out[law]["fit"] = fit(fs, da, dt, gh0, with_transverse=False)
            out[law]["fit_both"] = fit(fs, da, dt, gh0, with_transverse=True)
    return out


def predicted(res, law, F, key):
    r = res[law]
    if not r["fit"]:
        return None
    return interpolate(F * r["G_h_run_uN_per_m"] / r["fit"]["G_h_uN_per_m"], r["forces_pN"], r[key])


def table(args, runs, res, command):
    lines = [provenance(args, command), ""]
    elements = next((row["elements"] for law in args.laws for row in res[law]["runs"] if "elements" in row), None)
    lines += [f"Mesh: fluid {args.mesh or scene_mesh()} quadratic elements, membrane "
              f"{' x '.join(str(int(e)) for e in elements) if elements else '-'} "
              f"({'given' if '-solid_rbc_elements' in args.extra else 'automatic'}); G h of the runs "
              f"{fmt(res[args.laws[0]]['G_h_run_uN_per_m'], '.2f')} uN/m.", ""]
    complete = True
    lines += ["Runs (the scene's G h; equilibrium: the first time neither diameter changed by more than "
              "-equilibrium_tolerance over -equilibrium_window):", "",
              "| law | F pN | dt s | D_A um | D_T um | t_eq ms | steps | wall s | coupling it./step | r_P | max abs r_A | "
              "enclosed change | centroid shift um | status |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for law in args.laws:
        for row in res[law]["runs"]:
            ok = row["status"] == "completed"
            complete = complete and ok and row.get("equilibrium_time") is not None
            if "steps" not in row:
                lines.append(f"| {law} | {row['force_pN']:g} | - | - | - | - | - | - | - | - | - | - | - | {row['status']} |")
                continue
            steps = max(1, row["steps"] or 1)
            t_eq = row["equilibrium_time"]
            lines.append(
                f"| {law} | {row['force_pN']:g} | {row['dt']} | {fmt(row['axial_diameter'] and row['axial_diameter'] * 1e4, '.3f')} | "
                f"{fmt(row['transverse_diameter'] and row['transverse_diameter'] * 1e4, '.3f')} | "
                f"{fmt(t_eq and t_eq * 1e3, '.1f') if t_eq is not None else 'not reached'} | {row['steps']} | "
                f"{fmt(row['wall_time_s'], '.0f')} | {(row['coupling_iterations'] or 0) / steps:.1f} | "
                f"{fmt(row['r_P'], '.4f')} | {fmt(row['max_abs_r_A'], '.1e')} | {fmt(row['enclosed_change'], '.1e')} | "
                f"{fmt(row['centroid_shift'] and row['centroid_shift'] * 1e4, '.1e')} | {row['status']} |")
    lines += ["", "Fitted surface shear modulus G h (Mills et al. 2004 report 5-12 uN/m), least squares on the means "
              "of D_A alone and of D_A and D_T together (at the edge: the smallest G h the runs' largest force "
              "reaches):", "", "| law | fitted to | G h uN/m | RMS D_A um | RMS D_T um |", "|---|---|---|---|---|"]
    for law in args.laws:
        for key, what in (("fit", "D_A"), ("fit_both", "D_A and D_T")):
            f = res[law][key]
            lines.append(f"| {law} | {what} | " +
                         (f"{f['G_h_uN_per_m']:.2f}{' (at the edge)' if f['edge'] else ''} | "
                          f"{f['rms_axial_um']:.3f} | {f['rms_transverse_um']:.3f} |" if f else "- | - | - |"))
    lines += ["", "Each law at its G h fitted to D_A against Mills et al.'s means (spread in brackets) [um]:", "",
              "| F pN | D_A data | " + " | ".join(f"D_A {law}" for law in args.laws) + " | D_T data | " +
              " | ".join(f"D_T {law}" for law in args.laws) + " |",
              "|---|---|" + "---|" * len(args.laws) + "---|" + "---|" * len(args.laws)]
    for (F, m, lo, hi), (Ft, mt, lot, hit) in zip(MILLS_AXIAL, MILLS_TRANSVERSE):
        pa = [fmt(predicted(res, law, F, "axial_um"), ".2f") for law in args.laws]
        pt = [fmt(predicted(res, law, Ft, "transverse_um"), ".2f") for law in args.laws]
        lines.append(f"| {F:g} / {Ft:g} | {m:.2f} ({lo:.2f}-{hi:.2f}) | " + " | ".join(pa) +
                     f" | {mt:.2f} ({lot:.2f}-{hit:.2f}) | " + " | ".join(pt) + " |")
    write_table(args.table, lines)
    return complete


def figure(args, res):
    plt = pyplot(TOOL)
    if plt is None:
        return
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.4))
    for i, (data, key, name) in enumerate([(MILLS_AXIAL, "axial_um", "axial D_A"),
                                           (MILLS_TRANSVERSE, "transverse_um", "transverse D_T")]):
        F = [0.0] + [d[0] for d in data]
        m = [MILLS_REST[0]] + [d[1] for d in data]
        lo = [MILLS_REST[1]] + [d[2] for d in data]
        hi = [MILLS_REST[2]] + [d[3] for d in data]
        ax[i].errorbar(F, m, yerr=[[a - b for a, b in zip(m, lo)], [b - a for a, b in zip(m, hi)]], fmt="ko",
                       ms=4, capsize=3, label="Mills et al. 2004 (mean, spread)")
        for law, style in zip(args.laws, ["-", "--", "-.", ":"]):
            r = res[law]
            if not r["forces_pN"]:
                continue
            g0 = r["G_h_run_uN_per_m"]
            if r["fit"]:
                gh = r["fit"]["G_h_uN_per_m"]
                ax[i].plot([f * gh / g0 for f in r["forces_pN"]], r[key], "b" + style if law == "neo_hookean"
                           else "r" + style, marker="s", ms=3,
                           label=f"{law}, G h = {gh:.2f} uN/m (fitted to D_A)")
            ax[i].plot(r["forces_pN"], r[key], style, color="0.6", lw=1,
                       label=f"{law}, G h = {g0:.2f} uN/m (runs)")
        ax[i].set_xlabel("F (pN)")
        ax[i].set_ylabel(f"{name} (um)")
        ax[i].set_xlim(0, 200)
        ax[i].grid(alpha=0.3)
    ax[0].legend(fontsize=7)
    ax[0].set_title("axial diameter")
    ax[1].set_title("transverse diameter")
    save_figure(fig, args.figure, TOOL)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--forces", default="")
    p.add_argument("--laws", default="neo_hookean,strain_hardening")
    p.add_argument("--mesh", default="36x12x18")
    p.add_argument("--dt", type=float, default=0)
    p.add_argument("--final-time", type=float, default=0)
    p.add_argument("--extra", default="")
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", default="")
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--results", default="")
    p.add_argument("--table", default="")
    p.add_argument("--figure", default="")
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    args.forces = sorted(numbers(args.forces, "--forces")) if args.forces else None
    args.laws = [w for w in args.laws.split(",") if w]
    for law in args.laws:
        if law not in LAWS:
            sys.exit(f"{TOOL}: --laws '{law}' is invalid: give {', '.join(LAWS)}, comma-separated")
    # Default outputs: stretching[_skalak][_MESH] (a sweep with Skalak's law and a mesh other than the scene's have
    # pages of their own, so that one sweep does not overwrite another's).
    stem = "stretching" + ("_skalak" if "skalak" in args.laws else "") + \
        ("_hardening_membrane" if "strain_hardening_membrane" in args.laws else "") + \
        ("" if args.mesh == "36x12x18" else f"_{args.mesh}")
    args.runs = args.runs or os.path.join(ROOT, "out", stem)
    args.results = args.results or os.path.join(ROOT, "docs", "validation", stem + ".json")
    args.table = args.table or os.path.join(ROOT, "docs", "validation", stem + ".md")
    args.figure = args.figure or os.path.join(ROOT, "docs", "figures", stem + ".png")
    runs = runs_of(args)
    os.makedirs(args.runs, exist_ok=True)
    check_kept_runs(TOOL, args, [a for _, _, attempts in runs for a in attempts])
    if not args.report:
        for _, _, attempts in runs:  # one at a time: each run takes the machine's share of one core
            for tag, scene, options in attempts:
                # An attempt that inverted (or diverged) is not run again: the next, at half its dt, is.
                status = "kept (failed)" if inverted(args, tag) else run_one(args, tag, scene, options)[1]
                print(f"{TOOL}: {tag}: {status}", flush=True)
                if not inverted(args, tag):
                    break
    res = results(args, runs)
    os.makedirs(os.path.dirname(args.results) or ".", exist_ok=True)
    with open(args.results, "w") as f:
        json.dump(res, f, indent=1)
    complete = table(args, runs, res, "python3 bench/run_stretching.py " + " ".join(shlex.quote(a) for a in sys.argv[1:]))
    figure(args, res)
    sys.exit(0 if complete else 3)


if __name__ == "__main__":
    main()
