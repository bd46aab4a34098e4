#!/usr/bin/env python3
"""The automatic s_I (-s_interface auto, issue 27 item 4; docs/validation.md, "The automatic s_I") against the
hand-chosen values: short runs of the capsule in shear at the paper's Table 1 meshes (s_I 1e10 by hand), the
migrating capsule (1e9) and the six-RBC channel (1e9), each with -s_interface auto (|r_A| <= 1e-3) and with the
hand-chosen value. Writes, per run: the s_I used, the largest |r_A| of any membrane over the run and at its end,
the scene's metrics (theta and omega_TT; the lateral offset; zeta, eta and h_cf) and the coupling iterations per
step; and, first, the earlier measurements the rule was fitted on. --groups raise: the capsule in shear at 128 x 64
to 0.4 s with auto, with and without -s_interface_raise (not among the default groups).

  bench/run_auto_interface_scaling.py                          # every run, one at a time
  bench/run_auto_interface_scaling.py --groups shear --shear-time 0.2
  bench/run_auto_interface_scaling.py --groups raise --table docs/validation/auto_interface_scaling_raise.md
  bench/run_auto_interface_scaling.py --report                 # the table from the runs already there

A run whose summary.json says completed is kept. Needs a built cellfsi (scripts/build.sh)."""
import argparse
import csv
import json
import os
import sys

from bench_common import ROOT, check_kept_runs, fmt, provenance, run_one, write_table
from run_channel_rheology import area_row

# group: (scene, its runs per mesh (VARIANTS, or a hand-chosen s_I), meshes, time step, metrics of summary.json
# shown). "raise": the capsule in shear long enough for r_A to drift, with and without -s_interface_raise.
GROUPS = {
    "shear": ("capsule_shear.yaml", ["auto", "1e10"], ["96x48", "128x64", "192x96", "256x128"], "1e-3",
              ["membrane_theta_deg", "membrane_omega_tt"]),
    "migration": ("capsule_channel_migration.yaml", ["auto", "1e9"], ["128x64", "256x128"], "5e-4",
                  ["membrane_lateral_offset_final", "membrane_theta_deg"]),
    "rbc": ("rbc_channel.yaml", ["auto", "1e9"], ["96x32"], "5e-4", ["zeta", "eta", "h_cf"]),
    "raise": ("capsule_shear.yaml", ["auto", "raise"], ["128x64"], "1e-3",
              ["membrane_theta_deg", "membrane_omega_tt"]),
}
VARIANTS = {"auto": ["-s_interface", "auto"], "raise": ["-s_interface", "auto", "-s_interface_raise"]}

# The rule's basis (coupling/interface_marking.cpp, automatic_interface_scaling): earlier measured |r_A| with
# hand-chosen s_I, central marking. (what, where it is documented, domain width / elements along x [cm], degree,
# s_I, |r_A|.) The capsule in shear: r_A(0.3 s) of the Table 1 runs (validation/capsule_table1_central.md);
# the migrating capsule: r_A(0.1 s) of validation/area_error_study.md and the largest of the long runs
# (docs/notes/2026-11-24-val-channel-migration.md); six RBCs: the largest |r_A| of a cell (validation/channel_si_sweep*.md).
MIGRATION, RBC = 0.002, 0.003  # the channels' lengths [cm]
MEASURED = [(f"capsule in shear {n}x{n // 2}, p {p}, 0.3 s", "capsule_table1_central.md", 0.0024 / n, p, 1e10, r)
            for n, p, r in [(96, 2, 1.11e-3), (96, 3, 1.51e-4), (128, 2, 1.27e-3), (128, 3, 8.12e-4),
                            (192, 2, 3.36e-3), (192, 3, 1.37e-3), (256, 2, 3.91e-4), (256, 3, 1.07e-3)]]
STUDY, LONG = "area_error_study.md", "validation.md Sec. 4.2"
MEASURED += [(f"migrating capsule {n}x{n // 2}, {t}", where, MIGRATION / n, 3, s_i, r)
             for n, t, where, s_i, r in [(256, "0.1 s", STUDY, 1e5, 3.49e-2), (256, "0.1 s", STUDY, 1e7, 4.28e-3),
                                         (256, "0.1 s", STUDY, 1e9, 4.79e-4), (256, "0.1 s", STUDY, 1e11, 5.36e-5),
                                         (128, "0.1 s", STUDY, 1e9, 1.81e-4), (256, "to 2.1 s", LONG, 1e9, 6.0e-3),
                                         (128, "to 2.4 s", LONG, 1e9, 2.0e-3)]]
SWEEP, SWEEP_384 = "channel_si_sweep.md", "channel_si_sweep_384x128.md"
MEASURED += [(f"six RBCs {n}x{n // 3}, {t}", where, RBC / n, 3, s_i, r)
             for n, t, where, s_i, r in [(384, "0.4 s", SWEEP_384, 1e6, 5.15e-2),
                                         (384, "0.4 s", SWEEP_384, 1e9, 1.85e-3),
                                         (384, "0.4 s", SWEEP_384, 1e11, 1.85e-4), (96, "to 1.1 s", SWEEP, 1e6, 2.8e-2),
                                         (96, "to 1.1 s", SWEEP, 1e9, 6.1e-4)]]
REFERENCE_BAND, BAND_EXPONENT, RULE_CONSTANT = 5e-5, 1.4, 250  # as in automatic_interface_scaling


def fit_lines():
    """The measured points as r_A s_I^(1/2) (w / w_ref)^1.4, the rule's constant being their envelope."""
    lines = ["Basis of the rule: earlier runs with hand-chosen s_I (central marking). C = abs r_A s_I^(1/2) "
             f"(w / {REFERENCE_BAND:g} cm)^{BAND_EXPONENT}, w = (2p - 1) h the s_I band's width; the rule takes "
             f"C = {RULE_CONSTANT} (their largest, rounded up).", "",
             "| run | table | h cm | p | s_I | abs r_A | C |", "|---|---|---|---|---|---|---|"]
    largest = 0
    for what, where, h, p, s_i, r_a in MEASURED:
        c = r_a * s_i ** 0.5 * ((2 * p - 1) * h / REFERENCE_BAND) ** BAND_EXPONENT
        largest = max(largest, c)
        lines.append(f"| {what} | {where} | {h:.3g} | {p} | {s_i:.0e} | {r_a:.3g} | {c:.0f} |")
    return lines + ["", f"Largest C: {largest:.0f}."]


def final_area_error(args, tag):
    """The largest abs r_A of any body at the run's last step (metrics.csv; summary.json averages r_A)."""
    with open(os.path.join(args.runs, tag, "metrics.csv")) as f:
        last = list(csv.DictReader(f))[-1]
    return max(abs(float(v)) for k, v in last.items() if k.endswith("_r_A"))


def runs_of(args):
    """(tag, scene, options) of every run of the chosen groups: auto and the hand-chosen s_I per mesh."""
    runs = []
    for group in args.groups.split(","):
        scene, variants, meshes, dt, _ = GROUPS[group]
        T = getattr(args, f"{group}_time")
        body = "rbc" if group == "rbc" else "membrane"
        for mesh in args.meshes.split(",") if args.meshes else meshes:
            common = ["-fluid_elements", mesh.replace("x", ","), "-dt", dt, "-final_time", f"{T:g}",
                      "-metrics_average_from", f"{T / 2:g}", "-output_every", "0",
                      f"-solid_{body}_elements", "1,0"]
            for v in variants:
                runs.append((f"{group}_{mesh}_{v}", scene, common + VARIANTS.get(v, ["-s_interface", v])))
    return runs


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--groups", default="shear,migration,rbc", help="of: " + ", ".join(GROUPS))
    p.add_argument("--shear-time", type=float, default=0.12, help="final time of the shear runs [s]")
    p.add_argument("--migration-time", type=float, default=0.05, help="final time of the migration runs [s]")
    p.add_argument("--rbc-time", type=float, default=0.1, help="final time of the six-RBC runs [s]")
    p.add_argument("--raise-time", type=float, default=0.4, help="final time of the raise runs [s]")
    p.add_argument("--meshes", help="NXxNY,... for every group instead of its own (e.g. 48x24, for a test)")
    p.add_argument("--runs", default=os.path.join(ROOT, "out", "auto_interface_scaling"))
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "auto_interface_scaling.md"))
    p.add_argument("--report", action="store_true")
    args = p.parse_args()
    args.jobs = 1
    if any(g not in GROUPS for g in args.groups.split(",")):
        sys.exit(f"run_auto_interface_scaling: --groups {args.groups}: choose among {', '.join(GROUPS)}")
    os.makedirs(args.runs, exist_ok=True)
    runs = runs_of(args)
    check_kept_runs("run_auto_interface_scaling", args, runs)
    if not args.report:
        for run in runs:
            print(*run_one(args, *run), flush=True)
    lines = []
    missing = False
    for group in args.groups.split(","):
        scene, _, _, dt, shown = GROUPS[group]
        lines += ["", f"`{scene}`, dt {dt}, to t = {getattr(args, f'{group}_time'):g} s (metrics averaged over "
                  "its second half):", "",
                  "| mesh | s_I | chosen | largest abs r_A | abs r_A(T) | " + " | ".join(shown) +
                  " | coupling it./step | wall s |", "|---" * (7 + len(shown)) + "|"]
        for tag, _, options in (r for r in runs if r[0].startswith(group + "_")):
            try:
                with open(os.path.join(args.runs, tag, "summary.json")) as f:
                    s = json.load(f)
            except (OSError, ValueError):
                s = {}
            if s.get("status") != "completed":
                missing = True
                lines.append(f"| {tag.split('_')[1]} | - | {tag.split('_')[2]} | {s.get('status', 'not run')} |" +
                             " - |" * (len(shown) + 3))
                continue
            a = area_row(s)
            chosen = s.get("s_interface_choice")
            if "s_interface_raises" in s:
                chosen += f", raised {s['s_interface_raises']:.0f} times to {s['s_interface_final']:.3g}"
            lines.append(f"| {tag.split('_')[1]} | {s['s_interface']:.3g} | {chosen} | "
                         f"{fmt(a['max_abs_r_A'], '.2e')} | {fmt(final_area_error(args, tag), '.2e')} | " +
                         " | ".join(fmt(s.get(k), '.4g') for k in shown) +
                         f" | {fmt(a['coupling_per_step'], '.2f')} | {fmt(s.get('wall_time_s'), '.0f')} |")
    command = "bench/run_auto_interface_scaling.py " + " ".join(sys.argv[1:])
    write_table(args.table, ["# The automatic s_I against the hand-chosen values", "",
                             provenance(args, command.strip()), ""] + fit_lines() + lines)
    return 3 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
