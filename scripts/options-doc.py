#!/usr/bin/env python3
"""Writes docs/options.md from the option tables, as `-help` prints them, so that the document cannot drift
from the programs. Run from anywhere after a build:

    python3 scripts/options-doc.py > docs/options.md             # build/apps/cellfsi and cellfsi-geometry
    python3 scripts/options-doc.py --build DIR -o FILE

The ctest `OptionsDoc.MatchesHelp` regenerates the document into the build folder and diffs it against
docs/options.md.

How: `cellfsi SCENE.yaml -help` prints every option table of the scenes it is given (common/option_table.hpp:
one PETSc options block per table, each option with its default and help). The script writes two small scene
files into a temporary folder, a 2D one with a body of each 2D shape (and one given no shape) and a 3D one
with a body of each 3D shape, so that every table shows (scene, bodies and coupling, each body, fluid; the 3D
fluid table adds the z walls), and reads the tables from `-help`. -help prints an option's valid values where
its table states them ("[valid: ...]" after the help: a range, a word's choices), which is what the table's
check names when it refuses a value. Every other option (flags, options checked only against others) is given an invalid
value (nan, then -1000000000) with -help, and the range named by the error message ("option -X = V is invalid;
valid: ...") becomes the valid-values column.
cellfsi-geometry's table comes the same way.

What is filtered, so the output depends on no path, date or machine:
- the default of -scene is the scene file's stem (here a temporary file): written as "the scene file's stem";
- PETSc's parse detail after a valid-values text ("(Input string nan has no integer value ...)") is cut;
Nothing else is changed. What PETSc 3.18's -help prints as a default: for a number or a flag, the default; for
a word, the value read (so the scenes here give no word option but -solid_NAME_shape, whose table is taken from
the body given no shape, and -dim/-domain in 3D, whose rows are taken from the 2D scene); for a list, the values
read, and for a list not given only the first value of its default: the document writes that value and ",…".
"""
import argparse
import concurrent.futures
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RULE = "-" * 40
BAD_VALUES = ("nan", "-1000000000")  # a value no real range takes, then one no integer range takes
PARSE_DETAIL = re.compile(r" \((Input string|Unknown logical value|Invalid|Unable)[^)]*(\([^)]*\)[^)]*)?\)$")
INVALID = re.compile(r"option -(\S+) = .* is invalid; valid: (.*)$")

SHAPES_2D = ["hollow_ellipse", "ellipse", "rbc"]
SHAPES_3D = ["hollow_ellipsoid", "ellipsoid", "rbc_3d"]
DEFAULT_BODY = "body"  # a body of the 2D scene given no shape


def scene_yaml(dim, shapes):
    """A scene with a body of each shape named after it (and in 2D one given no shape)."""
    lines = []
    if dim == 3:
        # A small 3D mesh: the memory check of a big one would depend on this machine's memory.
        lines += ["dim: 3", "domain: box", "fluid_elements: 4,4,4", "fluid_degree: 2"]
    lines += ["solid:", "  bodies: " + ",".join(shapes + ([DEFAULT_BODY] if dim == 2 else []))]
    for s in shapes:
        lines += [f"  {s}:", f"    shape: {s}"]
    return "\n".join(lines) + "\n"


def run(cmd, cwd):
    # Each probe its own Open MPI session directory: isolated singletons (the test environment's
    # OMPI_MCA_ess_singleton_isolated) all get the same one, and probes run in parallel created and removed it
    # under each other (tests/support/ompi_session_dir.hpp).
    with tempfile.TemporaryDirectory(prefix="cellfsi-ompi-") as session:
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMPI_MCA_orte_tmpdir_base=session)
        return subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              universal_newlines=True)


def parse_tables(text, wanted):
    """{title: [row]} of the -help sections whose title `wanted` accepts; a row is a dict."""
    tables, title = {}, None
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line == RULE:
            title = None
            if i + 1 < len(lines) and lines[i + 1].endswith(":") and wanted(lines[i + 1][:-1]):
                title = lines[i + 1][:-1]
                tables[title] = []
            continue
        if title is None or not line.startswith("  -"):
            continue
        tables[title].append(parse_option(line))
    return tables


def parse_option(line):
    """One option line of PETSc 3.18's -help; "stated": the valid values its table states ("[valid: ...]" at
    the end of the help), when it states them."""
    row = parse_option_line(line)
    m = re.fullmatch(r"(.*?) \[valid: (.*)\]", row["help"])
    if m:
        row["help"], row["stated"] = m[1], m[2]
    return row


def parse_option_line(line):
    line = line.strip()
    if line.endswith(" (None)"):
        line = line[: -len(" (None)")]
    m = re.match(r"-(\S+?): <(\S+) : (\S+)> (.*)$", line)  # flag
    if m:
        return dict(name=m[1], kind="flag", default=m[3].lower(), help=m[4])
    m = re.match(r"-(\S+) <now (.*?) : formerly (.*?)>: (.*)$", line)  # integer or word
    if m:
        kind = "integer" if re.fullmatch(r"-?\d+", m[3]) else "word"
        return dict(name=m[1], kind=kind, default=m[3], help=m[4])
    m = re.match(r"-(\S+) <(\S+) : (\S+)>: (.*)$", line)  # real
    if m:
        return dict(name=m[1], kind="real", default=number(m[3]), help=m[4])
    m = re.match(r"-(\S+) <([^>]*)>: (.*)$", line)  # list: the values read, or the default's first
    if m:
        values = m[2]
        if values == "string1,string2,...":  # a list of words: PETSc prints this placeholder
            return dict(name=m[1], kind="words", default="", help=m[3])
        return dict(name=m[1], kind="list", default=",".join(number(v) for v in values.split(",")), help=m[3])
    raise SystemExit(f"options-doc: cannot read this -help line: {line}")


def number(v):
    return v[:-1] if re.fullmatch(r"-?\d+\.", v) else v


def probe(cmd_of, name, dim, cwd, kind="real"):
    """The valid values the program names for option `name`, or '' when it refuses neither bad value.
    The order of the bad values only saves runs: an integer's range refuses -1000000000 at once (nan is a parse
    error), and a flag refuses both alike (a parse error), so one run of nan says it."""
    parse_message = ""
    order = {"integer": BAD_VALUES[::-1], "flag": BAD_VALUES[:1]}.get(kind, BAD_VALUES)
    for bad in order:
        r = run(cmd_of(name, ",".join([bad] * dim)), cwd)
        for line in (r.stderr + r.stdout).splitlines():
            m = INVALID.search(line)
            if not m or m[1] != name:
                continue
            valid = PARSE_DETAIL.sub("", m[2])
            if valid == m[2]:
                return valid
            parse_message = parse_message or valid
    return parse_message


def merge(first, second):
    """Rows of `first`, with the rows only `second` has inserted after their predecessor there."""
    out = list(first)
    names = [r["name"] for r in out]
    prev = None
    for row in second:
        if row["name"] not in names:
            at = names.index(prev) + 1 if prev in names else len(out)
            out.insert(at, row)
            names.insert(at, row["name"])
        prev = row["name"]
    return out


def cell(text):
    return text.replace("|", "\\|")


def markdown(rows):
    out = ["| Option | Default | Valid values | Help |", "|---|---|---|---|"]
    for r in rows:
        default = r["default"]
        if r["kind"] == "list" and default:
            default += ",…"
        default = f"`{default}`" if default else "(none)"
        out.append(f"| `-{r['name']}` | {cell(default)} | {cell(r['valid']) or '—'} | {cell(r['help'])} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"), help="build folder (default: build/)")
    ap.add_argument("-o", "--output", help="file to write (default: standard output)")
    args = ap.parse_args()
    cellfsi = os.path.join(os.path.abspath(args.build), "apps", "cellfsi")
    geometry = os.path.join(os.path.abspath(args.build), "apps", "cellfsi-geometry")

    with tempfile.TemporaryDirectory(prefix="options-doc-") as tmp:
        scenes = {2: (os.path.join(tmp, "scene2d.yaml"), SHAPES_2D),
                  3: (os.path.join(tmp, "scene3d.yaml"), SHAPES_3D)}
        tables = {}
        for dim, (path, shapes) in scenes.items():
            with open(path, "w") as f:
                f.write(scene_yaml(dim, shapes))
            r = run([cellfsi, path, "-help"], tmp)
            if r.returncode != 0:
                raise SystemExit(f"options-doc: {cellfsi} {path} -help failed ({r.returncode}):\n{r.stderr}")
            tables[dim] = parse_tables(r.stdout, lambda t: t.startswith("cellfsi") or t.startswith("Fluid"))

        # The same tables in 2D and 3D, the 3D rows added. The bodies: one table, that of the body given no
        # shape (-help prints a word option's value read as its default), if every shape's is the same but for
        # the shape; else one per shape.
        sections, bodies = [], {}
        for title in list(tables[2]) + [t for t in tables[3] if t not in tables[2]]:
            m = re.fullmatch(r"cellfsi body '(\w+)'", title)
            if m:
                dim = 3 if m[1] in SHAPES_3D else 2
                bodies[m[1]] = [dict(r, name=r["name"].replace(f"solid_{m[1]}_", "solid_NAME_", 1))
                                for r in tables[dim][title]]
                continue
            sections.append([title, merge(tables[2].get(title, []), tables[3].get(title, []))])
        if len(sections) != 3 or set(bodies) != set(SHAPES_2D + SHAPES_3D + [DEFAULT_BODY]):
            raise SystemExit("options-doc: expected the scene, coupling and fluid tables and one table per body; "
                             f"-help gave {[t for t, _ in sections]} and bodies {sorted(bodies)}")
        but_shape = lambda rows: [r for r in rows if r["name"] != "solid_NAME_shape"]
        if all(but_shape(rows) == but_shape(bodies[DEFAULT_BODY]) for rows in bodies.values()):
            body_sections = [["cellfsi body 'NAME'", bodies[DEFAULT_BODY]]]
        else:
            body_sections = [[f"cellfsi body 'NAME' (the body {b} of the generator's scene)", rows]
                             for b, rows in bodies.items()]

        # Valid values: the stated ones, else what the program says when refusing a bad value; the probes run
        # (for the options that state none) on a small 2D mesh
        # (the z walls on the 3D scene's), the body options on the rbc body (a membrane: every check applies).
        small = os.path.join(tmp, "probe2d.yaml")
        with open(small, "w") as f:
            f.write(scene_yaml(2, SHAPES_2D) + "fluid_elements: 32,16\nfluid_degree: 2\n")
        probe_scene = {2: small, 3: scenes[3][0]}
        in_2d = {r["name"] for rows in tables[2].values() for r in rows}
        probes = []  # (row, program and scene, the option's name, values per list item)
        for title, rows in sections:
            for r in rows:
                dim = 2 if r["name"] in in_2d else 3
                probes.append((r, [cellfsi, probe_scene[dim]], r["name"], dim if r["kind"] == "list" else 1))
        for title, rows in body_sections:
            for r in rows:
                name = r["name"].replace("solid_NAME_", "solid_rbc_", 1)
                probes.append((r, [cellfsi, probe_scene[2]], name, 2 if r["kind"] == "list" else 1))

        r = run([geometry, "-help"], tmp)
        if r.returncode != 0:
            raise SystemExit(f"options-doc: {geometry} -help failed ({r.returncode}):\n{r.stderr}")
        geometry_tables = parse_tables(r.stdout, lambda t: t.startswith("cellfsi-geometry"))
        for title, rows in geometry_tables.items():
            for row in rows:
                probes.append((row, [geometry], row["name"], 1))

        # The probes are independent runs, mostly waiting on MPI's start-up: one per core at a time.
        def valid(job):
            row, program, name, count = job
            if "stated" in row:
                return row["stated"]
            return probe(lambda n, v: program + [f"-{n}", v, "-help"], name, count, tmp, row["kind"])
        with concurrent.futures.ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            for job, text in zip(probes, pool.map(valid, probes)):
                job[0]["valid"] = text

    for title, rows in sections:
        for r in rows:
            if r["name"] == "scene":
                r["default"] = "the scene file's stem"

    doc = [HEADER.strip(), ""]
    number_ = 0
    for title, rows in sections[:2] + body_sections + sections[2:]:
        number_ += 1
        doc += [f"## {number_}. {title}", "", markdown(rows), ""]
    for title, rows in geometry_tables.items():
        number_ += 1
        doc += [f"## {number_}. {title}", "", markdown(rows), ""]
    doc += [FOOTER.strip(), ""]
    text = "\n".join(doc)
    if args.output:
        with open(args.output, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)



HEADER = """
# cellfsi options

<!-- Generated by `python3 scripts/options-doc.py > docs/options.md` from the programs' -help; do not edit by
hand. The test OptionsDoc.MatchesHelp fails when this file and -help disagree. -->

Every option of `cellfsi` (and of `cellfsi-fluid` and `cellfsi-solid`, which take the same) and of
`cellfsi-geometry`, as `-help` lists them, one table per option table of the code (common/option_table.hpp).
Options go on the command line (`-fluid_elements 128,64`) or into a scene file, where nested keys join with `_`
(`fluid: {elements: 128,64}`); the command line wins. How a run uses them: [running.md](running.md).

- **Default**: the value -help gives as the default. For a list option -help shows only the first value of its
  default (PETSc prints the values a list was read with, and none are read when it is not given); such defaults
  end in `,…`, and the help text says what the whole default is where it depends on the scene.
- **Valid values**: what the program answers when given a bad value (`option -X = V is invalid; valid: ...`):
  the range or choices -help shows as `[valid: ...]` where the option's table states them, else found by giving
  the option nan and -1000000000; — where it refuses neither (any word or number is taken; checks between
  options may still refuse a combination, with a message naming both).
- Body options are per body: `NAME` is a name from `-solid_bodies` (`-solid_membrane_shape`).
"""

FOOTER = """
## Options outside these tables

- `SCENE.yaml` (the first argument, not an option): the scene file; without it, `cellfsi` runs the default
  scene `capsule_shear_quick.yaml`.
- `-help`: prints these tables, PETSc's own options and the solvers' options under their prefixes, and exits.
- `-solid_ranks B` (cellfsi only, on the command line only): the last B ranks of the job are the solid side
  ([running.md](running.md) §10).
- PETSc options of the fluid's solvers under `-fluid_` (`-fluid_snes_monitor`, `-fluid_ksp_type`, ...: runs
  without cells), and of the coupling loop's KSP under `-coupling_` (`-coupling_ksp_monitor`,
  `-coupling_sub_pc_type`, and the factorisations of the cellfsi PC types under `-coupling_band_` and
  `-coupling_fourier_region_`): which apply with which `-coupling_pc_type`, [running.md](running.md) §9;
  `cellfsi SCENE.yaml -help` lists those PETSc reads.
"""

if __name__ == "__main__":
    main()
