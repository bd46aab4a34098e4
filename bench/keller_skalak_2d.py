#!/usr/bin/env python3
"""The 2D Keller-Skalak model (a fixed-shape ellipse whose membrane tank-treads) against the capsule's
viscosity sweep (issue 27, item 3): reads the runs of `run_shear_sweeps.py viscosity`, measures each run's
shape (the axis ratio r = b/a of the ellipse with the enclosed region's second moments), evaluates the model
for that r and writes a table and a figure.

    /usr/bin/python3 bench/keller_skalak_2d.py --runs /work/main/out/sweeps_viscosity out/sweeps_viscosity_long
    /usr/bin/python3 bench/keller_skalak_2d.py --runs ... --window 8=0.17:1.23 --window 8=1.3:   # two phases
    /usr/bin/python3 bench/keller_skalak_2d.py --check   # only the formulas' checks

Each run is measured over its summary's averaging window (or over --window's), from the tracker's records in
its checkpoint, by the summary's own formulas (checked against summary.json on every run). A run that repeats
another's lambda gets a row of its own.

The model (derived in docs/notes/2026-11-26-val-viscosity.md; summary in docs/validation.md, "The capsule against the viscosity ratio and Keller-Skalak theory"): an ellipse with
semi-axes a >= b, r = b/a, at angle theta to the flow u = (gammadot y, 0), outer viscosity mu, inner lambda mu,
membrane points moving as x' = (a cos phi, b sin phi) in the body frame with dphi/dt = nu:

    dtheta/dt = -gammadot/2 (1 - B cos 2 theta),
    B = (1 - r^2)/(1 + r^2) + 4 r^2 (1 + r) / ((1 + r^2)(1 - r)(2 r + lambda (1 + r^2))),
    nu = -gammadot K cos 2 theta,   K = r (1 + r) / ((1 - r)(2 r + lambda (1 + r^2))).

Tank-treading (cos 2 theta = 1/B) exists while B >= 1, i.e. lambda <= lambda_c = 2/(1 - r); beyond it the
ellipse tumbles with axis period pi/omega, omega = gammadot sqrt(1 - B^2)/2. Frequencies are given as the
simulation reports them: turns per second, clockwise positive.

Before anything else the script checks the formulas (exit 1 if one fails): the circle limit (theta -> 45 deg),
the rigid limit (lambda -> infinity gives Jeffery's 2D ellipse), B(lambda_c) = 1, the 2D circular drop's
interior strain 2E/(1 + lambda), and an independent numerical solution of the outer Stokes flow (method of
fundamental solutions) for the model's motion: zero torque on the cell and the outer fluid's power on the
membrane equal to the dissipation inside, to 1e-3."""
import argparse
import datetime
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import ROOT, commit_of_head, fmt, pyplot, save_figure, write_table  # noqa: E402

# ---------------------------------------------------------------------------------------------- the model


def ks_B(r, lam):
    """The coefficient B of dtheta/dt = -gammadot/2 (1 - B cos 2 theta) for axis ratio r = b/a < 1."""
    return (1 - r * r) / (1 + r * r) + 4 * r * r * (1 + r) / ((1 + r * r) * (1 - r) * (2 * r + lam * (1 + r * r)))


def ks_K(r, lam):
    """nu = -gammadot K cos 2 theta: the membrane's parametric angular speed (rad/s, counter-clockwise)."""
    return r * (1 + r) / ((1 - r) * (2 * r + lam * (1 + r * r)))


def ks_lambda_c(r):
    """The viscosity ratio where B = 1: tank-treading below, tumbling above."""
    return 2 / (1 - r)


def ks_theta_deg(r, lam):
    """The tank-treading inclination (deg), None when the ellipse tumbles."""
    B = ks_B(r, lam)
    return 0.5 * math.degrees(math.acos(1 / B)) if B >= 1 else None


def ks_motion(r, lam, gammadot):
    """dict: regime, theta (deg or None), omega_tt (mean turns/s of the membrane's points about the centroid,
    clockwise), omega_tu (turns/s of the axis, clockwise; 0 when tank-treading)."""
    B, K = ks_B(r, lam), ks_K(r, lam)
    if B >= 1:
        return {"regime": "tank-treading", "theta": ks_theta_deg(r, lam), "omega_tt": gammadot * K / B / (2 * math.pi),
                "omega_tu": 0.0}
    s = math.sqrt(1 - B * B)
    # axis: theta turns by pi in T = 2 pi/(gammadot s); the time mean of cos 2 theta over a turn is (1 - s)/B.
    omega_axis = gammadot * s / 2  # rad/s, clockwise
    mean_nu = -gammadot * K * (1 - s) / B
    return {"regime": "tumbling", "theta": None, "omega_tt": (omega_axis - mean_nu) / (2 * math.pi),
            "omega_tu": omega_axis / (2 * math.pi)}


# ------------------------------------------------------------------------------------ checks of the formulas


def mfs_check(r, lam, theta, n=400, m=200, shrink=0.6, nu_factor=1.0):
    """The outer Stokes flow of the model's motion, solved by the method of fundamental solutions (2D
    Stokeslets inside the ellipse, least squares on n boundary points, zero net force): returns (torque on
    the cell / (mu gammadot A), |power - dissipation| / dissipation, boundary-velocity residual). Independent
    of the derivation: it only uses the membrane's velocity field and the Stokes equations."""
    import numpy as np
    a, b, mu, gd = 1.0, r, 1.0, 1.0
    nu = -gd * ks_K(r, lam) * math.cos(2 * theta) * nu_factor  # nu_factor != 1: a control that must fail
    thdot = -gd / 2 * (1 - ks_B(r, lam) * math.cos(2 * theta))
    c, s = math.cos(theta), math.sin(theta)
    R = np.array([[c, -s], [s, c]])
    L = thdot * np.array([[0, -1], [1, 0]]) + nu * R @ np.array([[0, -a / b], [b / a, 0]]) @ R.T
    G = np.array([[0, gd], [0, 0]])
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    X = (R @ np.vstack([a * np.cos(t), b * np.sin(t)])).T
    ds = np.hypot(a * np.sin(t), b * np.cos(t)) * (2 * np.pi / n)
    nrm = (R @ np.vstack([b * np.cos(t), a * np.sin(t)])).T
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    ts = np.linspace(0, 2 * np.pi, m, endpoint=False)
    Y = (R @ np.vstack([shrink * a * np.cos(ts), shrink * b * np.sin(ts)])).T
    A = np.zeros((2 * n, 2 * m))
    for k in range(m):
        d = X - Y[k]
        r2 = (d ** 2).sum(1)
        for i in range(2):
            for j in range(2):
                A[i::2, 2 * k + j] = (-(i == j) * 0.5 * np.log(r2) + d[:, i] * d[:, j] / r2) / (4 * np.pi * mu)
    C = np.zeros((2, 2 * m))
    C[0, 0::2] = C[1, 1::2] = 1
    rhs = ((L - G) @ X.T).T.reshape(-1)  # the disturbance's boundary velocity
    F = np.linalg.lstsq(np.vstack([A, 1e3 * C]), np.concatenate([rhs, [0, 0]]), rcond=None)[0]
    residual = np.abs(A @ F - rhs).max() / np.abs(rhs).max()
    f = (2 * mu * 0.5 * (G + G.T) @ nrm.T).T  # the undisturbed flow's traction (its pressure is uniform)
    for k in range(m):
        d = X - Y[k]
        r2 = (d ** 2).sum(1)
        f += (-(1 / np.pi) * (d @ F[2 * k:2 * k + 2]) * (d * nrm).sum(1) / r2 ** 2)[:, None] * d
    u = (L @ X.T).T
    area = np.pi * a * b
    torque = ((X[:, 0] * f[:, 1] - X[:, 1] * f[:, 0]) * ds).sum() / (mu * gd * area)
    power = ((u * f).sum(1) * ds).sum()
    eL = 0.5 * (L + L.T)
    dissipation = 2 * lam * mu * area * (eL * eL).sum()
    return torque, abs(power - dissipation) / dissipation, residual


def check_formulas(verbose=True):
    failures = []

    def need(ok, what):
        if verbose:
            print(f"  {'ok  ' if ok else 'FAIL'} {what}")
        if not ok:
            failures.append(what)

    th = ks_theta_deg(1 - 1e-6, 1.0)
    need(abs(th - 45) < 1e-3, f"circle limit: theta(r = 1 - 1e-6, lambda = 1) = {th:.6f} deg -> 45")
    jeff = (1 - 0.25) / (1 + 0.25)
    need(abs(ks_B(0.5, 1e12) - jeff) < 1e-9, f"rigid limit: B(r = 0.5, lambda = 1e12) = {ks_B(0.5, 1e12):.9f} ="
         f" Jeffery's (1 - r^2)/(1 + r^2) = {jeff:.9f}")
    for r in (0.3, 0.5, 0.7, 0.9):
        need(abs(ks_B(r, ks_lambda_c(r)) - 1) < 1e-12, f"B(r = {r}, lambda_c = 2/(1 - r) = {ks_lambda_c(r):.4f}) = 1")
    # the interior strain over the far field's, (a + b)^2 / (2ab + lambda (a^2 + b^2)), at r = 1: 2/(1 + lambda)
    for lam in (0.5, 1, 3):
        ratio = 4 / (2 + lam * 2)
        need(abs(ratio - 2 / (1 + lam)) < 1e-15, f"circle: interior strain 2E/(1 + lambda) at lambda = {lam}")
    try:
        import numpy  # noqa: F401
    except ImportError:
        need(False, "numpy for the Stokes-flow check (Debian's /usr/bin/python3 has it)")
        return failures
    for r, lam, theta in ((0.5, 1, 0.3), (0.5, 3, 0.2), (0.45, 5, -0.4), (0.7, 2, 0.6), (0.5, 8, 1.2)):
        torque, power, res = mfs_check(r, lam, theta)
        need(abs(torque) < 1e-3 and power < 1e-3,
             f"Stokes flow (MFS) at r = {r}, lambda = {lam}, theta = {theta}: torque/(mu gammadot A) = {torque:.1e},"
             f" |P_out - D_in|/D_in = {power:.1e} (boundary residual {res:.1e})")
    # the control: with the membrane 10 % too fast the energy balance must fail
    for r, lam, theta in ((0.5, 1, 0.3), (0.5, 3, 0.2), (0.45, 5, -0.4)):
        power = mfs_check(r, lam, theta, nu_factor=1.1)[1]
        need(power > 0.05, f"control: nu 10 % too fast at r = {r}, lambda = {lam}: |P_out - D_in|/D_in = {power:.3f}")
    return failures


# ------------------------------------------------------------------------------------------ the runs


def options_of(run):
    """The run's options.yaml as a dict of strings (flat 'key: value' lines)."""
    out = {}
    with open(os.path.join(run, "options.yaml")) as f:
        for line in f:
            if ":" in line and not line.lstrip().startswith("#"):
                k, v = line.split(":", 1)
                out[k.strip()] = v.strip()
    return out


def history_of(run):
    """The membrane tracker's records from the checkpoint: lists time, axis (rad, unwrapped), r, material."""
    with open(os.path.join(run, "checkpoint", "state.json")) as f:
        state = json.load(f)
    t = state["trackers"][state["body_names"].index("membrane")]
    k = 1 + int(t[0])
    n = int(t[k])
    k += 1
    per = (len(t) - k) // n  # 10 numbers a record (9 in old checkpoints)
    rec = [t[k + i * per:k + (i + 1) * per] for i in range(n)]
    return {"time": [x[0] for x in rec], "axis": [x[3] for x in rec],
            "r": [1 / math.sqrt(1 + x[4]) for x in rec], "material": [x[5] for x in rec]}


def crossings(times, axis, ref=math.pi / 2):
    """Times (after the first record) at which the unwrapped axis passes ref + k pi, linear between records."""
    out = []
    for i in range(1, len(times)):
        k0 = math.floor((axis[i - 1] - ref) / math.pi)
        k1 = math.floor((axis[i] - ref) / math.pi)
        if k0 != k1:
            target = ref + max(k0, k1) * math.pi
            f = (target - axis[i - 1]) / (axis[i] - axis[i - 1])
            out.append(times[i - 1] + f * (times[i] - times[i - 1]))
    return out


def wrap_deg(x):
    """An axis angle (deg) in (-90, 90]."""
    return x - 180 * math.ceil((x - 90) / 180)


def window_stats(h, t0, t1):
    """The summary's window measures, from the tracker's records in [t0, t1]: the time-mean inclination (deg, in
    (-90, 90]), its half peak-to-peak, the membrane's mean turn rate (turns/s, clockwise) and the regime, by the
    rules of solid/body_metrics.cpp (motion_regime, swing_deg 2)."""
    win = [i for i, t in enumerate(h["time"]) if t0 <= t <= t1]
    t, ax, mat = [h["time"][i] for i in win], [h["axis"][i] for i in win], [h["material"][i] for i in win]
    T = t[-1] - t[0]
    mean = sum(0.5 * (ax[i] + ax[i - 1]) * (t[i] - t[i - 1]) for i in range(1, len(t))) / T
    turned, moved = abs(ax[-1] - ax[0]), abs(mat[-1] - mat[0])
    half_range = 0.5 * math.degrees(max(ax) - min(ax))
    if turned >= math.pi * (1 - 1e-12) or (turned >= math.pi / 4 and turned >= 0.5 * moved):
        regime = "tumbling"
    elif moved < math.pi / 2:
        regime = "steady"
    else:
        regime = "swinging" if half_range >= 2.0 else "tank-treading"
    return {"theta": wrap_deg(math.degrees(mean)), "theta_osc": half_range,
            "omega_tt": -(mat[-1] - mat[0]) / (2 * math.pi * T), "regime": regime, "window": (t[0], t[-1]),
            "index": win}


def measure(run, window=None):
    """The run's measures over its summary's averaging window, or over `window` (t0, t1) in s."""
    with open(os.path.join(run, "summary.json")) as f:
        s = json.load(f)
    h = history_of(run)
    t0, t1 = s["membrane_average_from"], s["membrane_average_to"]
    w = window_stats(h, t0, t1)
    # The script's window measures are the summary's (same records, same formulas): checked on every run.
    if abs(wrap_deg(w["theta"] - s["membrane_theta_deg"])) > 1e-6 or abs(w["omega_tt"] - s["membrane_omega_tt"]) > 1e-9:
        sys.exit(f"keller_skalak_2d: {run}: the tracker's records do not give the summary's theta and omega_TT")
    if window is not None:
        w = window_stats(h, *window)
        t0, t1 = w["window"]
    win = w["index"]
    rs = [h["r"][i] for i in win]
    m = {"run": run, "lambda": s.get("membrane_viscosity_ratio", 1.0), "window": w["window"],
         "r": sum(rs) / len(rs), "r_min": min(rs), "r_max": max(rs),
         "regime": s.get("membrane_regime") if window is None else w["regime"],
         "theta": w["theta"], "theta_osc": w["theta_osc"], "omega_tt": w["omega_tt"], "omega_tu": None,
         "half_periods": [], "gammadot": float(options_of(run)["shear_rate"]), "commit": s.get("commit"),
         "mesh": options_of(run)["fluid_elements"].replace(",", "x"),
         "steps": s.get("steps")}
    # the axis's mean rate over the window (deg/s): how fast a not yet steady or slowly turning axis drifts
    m["drift"] = math.degrees(h["axis"][win[-1]] - h["axis"][win[0]]) / (m["window"][1] - m["window"][0])
    # The axis's passages through the vertical within the window. Two or more: it tumbles (whatever the
    # summary's classifier said: it wants a whole half-turn from the window's start, or a turn of at least half
    # the membrane's), and omega_TU, omega_TT and r are taken over the whole half-turns between the first and
    # the last passage.
    cross = [c for c in crossings(h["time"], h["axis"]) if t0 <= c <= t1]
    m["passages"] = cross
    if window is None and s.get("membrane_omega_tu_half_turns"):
        m["omega_tu"] = s.get("membrane_omega_tu")
    if len(cross) >= 2:
        m["half_periods"] = [b - a for a, b in zip(cross, cross[1:])]
        span = cross[-1] - cross[0]
        m["omega_tu"] = (len(cross) - 1) / (2 * span)

        def material_at(tc):
            i = next(i for i, t in enumerate(h["time"]) if t >= tc)
            f = (tc - h["time"][i - 1]) / (h["time"][i] - h["time"][i - 1])
            return h["material"][i - 1] + f * (h["material"][i] - h["material"][i - 1])
        m["omega_tt"] = -(material_at(cross[-1]) - material_at(cross[0])) / (2 * math.pi * span)
        rs = [h["r"][i] for i, t in enumerate(h["time"]) if cross[0] <= t <= cross[-1]]
        m["r"], m["r_min"], m["r_max"] = sum(rs) / len(rs), min(rs), max(rs)
        m["window"] = (cross[0], cross[-1])
        if m["regime"] != "tumbling":
            m["regime"] = f"tumbling (summary: {m['regime']})"
    return m


# ------------------------------------------------------------------------------------ table and figure


def write_outputs(args, rows, reference_r, command):
    gd = rows[0]["gammadot"]
    runs = ", ".join("`" + d + "`" for d in args.runs)
    commits = ", ".join(sorted({str(m["commit"]) for m in rows}))
    lines = [f"Generated by `{command}` on {datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC, git {commit_of_head()},"
             f" from the runs {runs} (their cellfsi commits: {commits}). Measured: r (the axis ratio"
             " of the ellipse with the membrane's enclosed second moments, mean and range over the window), theta, the"
             " membrane's turn rate omega_TT, the axis's omega_TU and the axis drift. Computed: the 2D Keller-Skalak"
             f" model (fixed-shape ellipse, tank-treading membrane, unbounded shear gammadot = {gd:g} 1/s) for the"
             f" measured r, and for the reference shape r = {reference_r:g}. The window is the run's averaging"
             " window; where the axis passed the vertical twice or more in it, the rows give omega_TT, omega_TU and r"
             " over the whole half-turns between the first and the last passage (that span is the window column).",
             "",
             "| lambda | mesh | window s | r measured (range) | regime | KS regime (r) | lambda_c = 2/(1-r) |"
             " theta deg | KS theta (r) | KS theta (r = 0.5) | omega_TT 1/s | KS omega_TT (r) | omega_TU 1/s |"
             " KS omega_TU (r) | axis drift deg/s | KS dtheta/dt at theta deg/s | vertical passages s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in rows:
        lam, r = m["lambda"], m["r"]
        ks, ks0 = ks_motion(r, lam, gd), ks_motion(reference_r, lam, gd)
        tumbling = m["regime"].startswith("tumbling")
        turning = tumbling or m["passages"]  # a mean inclination means nothing while the axis turns past 90 deg
        theta = "(turns)" if turning else f"{m['theta']:.2f} +- {m['theta_osc']:.2f}"
        ks_rate = "-"  # the model's turning rate at the run's mean theta, where the axis was not steady
        if not turning and m["regime"] != "tank-treading":
            ks_rate = f"{math.degrees(gd / 2 * (1 - ks_B(r, lam) * math.cos(2 * math.radians(m['theta'])))):.1f}"
        lines.append(
            f"| {lam:g} | {m['mesh']} | {m['window'][0]:.3f}-{m['window'][1]:.3f} |"
            f" {r:.3f} ({m['r_min']:.3f}-{m['r_max']:.3f}) |"
            f" {m['regime']} | {ks['regime']} | {ks_lambda_c(r):.2f} | {theta} | {fmt(ks['theta'], '.2f')} |"
            f" {fmt(ks0['theta'], '.2f')} | {m['omega_tt']:.3f} | {ks['omega_tt']:.3f} |"
            f" {fmt(m['omega_tu'], '.3f')} | {ks['omega_tu']:.3f} | {-m['drift']:.1f} | {ks_rate} |"
            f" {', '.join(f'{c:.3f}' for c in m['passages']) or '-'} |")
    lines += ["", "Axis drift and the model's dtheta/dt are clockwise positive (deg/s); the model's rate is taken at"
              " the run's mean theta and measured r, for the runs whose axis was not steady. Half-periods of the"
              " tumbling runs"
              " (s): " + "; ".join(f"lambda {m['lambda']:g}: " + ", ".join(f"{x:.4f}" for x in m["half_periods"])
                                     for m in rows if m["half_periods"]) + "."]
    write_table(args.table, lines)

    plt = pyplot("keller_skalak_2d")
    if plt is None:
        return
    # The figure shows each lambda's latest window (its longest run) on the first run's mesh; the table has them all.
    latest = {}
    for m in (m for m in rows if m["mesh"] == rows[0]["mesh"]):
        if m["lambda"] not in latest or m["window"][1] > latest[m["lambda"]]["window"][1]:
            latest[m["lambda"]] = m
    rows = [latest[x] for x in sorted(latest)]
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    lams = [1 + 0.02 * i for i in range(int((max(12, max(m["lambda"] for m in rows) + 1) - 1) / 0.02) + 1)]
    rs = sorted({round(m["r"], 3) for m in rows if m["regime"] == "tank-treading"})
    curves = [(reference_r, "k", "-"), (min(rs), "tab:green", "--"), (max(rs), "tab:orange", "--")] if rs else \
        [(reference_r, "k", "-")]
    for r, color, ls in curves:
        mot = [ks_motion(r, x, gd) for x in lams]
        axes[0].plot(lams, [q["theta"] if q["theta"] is not None else float("nan") for q in mot], ls, color=color,
                     lw=1, label=f"KS, r = {r:.3f}")
        axes[1].plot(lams, [q["omega_tt"] for q in mot], ls, color=color, lw=1, label=f"KS, r = {r:.3f}")
        axes[2].plot(lams, [q["omega_tu"] for q in mot], ls, color=color, lw=1, label=f"KS, r = {r:.3f}")
        for ax in axes:
            ax.axvline(ks_lambda_c(r), color=color, ls=":", lw=0.8)
    for m in rows:
        ks = ks_motion(m["r"], m["lambda"], gd)
        mk = {"tank-treading": "o", "swinging": "s", "tumbling": "x"}.get(m["regime"].split(" ")[0], "d")
        if not m["regime"].startswith("tumbling") and not m["passages"]:
            axes[0].plot(m["lambda"], m["theta"], mk, color="tab:blue", ms=7)
            axes[0].errorbar(m["lambda"], m["theta"], yerr=m["theta_osc"], color="tab:blue", capsize=3)
            if ks["theta"] is not None:
                axes[0].plot(m["lambda"], ks["theta"], "+", color="tab:red", ms=10, mew=1.5)
        axes[1].plot(m["lambda"], m["omega_tt"], mk, color="tab:blue", ms=7)
        axes[1].plot(m["lambda"], ks["omega_tt"], "+", color="tab:red", ms=10, mew=1.5)
        if m["omega_tu"]:
            axes[2].plot(m["lambda"], m["omega_tu"], mk, color="tab:blue", ms=7)
            axes[2].plot(m["lambda"], ks["omega_tu"], "+", color="tab:red", ms=10, mew=1.5)
    tt = [m["lambda"] for m in rows if m["regime"] == "tank-treading"]
    tu = [m["lambda"] for m in rows if m["regime"].startswith("tumbling")]
    if tt and tu:
        for ax in axes:
            ax.axvspan(max(tt), min(tu), color="tab:blue", alpha=0.08)
    for ax in axes:
        ax.set_xlim(0.5, lams[-1])
    names = ["theta (deg)", "omega_TT (turns/s, clockwise)", "omega_TU (turns/s of the axis)"]
    for ax, name in zip(axes, names):
        ax.set_xlabel("viscosity ratio lambda")
        ax.set_ylabel(name)
        ax.grid(True, lw=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle("Capsule, each lambda's latest window (blue: o tank-treading, s swinging, x tumbling; shaded: last"
                 " TT to first TU) against 2D Keller-Skalak (lines; red +: at each run's measured r; dotted: lambda_c"
                 " = 2/(1-r))", fontsize=9)
    save_figure(fig, args.figure, "keller_skalak_2d")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", nargs="+", default=[os.path.join(ROOT, "out", "sweeps_viscosity")],
                   help="folders holding run_shear_sweeps.py viscosity runs (each run: summary.json, options.yaml,"
                   " checkpoint/state.json)")
    p.add_argument("--table", default=os.path.join(ROOT, "docs", "validation", "shear_viscosity_theory.md"))
    p.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "shear_viscosity_theory.png"))
    p.add_argument("--reference-r", type=float, default=0.5,
                   help="the capsule's reference axis ratio (scene: 1e-4/2e-4)")
    p.add_argument("--window", dest="windows", action="append", default=[], metavar="LAMBDA=T0:T1",
                   help="measure the runs of this lambda that reach T1 over [T0, T1] s instead of their averaging"
                   " window (a row per window; T1 empty: to the run's end), e.g. a tumbling phase and what came"
                   " after it; repeatable")
    p.add_argument("--check", action="store_true", help="only check the formulas")
    args = p.parse_args()
    windows = {}
    for x in args.windows:
        lam, span = x.split("=")
        a, b = span.split(":")
        windows.setdefault(float(lam), []).append((float(a), float(b) if b else None))
    print("keller_skalak_2d: checks of the formulas")
    failures = check_formulas()
    if failures:
        sys.exit(f"keller_skalak_2d: {len(failures)} check(s) failed")
    if args.check:
        return
    rows = []
    for d in args.runs:
        for name in sorted(os.listdir(d)):
            run = os.path.join(d, name)
            if os.path.isfile(os.path.join(run, "summary.json")) and os.path.isdir(os.path.join(run, "checkpoint")):
                with open(os.path.join(run, "summary.json")) as f:
                    s = json.load(f)
                lam = s.get("membrane_viscosity_ratio", 1.0)
                t1 = s["membrane_average_to"]
                # the windows this run reaches (its last record is at its summary's t1)
                mine = [(a, b if b is not None else t1) for a, b in windows.get(lam, []) if (b or t1) <= t1 + 1e-9
                        and a < t1]
                for w in mine or [None]:
                    rows.append(measure(run, w))
    if not rows:
        sys.exit("keller_skalak_2d: no runs with summary.json and checkpoint/ in " + " ".join(args.runs))
    rows.sort(key=lambda m: (m["lambda"], m["window"][1]))
    command = "bench/keller_skalak_2d.py " + " ".join(sys.argv[1:])
    write_outputs(args, rows, args.reference_r, command)


if __name__ == "__main__":
    main()
