#!/usr/bin/env python3
"""The paper's rheology of RBCs in a channel (Sec. 4.3, Fig. 8): runs scenes/rbc_channel.yaml with 4, 6, 8, 10 and
12 cells (H_t 0.1716 ... 0.5147), collects each run's summary.json and profile_mean.csv, and writes a markdown table
and a figure: zeta (Fahraeus), h_cf, eta (Fahraeus-Lindqvist) against H_t, and the time-averaged velocity profiles
against the plasma's parabola.

    python3 bench/run_channel_rheology.py                       # 96x32 cubic, dt 5e-4, to 0.4 s (window 0.2-0.4)
    python3 bench/run_channel_rheology.py --mesh 384x128 --dt 2.5e-4 --final-time 1.1 --average-from 0.45  # paper

Options: --mesh NXxNY  --degree P (3)  --dt S  --final-time S  --average-from S  --counts N,N,...  --jobs N (1)
  --runs DIR (out/rheology)  --build DIR (build)  --table FILE (docs/validation/channel_rheology.md)
  --figure FILE (docs/figures/channel_rheology.png)  --report (no runs)  --extra "OPTIONS" (to every run)
  --results FILE (docs/validation/data/channel_rheology_<mesh>_p<degree>[_<extra options>].json)
A run whose summary.json says "completed" is not run again; exit code 3 when a run did not complete. Each completed
run's metrics and time-averaged profile are also kept in the results file (by cell count, with the date and commit
they were recorded at), so that the table and figure can be regenerated when the run folders are gone (they are
not in the repository) and counts run in different sessions come together. The figure needs python3-matplotlib
(scripts/install-deps.sh; Debian's /usr/bin/python3)."""
import argparse
import concurrent.futures
import csv
import datetime
import json
import os
import re
import shlex
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import (ROOT, check_kept_runs, commit_of_head, fmt, option_values, provenance,  # noqa: E402
                          pyplot, run_one, save_figure, write_table)

# The channel of scenes/rbc_channel.yaml (CGS): the plasma's parabola u(y) = f / (2 mu) y (H - y).
HEIGHT, FORCE, VISCOSITY = 0.001, 1666.66, 0.012


def runs_of(args):
    nx, ny = args.mesh.split("x")
    common = ["-fluid_elements", f"{nx},{ny}", "-fluid_degree", str(args.degree), "-dt", str(args.dt),
              "-final_time", str(args.final_time), "-metrics_average_from", str(args.average_from),
              "-output_every", "0", "-solid_rbc_elements", "1,0"] + shlex.split(args.extra)
    return [(f"rbc_{args.mesh}_p{args.degree}_{n}", "rbc_channel.yaml", ["-solid_rbc_count", str(n)] + common)
            for n in (int(c) for c in args.counts.split(","))]


KEPT = ("status", "steps", "wall_time_s", "H_t", "H_d", "zeta", "eta", "h_cf", "v_cells", "v_mean")


def option_of(command_line, name):
    """The value of -name on a run's command line (summary.json's command_line), as a float; None if absent."""
    value = option_values(shlex.split(command_line or "")).get(name)  # the last one, as PETSc reads it
    try:
        return float(value) if value is not None else None
    except ValueError:
        return None


def area_row(s):
    """From a run's summary.json: its status, size and cost and the cells' area change (mean of the final |r_A|
    and the largest |r_A| of any cell over the run; a failed run has the last step's values only)."""
    final = [abs(v) for k, v in s.items() if k.endswith("_r_A") and not k.endswith("max_abs_r_A") and v is not None]
    peak = [abs(v) for k, v in s.items() if k.endswith("_max_abs_r_A") and v is not None] or final
    its = s.get("coupling_iterations", s.get("newton_iterations"))
    return {"status": s.get("status"), "steps": s.get("steps"), "wall_time_s": s.get("wall_time_s"),
            "dt": option_of(s.get("command_line"), "dt"),
            "final_time": option_of(s.get("command_line"), "final_time"),
            "commit": str(s.get("commit", "?"))[:7], "mean_abs_r_A": sum(final) / len(final) if final else None,
            "max_abs_r_A": max(peak, default=None),
            "coupling_per_step": its / max(1, s.get("steps") or 1) if its is not None else None}


def load_results(path):
    if not os.path.isfile(path):
        return {}
    with open(path) as f:
        return json.load(f)


def collect(args):
    """The rows of the requested counts: from a run's folder when it is there (and then kept in the results file),
    otherwise from the results file."""
    results = load_results(args.results)
    for tag, _, _ in runs_of(args):
        path = os.path.join(args.runs, tag, "summary.json")
        if not os.path.isfile(path):
            continue
        with open(path) as f:
            s = json.load(f)
        row = dict(area_row(s), **{k: s.get(k) for k in KEPT})
        prof = os.path.join(args.runs, tag, "profile_mean.csv")
        if os.path.isfile(prof):
            with open(prof) as f:
                row["profile"] = [(float(r["y"]), float(r["vx"])) for r in csv.DictReader(f)]
        row["recorded"] = (f"{datetime.datetime.utcnow():%Y-%m-%d} (git {commit_of_head()}) from "
                           f"{os.path.relpath(path, ROOT)}, run with git {str(s.get('commit', '?'))[:7]}")
        count = tag.rsplit("_", 1)[1]
        if row["status"] == "completed" or count not in results:
            results[count] = row
    if results:
        os.makedirs(os.path.dirname(args.results) or ".", exist_ok=True)
        with open(args.results, "w") as f:
            json.dump(dict(sorted(results.items(), key=lambda kv: int(kv[0]))), f, indent=1)
    rows = []
    for n in (int(c) for c in args.counts.split(",")):
        if str(n) in results:
            rows.append(dict(results[str(n)], _count=n))
    return rows


def write_rheology_table(args, rows, command):
    lines = [provenance(args, command) + f" Every row is kept in `{os.path.relpath(args.results, ROOT)}`; "
             "'recorded' says when and from where.", "",
             "| cells | H_t | H_d | zeta = v_m / v_RBCs | eta = v_P / v_m | h_cf um | v_RBCs cm/s | v_m cm/s |"
             " max abs r_A | steps | wall s | status | recorded |", "|" + "---|" * 13]
    for s in rows:
        h = s.get("h_cf")
        lines.append(f"| {s['_count']} | {fmt(s.get('H_t'), '.4f')} | {fmt(s.get('H_d'), '.4f')} |"
                     f" {fmt(s.get('zeta'), '.4f')} | {fmt(s.get('eta'), '.4f')} |"
                     f" {fmt(h * 1e4 if h is not None else None, '.3f')} | {fmt(s.get('v_cells'), '.5f')} |"
                     f" {fmt(s.get('v_mean'), '.5f')} | {fmt(s.get('max_abs_r_A'), '.2e')} | {s.get('steps')} |"
                     f" {fmt(s.get('wall_time_s'), '.0f')} | {s.get('status')} | {s.get('recorded', '-')} |")
    lines.append("")
    lines.append(f"Plasma alone: v_P = f H^2 / (12 mu) = {FORCE * HEIGHT ** 2 / (12 * VISCOSITY):.5f} cm/s "
                 "(analytic; the code reproduces it to 2.2e-7, docs/validation.md, 'Plasma flows').")
    write_table(args.table, lines)


def write_figure(args, rows):
    plt = pyplot("run_channel_rheology")
    if plt is None:
        return
    done = [s for s in rows if s.get("status") == "completed" and s.get("zeta") is not None]
    if not done:
        print("run_channel_rheology: no completed runs: figure skipped", file=sys.stderr)
        return
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    ht = [s["H_t"] for s in done]
    for ax, (key, name, scale) in zip(axes[:3], [("zeta", "zeta = H_t / H_d = v_m / v_RBCs", 1),
                                                  ("h_cf", "cell-free layer h_cf (um)", 1e4),
                                                  ("eta", "eta = v_P / v_m", 1)]):
        ax.plot(ht, [s[key] * scale for s in done], "o-", color="tab:red")
        ax.set_xlabel("tube hematocrit H_t")
        ax.set_ylabel(name)
        ax.grid(True, lw=0.3)
    ax = axes[3]
    ys = [HEIGHT * i / 64 for i in range(65)]
    ax.plot([y * 1e4 for y in ys], [FORCE / (2 * VISCOSITY) * y * (HEIGHT - y) for y in ys], "k--", label="plasma")
    for s in done:
        if s.get("profile"):
            p = s["profile"]
            ax.plot([y * 1e4 for y, _ in p], [v for _, v in p], label=f"H_t = {s['H_t']:.3f}")
    ax.set_xlabel("y (um)")
    ax.set_ylabel("time-averaged vx (cm/s)")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=7)
    fig.suptitle(f"RBCs in a channel ({args.mesh}, p = {args.degree}, dt = {args.dt:g} s, averaged over "
                 f"{args.average_from:g}-{args.final_time:g} s)", fontsize=10)
    save_figure(fig, args.figure, "run_channel_rheology")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--mesh", default="96x32")
    p.add_argument("--degree", type=int, default=3)
    p.add_argument("--dt", type=float, default=5e-4)
    p.add_argument("--final-time", type=float, default=0.4)
    p.add_argument("--average-from", type=float, default=0.2)
    p.add_argument("--counts", default="4,6,8,10,12")
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "rheology"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "channel_rheology.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "channel_rheology.png"))
    p.add_argument("--extra", default="")
    p.add_argument("--results", default=None)
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    if args.results is None:  # runs with --extra options are kept apart from the default's
        extra = re.sub(r"[^A-Za-z0-9.+-]+", "_", re.sub(r"(^|\s)-+", r"\1", args.extra.strip())).strip("_")
        args.results = os.path.join(ROOT, "docs", "validation", "data",
                                    f"channel_rheology_{args.mesh}_p{args.degree}" + (f"_{extra}" if extra else "")
                                    + ".json")
    if "x" not in args.mesh:
        p.error(f"--mesh {args.mesh} is invalid; valid: NXxNY, e.g. 96x32")
    exe = os.path.join(args.build, "apps", "cellfsi")
    if not args.report and not os.access(exe, os.X_OK):
        sys.exit(f"run_channel_rheology: {exe} not found; build first (scripts/build.sh)")
    os.makedirs(args.runs, exist_ok=True)
    command = "bench/run_channel_rheology.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    check_kept_runs("run_channel_rheology", args, runs_of(args))
    if not args.report:
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            for tag, how in pool.map(lambda r: run_one(args, *r), runs_of(args)):
                print(f"run_channel_rheology: {tag}: {how}", flush=True)
    rows = collect(args)
    write_rheology_table(args, rows, command)
    write_figure(args, rows)
    missing = len(runs_of(args)) - sum(1 for s in rows if s.get("status") == "completed")
    if missing:
        print(f"run_channel_rheology: {missing} run(s) did not complete (see the .log files in {args.runs})",
              file=sys.stderr)
        sys.exit(3)


if __name__ == "__main__":
    main()
