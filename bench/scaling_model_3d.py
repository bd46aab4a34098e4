#!/usr/bin/env python3
"""A strong-scaling model of the 3D coupled step from bench/run_3d_steps.py's table (issue 45): per part of the
step (its log events, and the rest of the step), T(p) = s + d / p fitted to the rows of one mesh at several rank
counts (least squares; with two rows, through both), so that s is what does not divide by the ranks (replicated
work, communication, imbalance) and d what does. The model's step at P ranks is the sum of the parts; a part whose
s exceeds 10 % of that step is named. Writes docs/performance/scaling_model_3d_dc.md (or --out).

  python3 bench/scaling_model_3d.py                                   # 64^3 of coupled_steps_3d_dc.md, P = 64
  python3 bench/scaling_model_3d.py --mesh 32 --ranks 4,8,64 --table docs/performance/coupled_steps_3d.md

The rows are wall times of runs on real cores (oversubscribed rows are not: their ranks share cores); a fit from
two rank counts cannot tell a part's replicated work from its communication, and a negative s or d (noise) is
set to 0 and reported.
"""
import argparse
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, commit_of_head, fmt, write_table  # noqa: E402

TOOL = "scaling_model_3d.py"
PARTS = ["LinearSolve", "Jacobian", "Residual", "Locate", "SolidUpdate", "Track"]
OPTIONAL = {"Track"}  # (a column of tables from 2026-11-29 on; 0 where a table lacks it)
# What each part is, and what in it does not divide by the ranks today (docs/performance.md).
WHAT = {
    "LinearSolve": "FGMRES: bulk inverse (FFT of every line on every rank; banded solves divided), points' matrix",
    "Jacobian": "the points' tangent (their owners' points)",
    "Residual": "elements' terms (divided), points' terms (their owners'), state gathered to every rank",
    "Locate": "every point located and its x, F formed on every rank (the material at its owner's only), the repulsion",
    "SolidUpdate": "every body's kinematic update, on every rank",
    "Track": "the bodies' metrics of the step (area, volume, moments), on every rank",
    "rest": "end of step, the metrics' row, progress",
}


def read_rows(path, mesh):
    """(ranks, s/step, {part: s/step}) of the table's rows of mesh N^3 (run_3d_steps.py's columns), and the rows
    of that mesh left out (a failed run, a missing number)."""
    rows, skipped, header = [], [], None
    for line in open(path):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if cells and cells[0] == "mesh":
            header = cells
            continue
        if not header or not re.fullmatch(rf"{mesh}\^3", cells[0]):
            continue
        try:
            if len(cells) != len(header):
                raise ValueError
            row = dict(zip(header, cells))
            parts = {p: float(row[p]) if p in row or p not in OPTIONAL else 0.0 for p in PARTS}
            rows.append((int(row["ranks"]), float(row["s/step"]), parts))
        except (KeyError, ValueError):
            skipped.append(" | ".join(cells[:4]))
    return rows, skipped


def fit(points):
    """Least-squares s, d of T = s + d / p through (p, T), both >= 0: where the free fit gives a negative one,
    the fit again with it 0 (d = 0: s the mean; s = 0: d = sum(x T) / sum(x^2), x = 1 / p). Returns s, d and
    a note (empty if the free fit held)."""
    n = len(points)
    xs = [1.0 / p for p, _ in points]
    ts = [t for _, t in points]
    mx, mt = sum(xs) / n, sum(ts) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    d = sum((x - mx) * (t - mt) for x, t in zip(xs, ts)) / sxx
    s = mt - d * mx
    if s >= 0 and d >= 0:
        return s, d, ""
    free = f"free fit s = {s:.3f}, d = {d:.3f} s"
    if d < 0:
        return max(mt, 0.0), 0.0, free + "; fitted again with d = 0"
    return 0.0, max(sum(x * t for x, t in zip(xs, ts)) / sum(x * x for x in xs), 0.0), free + "; fitted again with s = 0"


def source_commit(path):
    """The commit a run_3d_steps.py table names in its provenance line ('git X[ with uncommitted changes]')."""
    m = re.search(r"git (\w+)( with uncommitted changes)?", open(path).read())
    return (m.group(1) + (" with uncommitted changes" if m.group(2) else "")) if m else "unknown"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--table", default=os.path.join(ROOT, "docs", "performance", "coupled_steps_3d_dc.md"))
    ap.add_argument("--mesh", type=int, default=64, help="N of the N^3 rows to fit")
    ap.add_argument("--ranks", default="4,8,64", help="rank counts to predict, comma-separated")
    ap.add_argument("--limit", type=float, default=0.10, help="largest share of the step a non-dividing part may have")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "performance", "scaling_model_3d_dc.md"))
    args = ap.parse_args()
    try:
        targets = [int(r) for r in args.ranks.split(",")]
        if any(r < 1 for r in targets):
            raise ValueError
    except ValueError:
        sys.exit(f"{TOOL}: --ranks '{args.ranks}' is invalid: give rank counts >= 1, comma-separated (e.g. 4,8,64)")
    if not 0 < args.limit < 1:
        sys.exit(f"{TOOL}: --limit {args.limit} is invalid: give a share between 0 and 1 (e.g. 0.1)")
    try:
        rows, skipped = read_rows(args.table, args.mesh)
        provenance_of_rows = source_commit(args.table)
    except (OSError, UnicodeDecodeError) as e:
        sys.exit(f"{TOOL}: --table {args.table} cannot be read ({e}): give run_3d_steps.py's table")
    counts = sorted({r for r, _, _ in rows})
    if len(counts) < 2:
        sys.exit(f"{TOOL}: {args.table} has rows of {args.mesh}^3 at {len(counts)} rank count(s)"
                 + (f" (left out: {'; '.join(skipped)})" if skipped else "")
                 + "; the fit needs two or more (bench/run_3d_steps.py --cases N:1:S,N:2:S)")
    if any(r > (os.cpu_count() or 1) for r in counts):
        print(f"{TOOL}: warning: rows at more ranks than this machine's {os.cpu_count()} cores: if they ran here, "
              "their ranks shared cores and their times are not the model's", file=sys.stderr)
    rows.sort(key=lambda r: r[0])
    parts = {}
    notes = []
    for name in PARTS + ["rest"]:
        pts = [(r, (step - sum(pv.values())) if name == "rest" else pv[name]) for r, step, pv in rows]
        s, d, note = fit(pts)
        if note:
            notes.append(f"{name}: {note}")
        parts[name] = (s, d)
    step = {p: sum(s + d / p for s, d in parts.values()) for p in targets}
    top = max(targets)
    cmd = ("python3 bench/scaling_model_3d.py " + " ".join(sys.argv[1:])).strip()
    dirty = subprocess.run(["git", "-C", ROOT, "diff", "--quiet", "HEAD", "--", "."]).returncode != 0
    link = os.path.relpath(args.table, os.path.dirname(os.path.abspath(args.out)))
    lines = ["# A strong-scaling model of the 3D step from its measured parts", "",
             f"Generated by `{cmd}` at git {commit_of_head()}{' with uncommitted changes' if dirty else ''} from "
             f"[{os.path.basename(args.table)}]({link}) (its {args.mesh}^3 rows at "
             f"{', '.join(str(r) for r in counts)} ranks, measured at git {provenance_of_rows}). Per part "
             "T(p) = s + d / p, least squares through the rows with s, d >= 0: s does not divide by the ranks "
             "(replicated work, communication, imbalance: two rank counts cannot tell them apart), d does. The "
             "rows' parts are each event's slowest rank, so on more than one rank their sum can exceed the step "
             f"and 'rest' is undercounted. Seconds per step. A part is flagged when its s exceeds {args.limit:.0%} "
             f"of the model's step at {top} ranks.", "",
             "| part | what does not divide today | s (does not divide) | d (divides) | "
             + " | ".join(f"at {p} ranks" for p in targets) + f" | s / step at {top} ranks |",
             "|---|---|---|---|" + "---|" * len(targets) + "---|"]
    for name, (s, d) in parts.items():
        share = s / step[top]
        lines.append(f"| {name} | {WHAT[name]} | {fmt(s, '.2f')} | {fmt(d, '.2f')} | "
                     + " | ".join(fmt(s + d / p, ".3f") for p in targets)
                     + f" | {share:.0%}{' (over the limit)' if share > args.limit else ''} |")
    lines.append("| step | | {} | {} | {} | |".format(
        fmt(sum(s for s, _ in parts.values()), ".2f"), fmt(sum(d for _, d in parts.values()), ".2f"),
        " | ".join(fmt(step[p], ".2f") for p in targets)))
    over = [n for n, (s, _) in parts.items() if s / step[top] > args.limit]
    model = {r: sum(s + d / r for s, d in parts.values()) for r in counts}
    lines += ["", f"Parts over the limit at {top} ranks: {', '.join(over) if over else 'none'}; "
              f"the non-dividing total {sum(s for s, _ in parts.values()) / step[top]:.0%} of the step. "
              "The model against the measured rows: "
              + "; ".join(f"{r} ranks {t:.1f} s (model {model[r]:.1f})" for r, t, _ in rows) + "."]
    if skipped:
        lines += ["", f"Rows of {args.mesh}^3 left out (a failed run or a missing number): " + "; ".join(skipped) + "."]
    if notes:
        lines += ["", "Fit notes: " + "; ".join(notes) + "."]
    write_table(args.out, lines)


if __name__ == "__main__":
    main()
