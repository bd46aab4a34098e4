"""What the bench/ drivers and plotting scripts share: the repository root, running one cellfsi run of a sweep
(kept when it already completed), the provenance line of a generated table, writing a table, and matplotlib
(python3-matplotlib, installed by scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import ctypes
import datetime
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# The paper's membrane of the scenes that now take theirs from the mesh (on the divergence-conforming space), or
# a finer one in 3D: what the drivers' tables of them were measured with.
PAPER_MEMBRANE = {"capsule_shear": "1,208", "capsule_channel_migration": "1,360", "compound_capsule_shear_3d": "1,32,96"}


def paper_space(options, scene=None):
    """The options with the paper's equal-order space (-fluid_space equal_order) added unless they name a space,
    and for `scene` (a file name) the paper's membrane unless they name one (PAPER_MEMBRANE): the drivers' tables
    were measured so, and several scenes now default to the divergence-conforming space with other membranes
    (README, "Which space a scene uses"); --extra "-fluid_space div_conforming ..." runs that space as the
    scene has it."""
    out = list(options)
    if "-fluid_space" in out:
        return out
    out += ["-fluid_space", "equal_order"]
    stem = os.path.splitext(os.path.basename(scene))[0] if scene else None
    if stem in PAPER_MEMBRANE and "-solid_membrane_elements" not in out:
        out += ["-solid_membrane_elements", PAPER_MEMBRANE[stem]]
    return out


def run_one(args, tag, scene, options):
    """Runs `cellfsi scenes/SCENE OPTIONS` on the paper's space unless OPTIONS name one (paper_space), kept when
    it already completed."""
    out_dir = os.path.join(args.runs, tag)
    summary = os.path.join(out_dir, "summary.json")
    if os.path.isfile(summary):
        with open(summary) as f:
            if json.load(f).get("status") == "completed":
                return tag, "kept"
    cmd = [os.path.join(args.build, "apps", "cellfsi"), os.path.join(ROOT, "scenes", scene), "-output_dir",
           out_dir] + paper_space(options, scene)
    rc, _ = launch(cmd, os.path.join(args.runs, tag + ".log"))
    return tag, f"exit {rc}"


def launch(cmd, log_path):
    """Runs cmd (one process) with its command line and output in log_path; returns (exit code, peak resident
    memory in kB)."""
    # A private Open MPI session directory for the run: isolated singletons (the test environment's
    # OMPI_MCA_ess_singleton_isolated) all share one, and concurrent runs removed it under each other
    # (tests/support/ompi_session_dir.hpp).
    with tempfile.TemporaryDirectory(prefix="cellfsi-ompi-") as session:
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", OMPI_MCA_orte_tmpdir_base=session)
        with open(log_path, "w") as log:
            log.write(" ".join(shlex.quote(c) for c in cmd) + "\n")
            log.flush()
            child = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
            _, status, usage = os.wait4(child.pid, 0)
            child.returncode = os.waitstatus_to_exitcode(status)
    return child.returncode, usage.ru_maxrss


def summary_of(args, tag):
    """The run's summary.json (in args.runs/tag) as a dict, or None when it is missing or unreadable."""
    try:
        with open(os.path.join(args.runs, tag, "summary.json")) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def option_values(words):
    """-name -> its last value (None for a flag) among command-line words, as PETSc reads them."""
    values, name = {}, None
    for w in words:
        if re.fullmatch(r"-[A-Za-z_]\w*", w):
            name = w[1:]
            values[name] = None
        elif name is not None:
            values[name] = w
            name = None
    return values


def same_value(a, b):
    try:
        return float(a) == float(b)
    except (TypeError, ValueError):
        return a == b


def output_only(name):
    """Whether a cellfsi or PETSc option changes only what a run writes or shows, not its results."""
    return (name in ("output_every", "output_dir", "output_dir_adopt", "checkpoint_every", "restart", "log_view")
            or name.endswith(("_monitor", "_view")))


def yaml_options(path):
    """The options a YAML file sets, named and written as cellfsi reads them (apps/scene_file.cpp): nested keys
    joined by '_', a list's items by commas, every value as its text (python3-yaml)."""
    import yaml  # (here: only a run continued from its options.yaml needs it)
    with open(path) as f:
        root = yaml.load(f, Loader=yaml.BaseLoader) or {}
    out = {}

    def walk(node, prefix):
        for key, value in node.items():
            if isinstance(value, dict):
                walk(value, prefix + key + "_")
            else:
                out[prefix + key] = ",".join(value) if isinstance(value, list) else value
    walk(root, "")
    return out


def options_of_run(run_dir, scene, command_line):
    """(the options a run was made with, those of them its scene file sets with the same value). A run continued
    from its own options.yaml (`cellfsi DIR/options.yaml -restart ...`, docs/running.md) has only that launch's
    options on its command line: its options are then those of its options.yaml, which cellfsi rewrites at each
    launch with every option the run has (the scene file's and both command lines'), less the scene file's own."""
    words = shlex.split(command_line or "")
    ran = option_values(words)
    first = words[1] if len(words) > 1 and not re.fullmatch(r"-[A-Za-z_]\w*", words[1]) else ""
    kept = os.path.join(run_dir, "options.yaml")
    if os.path.basename(first) != "options.yaml" or not scene or not os.path.isfile(kept):
        return ran, {}
    ran = {**yaml_options(kept), **ran}
    in_scene = yaml_options(os.path.join(ROOT, "scenes", scene))
    # (options.yaml names the run's scene: the file's stem unless the file names another)
    in_scene.setdefault("scene", os.path.splitext(os.path.basename(scene))[0])
    return ran, {k: v for k, v in in_scene.items() if same_value(ran.get(k), v)}


def check_kept_runs(tool, args, runs):
    """Exits (code 1) when a completed run that run_one would keep was made with other values of the options
    it would be run with now (a folder of another sweep or s_I), or with an option it would not be run with
    now (another box or law), naming the folder and the options. `runs`: (tag, scene file or None, options)."""
    bad = []
    for tag, scene, options in runs:
        summary = os.path.join(args.runs, tag, "summary.json")
        if not os.path.isfile(summary):
            continue
        with open(summary) as f:
            js = json.load(f)
        if js.get("status") != "completed":
            continue
        ran, from_scene = options_of_run(os.path.join(args.runs, tag), scene, js.get("command_line"))
        asked = option_values(options)
        differ = [f"-{k} {v} (the run: {ran[k] if k in ran else 'not set'})"
                  for k, v in asked.items() if not same_value(ran.get(k), v)]
        # Options the run had and run_one would not pass, but for those that change only what is written or
        # shown (the output, checkpoints, -restart, monitors and -log_view) and, for a run continued from its
        # options.yaml, those its scene file sets; paper_space adds the space and, for a scene it names (unknown
        # without `scene`), the membrane.
        passed = option_values(paper_space(options, scene))
        differ += [f"-{k}{'' if ran[k] is None else ' ' + ran[k]} (the run's; not asked now)"
                   for k in ran if k not in passed and not output_only(k) and k not in from_scene
                   and not (scene is None and k == "solid_membrane_elements")]
        if differ:
            bad.append(f"{os.path.join(args.runs, tag)}: {', '.join(differ)}")
    if bad:
        sys.exit(f"{tool}: completed runs in --runs {args.runs} were made with other options than asked; use "
                 "another --runs folder or delete them:\n  " + "\n  ".join(bad))


def mesh_of(tool, text, what):
    """NX, NY from 'NXxNY' (both at least 4), or exit (code 1) with a message naming `what` (the option)."""
    try:
        nx, ny = (int(v) for v in text.split("x"))
        if nx < 4 or ny < 4:
            raise ValueError
        return nx, ny
    except ValueError:
        sys.exit(f"{tool}: {what} '{text}' is invalid: give NXxNY with NX, NY >= 4 (e.g. 128x64)")


def fmt(x, f):
    return "-" if x is None or (isinstance(x, float) and x != x) else format(x, f)


def commit_of_head():
    return subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True,
                          text=True).stdout.strip() or "unknown"


def blas_kernels():
    """OpenBLAS's kernels as the runs get them (they inherit this process's environment): they set the speed of
    the LU factorisations (docs/design.md §5)."""
    try:
        lib = ctypes.CDLL("libopenblas.so.0")
        lib.openblas_get_corename.restype = ctypes.c_char_p
        core = lib.openblas_get_corename().decode()
    except (OSError, AttributeError):
        return "a BLAS other than OpenBLAS"
    chosen = os.environ.get("OPENBLAS_CORETYPE")
    return f"OpenBLAS's {core} kernels ({'OPENBLAS_CORETYPE=' + chosen if chosen else 'its own choice'})"


def provenance(args, command):
    """The line under a generated table: command, date, commit, machine, load, where the runs are."""
    load = open("/proc/loadavg").read().split()[:3] if os.path.exists("/proc/loadavg") else ["?"] * 3
    commit = commit_of_head()
    dirty = subprocess.run(["git", "-C", ROOT, "diff", "--quiet", "HEAD", "--", "."]).returncode != 0
    return (f"Generated by `{command}` on {datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC, git {commit}"
            f"{' with uncommitted changes' if dirty else ''}, {os.cpu_count()} cores, {args.jobs} runs at a time "
            f"(one rank each), load average {' '.join(load)}, {blas_kernels()}. "
            f"Runs kept in `{os.path.relpath(args.runs, ROOT)}`{runs_made_by(args.runs)}.")


def runs_made_by(runs):
    """', made by cellfsi at C1, C2': the commits the summary.json of each run folder in `runs` records (a table
    redrawn later from kept runs names the code that made them, not only its own), or ''."""
    commits = set()
    for name in sorted(os.listdir(runs)) if os.path.isdir(runs) else []:
        try:
            with open(os.path.join(runs, name, "summary.json")) as f:
                commits.add(json.load(f).get("commit"))
        except (OSError, ValueError):
            continue
    commits.discard(None)
    return f", made by cellfsi at {', '.join(sorted(c[:7] for c in commits))}" if commits else ""


def write_table(path, lines):
    """Writes the table's lines to path (folders made; None: nowhere) and prints them."""
    if path:
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def pyplot(tool):
    """matplotlib.pyplot on the Agg backend, or None (with a message naming `tool`) when it is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"{tool}: no matplotlib (python3-matplotlib): figure skipped", file=sys.stderr)
        return None
    return plt


def save_figure(fig, path, tool):
    fig.tight_layout()
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"{tool}: wrote {path}")
