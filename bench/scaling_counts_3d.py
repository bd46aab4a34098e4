#!/usr/bin/env python3
"""A strong-scaling model of the 3D coupled step from per-rank operation counts (issue 45 part 1): the runs of
bench/run_3d_steps.py at one mesh on several rank counts (oversubscribed runs are fine: counts do not depend on
the cores), read from their -log_view. Per part of the step (its log event), the slowest rank's counted
operations F(p) = a + b / p are fitted over the rank counts (least squares, a, b >= 0), a the operations that
do not divide by the ranks (replicated work, imbalance: the slowest rank's share), b those that do. A part's
time at p ranks is its one-rank time scaled by F(p) / F(1); a part with no counts (the solids' work: the solid
library does not call PETSc) does not divide at all (every rank does it today), nor does the step's rest. The
model's step at P ranks is the sum; a part whose non-dividing time exceeds --limit of it is named. Writes
docs/performance/scaling_counts_3d_dc.md (or --out).

  python3 bench/run_3d_steps.py --cases 64:1:3,64:2:3,64:4:3,64:8:3 --runs out/counts \\
      --extra "-fluid_space div_conforming -fluid_dc_degree 2" --table /tmp/counts.md
  python3 bench/scaling_counts_3d.py --runs out/counts --mesh 64 --ranks 1,2,4,8

What the counts leave out: communication (messages and reductions are in the log, not in the model), and the
time of uncounted work inside a counted part (taken to divide as the part's counts do).
"""
import argparse
import json
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, commit_of_head, fmt, write_table  # noqa: E402

TOOL = "scaling_counts_3d.py"
# The step's parts: run_3d_steps.py's events (top level: their times and counts include the events inside).
PARTS = [
    "FsiLinearSolve", "FsiJacobian", "FsiResidual", "FsiLocate", "FsiRepulsion", "FsiSolidUpdate", "FsiKinematic",
    "FsiStepEnds", "CellfsiTrack"
]
# Events inside another, in order: each one's time and counts are taken out of the outer one. The repulsion
# runs inside FsiLocate over every membrane point on every rank and counts nothing: scaled by FsiLocate's
# counts it would seem to divide. Its construction (FsiRepulsionSetUp, inside it at the first call, once per
# run) is left out of the model, as the bulk inverse's factorisation (FsiFactor) is.
# A run's first call of the location (FsiLocateSetUp, inside FsiLocate: every point formed and located on
# every rank, to deal them out) is left out likewise.
# Only events whose work is the same on every rank are taken out so (-log_view gives the slowest rank's count
# of each event, not which rank's): the bodies' control increments in the Krylov products (FsiSolidControl,
# dealt out by columns, some ranks without any) and the points' matrix's pattern (DcImmersedPattern) stay
# inside the linear solves and the Jacobian, whose counts hold them.
NESTED = [("FsiRepulsion", "FsiLocate"), ("FsiRepulsionSetUp", "FsiRepulsion"), ("FsiLocateSetUp", "FsiLocate")]
# Events that came later (FsiKinematic f0b4c65, FsiStepEnds 853ee54, FsiRepulsionSetUp after a28c636,
# FsiLocateSetUp after 5ceeae0) or
# that a run without membranes does not log (FsiRepulsion): read as 0 where a log lacks them (an older log's
# kinematic updates are inside FsiSolidUpdate, its step's ends in the rest).
OPTIONAL = ["FsiKinematic", "FsiStepEnds", "FsiRepulsion", "FsiRepulsionSetUp", "FsiLocateSetUp"]
WHAT = {
    "FsiLinearSolve": "FGMRES: the bulk inverse (each rank reads its lines, transforms them and solves its wave "
                      "vectors), the points' matrix (its rows dealt out evenly), the solids' products (each rank "
                      "reads the unknowns its collocation rows touch; the control increments' solves dealt out "
                      "by columns, 3 per body, so they stop dividing beyond that many ranks: the fit from 8 "
                      "ranks holds that only in part)",
    "FsiJacobian": "the points' tangent (each rank an equal run of the points, or its elements' points), the "
                   "solids' collocation rows (each rank its run), the points' matrix's pattern (every rank goes "
                   "over every element with points)",
    "FsiResidual": "the elements' terms (dealt out), the points' terms (as the Jacobian's); each rank gathers "
                   "and steps to the alpha levels only the unknowns its elements and its points' elements read "
                   "(its part of the iterate)",
    "FsiLocate": "each rank its run of the points located and formed, with their material (not counted); "
                 "the counting sort and the exchange's unpacking of every point (not counted: a lower bound); "
                 "a run's first call, every point on every rank, is FsiLocateSetUp (once per run, left out)",
    "FsiRepulsion": "the repulsion over every membrane point on every rank (not counted; its construction, "
                    "once per run, left out)",
    "FsiSolidUpdate": "the fluid's velocity at the bodies' collocation points (each rank its share, gathered), "
                      "from the unknowns of their elements alone (each rank its part of the iterate)",
    "FsiKinematic": "the bodies' kinematic updates (each rank its run of the points and its collocation "
                    "columns, dealt out over the bodies in turn, gathered; counted: an estimate)",
    "FsiStepEnds": "the fluid's and the bodies' begin and end of a step (the solution gathered whole to every "
                   "rank once per step, the divergence diagnostic)",
    "CellfsiTrack": "the bodies' metrics (each rank its share of the elements; counted: an estimate of their "
                    "points' operations)",
    "rest": "the rest of the one-rank step after the first (its wall time less the parts, which average every "
            "step, the first's set-up included: a lower bound; not counted)",
}


def events(path):
    """-log_view's event lines of a log: name -> (time max s, flop max, flop max / min)."""
    ev = {}
    for line in open(path):
        f = line.split()
        if len(f) > 7 and re.match(r"^[A-Za-z]\w*$", f[0]) and re.match(r"^\d+$", f[1]):
            try:
                ev[f[0]] = (float(f[3]), float(f[5]), float(f[6]))
            except ValueError:
                pass
    return ev


def fit(points):
    """Least-squares a, b >= 0 of F = a + b / p through (p, F) (with a negative one set to 0, the other fitted
    again)."""
    xs = [1.0 / p for p, _ in points]
    fs = [f for _, f in points]
    n = len(points)
    mx, mf = sum(xs) / n, sum(fs) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    b = sum((x - mx) * (f - mf) for x, f in zip(xs, fs)) / sxx if sxx > 0 else 0.0
    a = mf - b * mx
    if a >= 0 and b >= 0:
        return a, b
    if b < 0:
        return max(mf, 0.0), 0.0
    return 0.0, max(sum(x * f for x, f in zip(xs, fs)) / sum(x * x for x in xs), 0.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", required=True, help="run_3d_steps.py's --runs directory")
    ap.add_argument("--mesh", type=int, default=64)
    ap.add_argument("--ranks", default="1,2,4,8", help="the runs' rank counts (1 among them)")
    ap.add_argument("--predict", type=int, default=64, help="the rank count of the model's verdict")
    ap.add_argument("--limit", type=float, default=0.10)
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "performance", "scaling_counts_3d_dc.md"))
    args = ap.parse_args()
    try:
        counts = sorted({int(r) for r in args.ranks.split(",")})
        if counts[0] != 1 or len(counts) < 2:
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --ranks '{args.ranks}' is invalid: give two or more rank counts, 1 among them "
                 "(e.g. 1,2,4,8)")
    if not 0 < args.limit < 1:
        sys.exit(f"{TOOL}: --limit {args.limit} is invalid: give a share between 0 and 1 (e.g. 0.1)")
    if args.predict < 1:
        sys.exit(f"{TOOL}: --predict {args.predict} is invalid: give a rank count >= 1")
    logs, steps, commits = {}, {}, set()
    for r in counts:
        tag = f"{args.mesh}cube_{r}rank"
        path = os.path.join(args.runs, tag + ".log")
        try:
            logs[r] = events(path)
            with open(os.path.join(args.runs, tag, "summary.json")) as f:
                s = json.load(f)
        except (OSError, ValueError) as e:
            sys.exit(f"{TOOL}: the run {tag} in --runs {args.runs} cannot be read ({e}): run bench/run_3d_steps.py "
                     f"--cases {args.mesh}:{r}:3 --runs {args.runs} first")
        if s.get("status") != "completed":
            sys.exit(f"{TOOL}: the run {tag} did not complete (status {s.get('status')})")
        steps[r] = s["steps"]
        commits.add(s.get("commit", "unknown"))
        for p in OPTIONAL:  # (events added later: in an older run's log their work is inside the others)
            logs[r].setdefault(p, (0.0, 0.0, 1.0))
        missing = [p for p in PARTS if p not in logs[r]]
        if missing:
            sys.exit(f"{TOOL}: {path} has no -log_view line for {', '.join(missing)}: a run with -log_view")
    # The one-rank step: the wall time between the first and the last step's line (the first step also builds
    # the bulk inverse, FsiFactor, once per run: left out of the model).
    wall1 = None
    with open(os.path.join(args.runs, f"{args.mesh}cube_1rank.log")) as f:
        m = re.findall(r"^step (\d+)/\d+ .*elapsed ([0-9.]+) s", f.read(), re.M)
        if len(m) > 1:
            wall1 = (float(m[-1][1]) - float(m[0][1])) / (int(m[-1][0]) - int(m[0][0]))
    P = args.predict
    for r in counts:
        for inner, outer in NESTED:
            t, f, ratio = logs[r][outer]
            logs[r][outer] = (max(t - logs[r][inner][0], 0.0), f - logs[r][inner][1], ratio)
    rows, model = [], {}
    for name in PARTS:
        t1 = logs[1][name][0] / steps[1]
        F = [(r, logs[r][name][1] / steps[r]) for r in counts]
        if F[0][1] > 0:
            a, b = fit(F)
            scale = t1 / F[0][1]
            s, d = scale * a, scale * b
        else:
            a = b = float("nan")
            s, d = t1, 0.0
        model[name] = (s, d)
        rows.append((name, t1, F, a, b, s, d, logs[counts[-1]][name][2]))
    parts_sum = sum(r[1] for r in rows)
    rest = max((wall1 or parts_sum) - parts_sum, 0.0)
    model["rest"] = (rest, 0.0)
    step = {p: sum(s + d / p for s, d in model.values()) for p in counts + [P]}
    cmd = ("python3 bench/scaling_counts_3d.py " + " ".join(sys.argv[1:])).strip()
    dirty = subprocess.run(["git", "-C", ROOT, "diff", "--quiet", "HEAD", "--", "."]).returncode != 0
    lines = ["# A strong-scaling model of the 3D step from operation counts", "",
             f"Generated by `{cmd}` at git {commit_of_head()}{' with uncommitted changes' if dirty else ''} from "
             f"the -log_view of bench/run_3d_steps.py's {args.mesh}^3 runs at {', '.join(map(str, counts))} ranks "
             f"(binaries: {', '.join(sorted(commits))}; oversubscribed on this machine's {os.cpu_count()} cores, "
             "which changes times, not counts). Per part, the slowest rank's counted operations per step "
             "F(p) = a + b / p (least squares, a, b >= 0); its time at p ranks its one-rank time times F(p) / "
             "F(1), so s = t(1) a / F(1) does not divide and d = t(1) b / F(1) does. Parts without counts and the "
             "rest of the step do not divide (every rank does them today). Communication is not in the model. "
             f"Seconds per step; a part is flagged when its s exceeds {args.limit:.0%} of the model's step at "
             f"{P} ranks.", "",
             "| part | what does not divide today | t at 1 rank | F per step at " + ", ".join(map(str, counts))
             + " ranks (flop, slowest rank) | max/min at " + str(counts[-1]) + " | a / F(1) | s | d | "
             + " | ".join(f"at {p}" for p in counts + [P]) + f" | s / step at {P} |",
             "|---|---|---|---|---|---|---|---|" + "---|" * (len(counts) + 1) + "---|"]
    for name, t1, F, a, b, s, d, ratio in rows:
        share = s / step[P]
        lines.append(f"| {name} | {WHAT[name]} | {fmt(t1, '.3f')} | "
                     + (" / ".join(f"{f:.3g}" for _, f in F) if F[0][1] > 0 else "not counted")
                     + f" | {('a rank has none' if ratio == 0 else fmt(ratio, '.2f')) if F[0][1] > 0 else '-'} | "
                     + (f"{a / F[0][1]:.2f}" if F[0][1] > 0 else "1 (all)")
                     + f" | {fmt(s, '.3f')} | {fmt(d, '.3f')} | "
                     + " | ".join(fmt(s + d / p, ".3f") for p in counts + [P])
                     + f" | {share:.0%}{' (over the limit)' if share > args.limit else ''} |")
    share = rest / step[P]
    lines.append(f"| rest | {WHAT['rest']} | {fmt(rest, '.3f')} | not counted | - | 1 (all) | {fmt(rest, '.3f')} | "
                 f"0 | " + " | ".join(fmt(rest, ".3f") for _ in counts + [P])
                 + f" | {share:.0%}{' (over the limit)' if share > args.limit else ''} |")
    total_s = sum(s for s, _ in model.values())
    lines.append(f"| step | | {fmt(wall1 or parts_sum, '.3f')} | | | | {fmt(total_s, '.3f')} | "
                 f"{fmt(sum(d for _, d in model.values()), '.3f')} | "
                 + " | ".join(fmt(step[p], ".3f") for p in counts + [P]) + f" | {total_s / step[P]:.0%} |")
    over = [n for n, (s, _) in model.items() if s / step[P] > args.limit]
    lines += ["", f"Parts over the limit at {P} ranks: {', '.join(over) if over else 'none'}; what does not "
              f"divide is {total_s / step[P]:.0%} of the model's step there ({fmt(step[P], '.2f')} s against "
              f"{fmt(step[1], '.2f')} s on one rank)."]
    write_table(args.out, lines)


if __name__ == "__main__":
    main()
