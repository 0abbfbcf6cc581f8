#!/usr/bin/env python3
"""The project's methods against their raw peers, timed side by side in one run (issue 15).

    python benchmarks/bench_peers.py [--out benchmarks/results] [--repeat 15] [--quick]
                                     [--only topp,ruckig,nlp]

Every comparison is interleaved (A, B, A, B, … with the order swapped every round) on the
same inputs, and reported as medians and the ratio of medians per case; the summary gives the
median and the largest ratio over the cases. The machine is shared (2 cores): read the ratios.

1. TOPP-RA (random DP joint paths on every shipped machine, velocity + acceleration + pump):
   raw toppra ``TOPPRA(...).compute_trajectory`` (ConstAccel) plus its own 500 Hz sampling
   (``jt(t)``, ``jt(t, 1)``, ``jt(t, 2)``) against the verified
   :func:`planner.methods.topp.retime` (default: 100 grid intervals refined adaptively, 500 Hz,
   returned Trajectory).
   Also: each result judged by ``evaluate()`` (raw toppra breaks the limits between its grid
   points), and the verified duration at 100 against 400 grid points.       target ≤ 3×, ≤ 1 %
2. Ruckig (random rest-to-rest joint moves on every machine): ``Ruckig.calculate`` on a
   prepared input (the issue's peer), and the raw library as a user calls it (input filled from
   arrays, calculate, ``at_time`` at the switching times), against
   :func:`planner.methods.ruckig.rest_to_rest` sampled at its switching times
   (``sample_rate=None``) and at its default 200 Hz.                         target ≤ 20×
3. The move NLP (:class:`planner.methods.nlp.MoveNLP`, minimum time, N = 40, built once):
   its solve on umea-lab's tip move against the plain Opti triple integrator with the same
   limits (benchmarks/opti_baseline.py, built once, solve timed), pump on and off, and against
   that baseline with a pump inequality at the nodes; each side's result judged by
   ``evaluate()``.                                         target pump on ≤ 2×, pump off ≤ 1.2×
   Joint-space ends without pump (random configurations, umea-lab and s100f): the returned
   duration and the NLP's own (before the exact-Ruckig swap) against the Ruckig optimum.
                                                                              target max ≤ 1 %
   Tip ends with pump (random tips, umea-lab and s100f): duration above the analytic lower
   bound (:func:`planner.bounds.lower_bound`, combined).  target p90 ≤ 3 %, never below it
The one-off call (build + solve, fresh process) against the same Opti baseline is measured by
benchmarks/bench_nlp_cache.py.

Writes <out>/peers.json and <out>/peers.md (atomically) and prints the markdown.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if str(ROOT) not in sys.path:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))
if str(HERE) not in sys.path:  # the shared Opti baseline
    sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402
import ruckig  # noqa: E402

from opti_baseline import PlainOpti  # noqa: E402
from planner.bounds import lower_bound  # noqa: E402
from planner.geometry.paths import Line  # noqa: E402
from planner.io import atomic_write_text, dumps  # noqa: E402
from planner.methods.dp import dp  # noqa: E402
from planner.methods.nlp import MoveNLP  # noqa: E402
from planner.methods.ruckig import NO_JERK, rest_to_rest, switch_times  # noqa: E402
from planner.methods.topp import raw_retime, retime  # noqa: E402
from planner.model import Crane  # noqa: E402
from planner.trajectory import evaluate  # noqa: E402
from planner.problems import crane_ids  # noqa: E402

SEED = 15
TOPP_MOVES, RUCKIG_MOVES = 4, 6     # per machine
SAMPLE_RATE = 500.0                 # [Hz] both TOPP-RA sides
KINDS = ("velocity", "acceleration", "pump_flow")
NLP_MOVE = ("umea-lab", (2.65, 2.2, 0.2), (3.2, 1.6, -0.4))   # as benchmarks/bench_nlp_cache.py
NLP_MACHINES = ("umea-lab", "s100f")
JOINT_MOVES, TIP_MOVES = 8, 10      # per machine
TOL = 1e-3                          # evaluate(): largest relative limit excess that passes
FINE = 1600                         # TOPP-RA reference: uniform grid intervals, no adaptation


def configs(crane, n, seed, margin=0.1):
    """n random joint configurations inside the limits (a margin of the range at each end)."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + margin * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - margin * (L["q_max"] - L["q_min"])
    return lo + rng.random((n, crane.n)) * (hi - lo)


def interleaved(fa, fb, repeat):
    """Median seconds of ``fa`` and ``fb``, timed alternately (order swapped every round)
    after one warm-up call each."""
    fa(), fb()
    ta, tb = [], []
    for k in range(repeat):
        for f, out in ((fa, ta), (fb, tb)) if k % 2 == 0 else ((fb, tb), (fa, ta)):
            t0 = time.perf_counter()
            f()
            out.append(time.perf_counter() - t0)
    return statistics.median(ta), statistics.median(tb)


# ---------------------------------------------------------------------------- TOPP-RA
def raw_toppra(crane, path_q, gridpoints=200, rate=SAMPLE_RATE):
    """Raw toppra as its documentation shows it (:func:`planner.methods.topp.raw_retime`)."""
    return raw_retime(crane, path_q, gridpoints, rate)


def topp_cases(quick):
    out = []
    for cid in crane_ids():
        crane = Crane.from_id(cid)
        qs = configs(crane, 2 * TOPP_MOVES, SEED)
        for k in range(TOPP_MOVES if not quick else 1):
            a, b = crane.tip(qs[k]), crane.tip(qs[TOPP_MOVES + k])
            d = dp(crane, Line(tuple(a), tuple(b)), step=0.05, tele_step=0.05, window=3)
            if d.ok:
                out.append((cid, crane, np.round(a, 3).tolist(), np.round(b, 3).tolist(),
                            d.path_q))
    return out


def topp_rows(repeat, quick):
    rows = []
    for cid, crane, a, b, path_q in topp_cases(quick):
        t_raw, t_ours = interleaved(lambda: raw_toppra(crane, path_q),
                                    lambda: retime(crane, path_q), repeat)
        raw = raw_toppra(crane, path_q)
        ours = retime(crane, path_q)
        r100, r400 = (retime(crane, path_q, gridpoints=g) for g in (100, 400))
        fine = retime(crane, path_q, gridpoints=FINE, adapt=0)   # the reference: uniform, fine
        viol = {}
        for name, tr in (("raw", raw), ("ours", ours.trajectory)):
            ev = evaluate(crane, tr, kinds=KINDS) if tr is not None else None
            viol[name] = ev.max_limit_violation if ev is not None else float("nan")
        rows.append(dict(machine=cid, start=a, goal=b, raw_ms=1e3 * t_raw,
                         ours_ms=1e3 * t_ours, ratio=t_ours / t_raw,
                         raw_s=raw.duration, ours_s=ours.duration_s, ours_status=ours.status,
                         passes=ours.iterations, raw_violation=viol["raw"],
                         ours_violation=viol["ours"], s100=r100.duration_s,
                         s400=r400.duration_s, coarse_excess=r100.duration_s / r400.duration_s - 1,
                         intervals=ours.intervals, fine_s=fine.duration_s,
                         ours_vs_fine=ours.duration_s / fine.duration_s - 1,
                         raw_vs_fine=raw.duration / fine.duration_s - 1))
    return rows


# ---------------------------------------------------------------------------- Ruckig
def ruckig_rows(repeat, quick):
    rows = []
    for cid in crane_ids():
        crane = Crane.from_id(cid)
        L = crane.limit_arrays()
        jerk = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], NO_JERK)
        qs = configs(crane, 2 * RUCKIG_MOVES, SEED + 1)
        n = crane.n
        for k in range(RUCKIG_MOVES if not quick else 1):
            q0, q1 = qs[k], qs[RUCKIG_MOVES + k]

            def fill():
                inp = ruckig.InputParameter(n)
                inp.current_position, inp.target_position = q0.tolist(), q1.tolist()
                inp.max_velocity, inp.min_velocity = L["qd_max"].tolist(), L["qd_min"].tolist()
                inp.max_acceleration, inp.max_jerk = L["qdd_max"].tolist(), jerk.tolist()
                return inp

            inp, otg, tr = fill(), ruckig.Ruckig(n), ruckig.Trajectory(n)

            def raw_user():   # what a user of the raw library writes for one sampled move
                i, t = fill(), ruckig.Trajectory(n)
                ruckig.Ruckig(n).calculate(i, t)
                sw = switch_times(t)
                return [t.at_time(x) for x in sw]

            t_calc, t_sw = interleaved(lambda: otg.calculate(inp, tr),
                                       lambda: rest_to_rest(crane, q0, q1, sample_rate=None),
                                       repeat * 20)
            t_user, t_sw2 = interleaved(raw_user,
                                        lambda: rest_to_rest(crane, q0, q1, sample_rate=None),
                                        repeat * 20)
            t_user2, t_200 = interleaved(raw_user, lambda: rest_to_rest(crane, q0, q1),
                                         repeat * 5)
            r = rest_to_rest(crane, q0, q1, sample_rate=None)
            rows.append(dict(machine=cid, duration_s=r.duration_s,
                             samples=len(r.trajectory.t), calc_us=1e6 * t_calc,
                             ours_switch_us=1e6 * t_sw, ratio_calc=t_sw / t_calc,
                             raw_user_us=1e6 * t_user, ours_switch2_us=1e6 * t_sw2,
                             ratio_user=t_sw2 / t_user, ours_200hz_us=1e6 * t_200,
                             ratio_200hz_user=t_200 / t_user2))
    return rows


# ---------------------------------------------------------------------------- NLP
def judged(crane, traj, kinds):
    """evaluate()'s largest relative limit excess over ``kinds`` (NaN without a trajectory)."""
    return float("nan") if traj is None else evaluate(crane, traj, kinds=kinds).max_limit_violation


def nlp_timing(repeat):
    """The NLP's solve against the plain Opti baseline on umea-lab's tip move, interleaved."""
    cid, a, b = NLP_MOVE
    crane = Crane.from_id(cid)
    lb = lower_bound(crane, a, b)
    q0, q1 = crane.ik(a, lb.tele_start), crane.ik(b, lb.tele_goal)
    nlp = {(p, s): MoveNLP(crane, "time", N=40, pump=p, cache="off", solver=s)
           for p in (True, False) for s in ("ipopt", "fatrop")}
    opti = {p: PlainOpti(crane, q0, q1, 40, pump=p, guess_T=lb.combined_s)
            for p in (True, False)}
    rows = []
    for solver in ("ipopt", "fatrop"):
        for pump, base in ((True, False), (False, False), (True, True)):
            rows.append(nlp_timing_row(crane, a, b, nlp[pump, solver], opti[base], pump, base,
                                       repeat))
    return rows


def nlp_timing_row(crane, a, b, nlp, opti, pump, base, repeat):
    """One interleaved comparison of :func:`nlp_timing`."""
    t_nlp, t_opti = interleaved(lambda: nlp.solve(a, b), opti.solve, repeat)
    r = nlp.solve(a, b)
    T_opti, it_opti = opti.solve()
    kinds = ("position", "velocity", "acceleration", "jerk") + (("pump_flow",) if pump else ())
    return dict(solver=nlp.solver_name, pump=pump, baseline_pump=base, nlp_ms=1e3 * t_nlp,
                opti_ms=1e3 * t_opti, ratio=t_nlp / t_opti, nlp_s=r.duration_s,
                nlp_own_s=r.stats.get("nlp_duration_s", r.duration_s),
                winner=r.stats.get("winner", "nlp"), nlp_iterations=r.iterations,
                nlp_variables=nlp.nw, nlp_constraints=len(nlp.lbg),
                opti_s=T_opti, opti_iterations=it_opti, opti_variables=opti.variables,
                opti_constraints=opti.constraints,
                nlp_violation=judged(crane, r.trajectory, kinds),
                opti_violation=judged(crane, opti.trajectory(crane), kinds))


def nlp_joint_rows(quick):
    """Joint-space ends, no pump: the NLP against the Ruckig optimum."""
    rows = []
    kinds = ("position", "velocity", "acceleration", "jerk")
    for cid in NLP_MACHINES:
        crane = Crane.from_id(cid)
        m = MoveNLP(crane, "time", N=40, pump=False, cache="off")
        k_moves = 2 if quick else JOINT_MOVES
        qs = configs(crane, 2 * k_moves, SEED + 2)
        for k in range(k_moves):
            q0, q1 = qs[k], qs[k_moves + k]
            opt = rest_to_rest(crane, q0, q1).duration_s
            r = m.solve(q_start=q0, q_goal=q1)
            own = r.stats.get("nlp_duration_s", r.duration_s)
            rows.append(dict(machine=cid, solver=r.stats.get("solver") or m.solver_name,
                             status=r.status, ruckig_s=opt,
                             nlp_s=r.duration_s,
                             nlp_own_s=own, winner=r.stats.get("winner", "nlp"),
                             excess=r.duration_s / opt - 1, own_excess=own / opt - 1,
                             solve_s=r.solve_time_s,
                             violation=judged(crane, r.trajectory, kinds)))
    return rows


def nlp_tip_rows(quick):
    """Tip ends with the pump: the NLP against the analytic lower bound."""
    rows = []
    for cid in NLP_MACHINES:
        crane = Crane.from_id(cid)
        m = MoveNLP(crane, "time", N=40, pump=True, cache="off")
        k_moves = 2 if quick else TIP_MOVES
        qs = configs(crane, 2 * k_moves, SEED + 3)
        for k in range(k_moves):
            a, b = (tuple(float(x) for x in np.round(crane.tip(q), 3))
                    for q in (qs[k], qs[k_moves + k]))
            lb = lower_bound(crane, a, b)
            r = m.solve(a, b)
            ev = evaluate(crane, r.trajectory) if r.ok else None
            rows.append(dict(machine=cid, solver=r.stats.get("solver") or m.solver_name,
                             start=list(a), goal=list(b),
                             status=r.status,
                             bound_s=lb.combined_s, pump_bound_s=lb.pump_s,
                             nlp_s=r.duration_s,
                             nlp_own_s=r.stats.get("nlp_duration_s", r.duration_s),
                             winner=r.stats.get("winner", "nlp"),
                             excess=r.duration_s / lb.combined_s - 1, solve_s=r.solve_time_s,
                             violation=ev.max_limit_violation if ev else float("nan"),
                             peak_pump=(ev.peak_pump_flow / crane.spec.pump.max_flow
                                        if ev else float("nan"))))
    return rows


def nlp_summary(timing, joint, tip):
    out = {}
    for r in timing:
        key = ("pump_on" if r["pump"] else "pump_off") + ("_vs_pump_opti" if r["baseline_pump"]
                                                          else "")
        out[f"{r['solver']}_{key}"] = r["ratio"]
    out["joint_excess"] = summary([r["excess"] for r in joint])
    out["joint_own_excess"] = summary([r["own_excess"] for r in joint])
    for cid in NLP_MACHINES:
        ex = [r["excess"] for r in tip if r["machine"] == cid and r["status"] == "ok"]
        out[f"tip_{cid}"] = dict(summary(ex), p90=float(np.percentile(ex, 90)) if ex else
                                 float("nan"), failed=sum(r["machine"] == cid and
                                                          r["status"] != "ok" for r in tip))
    out["worst_violation"] = float(np.nanmax([r["nlp_violation"] for r in timing]
                                             + [r["violation"] for r in joint + tip]))
    return out


def nlp_report(nl) -> list:
    """The NLP section of the markdown."""
    m, s = nl["machine"], nl["summary"]
    pc = lambda v: f"{100 * v:+.2f} %"  # noqa: E731
    lines = ["", "## NLP", "",
             f"{m['date']}, load {m['load']}, casadi {m['casadi']}, {nl['repeat']} interleaved "
             "rounds, medians (`python benchmarks/bench_peers.py --only nlp`). Ours: "
             "`MoveNLP(crane, 'time', N=40, pump=…, solver=…).solve(start, goal)` built once "
             "(cache off), "
             "the whole call timed (default guess, IPOPT, the exact-Ruckig check). Baseline: "
             "benchmarks/opti_baseline.py (`PlainOpti`, built once, `opti.solve()` timed) "
             "between the joint configurations at the lower bound's telescopes. Violation: "
             "`evaluate()` at 1 kHz (position, velocity, acceleration, jerk, pump).", "",
             "| solver | NLP pump | baseline | ours ms | Opti ms | ratio | target | ours s (NLP's own) | "
             "winner | ours it. | ours vars/cons | Opti s | Opti it. | Opti vars/cons | "
             "ours violation | Opti violation |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | "
             "--- | --- | --- |"]
    for r in nl["timing"]:
        target = "" if r["baseline_pump"] else ("≤ 2×" if r["pump"] else "≤ 1.2×")
        base = "pump at nodes" if r["baseline_pump"] else "no pump"
        lines.append(
            f"| {r.get('solver', 'ipopt')} | {'on' if r['pump'] else 'off'} | {base} | "
            f"{r['nlp_ms']:.0f} | {r['opti_ms']:.0f} | {r['ratio']:.2f}× | {target} | "
            f"{r['nlp_s']:.4f} ({r['nlp_own_s']:.4f}) | {r['winner']} | {r['nlp_iterations']} | "
            f"{r['nlp_variables']}/{r['nlp_constraints']} | {r['opti_s']:.4f} | "
            f"{r['opti_iterations']} | {r['opti_variables']}/{r['opti_constraints']} | "
            f"{100 * r['nlp_violation']:.3f} % | {100 * r['opti_violation']:.2f} % |")
    j, jo = s["joint_excess"], s["joint_own_excess"]
    lines += ["", "Joint-space ends, no pump (solved by: "
              f"{', '.join(sorted({r.get('solver', 'ipopt') for r in nl['joint']}))}), "
              "against the Ruckig optimum (`rest_to_rest`): "
              f"returned median {pc(j['median'])}, max {pc(j['max'])} (target ≤ 1 %); the "
              f"NLP's own solution before the exact-Ruckig swap median {pc(jo['median'])}, "
              f"max {pc(jo['max'])}, min {pc(jo['min'])}.", "",
              "| machine | status | Ruckig s | returned s | winner | above | NLP's own s | above "
              "| solve s | violation |", "| --- | --- | --- | --- | --- | --- | --- | --- | --- "
              "| --- |"]
    for r in nl["joint"]:
        lines.append(f"| {r['machine']} | {r['status']} | {r['ruckig_s']:.4f} | "
                     f"{r['nlp_s']:.4f} | {r['winner']} | {pc(r['excess'])} | "
                     f"{r['nlp_own_s']:.4f} | {pc(r['own_excess'])} | {r['solve_s']:.3f} | "
                     f"{100 * r['violation']:.4f} % |")
    lines += ["", "Tip ends with the pump (solved by: "
              f"{', '.join(sorted({r.get('solver', 'ipopt') for r in nl['tip']}))}) "
              "against the analytic lower bound "
              "(`lower_bound(...).combined_s`; target p90 ≤ 3 %, never below): " + "; ".join(
                  f"{cid} median {pc(s['tip_' + cid]['median'])}, p90 "
                  f"{pc(s['tip_' + cid]['p90'])}, max {pc(s['tip_' + cid]['max'])}, min "
                  f"{pc(s['tip_' + cid]['min'])}, failed {s['tip_' + cid]['failed']}"
                  for cid in NLP_MACHINES) + ".", "",
              "| machine | start | goal | status | bound s (pump) | returned s | winner | "
              "above | NLP's own s | solve s | peak pump / Q_max | violation |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in nl["tip"]:
        lines.append(f"| {r['machine']} | {r['start']} | {r['goal']} | {r['status']} | "
                     f"{r['bound_s']:.3f} ({r['pump_bound_s']:.3f}) | {r['nlp_s']:.3f} | "
                     f"{r['winner']} | {pc(r['excess'])} | {r['nlp_own_s']:.3f} | "
                     f"{r['solve_s']:.3f} | {r['peak_pump']:.4f} | "
                     f"{100 * r['violation']:.4f} % |")
    lines.append(f"\nWorst `evaluate()` violation of every NLP result above: "
                 f"{100 * s['worst_violation']:.4f} % (passes at ≤ {100 * TOL:.1f} %).")
    return lines


# ---------------------------------------------------------------------------- report
def summary(values):
    v = [x for x in values if np.isfinite(x)]
    return dict(median=float(np.median(v)), max=float(np.max(v)), min=float(np.min(v)),
                n=len(v)) if v else dict(median=float("nan"), max=float("nan"), n=0)


def report(res) -> str:
    m, tp, rk = res["machine"], res["topp"], res["ruckig"]
    s = res["summary"]
    runs = res.get("runs", {})   # per section: when it was run (--only keeps the others)
    when = "; ".join(f"{name} section: {r['date']} ({r['repeat']} rounds, load {r['load']})"
                     for key, name in (("topp", "TOPP-RA"), ("ruckig", "Ruckig"))
                     if (r := runs.get(key)))
    lines = [
        "# Peers: the project's methods against their raw libraries (issue 15)", "",
        f"{when or m['date']}; NLP section: its own header below. {m['platform']}, Python "
        f"{m['python']}, {m['cpus']} CPUs, numpy {m['numpy']}, toppra {m['toppra']}, ruckig "
        f"{m['ruckig']}. Interleaved A/B timings (Ruckig: ×20 / ×5 calls per round), medians; "
        "the machine is shared, so read the ratios. `python benchmarks/bench_peers.py "
        "[--only topp,ruckig,nlp] [--repeat N]`.", "",
        "## Summary", "",
        "| comparison | ratio median | ratio max | target |", "| --- | --- | --- | --- |",
        f"| verified TOPP-RA retime / raw toppra + own 500 Hz sampling | "
        f"{s['topp_ratio']['median']:.2f}× | {s['topp_ratio']['max']:.2f}× | ≤ 3× |",
        f"| verified duration at 100 vs 400 grid points | "
        f"{100 * s['topp_coarse']['median']:+.2f} % | {100 * s['topp_coarse']['max']:+.2f} % "
        "| ≤ 1 % |",
        f"| verified durations at 100 points within 1 % of 400 points | "
        f"{sum(r['coarse_excess'] <= 0.01 for r in tp)} of {len(tp)} moves | | all |",
        f"| raw toppra's evaluate() violation (velocity, acceleration, pump) | "
        f"{100 * s['topp_raw_violation']['median']:.1f} % | "
        f"{100 * s['topp_raw_violation']['max']:.1f} % | (ours ≤ 0.1 %) |",
        f"| `rest_to_rest` at its switch times / `Ruckig.calculate` (prepared input) | "
        f"{s['ruckig_calc']['median']:.1f}× | {s['ruckig_calc']['max']:.1f}× | ≤ 20× |",
        f"| `rest_to_rest` at its switch times / raw Ruckig as a user calls it | "
        f"{s['ruckig_user']['median']:.2f}× | {s['ruckig_user']['max']:.2f}× | |",
        f"| `rest_to_rest` at 200 Hz / raw Ruckig as a user calls it | "
        f"{s['ruckig_200hz']['median']:.2f}× | {s['ruckig_200hz']['max']:.2f}× | |", "",
        "## TOPP-RA", "",
        "Raw: `TOPPRA(velocity, acceleration, pump).compute_trajectory` with "
        "`ParametrizeConstAccel` and toppra's own sampling at 500 Hz. Ours: "
        "`retime(crane, path_q)` (its default: 100 uniform grid intervals refined where the "
        "timing loses time, verified on every interval, 500 Hz Trajectory; `intervals`: the "
        "final grid). Raw toppra on 200 uniform intervals. Violation: `evaluate()` over "
        "velocity, acceleration, pump. Reference: `retime(..., gridpoints=1600, adapt=0)` "
        "(uniform and fine, verified); `raw s` is below it where raw toppra breaks the limits.",
        "",
        "| machine | raw ms | ours ms | ratio | raw s | ours s | intervals | passes | "
        "raw violation | ours violation | 1600 pts s | raw vs 1600 | ours vs 1600 | "
        "100 pts s | 400 pts s | 100 vs 400 |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- "
        "| --- | --- |"]
    for r in tp:
        lines.append(f"| {r['machine']} | {r['raw_ms']:.1f} | {r['ours_ms']:.1f} | "
                     f"{r['ratio']:.2f}× | {r['raw_s']:.3f} | {r['ours_s']:.3f} | "
                     f"{r['intervals']} | {r['passes']} | {100 * r['raw_violation']:.1f} % | "
                     f"{100 * r['ours_violation']:.2f} % | {r['fine_s']:.3f} | "
                     f"{100 * r['raw_vs_fine']:+.2f} % | {100 * r['ours_vs_fine']:+.2f} % | "
                     f"{r['s100']:.3f} | "
                     f"{r['s400']:.3f} | {100 * r['coarse_excess']:+.2f} % |")
    lines += ["", "## Ruckig", "",
              "Peer 1: `Ruckig.calculate(inp, traj)` on a prepared input. Peer 2: the raw "
              "library as a user calls it (InputParameter filled from arrays, calculate, "
              "`at_time` at every switching time). Ours: `rest_to_rest(crane, q0, q1, "
              "sample_rate=None)` (validated input, the planner Trajectory at the switching "
              "times, a PlanResult), and at its default 200 Hz.", "",
              "| machine | move s | samples | calculate µs | ours µs | ratio | raw user µs | "
              "ours µs | ratio | ours 200 Hz µs | ratio |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rk:
        lines.append(f"| {r['machine']} | {r['duration_s']:.3f} | {r['samples']} | "
                     f"{r['calc_us']:.1f} | {r['ours_switch_us']:.1f} | "
                     f"{r['ratio_calc']:.1f}× | {r['raw_user_us']:.1f} | "
                     f"{r['ours_switch2_us']:.1f} | {r['ratio_user']:.2f}× | "
                     f"{r['ours_200hz_us']:.1f} | {r['ratio_200hz_user']:.2f}× |")
    if res.get("nlp"):
        lines += nlp_report(res["nlp"])
    lines += ["", "The NLP's one-off call (build + solve, fresh process) against the same Opti "
              "baseline: benchmarks/results/nlp_cache.md."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(HERE / "results"))
    ap.add_argument("--repeat", type=int, default=15, help="interleaved rounds per case")
    ap.add_argument("--quick", action="store_true", help="one move per machine, 3 rounds")
    ap.add_argument("--only", default="topp,ruckig,nlp",
                    help="comma-separated sections to run (topp, ruckig, nlp); the others are "
                         "kept from the existing peers.json")
    a = ap.parse_args(argv)
    only = {x.strip() for x in a.only.split(",") if x.strip()}
    if only - {"topp", "ruckig", "nlp"}:
        raise SystemExit(f"--only {a.only!r}: allowed topp, ruckig, nlp")
    repeat = 3 if a.quick else a.repeat
    machine = dict(date=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                   platform=platform.platform(), python=platform.python_version(),
                   cpus=os.cpu_count(), load=" ".join(f"{x:.1f}" for x in os.getloadavg()),
                   numpy=np.__version__, toppra=metadata.version("toppra"),
                   ruckig=metadata.version("ruckig"), casadi=metadata.version("casadi"))
    out = Path(a.out)
    old = json.loads((out / "peers.json").read_text()) if (out / "peers.json").exists() else {}
    if not {"topp", "ruckig"} <= only and not {"topp", "ruckig"} <= set(old):
        raise SystemExit("no earlier peers.json with the TOPP-RA and Ruckig sections: run "
                         "them too (leave out --only)")
    res = dict(old)
    if {"topp", "ruckig"} & only:
        tp = topp_rows(repeat, a.quick) if "topp" in only else old["topp"]
        rk = ruckig_rows(repeat, a.quick) if "ruckig" in only else old["ruckig"]
        runs = dict(res.get("runs", {}))
        runs.update({k: dict(date=machine["date"], load=machine["load"], repeat=repeat)
                     for k in ("topp", "ruckig") if k in only})
        res.update(machine=machine, repeat=repeat, topp=tp, ruckig=rk, runs=runs,
                   summary=dict(topp_ratio=summary([r["ratio"] for r in tp]),
                                topp_coarse=summary([r["coarse_excess"] for r in tp]),
                                topp_raw_violation=summary([r["raw_violation"] for r in tp]),
                                ruckig_calc=summary([r["ratio_calc"] for r in rk]),
                                ruckig_user=summary([r["ratio_user"] for r in rk]),
                                ruckig_200hz=summary([r["ratio_200hz_user"] for r in rk])))
    if "nlp" in only:
        timing, joint, tip = nlp_timing(repeat), nlp_joint_rows(a.quick), nlp_tip_rows(a.quick)
        res["nlp"] = dict(machine=machine, repeat=repeat, timing=timing, joint=joint, tip=tip,
                          summary=nlp_summary(timing, joint, tip))
    out.mkdir(parents=True, exist_ok=True)
    md = report(res)
    atomic_write_text(out / "peers.json", dumps(res))
    atomic_write_text(out / "peers.md", md)
    print(md)


if __name__ == "__main__":
    main()
