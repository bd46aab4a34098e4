#!/usr/bin/env python3
"""The reference tables of docs/validation.md, docs/validation-future-work.md and docs/performance.md, generated
from the kept results.

One table per scene (mesh, degree, dt, the error against the paper or the truth, s/step, memory, commit,
command), written between marker comments in those pages:

    <!-- BEGIN TABLE name -->  ...generated...  <!-- END TABLE name -->

Sources, in this order of preference:
  1. the tables the bench scripts wrote into docs/validation/*.md and docs/performance/*.md (their provenance
     line gives the commit), and the kept runs' docs/validation/runs/*_summary.json;
  2. REGISTRY below: the values that exist only as prose, each with the commit it was measured at and the
     note in docs/notes/ it comes from. Add a value here only with both; better, keep its run's table.

Usage:
  python3 bench/reference_tables.py           rewrite the tables in the docs
  python3 bench/reference_tables.py --check   exit 1 if a table differs from what would be written, or if a
                                              relative link in README.md, CHANGELOG.md or docs/ (its notes
                                              included) names a missing file or heading; print each
Python 3 and its standard library only.
"""
import argparse
import glob
import json
import math
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
from bench_common import PAPER_MEMBRANE  # noqa: E402  (the scenes' paper membranes, as the drivers run them)
from run_rbc_shear_3d import ASPECT as ASPECT_RBC, RATE as RATE_RBC  # noqa: E402  (Ca 0.46's 700 1/s)

VAL = os.path.join(ROOT, "docs", "validation")
PERF = os.path.join(ROOT, "docs", "performance")
PAGES = ["docs/validation.md", "docs/validation-future-work.md", "docs/performance.md"]

# ---------------------------------------------------------------------------------------------------------
# Values that exist only as prose: (commit, note in docs/notes/) for each.
# ---------------------------------------------------------------------------------------------------------
N = "docs/notes/"
REGISTRY = {
    "stiff_disk": dict(
        commit="d61f5db", note=N + "2026-11-23-val-stiff-disk.md",
        rows=[("64x32", 0.9971), ("128x64", 0.9911), ("256x128", 0.9901)]),
    "plasma": dict(
        commit="6d1dfde", note=N + "2026-11-21-perf03-scene-costs.md",
        rows=[("shear", "64x32", "shear profile against the linear one", "1.7e-16 of the wall speed", 1.7, 20),
              ("poiseuille", "96x32", "u_max against f H^2 / (8 mu)", "2.6e-7 (relative)", 2.9, 20)]),
    "migration": dict(
        note=N + "2026-11-24-val-channel-migration.md",
        rows=[dict(mesh="128x64", commit="678009a", tenth=1.71, offset08=0.72, s_step=0.59, memory="0.78 GB",
                   extra="-final_time 2.4", how="continued twice from its checkpoint with -restart"),
              dict(mesh="256x128", commit="88d52c0", tenth=1.38, offset08=0.61, s_step=2.8, memory="-",
                   extra="-final_time 3.0", how="stopped at 2.19 s; -restart continues it")]),
    "ctc_192": dict(
        commit="b2c4108", note=N + "2026-11-24-val-ctc-narrowing.md", mesh="192x64", transit=0.051,
        dip=-30, anisotropy=12.0, r_A=2.3e-3, s_step=1.9, memory="1.5 GB"),
    "rbc_shear_3d": dict(
        commit="9f922d2", note=N + "2026-11-26-val-rbc-3d.md", mesh="16x16x16", p=2, dt="1e-3",
        half_turn=0.147, jeffery=0.152, s_step=6.7, memory="0.73 GB"),
    # The 12^3 and 16^3 runs of shear_3d.md: their commit and peak memory (one rank, an LU per step then).
    "compound_3d_coarse": dict(
        commit="6ff938d", note=N + "2026-11-27-val-compound-capsule-3d.md",
        memory={"12": "0.53 GB", "16": "1.32 GB"}),
    # The 64^3 runs' s/step and memory: their summaries' wall times cover only the part run after a restart.
    "compound_3d_cost": dict(
        note=N + "2026-11-27-val-compound-capsule-3d.md",
        rows={"shear_3d_32cube": ("15.6", "2.8 GB"), "shear_3d_48cube": ("about 36 (one rank, loaded)", "4.8 GB"),
              "shear_3d_64cube": ("31-36 (undisturbed steps)", "4.6 GB per rank"),
              "shear_3d_64cube_scene": ("29-31 (undisturbed steps)", "4.6 GB per rank")}),
    # Kernels: the latest measured per element (us), best of 7 (bench/fluid_assembly).
    "assembly": dict(
        note=N + "2026-11-27-perf16-residual-and-region-lu-parts.md", commit="3dc13db",
        rows=[("2D residual", 2, "0.86"), ("2D residual", 3, "1.82"), ("3D residual", 2, "5.15-5.38"),
              ("3D residual", 3, "19.8-20.0"), ("3D Jacobian", 2, "90.0-98.8")]),
    "assembly_2d_jacobian": dict(
        note=N + "2026-11-21-perf01-fluid-assembly.md", commit="30647ab",
        rows=[("2D Jacobian", 2, "2.03"), ("2D Jacobian", 3, "5.16-5.71")]),
    "targets_26": dict(
        note=N + "2026-11-27-perf19-openblas-kernels.md", commit="e017b11",
        rows=[("64^3, a coupled step on 2 ranks", "at most 12 s", "25.8 s (21.4 s with OpenBLAS's AVX-512 kernels)",
               "missed by 2.1x"),
              ("64^3 on 1 rank", "at most 8 GB", "5.20 GB", "met"),
              ("32^3, a step on 2 ranks", "at most 2 s", "3.5-4.3 s", "missed by 1.75x or more"),
              ("the paper's 64^3 run to 0.3 s on 2 ranks", "within 2 h", "about 4.5-5.5 h (600 steps)",
               "missed by 2.3-2.8x")]),
}


# ---------------------------------------------------------------------------------------------------------
# Reading the kept results
# ---------------------------------------------------------------------------------------------------------
def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def md_tables(path):
    """Every pipe table of a markdown file: a list of lists of dicts keyed by the header's cells."""
    tables, cur, header = [], None, None
    for line in read(path).split("\n"):
        if line.startswith("|"):
            cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
            if header is None:
                seen = {}
                header = []
                for c in cells:  # a repeated header cell ("paper" twice) gets its count: "paper 2"
                    seen[c] = seen.get(c, 0) + 1
                    header.append(c if seen[c] == 1 else f"{c} {seen[c]}")
            elif set("".join(cells)) <= set("-: "):
                cur = []
                tables.append(cur)
            elif cur is not None:
                cur.append(dict(zip(header, cells)))
        else:
            header, cur = None, None
    return tables


def commit_of(path):
    """The commit in a kept table's provenance line: 'git abc1234' (-dirty or 'with uncommitted changes')."""
    m = re.search(r"git\s+([0-9a-f]{7,12})(-dirty|\s+with\s+uncommitted\s+changes)?", read(path))
    if not m:
        return "-"
    return m.group(1)[:7] + ("-dirty" if m.group(2) else "")


def rel(path):
    return os.path.relpath(path, ROOT)


def summary(name):
    return json.loads(read(os.path.join(VAL, "runs", name + "_summary.json")))


def num(s):
    return float(s.replace("\\", "").split()[0])


def per_step(wall, steps):
    return f"{float(wall) / float(steps):.2f}"


def mesh_comma(mesh):
    return mesh.replace("x", ",")


# ---------------------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------------------
COLUMNS = ["mesh", "p", "dt s", "compared", "cellfsi", "paper / truth", "difference", "s/step", "memory",
           "commit", "command"]


def table(rows, sources, columns=COLUMNS):
    out = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for r in rows:
        out.append("| " + " | ".join(str(c) for c in r) + " |")
    out.append("")
    out.append("Generated by `python3 bench/reference_tables.py` from " + "; ".join(sources) + ".")
    return "\n".join(out)


# The scenes that run on the divergence-conforming space as shipped (README, "Which space a scene uses"): a
# table's command of one of them without -fluid_space was measured on the paper's space, which it then names
# (and the paper's membrane where the scene's is now from the mesh, or finer in 3D).
DC_SCENES = r"(capsule_shear|compound_capsule_shear|biconcave_capsule_shear|capsule_channel_migration|" \
            r"compound_capsule_shear_3d)"


def code(s):
    m = re.search(r"\bcellfsi scenes/" + DC_SCENES + r"\.yaml", s)
    if m and "-fluid_space" not in s:
        s += " -fluid_space equal_order"
        if m.group(1) in PAPER_MEMBRANE and "-solid_membrane_elements" not in s:
            s += " -solid_membrane_elements " + PAPER_MEMBRANE[m.group(1)]
    return "`" + s + "`"


def note_link(note):
    """A note of docs/notes/ as a link from docs/X.md."""
    return f"[{os.path.basename(note)}]({note[len('docs/'):]})"


def link_from_page(path):
    """A kept file as a link from docs/X.md."""
    r = rel(path)
    return f"[{os.path.basename(r)}]({os.path.relpath(os.path.join(ROOT, r), os.path.join(ROOT, 'docs'))})"


# ---------------------------------------------------------------------------------------------------------
# validation.md: one table per scene
# ---------------------------------------------------------------------------------------------------------
def t_capsule_shear():
    path = os.path.join(VAL, "capsule_table1_central.md")
    commit = commit_of(path)
    rows = []
    for r in md_tables(path)[0]:
        th, thp = num(r["theta deg"]), float(r["paper"])
        om, omp = num(r["omega_TT 1/s"]), float(r["paper 2"])
        cmd = (f"cellfsi scenes/capsule_shear.yaml -fluid_elements {mesh_comma(r['mesh'])} -fluid_degree {r['p']} "
               f"-dt {r['dt s']} -final_time 0.3 -metrics_average_from 0.15 -solid_membrane_elements 1,0 "
               f"-s_interface 1e10")
        rows.append([r["mesh"], r["p"], r["dt s"], "theta deg, omega_TT 1/s", f"{th:.2f}, {om:.3f}",
                     f"{thp:.2f}, {omp:.2f} (paper, same mesh)", f"{th - thp:+.2f} deg, {100 * (om / omp - 1):+.1f} %",
                     r["s/step"], "-", commit, code(cmd)])
    return table(rows, [link_from_page(path) + " (memory not recorded)"])


RA = "max \\|r_A\\|"  # a header cell of the generated tables (the pipe escaped)


def t_capsule_two_spaces():
    # dt 1e-3 (the project's Table 1 runs) and dt 5e-4 (the scene's and the paper's), one file each
    paths = [os.path.join(VAL, f) for f in ("two_spaces_capsule.md", "two_spaces_capsule_dt5e-4.md")]
    paths = [p for p in paths if os.path.exists(p)]
    rows = []
    for path in paths:
        rows += capsule_two_spaces_rows(path)
    cols = ["space, degree" if c == "p" else c for c in COLUMNS]
    return table(rows, [" and ".join(link_from_page(p) for p in paths) +
                        " (memory not recorded; coupling and FGMRES iterations there)"], cols)


def capsule_two_spaces_rows(path):
    commit = commit_of(path)
    rows = []
    for r in md_tables(path)[0]:
        th, om = num(r["theta deg"]), num(r["omega_TT 1/s"])
        space, degree = r["space"], r["degree"]
        extra = (f"-fluid_space div_conforming -fluid_dc_degree {degree}" if space == "div_conforming"
                 else "-fluid_space equal_order")
        cmd = (f"cellfsi scenes/capsule_shear.yaml -fluid_elements {mesh_comma(r['mesh'])} -fluid_degree {degree} "
               f"-dt {r['dt s']} -final_time 0.3 -metrics_average_from 0.15 -solid_membrane_elements 1,0 {extra}")
        ra = r[RA]
        rows.append([r["mesh"], f"{space} {degree}", r["dt s"], f"theta deg, omega_TT 1/s; {RA}",
                     f"{th:.2f}, {om:.3f}; {ra}", "26.09, 3.90 (paper, 512 x 256 cubic)",
                     f"{th - 26.09:+.2f} deg, {100 * (om / 3.90 - 1):+.1f} %", r["s/step"], "-", commit, code(cmd)])
    return rows


def t_two_spaces_area():
    # dt fixed (two_spaces_area.md), then dt halved with h from 1e-3 and from 5e-4 (two_spaces_area_dt_h.md,
    # two_spaces_area_dt_h5.md, when they have been run)
    paths = [os.path.join(VAL, f)
             for f in ("two_spaces_area.md", "two_spaces_area_dt_h.md", "two_spaces_area_dt_h5.md")]
    paths = [p for p in paths if os.path.exists(p)]
    rows = []
    for path in paths:
        tables = md_tables(path)
        rows += [[r["mesh"], f"{r['space']} {r['degree']}", r["dt s"], r["T s"], r[RA], r[RA + " from 0.1 s"],
                  r["r_A(T)"], r["ratio to the coarser mesh (from 0.1 s)"], r["coupling it/step"], r["s/step"],
                  r["status"]]
                 for r in (tables[0] if tables else [])]
    cols = ["mesh", "space", "dt s", "T s", RA, RA + " from 0.1 s", "r_A(T)", "ratio to the coarser mesh (from 0.1 s)",
            "coupling it/step", "s/step", "status"]
    return table(rows, [" and ".join(link_from_page(p) for p in paths)], cols)


def t_two_spaces_sweeps():
    """The paper's shear sweeps on both spaces at one mesh, side by side: each quantity as
    divergence-conforming / equal-order, and each space's seconds per step."""
    rows, sources = [], []
    skip = {"steps", "wall s", "status", "half-turns"}
    for sweep in ("swelling", "bulky", "compound"):
        paths = [os.path.join(VAL, f"two_spaces_shear_{sweep}_{s}.md") for s in ("dc", "eo")]
        if not all(os.path.exists(p) for p in paths):
            continue
        sources += [link_from_page(p) for p in paths]
        dc, eo = (md_tables(p)[0] for p in paths)
        eo_by_key = {r[list(r)[0]]: r for r in eo}
        for r in dc:
            key = list(r)[0]
            o = eo_by_key.get(r[key])
            if o is None:
                continue
            pairs = [f"{c} {r[c]} / {o[c]}" for c in list(r)[2:] if c not in skip and (r[c], o[c]) != ("-", "-")]
            per_step = [fmt_per_step(x) for x in (r, o)]
            rows.append([sweep, f"{key} {r[key]}", f"{list(r)[1]} {r[list(r)[1]]}", "; ".join(pairs),
                         " / ".join(per_step), f"{r['status']} / {o['status']}"])
    cols = ["sweep", "value", "shape", "div-conforming / equal-order", "s/step", "status"]
    return table(rows, sources or ["(not run)"], cols)


def fmt_per_step(r):
    try:
        return f"{float(r['wall s']) / float(r['steps']):.3f}"
    except (KeyError, ValueError, ZeroDivisionError):
        return "-"


def t_default_scene():
    path = os.path.join(VAL, "default_scene.md")
    rows = []
    for r in md_tables(path)[0]:
        space, _, degree = r["space, degree"].partition(" ")
        rows.append([r["mesh"], f"{degree} ({space})", r["dt s"], "theta deg, omega_TT 1/s; max \\|r_A\\|",
                     r["theta deg, omega_TT 1/s"] + "; " + r["max abs r_A"],
                     "26.09, 3.90 (paper's converged, 512 x 256)", r["difference"],
                     per_step(num(r["wall s"]), 125), r["memory"], commit_of(path), r["command"]])
    return table(rows, [f"[default_scene.md](validation/default_scene.md) (`python3 bench/run_default_scene.py`, "
                        "one run after the other, one rank each; s/step: the run's wall time over its 125 steps, "
                        "set-up included)"])


def t_stiff_disk():
    d = REGISTRY["stiff_disk"]
    rows = []
    for mesh, w in d["rows"]:
        cmd = ("cellfsi scenes/capsule_shear.yaml -solid_membrane_shape ellipse "
               "-solid_membrane_semi_axes 7.5e-5,7.5e-5 "
               "-solid_membrane_elements 0,0 -solid_membrane_shear_modulus 40 -solid_membrane_density 1.025 "
               f"-dt 1e-3 -final_time 0.1 -fluid_elements {mesh_comma(mesh)} -s_interface 1e10")
        rows.append([mesh, 3, "1e-3", "rotation / (gammadot / 2)", f"{w:.4f}", "1 (unbounded shear)",
                     f"{100 * (w - 1):+.2f} %", "-", "-", d["commit"], code(cmd)])
    return table(rows, [f"REGISTRY['stiff_disk'] ({note_link(d['note'])})"])


def sweep_rows(path, mesh, dt, pick, compare, scene, extra):
    commit = commit_of(path)
    rows = []
    for r in md_tables(path)[0]:
        if not pick(r):
            continue
        ours, ref, diff, what = compare(r)
        cmd = (f"cellfsi scenes/{scene} -fluid_elements {mesh_comma(mesh)} -dt {dt} {extra(r)}").strip()
        rows.append([mesh, 3, dt, what, ours, ref, diff, per_step(r["wall s"], r["steps"]), "-", commit, code(cmd)])
    return rows


def t_biconcave():
    path = os.path.join(VAL, "shear_swelling.md")
    rs = md_tables(path)[0]
    ell = [(num(r["Delta"]), num(r["theta deg"]), num(r["omega_TT 1/s"])) for r in rs if r["a cm"] != "biconcave"]
    bic = [r for r in rs if r["a cm"] == "biconcave"][0]
    delta = num(bic["Delta"])
    lo = max((e for e in ell if e[0] <= delta), key=lambda e: e[0])
    hi = min((e for e in ell if e[0] >= delta), key=lambda e: e[0])
    f = (delta - lo[0]) / (hi[0] - lo[0])
    th_i, om_i = lo[1] + f * (hi[1] - lo[1]), lo[2] + f * (hi[2] - lo[2])

    def compare(r):
        th, om = num(r["theta deg"]), num(r["omega_TT 1/s"])
        return (f"{th:.2f}, {om:.3f}", f"{th_i:.2f}, {om_i:.2f} (the elliptic capsules' curve, interpolated)",
                f"{th - th_i:+.2f} deg, {100 * (om / om_i - 1):+.1f} %", "theta deg, omega_TT 1/s")
    rows = sweep_rows(path, "128x64", "1e-3", lambda r: r["a cm"] == "biconcave", compare,
                      "biconcave_capsule_shear.yaml",
                      lambda r: "-final_time 0.3 -metrics_average_from 0.15 -s_interface 1e10")
    p5 = os.path.join(VAL, "shear_viscosity_biconcave_capsule_shear_256x128.md")
    rows += sweep_rows(p5, "256x128", "1e-3", lambda r: True,
                       lambda r: (f"{num(r['theta deg']):.2f}, {num(r['omega_TT 1/s']):.3f}",
                                  "no paper value (lambda = 5)",
                                  "-", "lambda 5: theta deg, omega_TT 1/s"),
                       "biconcave_capsule_shear.yaml",
                       lambda r: "-final_time 1.0 -metrics_average_from 0.5 -solid_membrane_inner_viscosity 0.06")
    return table(rows, [link_from_page(path), link_from_page(p5)])


def t_bulky():
    path = os.path.join(VAL, "shear_bulky.md")

    def compare(r):
        a, b = float(r["a cm"]), 1e-4
        jeff = 70.0 / (2 * 3.141592653589793 * (a / b + b / a))
        om = num(r["omega_TU 1/s"])
        return (f"{om:.3f} ({r['regime']})", f"{jeff:.3f} (Jeffery, unbounded)", f"{100 * (om / jeff - 1):+.0f} %",
                f"a = {float(r['a cm']):g} cm: omega_TU 1/s")
    rows = sweep_rows(path, "128x64", "1e-3", lambda r: True, compare, "bulky_ellipse_shear.yaml",
                      lambda r: f"-solid_body_semi_axes {float(r['a cm']):g},1e-4 -final_time 0.5 "
                                f"-metrics_average_from 0.1 -s_interface 1e10")
    return table(rows, [link_from_page(path) + "; Jeffery's rate gammadot / (2 pi (a/b + b/a))"])


def t_compound_2d():
    path = os.path.join(VAL, "shear_compound.md")

    def compare(r):
        ok = r["membrane regime"] == "tank-treading" and r["nucleus regime"] == "tumbling"
        return (f"{num(r['membrane theta deg']):.2f}, {num(r['membrane omega_TT 1/s']):.3f}; {r['membrane regime']}, "
                f"nucleus {r['nucleus regime']} ({num(r['nucleus omega_TU 1/s']):.3f})",
                "membrane tank-treads, nucleus tumbles (Fig. 4b-d)", "as the paper" if ok else "differs",
                f"r = {float(r['r cm']):g} cm: membrane theta deg, omega_TT 1/s; regimes")
    rows = sweep_rows(path, "256x128", "1e-3", lambda r: True, compare, "compound_capsule_shear.yaml",
                      lambda r: f"-solid_nucleus_semi_axes {float(r['r cm']):g},{float(r['r cm']):g} -final_time 0.3 "
                                f"-metrics_average_from 0.15 -s_interface 1e10")
    return table(rows, [link_from_page(path)])


def t_compound_3d():
    rows = []
    path = os.path.join(VAL, "shear_3d.md")
    coarse = REGISTRY["compound_3d_coarse"]
    for r in md_tables(path)[0]:
        n = r["mesh"].split("x")[0]
        if n not in coarse["memory"]:  # the finer meshes' rows: from their kept summaries below
            continue
        m, nu = num(r["membrane omega_TU 1/s (half-turns)"]), num(r["nucleus omega_TU 1/s"])
        minutes = num(r["wall time"])
        cmd = (f"cellfsi scenes/compound_capsule_shear_3d.yaml -fluid_elements {n},{n},{n} -solid_membrane_elements "
               f"1,0,0 -solid_nucleus_elements 0,0,0 -dt 1e-3 -final_time 0.3 -s_interface 1e9")
        rows.append([f"{n}^3", 2, "1e-3", "omega_TU 1/s, membrane / nucleus", f"{m:.3f} / {nu:.3f}", "4.68 / 4.68",
                     f"{100 * (m / 4.68 - 1):+.1f} % / {100 * (nu / 4.68 - 1):+.1f} %",
                     per_step(minutes * 60, num(r["steps"])), coarse["memory"][n], coarse["commit"], code(cmd)])
    cost = REGISTRY["compound_3d_cost"]
    for name in ["shear_3d_32cube", "shear_3d_48cube", "shear_3d_64cube", "shear_3d_64cube_scene"]:
        s = summary(name)
        cl = s["command_line"].split()
        opt = {cl[i]: cl[i + 1] for i in range(len(cl) - 1) if cl[i].startswith("-")}
        n = opt.get("-fluid_elements", "64").split(",")[0]  # the scene's own mesh when not given
        dt = opt.get("-dt", "5e-4")
        m, nu = s["membrane_omega_tu"], s.get("nucleus_omega_tu")
        shipped = name.endswith("scene")
        if shipped:
            w = [r for r in md_tables(os.path.join(VAL, "shear_3d_mesh_64.md"))[1] if "4.5e10" in r["run"]][0]
            m, nu = num(w["membrane omega_TU 1/s"]), num(w["nucleus omega_TU 1/s"])
            what = "omega_TU 1/s over t = 0.001-0.1 s (run stopped at 0.167 s), membrane / nucleus"
            ours = f"{m:.3f} / {nu:.3f}"
            diff = f"{100 * (m / 4.68 - 1):+.1f} % / {100 * (nu / 4.68 - 1):+.1f} %"
            cmd = "mpirun -np 2 cellfsi scenes/compound_capsule_shear_3d.yaml"
        else:
            what = "omega_TU 1/s, membrane / nucleus"
            ours = f"{m:.3f} / {nu:.3f}"
            diff = f"{100 * (m / 4.68 - 1):+.1f} % / {100 * (nu / 4.68 - 1):+.1f} %"
            cmd = (f"{'mpirun -np 2 ' if s['ranks'] == 2 else ''}cellfsi scenes/compound_capsule_shear_3d.yaml "
                   f"-fluid_elements {n},{n},{n} -solid_membrane_elements 1,0,0 -solid_nucleus_elements 0,0,0 "
                   f"-dt {dt} -final_time 0.3 -s_interface 1e9")
        sstep, mem = cost["rows"][name]
        rows.append([f"{n}^3" + (" (the paper's bodies)" if shipped else ""), 2, dt, what, ours, "4.68 / 4.68", diff,
                     sstep, mem,
                     s["commit"][:7] + ("-dirty" if "dirty" in s["commit"] else ""), code(cmd)])
    return table(rows, [link_from_page(path), "docs/validation/runs/shear_3d_*_summary.json",
                        link_from_page(os.path.join(VAL, "shear_3d_mesh_64.md")),
                        "s/step and memory of the runs from 32^3 on: REGISTRY['compound_3d_cost'] "
                        f"({note_link(cost['note'])})"])


def t_rbc_shear_3d():
    d = REGISTRY["rbc_shear_3d"]
    rows = [[d["mesh"], d["p"], d["dt"], "half-turn s", f"{d['half_turn']:.3f}",
             f"{d['jeffery']:.3f} (Jeffery's rigid oblate spheroid, r = 0.328)",
             f"{100 * (d['half_turn'] / d['jeffery'] - 1):+.0f} %", f"{d['s_step']}", d["memory"], d["commit"],
             code("cellfsi scenes/rbc_shear_3d.yaml -s_interface 1e9")]]
    sources = [f"REGISTRY['rbc_shear_3d'] ({note_link(d['note'])}; one rank beside other jobs)"]
    # Ca 0.46 on the divergence-conforming space (bench/run_rbc_shear_3d.py): each box's half turns; the shell
    # without poles (-solid_rbc_patches 6) and that shell cubic through its thickness in their own tables, their
    # runs made later.
    for path in (os.path.join(VAL, name) for name in ("rbc_shear_3d_ca046.md", "rbc_shear_3d_ca046_faces.md",
                                                      "rbc_shear_3d_ca046_thick3.md",
                                                      "rbc_shear_3d_ca046_plane24.md",
                                                      "rbc_shear_3d_ca046_thin.md")):
        if not os.path.exists(path):
            continue
        sources.append(link_from_page(path))
        tables = md_tables(path)
        # (A cell that swings in the shear plane without flipping: its row of the table's second table, if any.)
        swings = {w["box, fluid elements"]: w for w in (tables[1] if len(tables) > 1 else [])}
        for r in tables[0]:
            # (A run that failed is reported up to where it stopped, and says so.)
            if not r["status"].startswith(("completed", "failed")):
                continue
            box, mesh = r["box, fluid elements"].split(", ", 1)
            half = [float(h) for h in r["half turns"].split(", ")] if r["half turns"] != "-" else []
            flips = r["flips"]
            # (The oblate spheroid's row against Jeffery's spheroid of its own aspect, 0.5.)
            aspect = 0.5 if "oblate spheroid (aspect 0.5)" in mesh else ASPECT_RBC
            half_turn = math.pi * (aspect + 1 / aspect) / RATE_RBC
            jeffery = f"{1e3 * half_turn:.1f} (Jeffery's rigid oblate spheroid, r = {aspect:g})"
            what = ", ".join(f"{h:.1f}" for h in half) if half else f"flips at {flips} ms"
            swing = swings.get(r["box, fluid elements"])
            if flips == "-" and swing:
                # Swings in the shear plane (Abkarian, Faivre & Viallat 2007: a swing period half the
                # tank-treading period).
                what = (f"no flip, swings {r['status'].split(', ', 1)[1]}: period {swing['swing period']} ms, theta "
                        f"{swing['theta mean; range']} deg, DI {swing['DI']}, tank-treading period "
                        f"{swing['1 / omega_TT']} ms")
                if "folded" in r["status"]:
                    what += f" ({r['status'].split('(', 1)[1].split(')')[0]})"
                failed = re.search(r" in step (\d+) at", r["status"]) if r["status"].startswith("failed") else None
                if failed:
                    what += f" (then failed in step {failed.group(1)}: {r['status'].split(':')[1].strip()})"
                ratio = float(swing["swing / tank-treading period"])
                faces = " a face" if "six patches" in mesh else ""
                rows.append([f"{mesh.replace(' x ', 'x')} ({box} box), membrane 1 x {r['membrane']}{faces}", 2,
                             "1e-4", "Ca 0.46, divergence-conforming space: swing period over the tank-treading "
                             "period", what, "0.5 (Abkarian, Faivre & Viallat 2007, experiments)",
                             f"{100 * (ratio / 0.5 - 1):+.0f} %", r["s/step"], "-", commit_of(path),
                             code("python3 bench/run_rbc_shear_3d.py")])
                continue
            if flips == "-":
                # No flip (a start out of the shear plane): the short axis's angle to the vorticity at the start
                # and its range over the run's last third instead.
                what = f"no flip {r['status'].split(', ', 1)[1]}"
                if "; " in r["short axis to vorticity"]:  # (runs made before the metric have none)
                    start, late = r["short axis to vorticity"].split("; ")
                    what += f"; short axis to vorticity {start} deg at the start, {late} over the last third"
                jeffery = ("in the shear plane from any start (Dupont et al. 2016: an oblate capsule of aspect 0.5 at "
                           "ratio 1, Ca below about 1)" if aspect == 0.5
                           else "tumbling from the start in the shear plane (the rows above)")
            failed = re.search(r" in step (\d+) at", r["status"]) if r["status"].startswith("failed") else None
            if failed:
                what += f" (then failed in step {failed.group(1)}: {r['status'].split(':')[1].strip()})"
            diff = ", ".join(f"{100 * (h / (1e3 * half_turn) - 1):+.0f} %" for h in half) if half else "-"
            faces = " a face" if "six patches" in mesh else ""
            rows.append([f"{mesh.replace(' x ', 'x')} ({box} box), membrane 1 x {r['membrane']}{faces}", 2, "1e-4",
                         "Ca 0.46, divergence-conforming space: half turns ms", what, jeffery, diff,
                         r["s/step"], "-", commit_of(path), code("python3 bench/run_rbc_shear_3d.py")])
    return table(rows, sources)




HARDENING_MEMBRANE = "strain_hardening_membrane"


def t_stretching():
    rows, sources = [], []
    for name, mesh, laws in [("stretching.md", "36x12x18", ["strain_hardening", "neo_hookean"]),
                             ("stretching_24x8x12.md", "24x8x12", ["strain_hardening", "neo_hookean"]),
                             ("stretching_skalak.md", "36x12x18", ["skalak"]),
                             ("stretching_skalak_24x8x12.md", "24x8x12", ["skalak"]),
                             ("stretching_skalak_48x16x24.md", "48x16x24", ["skalak"]),
                             ("stretching_skalak_dc_24x8x12.md", "24x8x12", ["skalak"]),
                             ("stretching_skalak_dc.md", "36x12x18", ["skalak"]),
                             ("stretching_skalak_dc_48x16x24.md", "48x16x24", ["skalak"]),
                             ("stretching_skalak_dc_fine_membrane.md", "36x12x18", ["skalak"]),
                             ("stretching_skalak_dc_24x8x12_c3.md", "24x8x12", ["skalak"]),
                             ("stretching_skalak_dc_24x8x12_c1.md", "24x8x12", ["skalak"]),
                             ("stretching_hardening_membrane_dc_24x8x12.md", "24x8x12", [HARDENING_MEMBRANE]),
                             ("stretching_hardening_membrane_dc_36x12x18.md", "36x12x18", [HARDENING_MEMBRANE]),
                             ("stretching_hardening_membrane_dc_48x16x24.md", "48x16x24", [HARDENING_MEMBRANE]),
                             ("stretching_hardening_membrane_dc_24x8x12_c100.md", "24x8x12", [HARDENING_MEMBRANE])]:
        path = os.path.join(VAL, name)
        if not os.path.exists(path):
            continue
        sources.append(link_from_page(path))
        # The command that runs them (not the one that redrew the table from kept runs, nor its folders).
        m = re.search(r"Generated by `(python3 bench/run_stretching\.py[^`]*)`", read(path))
        # (Its outputs kept where they are not the bench's defaults: the tables of the other space share them.)
        command = re.sub(r" --report| --(runs|build) \S+", "", m.group(1)) if m else "-"
        if "_dc" not in name:
            command = re.sub(r" --(results|table|figure) \S+", "", command)
        # (The membrane's elements, from the table's "Mesh:" line.)
        membrane = re.search(r"membrane (1 x \d+ x \d+)", read(path))
        mesh_cell = f"{mesh}, membrane {membrane.group(1)}" if membrane else mesh
        rs = [r for t in md_tables(path) for r in t if "law" in r and "wall s" in r]
        fit = {r["law"]: r for t in md_tables(path) for r in t if r.get("fitted to") == "D_A"}
        for law in laws:
            mine = [r for r in rs if r["law"] == law]
            gh, rms = num(fit[law]["G h uN/m"]), num(fit[law]["RMS D_A um"])
            sps = sorted(float(r["wall s"]) / float(r["steps"]) for r in mine)
            area_law = law in ("skalak", HARDENING_MEMBRANE)
            if area_law:  # the area-preserving laws: D_T is what they are for
                rms_t = num(fit[law]["RMS D_T um"])
                space = " on the divergence-conforming space" if "div_conforming" in command else ""
                c = re.search(r"-solid_rbc_area_dilation (\S+)", command)
                what, value = f"{law} (C = {c.group(1).strip(chr(39)) if c else 10}){space}: G h fitted to D_A, " \
                              "RMS of D_A and D_T", \
                    f"{gh:.2f} uN/m{' (at the edge)' if 'edge' in fit[law]['G h uN/m'] else ''}, {rms:.2f} / {rms_t:.2f} um"
                dts = sorted({float(r["dt s"]) for r in mine}, reverse=True)
                diff = f"RMS {rms:.2f} / {rms_t:.2f} um"
                failed = sum(r["status"].startswith("failed") for r in mine)
                dt = f"{dts[0]:g}, force grown over 5 ms" + (
                    f" ({', '.join(f'{d:g}' for d in dts[1:])} where it failed)" if len(dts) > 1 else "") + (
                    f"; {failed} of {len(mine)} forces failed at every dt" if failed else "")
            else:
                what, value, diff = f"{law}: G h fitted to D_A, RMS of D_A", f"{gh:.2f} uN/m, {rms:.2f} um", f"RMS {rms:.2f} um"
                dt = "1e-3 (5e-4, 2.5e-4 where it inverted)"
            rows.append([mesh_cell, 2, dt, what, value, "5-12 uN/m (Mills et al. 2004); their D_A at 12 forces",
                         diff, f"{sps[0]:.1f}-{sps[-1]:.1f}", "-", commit_of(path),
                         code(command if area_law else
                              "python3 bench/run_stretching.py" + ("" if mesh == "36x12x18" else f" --mesh {mesh}"))])
    return table(rows, sources)


def t_rbc_channel():
    rows = []
    paper_ht = {4: 0.1716, 6: 0.2573, 8: 0.3431, 10: 0.4290, 12: 0.5147}
    srcs = []
    for name, mesh, dt, extra in [("channel_rheology.md", "96x32", "5e-4", ""),
                                  ("channel_rheology_384x128.md", "384x128", "2.5e-4",
                                   " --mesh 384x128 --dt 2.5e-4 --final-time 0.4 --average-from 0.2")]:
        path = os.path.join(VAL, name)
        srcs.append(link_from_page(path))
        for r in md_tables(path)[0]:
            n = int(r["cells"])
            ht = num(r["H_t"])
            rows.append([mesh, 3, dt, f"{n} cells: H_t; zeta, eta, h_cf um",
                         f"{ht:.4f}; {num(r['zeta = v_m / v_RBCs']):.3f}, "
                         f"{num(r['eta = v_P / v_m']):.3f}, {num(r['h_cf um']):.2f}",
                         f"{paper_ht[n]:.4f}; trends of Fig. 8 (no numbers)", f"H_t {ht - paper_ht[n]:+.4f}",
                         per_step(r["wall s"], r["steps"]), "-", commit_of(path),
                         code(f"python3 bench/run_channel_rheology.py --counts {n}{extra} "
                              "--extra \"-s_interface 1e9\"")])
    return table(rows, srcs)


def t_migration():
    d = REGISTRY["migration"]
    rows = []
    for r in d["rows"]:
        cmd = (f"cellfsi scenes/capsule_channel_migration.yaml -fluid_elements {mesh_comma(r['mesh'])} "
               f"-solid_membrane_elements 1,0 -dt 5e-4 {r['extra']} -s_interface 1e9")
        rows.append([r["mesh"], 3, "5e-4", "t to a tenth of the 2 um offset s; offset at 0.8 s um",
                     f"{r['tenth']:.2f}; {r['offset08']:.2f}",
                     "migrates to the centre line, parachute (Fig. 7; no time scale)",
                     "as the paper (qualitative)", f"{r['s_step']}", r["memory"], r["commit"],
                     code(cmd) + f" ({r['how']})"])
    return table(rows, [f"REGISTRY['migration'] ({note_link(d['note'])})"])


def t_inertial_migration():
    """The stiff disk in the channel (bench/run_inertial_migration.py's tables): y_eq / W per Reynolds number,
    mesh and start, against Pan & Glowinski (2002) at the nearest Reynolds number."""
    reference = [(12.78, 0.2732), (27.73, 0.2725), (96.74, 0.2722)]  # as in the bench script
    rows, sources = [], []
    for path in [os.path.join(VAL, n) for n in ("inertial_migration.md", "inertial_migration_128.md")]:
        if not os.path.isfile(path):
            continue
        m = re.search(r"Generated by `(python3 bench/run_inertial_migration\.py[^`]*)`", read(path))
        # The command that runs them (not the one that redrew the table from kept runs, nor where they were kept).
        cmd = re.sub(r" --report| --runs \S+", "", m.group(1)) if m else "-"
        sources.append(link_from_page(path))
        for r in md_tables(path)[0]:
            if r["status"] != "completed" or r.get("body", "stiff disk") != "stiff disk":
                continue
            re_m = float(r["Re (measured)"])
            ref_re, ref_y = min(reference, key=lambda q: abs(q[0] - re_m))
            y = float(r["y_eq / W"])
            still = " (still drifting)" if r["settled after (W travelled)"] == "drifting" else ""
            rows.append([r["mesh"], 3, r["dt (s)"],
                         f"y_eq / W from {r['start y / W']}{still}, Re {re_m:.2f} (plasma {r['Re (plasma)']}); "
                         "drift / u", f"{y:.4f}; {r['drift / u']}", f"{ref_y} at Re {ref_re} (Pan & Glowinski 2002)",
                         f"{y - ref_y:+.4f}", r["s/step"], "-", commit_of(path), code(cmd)])
        # Two starts that bracket the position: where the interpolated drift vanishes.
        for b in re.findall(r"Re ([0-9.]+) \(plasma\), (\d+x\d+), stiff disk: between (\d\.\d+) and (\d\.\d+), "
                            r"zero drift at (\d\.\d+)", read(path)):
            re_p, mesh, lo, hi, y = b
            ref_re, ref_y = min(reference, key=lambda q: abs(q[0] - 0.92 * float(re_p)))
            rows.append([mesh, 3, "-", f"y_eq / W where the drift of the runs from {lo} and {hi} vanishes "
                         f"(plasma Re {re_p})", y, f"{ref_y} at Re {ref_re} (Pan & Glowinski 2002)",
                         f"{float(y) - ref_y:+.4f}", "-", "-", commit_of(path), code(cmd)])
    return table(rows, sources)


def t_inertial_migration_cells():
    """The deformable bodies in the channel (bench/run_inertial_migration.py's tables with capsules, red cells and
    CTCs): where each settles per Ca, Reynolds number, mesh and fluid space, and how long it took. No published
    2D value to compare with: the table states them with their mesh and cost."""
    rows, sources = [], []
    names = sorted(n for n in os.listdir(VAL) if re.fullmatch(r"inertial_migration_.*\.md", n))
    for path in [os.path.join(VAL, n) for n in names]:
        text = read(path)
        m = re.search(r"Generated by `(python3 bench/run_inertial_migration\.py[^`]*)`", text)
        cmd = re.sub(r" --report| --runs \S+| --table \S+| --figure \S+", "", m.group(1)) if m else "-"
        space = "div.-conf." if "div_conforming" in cmd else "equal-order"
        travel = re.search(r"to ([0-9.]+) widths of travel", text)
        used = False
        for r in md_tables(path)[0]:
            body = r.get("body", "stiff disk")
            if r["status"] != "completed" or body == "stiff disk":
                continue
            used = True
            kind, ca = body.rsplit(" Ca ", 1)
            settled = r["settled after (W travelled)"]
            rows.append([kind, ca, r["Re (plasma)"], r["mesh"], space, r["start y / W"],
                         travel.group(1) if travel else "-", r["y_eq / W"],
                         r.get("second half: mean (range)", "-"), settled, r["s/step"], commit_of(path), code(cmd)])
        if used:
            sources.append(link_from_page(path))
    rows.sort(key=lambda r: (r[0], float(r[2]), float(r[1]), int(r[3].split("x")[0]), r[4]))
    return table(rows, sources, ["body", "Ca", "Re (plasma)", "mesh", "fluid", "start y / W", "travel (W)",
                                 "y_eq / W", "second half: mean (range)", "settled after (W)", "s/step", "commit",
                                 "command"])


def ctc_among_rbcs_files(prefix):
    """bench/run_ctc_among_rbcs.py's kept tables whose names start with prefix: (path, its per-run rows, its
    mesh, its command without the folders)."""
    out = []
    for name in sorted(n for n in os.listdir(VAL) if n.startswith(prefix) and n.endswith(".md")):
        path = os.path.join(VAL, name)
        text = read(path)
        m = re.search(r"Generated by `(python3 bench/run_ctc_among_rbcs\.py[^`]*)`", text)
        cmd = re.sub(r" --report| --(runs|build|table|figure|snapshots) \S+", "", m.group(1)) if m else "-"
        mesh = re.search(r"^Mesh (\S+) of degree", text, re.M)
        out.append((path, md_tables(path)[0], mesh.group(1) if mesh else "-", cmd))
    return out


def ctc_among_rbcs_fluid(cmd, path):
    """The fluid space and the membranes of a run_ctc_among_rbcs.py table: ("div.-conf." or "equal-order", "auto"
    or the elements around the CTC's membrane and a red cell's), as its heading says them (the driver writes them
    there since the scene runs on either space) or else as its command's --extra gives them."""
    said = re.search(r"^Mesh \S+ of degree \d+ on the (divergence-conforming|equal-order) space"
                     r"(?: \(elements around: CTC membrane (\d+)(?:, red cell (\d+))?\))?", read(path), re.M)
    if said:
        space = "div.-conf." if said.group(1) == "divergence-conforming" else "equal-order"
        return space, f"{said.group(2)}, {said.group(3) or '-'}" if said.group(2) else "auto"
    space = "div.-conf." if "div_conforming" in cmd else "equal-order"
    ctc = re.search(r"-solid_membrane_elements \d+,(\d+)", cmd)
    rbc = re.search(r"-solid_rbc_elements \d+,(\d+)", cmd)
    if not ctc and not rbc:
        return space, "auto"
    return space, f"{ctc.group(1) if ctc else 'auto'}, {rbc.group(1) if rbc else 'auto'}"


def early_row_order(r):
    """Mesh, then the fluid space (the paper's first), then the automatic s_I before given ones (largest first),
    then the automatic membranes before given ones (the finest first), then red cells and seed (numbers where the
    cells are numbers)."""
    def value(text):
        m = re.match(r"[0-9.eE+-]+", text)
        try:
            return float(m.group()) if m else 0.0
        except ValueError:
            return 0.0
    return (value(r[0]), r[1] != "equal-order", r[2] != "auto", -value(r[2]) if r[2] != "auto" else 0.0,
            r[3] != "auto", -value(r[3]), value(r[4]), value(r[6]))


def t_ctc_among_rbcs_early():
    """How much the red cells hold the flow back early in the run (before the CTC reaches the narrowing), against
    the CTC alone on the same mesh, per mesh, fluid space and s_I (the divergence-conforming space has none): a
    mesh study a short run can make."""
    rows, sources, seen = [], [], set()
    for path, runs, mesh, cmd in ctc_among_rbcs_files("ctc_among_rbcs"):
        used = False
        space, membranes = ctc_among_rbcs_fluid(cmd, path)
        si = re.search(r"-s_interface (\S+?)'?(\s|$)", cmd)
        s_i = "-" if space != "equal-order" else si.group(1) if si else "auto"
        for r in runs:
            early = next((v for k, v in r.items() if k.startswith("at ")), "-")
            # Any run that got past the early time (a passage run stopped by hand too).
            if r["red cells"] in ("0", "-") or "(" not in early:
                continue
            key = next(k for k in r if k.startswith("at "))
            t_early = re.match(r"at (\S+) s", key).group(1)
            # One row per run: a run kept in an early table and continued into a passage table is the same run
            # (the early table, first by name, gives it).
            run = (mesh, space, s_i, membranes, r["red cells"], r["seed"], t_early)
            if run in seen:
                continue
            seen.add(run)
            flow, travel = early.split("(")[0].rstrip().split(", ")
            ratio_q, ratio_x = early.split("(")[1].rstrip(")").split(", ")
            rows.append([mesh, space, s_i, membranes, r["red cells"], r["haematocrit (%)"], r["seed"], t_early, flow,
                         ratio_q, travel, ratio_x, r["s/step"], commit_of(path), code(cmd)])
            used = True
        if used:
            sources.append(link_from_page(path))
    rows.sort(key=early_row_order)
    return table(rows, sources, ["mesh", "fluid", "s_I", "membranes (elements around: CTC, red cell)", "red cells",
                                 "haematocrit (%)", "seed", "at t (s)",
                                 "flow rate (1e-6 cm^2/s)", "against the CTC alone", "CTC travel (um)",
                                 "against the CTC alone", "s/step", "commit", "command"])


def t_ctc_among_rbcs():
    """The CTC's passage through the throat alone and among red cells (bench/run_ctc_among_rbcs.py's kept tables
    named ctc_among_rbcs_passage_*: their runs that completed or were stopped by hand)."""
    rows, sources = [], []
    for path, runs, mesh, cmd in ctc_among_rbcs_files("ctc_among_rbcs_passage"):
        for r in runs:
            if not r["status"].startswith(("completed", "interrupted")):
                continue
            rows.append([mesh, *ctc_among_rbcs_fluid(cmd, path), r["haematocrit (%)"], r["seed"], r["status"],
                         r["throat entry / exit"], r["transit"],
                         r["membrane anisotropy max"], r["nucleus anisotropy max"],
                         r["lateral at entry / exit, max"], r["cell-free layer in the throat (steps)"], r["s/step"],
                         commit_of(path), code(cmd)])
        sources.append(link_from_page(path))
    return table(rows, sources, ["mesh", "fluid", "membranes (elements around: CTC, red cell)", "haematocrit (%)",
                                 "seed", "status", "throat entry / exit (s)", "transit (s)",
                                 "membrane anisotropy max", "nucleus anisotropy max",
                                 "lateral at entry / exit, max (um)", "cell-free layer in the throat, um (steps)",
                                 "s/step", "commit", "command"])


def t_ctc():
    d = REGISTRY["ctc_192"]
    path = os.path.join(VAL, "ctc_passage_384x128.md")
    q = {r["quantity"]: r["384x128"] for r in md_tables(path)[0]}
    transit = float(q["membrane: throat entry / exit / transit (s)"].split("/")[2])
    dip = float(re.search(r"\(([-0-9.]+) %\)", q["flow rate minimum (change against developed)"]).group(1))
    aniso = float(q["membrane: largest anisotropy (at t, centroid x)"].split()[0])
    ra = float(q["membrane: r_A at the end / largest abs r_A / largest abs r_P"].split("/")[0])
    steps, _, wall = [x.strip() for x in q["steps, final time, wall"].split(",")[:3]]
    base = ("cellfsi scenes/ctc_narrowing.yaml -fluid_elements {m} -solid_membrane_elements 1,0 "
            "-solid_nucleus_elements 0,0 -final_time 0.3 -s_interface 1e9")
    what = "membrane transit s; flow-rate dip; largest anisotropy; r_A at 0.3 s"
    ref = "passes, flow slows, nucleus deforms leaving (Fig. 10; no numbers)"
    rows = [["192x64", 3, "2.5e-4", what, f"{d['transit']:.3f}; {d['dip']} %; {d['anisotropy']:.1f}; {d['r_A']:.1e}",
             ref, "as the paper (qualitative)", f"{d['s_step']}", d["memory"], d["commit"],
             code(base.format(m="192,64"))],
            ["384x128", 3, "2.5e-4", what, f"{transit:.3f}; {dip:.0f} %; {aniso:.1f}; {ra:.1e}", ref,
             f"transit {100 * (transit / d['transit'] - 1):+.0f} % against 192x64", per_step(wall.split()[0], steps),
             "-", commit_of(path) + " (binary b0183e9)", code(base.format(m="384,128"))]]
    return table(rows, [f"REGISTRY['ctc_192'] ({note_link(d['note'])})", link_from_page(path)])


def t_plasma():
    d = REGISTRY["plasma"]
    rows = [[mesh, 3, "5e-4", what, err, "exact", err.split()[0], per_step(wall, steps), "-", d["commit"],
             code(f"cellfsi scenes/{scene}.yaml -output_every 0")]
            for scene, mesh, what, err, wall, steps in d["rows"]]
    return table(rows, [f"REGISTRY['plasma'] ({note_link(d['note'])}; 20 steps, one LU factorisation dominates)"])


# ---------------------------------------------------------------------------------------------------------
# performance.md
# ---------------------------------------------------------------------------------------------------------
def steps_3d_table(name, space_column, extra, about):
    """A run_3d_steps.py table: per row the step's split, with space_column (header, column of the kept table)
    for what differs between the spaces; extra, the --extra the runs were given."""
    path = os.path.join(PERF, name)
    head, key = space_column
    cols = ["mesh", "ranks", "s/step", "linear solves", "Jacobian", "residuals", "location", head,
            "coupling it./step", "peak GB per rank", "commit", "command"]
    rows = []
    commit = commit_of(path)
    for r in md_tables(path)[0]:
        n = r["mesh"].split("^")[0]
        rows.append([r["mesh"], r["ranks"], r["s/step"], r["LinearSolve"], r["Jacobian"], r["Residual"], r["Locate"],
                     r[key], r["coupling/step"], r["peak GB"], commit,
                     code(f"python3 bench/run_3d_steps.py --cases {n}:{r['ranks']}:{r['steps']}{extra}")])
    return table(rows, [link_from_page(path) + f" ({about}; seconds per step)"], cols)


def t_steps_3d():
    return steps_3d_table("coupled_steps_3d.md", ("region LU (PCSetUp)", "PCSetUp"), "",
                          "the compound capsule, the paper's bodies scaled with N, dt 5e-4, quadratic")


def t_steps_3d_dc():
    return steps_3d_table("coupled_steps_3d_dc.md", ("bulk build (once)", "Factor (once)"),
                          " --extra \"-fluid_space div_conforming -fluid_dc_degree 2\"",
                          "the compound capsule on the divergence-conforming space, k' = 2, the paper's bodies "
                          "scaled with N, dt 5e-4; nothing factorised in a step")


def t_steps_2d():
    path = os.path.join(PERF, "coupled_steps_fourier.md")
    cols = ["mesh", "p", "dt s", "preconditioner", "s/step", "coupling it./step", "peak MB", "commit", "command"]
    rows = []
    for r in md_tables(path)[0]:
        if "x" not in r["mesh"] or r["mesh"].count("x") != 1 or r["ranks"] != "1":
            continue
        cmd = (f"cellfsi scenes/capsule_shear.yaml -fluid_elements {mesh_comma(r['mesh'])} -dt 1e-3 "
               f"-solid_membrane_elements 1,0 -coupling_pc_type cellfsi_{r['solver']}")
        rows.append([r["mesh"], 3, "1e-3", "cellfsi_" + r["solver"], r["s/step"], r["coupling/step"], r["peak MB"],
                     commit_of(path), code(cmd)])
    return table(rows, [link_from_page(path) + " (one rank, the capsule's first 20-40 steps, set-up included)"], cols)


def t_kernels():
    cols = ["kernel", "p", "us per element", "commit", "note", "command"]
    rows = []
    for key in ["assembly_2d_jacobian", "assembly"]:
        d = REGISTRY[key]
        for what, p, us in d["rows"]:
            rows.append([what, p, us, d["commit"], note_link(d["note"]),
                         code("build/bench/fluid_assembly -repeat 7" + (" -n3d 20" if what.startswith("3D") else
                                                                      " -n2d 128 -three_d false"))])
    return table(rows, ["REGISTRY['assembly'], REGISTRY['assembly_2d_jacobian'] (one rank, best of 5-7)"], cols)


def t_targets():
    d = REGISTRY["targets_26"]
    cols = ["issue 26's target", "asked", "measured", "status"]
    return table([list(r) for r in d["rows"]],
                 [f"REGISTRY['targets_26'] ({note_link(d['note'])}, commit {d['commit']}, "
                  "this machine's Haswell kernels)"], cols)


TABLES = {
    "capsule_shear": t_capsule_shear, "capsule_two_spaces": t_capsule_two_spaces,
    "two_spaces_area": t_two_spaces_area, "two_spaces_sweeps": t_two_spaces_sweeps,
    "default_scene": t_default_scene, "stiff_disk": t_stiff_disk,
    "biconcave_capsule_shear": t_biconcave, "bulky_ellipse_shear": t_bulky, "compound_capsule_shear": t_compound_2d,
    "compound_capsule_shear_3d": t_compound_3d, "rbc_shear_3d": t_rbc_shear_3d, "rbc_stretch_3d": t_stretching,
    "rbc_channel": t_rbc_channel, "capsule_channel_migration": t_migration, "ctc_narrowing": t_ctc,
    "ctc_among_rbcs_early": t_ctc_among_rbcs_early, "ctc_among_rbcs": t_ctc_among_rbcs,
    "inertial_migration": t_inertial_migration, "inertial_migration_cells": t_inertial_migration_cells,
    "plasma": t_plasma, "steps_3d": t_steps_3d, "steps_3d_dc": t_steps_3d_dc, "steps_2d": t_steps_2d, "kernels": t_kernels,
    "targets_26": t_targets,
}
MARK = re.compile(r"(<!-- BEGIN TABLE (\w+) -->\n)(.*?)(<!-- END TABLE \2 -->)", re.S)


def render(text):
    def rep(m):
        name = m.group(2)
        if name not in TABLES:
            raise SystemExit(f"reference_tables.py: no table named '{name}'")
        return m.group(1) + TABLES[name]() + "\n" + m.group(4)
    return MARK.sub(rep, text)


# ---------------------------------------------------------------------------------------------------------
# Link check
# ---------------------------------------------------------------------------------------------------------
def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    h = re.sub(r"[`*_]", "", heading.strip().lower())
    h = re.sub(r"[^\w\- ]", "", h)
    return h.replace(" ", "-")


def anchors(path):
    seen, out = {}, set()
    in_code = False
    for line in read(path).split("\n"):
        if line.startswith("```"):
            in_code = not in_code
        if in_code or not line.startswith("#"):
            continue
        s = slug(line.lstrip("#"))
        out.add(s if s not in seen else f"{s}-{seen[s]}")
        seen[s] = seen.get(s, 0) + 1
    return out


def check_links():
    files = [os.path.join(ROOT, "README.md"), os.path.join(ROOT, "CHANGELOG.md")]
    files += sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
    files += sorted(glob.glob(os.path.join(ROOT, "docs", "notes", "*.md")))
    bad = []
    for f in files:
        if not os.path.exists(f):
            continue
        text = re.sub(r"```.*?```", "", read(f), flags=re.S)
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"^(https?:|mailto:)", target):
                continue
            path, _, anchor = target.partition("#")
            dest = os.path.normpath(os.path.join(os.path.dirname(f), path)) if path else f
            if not os.path.exists(dest):
                bad.append(f"{rel(f)}: link to a missing file: {target}")
            elif anchor and dest.endswith(".md") and anchor not in anchors(dest):
                bad.append(f"{rel(f)}: link to a missing heading: {target}")
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 if the docs differ or a link is broken")
    args = ap.parse_args()
    problems = []
    for page in PAGES:
        path = os.path.join(ROOT, page)
        old = read(path)
        new = render(old)
        if args.check:
            if new != old:
                names = [m.group(2) for m in MARK.finditer(old) if m.group(0) not in new]
                problems.append(f"{page}: tables not as generated: {', '.join(names)} "
                                "(run python3 bench/reference_tables.py)")
        elif new != old:
            with open(path, "w", encoding="utf-8") as f:
                f.write(new)
            print(f"reference_tables.py: wrote {page}")
    if args.check:
        problems += check_links()
        for p in problems:
            print(p)
        sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
