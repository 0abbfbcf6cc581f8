"""Where the minimum-time NLP's extra time goes, in process, against a plain CasADi Opti of the
same size (issue 31, the "NLP pump on ≤ 1.5× a plain Opti" item).

    python benchmarks/bench_nlp_overhead.py [--moves 20] [--rounds 3] [--machines umea-lab]
    python benchmarks/bench_nlp_overhead.py --ab '{}' '{"fast_step_computation": "no"}' \
        [--seed 7] [--moves 40] [--rounds 1]       # IPOPT option sets against each other

For each machine, ``--moves`` random tip moves (joint configurations drawn inside the limits,
as benchmarks/bench_peers.py draws its tip moves); for each move, interleaved ``--rounds`` times
after one warm-up each:

* ``nlp`` — ``MoveNLP(crane, "time", N=40, pump=True, solver="ipopt").solve(start, goal)``, the
  whole call (first guess, the exact-Ruckig check, IPOPT unless the exact move is certified),
  built once per machine; three times: with its functions interpreted (``cache="off"``:
  CasADi's SX virtual machine, what bench_peers.py times), compiled (``cache="build"``: the C
  library a ``plan`` loads from the cache), and interpreted with the NLP always solved
  (``certify = False``: the NLP's own overhead, also where the exact move would be certified);
* ``opti`` — benchmarks/opti_baseline.py's ``PlainOpti`` (no pump) between the joint
  configurations at the lower bound's telescopes, built once per move, ``solve()`` timed.

The split of each call, from IPOPT's own statistics (``solver.stats()``): the time in the NLP's
functions (f, g, their gradients, the Jacobian, the Hessian of the Lagrangian), the rest of the
solver call (IPOPT's own work: the KKT factorisations with MUMPS, the line search), and, for the
NLP, the Python around the solver call (lower bound, Ruckig guess, exact check). Ratios are per
move (median of its rounds), summarised over moves. Writes benchmarks/results/nlp_overhead.md
and .json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for p in (ROOT, HERE):   # run from a checkout; the shared Opti baseline
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

from opti_baseline import PlainOpti  # noqa: E402
from planner.bounds import lower_bound  # noqa: E402
from planner.methods.nlp import MoveNLP  # noqa: E402
from planner.model import Crane  # noqa: E402

SEED = 31
# variant -> (cache mode, certify): the whole call (certified exact moves skip the NLP), the
# same with the compiled functions, and the NLP always solved (its own overhead)
VARIANTS = {"interpreted": ("off", True), "compiled": ("build", True),
            "nlp_always": ("off", False)}
LABELS = {"interpreted": "NLP, functions interpreted", "compiled": "NLP, functions compiled",
          "nlp_always": "NLP always solved (no certificate), interpreted"}
FUNCS = ("nlp_f", "nlp_g", "nlp_grad_f", "nlp_jac_g", "nlp_hess_l")


class TimedSolver:
    """A CasADi solver whose calls are timed (wall clock of each ``solver(...)``)."""

    def __init__(self, solver):
        self.solver, self.calls = solver, []

    def __call__(self, *a, **kw):
        t0 = time.perf_counter()
        try:
            return self.solver(*a, **kw)
        finally:
            self.calls.append(time.perf_counter() - t0)

    def __getattr__(self, name):
        return getattr(self.solver, name)


def moves(crane, n: int, seed: int) -> list:
    """``n`` (start, goal) tip pairs from random joint configurations (10 % margins)."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.1 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.1 * (L["q_max"] - L["q_min"])
    qs = lo + rng.random((2 * n, crane.n)) * (hi - lo)
    return [tuple(tuple(float(x) for x in np.round(crane.tip(q), 3)) for q in (qs[k], qs[n + k]))
            for k in range(n)]


def eval_ms(stats: dict) -> float:
    """Milliseconds the last solve spent in the NLP's functions."""
    return 1e3 * sum(stats.get(f"t_wall_{f}", 0.0) for f in FUNCS)


def time_nlp(m: MoveNLP, timed: TimedSolver, a, b) -> dict:
    timed.calls.clear()
    t0 = time.perf_counter()
    r = m.solve(a, b)
    total = time.perf_counter() - t0
    st = m.solver.stats() if timed.calls else {}   # certified: the NLP was not solved
    call = 1e3 * sum(timed.calls)
    return dict(total_ms=1e3 * total, call_ms=call, eval_ms=eval_ms(st),
                hess_ms=1e3 * st.get("t_wall_nlp_hess_l", 0.0),
                jac_ms=1e3 * st.get("t_wall_nlp_jac_g", 0.0),
                g_ms=1e3 * st.get("t_wall_nlp_g", 0.0),
                python_ms=1e3 * total - call, iterations=int(st.get("iter_count", 0)),
                ok=r.ok, duration_s=r.duration_s, own_s=r.stats.get("nlp_duration_s"),
                certified=float(bool(r.stats.get("certified"))))


def time_opti(o: PlainOpti) -> dict:
    t0 = time.perf_counter()
    T, it = o.solve()
    total = time.perf_counter() - t0
    st = o.opti.stats()
    return dict(total_ms=1e3 * total, eval_ms=eval_ms(st),
                hess_ms=1e3 * st.get("t_wall_nlp_hess_l", 0.0),
                jac_ms=1e3 * st.get("t_wall_nlp_jac_g", 0.0),
                g_ms=1e3 * st.get("t_wall_nlp_g", 0.0), iterations=it, duration_s=T)


def nonzeros(m: MoveNLP, o: PlainOpti) -> dict:
    """Structural nonzeros of the constraint Jacobian and of the Lagrangian's Hessian (lower
    triangle, what IPOPT factorises) of the NLP and of the Opti problem."""
    jac, hess = (m.solver.get_function(f) for f in ("nlp_jac_g", "nlp_hess_l"))
    x, g = o.opti.x, o.opti.g
    lam = ca.MX.sym("lam", g.shape[0])
    return dict(nlp=dict(jacobian=jac.sparsity_out(1).nnz(), hessian=hess.sparsity_out(0).nnz()),
                opti=dict(jacobian=ca.jacobian(g, x).nnz(),
                          hessian=ca.tril(ca.hessian(o.opti.f + ca.dot(lam, g), x)[0]).nnz()))


def med_dict(rows: list) -> dict:
    """The median of every numeric field over ``rows``."""
    return {k: statistics.median(r[k] for r in rows) for k, v in rows[0].items()
            if isinstance(v, (int, float)) and not isinstance(v, bool) and v is not None}


def machine_rows(cid: str, n: int, rounds: int, variants=tuple(VARIANTS)) -> dict:
    crane = Crane.from_id(cid)
    nlps = {}
    for variant in variants:
        cache, certify = VARIANTS[variant]
        t0 = time.perf_counter()
        m = MoveNLP(crane, "time", N=40, pump=True, solver="ipopt", cache=cache)
        m.certify = certify
        m.solver = timed = TimedSolver(m.solver)
        nlps[variant] = (m, timed, dict(cache=m.cache_status, setup_s=time.perf_counter() - t0))
    rows = []
    for a, b in moves(crane, n, SEED):
        lb = lower_bound(crane, a, b)
        o = PlainOpti(crane, crane.ik(a, lb.tele_start), crane.ik(b, lb.tele_goal), 40,
                      guess_T=lb.combined_s)
        row = dict(start=list(a), goal=list(b), nlp={}, vars=dict(opti=o.variables),
                   cons=dict(opti=o.constraints))
        for v, (m, timed, _) in nlps.items():
            time_nlp(m, timed, a, b)     # warm-up
            row["vars"][v], row["cons"][v] = m.nw, len(m.lbg)
        time_opti(o)
        got = {v: [] for v in nlps} | {"opti": []}
        for k in range(rounds):          # interleaved, the order turned every round
            order = list(nlps) + ["opti"]
            for v in (order if k % 2 == 0 else order[::-1]):
                got[v].append(time_opti(o) if v == "opti" else time_nlp(*nlps[v][:2], a, b))
        row["opti"] = med_dict(got.pop("opti"))
        for v, rs in got.items():
            row["nlp"][v] = med_dict(rs)
            row["nlp"][v]["ok"] = all(r["ok"] for r in rs)
            row["nlp"][v]["ratio"] = row["nlp"][v]["total_ms"] / row["opti"]["total_ms"]
        rows.append(row)
    return dict(machine=cid, nlp_setup={v: x[2] for v, x in nlps.items()}, moves=rows,
                nonzeros=nonzeros(next(iter(nlps.values()))[0], o))


def ab_rows(cid: str, n: int, rounds: int, seed: int, specs: list) -> list:
    """The NLP always solved under several IPOPT option sets ``specs`` (dicts added to
    MoveNLP's own; the first the reference), interleaved per move (the order turned every
    round): per set the median whole-call ms, the median per-move time ratio to the reference,
    the iterations in all, the solves ok and the NLP's own durations against the reference's
    (largest relative difference)."""
    crane = Crane.from_id(cid)
    nlps = []
    for spec in specs:
        m = MoveNLP(crane, "time", N=40, pump=True, solver="ipopt", cache="off",
                    ipopt_options=spec or None)
        m.certify = False
        nlps.append(m)
    got = [dict(ms=[], iters=0, ok=0, own=[]) for _ in specs]
    for a, b in moves(crane, n, seed):
        ts = [[] for _ in specs]
        for i, m in enumerate(nlps):   # warm-up, and the solution compared
            r = m.solve(a, b)
            got[i]["iters"] += r.iterations
            got[i]["ok"] += r.ok
            got[i]["own"].append(r.stats.get("nlp_duration_s", r.duration_s))
        for k in range(rounds):
            order = range(len(nlps)) if k % 2 == 0 else reversed(range(len(nlps)))
            for i in order:
                t0 = time.perf_counter()
                nlps[i].solve(a, b)
                ts[i].append(time.perf_counter() - t0)
        for i in range(len(specs)):
            got[i]["ms"].append(1e3 * statistics.median(ts[i]))
    ref = got[0]
    return [dict(spec=spec, ms=statistics.median(g["ms"]), ratio=statistics.median(
        x / y for x, y in zip(g["ms"], ref["ms"])), iterations=g["iters"], ok=g["ok"],
        own_rel=max(abs(x / y - 1) for x, y in zip(g["own"], ref["own"])))
        for spec, g in zip(specs, got)]


def summary(res: dict) -> dict:
    out = {}
    for mres in res["machines"]:
        rows = mres["moves"]
        s = {}
        for v in [v for v in VARIANTS if v in rows[0]["nlp"]]:
            ratios = sorted(r["nlp"][v]["ratio"] for r in rows)
            parts = {k: statistics.median(r["nlp"][v][k] for r in rows)
                     for k in ("total_ms", "python_ms")}
            # the solver's parts over the moves the NLP was solved on (not the certified ones)
            solved = [r["nlp"][v] for r in rows if r["nlp"][v]["iterations"]] or [
                dict(call_ms=0.0, eval_ms=0.0, hess_ms=0.0, jac_ms=0.0, g_ms=0.0, iterations=1)]
            parts.update({k: statistics.median(x[k] for x in solved)
                          for k in ("call_ms", "eval_ms", "hess_ms", "jac_ms", "g_ms",
                                    "iterations")})
            parts["ipopt_own_ms"] = statistics.median(x["call_ms"] - x["eval_ms"] for x in solved)
            parts["per_iteration_own_ms"] = statistics.median(
                (x["call_ms"] - x["eval_ms"]) / x["iterations"] for x in solved)
            parts["certified"] = sum(r["nlp"][v]["certified"] > 0.5 for r in rows)
            parts["duration_s"] = statistics.median(r["nlp"][v]["duration_s"] for r in rows)
            s[v] = dict(ratio_median=statistics.median(ratios), ratio_p90=float(
                np.percentile(ratios, 90)), ratio_max=ratios[-1], ratio_min=ratios[0],
                ok=sum(r["nlp"][v]["ok"] for r in rows), **parts)
        o = {k: statistics.median(r["opti"][k] for r in rows)
             for k in ("total_ms", "eval_ms", "hess_ms", "jac_ms", "g_ms", "iterations")}
        o["ipopt_own_ms"] = statistics.median(r["opti"]["total_ms"] - r["opti"]["eval_ms"]
                                              for r in rows)
        o["per_iteration_own_ms"] = statistics.median(
            (r["opti"]["total_ms"] - r["opti"]["eval_ms"]) / r["opti"]["iterations"]
            for r in rows)
        s["opti"] = o
        s["size"] = dict({k: rows[0][k] for k in ("vars", "cons")}, nonzeros=mres["nonzeros"])
        s["variants"] = [v for v in VARIANTS if v in s]
        out[mres["machine"]] = s
    return out


# the same command before issue 31's changes (main 6dd9805's nlp_overhead.md, 2026-11-26 09:24,
# load 9.5-11.5), and the plans of the run after them against that run's, move by move
BEFORE = ("Second session (branch wt-nlp6, from main f90ec7a: the trials below from \"second "
          "session, start\"): the NLP always solved went from 1.54× (umea-lab) and 2.90× "
          "(s100f), trial runs of `--variants nlp_always` at load 2.4-6.8, to the table's "
          "(umea-lab **1.23×**; a repeat with `--variants nlp_always` right after, load "
          "8.7-9.2: **1.20×**); the plans' durations against the first session's final run "
          "(umea-lab, all three variants) and the start's trial run (s100f), move by move: "
          "within 7e-8 relative (median 0). First session: "
          "Before (the same command, main 6dd9805, load 9.5-11.5): **1.92×** interpreted, "
          "**1.82×** compiled, the NLP solved on every move (28 iterations, 1743 rows, 7764 "
          "Jacobian nonzeros). After (2026-11-26 13:11, load 7.0-7.6): the plans' durations "
          "against that run's, move by move: median -2.5e-5, max +2.9e-6, min -1.1e-3 "
          "(relative); every plan within every limit on evaluate()'s 1 kHz resampling "
          "(tests/methods).")

# The trials of issue 31 (runs of this bench's "NLP always" variant on umea-lab: 20 moves,
# 3 interleaved rounds, interpreted, 2 shared cores under load 1.2-5.9, so ratios within ~0.1
# of each other are noise): what was tried, the median ratio, the median IPOPT iterations, the
# NLP's own durations against the start (median relative), kept or not.
TRIALS = (
    ("start: two velocity rows per check point, ε = 1e-3 (re-runs 1.95×, 1.91×)", "1.91×", 32,
     "0", "-"),
    ("IPOPT linear_solver spral (the only other solver in the wheel)", "9.39×", 28.5, "-",
     "no"),
    ("IPOPT mu_strategy monotone", "2.46×", 38, "-", "no"),
    ("IPOPT hessian_approximation limited-memory", "3.78×", 35, "-", "no"),
    ("IPOPT mu_oracle probing / loqo", "3.36× / 3.20×", "43 / 65", "-", "no"),
    ("IPOPT mu_init 0.01", "1.90×", 32, "-", "no"),
    ("IPOPT bound_push = bound_frac = 1e-4", "2.31×", 27, "-", "no"),
    ("IPOPT nlp_scaling_method none", "1.91×", 32, "-", "no"),
    ("no velocity rows between the nodes (what they cost; infeasible between nodes)", "1.28×",
     17.5, "-2.0e-4", "no: every solution overshot between nodes; slowing it to the exact "
     "peak cost +0.3 to +0.86 % (an active-set first pass would need the full solve again)"),
    ("velocity: node rows merged (gap of both intervals), two check points per interval",
     "3.00×", 36.5, "+3.0e-5", "no"),
    ("velocity: ε = 1e-2 / 1e-1 (two rows)", "1.74× / 1.71×", "21 / 19.5",
     "+4.9e-6 / +6.6e-5", "no (alone)"),
    ("velocity: one smooth row per check point (|q̇ − c| + gap ≤ r), ε = 1e-3", "1.56×", 24.5,
     "+2.4e-7", "no (alone)"),
    ("one smooth row per check point, ε = 1e-1 / 3e-2 / 1e-2", "1.51× / 1.53× / 1.51×",
     "18.5 / 19 / 19", "+6.5e-5 / +1.7e-5 / +5.0e-6", "no: ε = 1e-2 kept, but the smooth "
     "|q̇ − c| stalled IPOPT on long s100f moves (40 random: one max_iter, 219-1000 "
     "iterations on eight)"),
    ("one exact row ((q̇ − c)/r)² ≤ x·|x|, x = 1 − gap/r, ε = 1e-2 (ratios in CPU time, one "
     "interleaved run: two rows ε = 1e-2 1.71×, smooth row 1.57×)", "1.52×-1.57×", "438 in all "
     "(two rows ε = 1e-3: 656)", "+4e-6 (40 random umea-lab), +7e-6 (s100f)", "**yes**: 40 of "
     "40 ok on both machines, 1459 → 908 and 1475 → 1259 iterations in all"),
    ("one duration variable instead of the per-node chain (IPOPT only)", "1.53× (same run: "
     "1.54×)", "389 (438)", "-", "no: fewer iterations, dearer ones"),
    ("MUMPS pivot order AMD / AMF / PORD / QAMD; no (permuting) scaling", "1.70× / 1.58× / "
     "1.58× / 1.74×; 1.49-1.64× (same run: 1.54-1.56×)", "434-440", "-", "no: noise"),
    ("a failed minimum-time solve tries IPOPT with mu_oracle probing (a twin built on first "
     "use)", "-", "-", "-", "**yes**: a 9 L/min umea-lab move of tests/methods/test_ramps.py "
     "hit max_iter (it took 227 iterations before, chaotic in round-off); probing solves it"),
    ("+ no position rows at the midpoints (an active-set candidate)", "1.45× (same load: "
     "1.52×)", 22.5, "+5.0e-6", "no: more iterations, within noise"),
    ("+ IPOPT mu_init 0.01 / bound_push = bound_frac = 1e-3", "1.80× / 1.73×", "19 / 21.5", "-",
     "no"),
    ("the exact move's check rejects at its switch times first (evaluate at rate ~0)",
     "-", "-", "0", "yes: 0.6 ms instead of ~4 ms where the pump rejects it"),
    ("certificate: the feasible Ruckig move that lasts the guess's (coarse) lower bound, "
     "without the NLP (whole call)", "0.31×", "0 (15 of 20 moves)", "0 (the same plans)",
     "no: on one of 40 other umea-lab moves the coarse search missed a basin (0.28 % above "
     "the fine bound) and the plan came out 0.065 % slower than the NLP's"),
    ("certificate against the fine telescope search (lower_bound's default grid, 1e-4)",
     "0.65× / 0.60× compiled (final run)", "0 (14 of 20 moves)", "max +2.9e-6 (plans)",
     "**yes** (the fine bound costs ~20 ms of the certified call)"),
    # the second session on the item (branch wt-nlp6, from main f90ec7a): the Python around
    # the solver call, then the Hessian; --variants nlp_always, plans against the start
    ("second session, start (main f90ec7a; load 2.4-3.4; Python around the call 28.2 ms)",
     "1.54×", 17.5, "0", "-"),
    ("the exact move's limit check only where it decides (the certificate by duration first, "
     "the swap only for a move faster than the NLP's) and without evaluate()'s dynamics "
     "(kinematic limits and the pump's draw from the stroke rates: the same numbers on 120 "
     "moves of 4 machines); no load-sensing mask for minimum time",
     "1.48× (load 4.0-4.6)", 17.5, "0 (plans identical)",
     "**yes**: Python around 28.2 → 23.2 ms"),
    ("the guess's lower bound: both ends' IK in one call per level, reasons spelled out only "
     "to raise, combined_only computing only the timing bounds (the other fields at their grid "
     "values, as documented)", "1.56× (load 3.5-3.7, both sides faster: Opti 53 ms)", 17.5,
     "0 (plans identical)", "**yes**: 8.4 → 6.6 ms per bound (48 moves, 4 machines, combined "
     "bound and telescopes bit-identical); Python around 9.7 ms in that run"),
    ("CasADi's cse on the Hessian", "-", "-", "-", "no: 121k → 111k instructions, 1.02 → 0.95 "
     "ms per evaluation, +0.85 s build"),
    ("the pump rows' Hessian through the stroke Jacobians (chain rule, exact: "
     "planner/methods/nlp/hessian.py)", "1.36× (load 4.5-4.7)", 17.5, "≤ 7e-16 (plans)",
     "**yes**: 121k → 112k instructions, 0.95 → 0.74 ms per evaluation (interleaved), the "
     "same matrix within 3e-16 relative, the same sparsity"),
    ("+ J, J′, J″ of each node from one function with common subexpressions merged, placed "
     "by index (J″ alone: 966 → 479 instructions per node)", "1.24× (load 8.0)", 19,
     "≤ 1.3e-14 (plans)", "**yes**: 83k instructions, 1.23 vs 1.73 ms per evaluation against "
     "CasADi's own (interleaved, loaded)"),
    ("the constraint Jacobian through the stroke Jacobians likewise (jac_g)", "-", "-", "-",
     "no: 54.0k → 53.6k instructions, 0.56 → 0.50 ms (umea-lab), not worth the code"),
    ("IPOPT fast_step_computation yes (minimum time, free path: no residual check of the "
     "Newton step); A/B in one process, interleaved, the NLP always solved",
     "1.28× (load 6.0); A/B 0.94× (bench moves), 0.92× (40 other moves)", "20 (939 in all on "
     "the 40, before 903)", "≤ 1.3e-6 (NLP's own), plans ≤ 7e-8",
     "**yes**: s100f A/B 0.86× / 0.93× (1315 vs 1258 iterations on 40 moves); every solve "
     "ok. At the end, on top of every kept change (`--ab '{}' '{\"fast_step_computation\": "
     "\"no\"}' --seed 7 --moves 40 --rounds 1 --machines umea-lab,s100f`, load 5.4-6.6): "
     "without it 1.16× / 1.13× the time, 40/40 ok both ways, own durations within 1.3e-7"),
    ("IPOPT (A/B against the kept options) max_soc 0 / mumps_pivtol 1e-8 / "
     "first_hessian_perturbation 1e-2 / neg_curv_test_reg no / alpha_for_y primal-and-full / "
     "recalc_y yes / mu_max 1e3 / adaptive_mu_globalization kkt-error, never-monotone-mode / "
     "quality_function_max_section_steps 3", "1.03 / 1.09 / 1.02 / 1.03 / 1.03 / 1.03 / 1.02 / "
     "1.07, 1.02 / 1.09 (× the reference's time)", "413-590 in all (reference 415-426)", "-",
     "no"),
)


def trials_table() -> list:
    """The trials of issue 31 as a markdown table (:data:`TRIALS`)."""
    L = ["### Trials (issue 31: toward ≤ 1.5× with the NLP solved)", "",
         "20 umea-lab moves, 3 interleaved rounds, the NLP always solved, functions "
         "interpreted; one change at a time on top of the kept ones. Durations: the NLP's own "
         "solution against the start (median relative); the plans returned were the same "
         "within 3e-6 in every kept trial.", "",
         "| trial | ratio (median) | iterations | NLP's own duration | kept |",
         "| --- | --- | --- | --- | --- |"]
    L += [f"| {a} | {b} | {c} | {d} | {e} |" for a, b, c, d, e in TRIALS]
    return L + [""]


def report(res: dict) -> str:
    m = res["meta"]
    f1 = lambda v: f"{v:.1f}"  # noqa: E731
    L = ["# The minimum-time NLP in process against a plain Opti: where the time goes (issue 31)",
         "", f"Command: `{m['command']}`  ",
         f"Machine: {m['platform']}, {m['cpus']} CPUs, CasADi {m['casadi']}, {m['date']}; load "
         f"average {m['load_before']} before, {m['load_after']} after (shared with other "
         "sessions).  ",
         f"{m['moves']} random tip moves per machine (seed {SEED}), {m['rounds']} interleaved "
         "rounds each, medians per move, then over the moves. NLP: `MoveNLP(crane, 'time', "
         "N=40, pump=True, solver='ipopt').solve(start, goal)`, the whole call; Opti: "
         "`PlainOpti` (no pump) between the same ends, `solve()`. Split from IPOPT's own "
         "statistics (`t_wall_nlp_*`) and a wall clock around the solver call; iterations, "
         "functions and IPOPT's own work are medians over the moves the NLP was solved on "
         "(certified moves skip it).", "", BEFORE, ""]
    for cid, s in res["summary"].items():
        nz = s["size"]["nonzeros"]
        v0 = s["variants"][0]
        L += [f"## {cid}", "",
              f"Size: NLP {s['size']['vars'][v0]} variables / "
              f"{s['size']['cons'][v0]} constraints, {nz['nlp']['jacobian']} "
              f"Jacobian and {nz['nlp']['hessian']} Hessian nonzeros; Opti "
              f"{s['size']['vars']['opti']} / {s['size']['cons']['opti']}, "
              f"{nz['opti']['jacobian']} and {nz['opti']['hessian']}.", "",
              "| | whole call ms | ratio to Opti (median, p90, max) | iterations | functions ms "
              "(Hessian, Jacobian, g) | IPOPT's own ms (per iteration) | Python around ms |",
              "| --- | ---: | --- | ---: | --- | --- | ---: |"]
        for v in s["variants"]:
            x = s[v]
            L.append(f"| {LABELS[v]} ({x['ok']} ok, {x['certified']} certified) | "
                     f"{f1(x['total_ms'])} | "
                     f"**{x['ratio_median']:.2f}×**, {x['ratio_p90']:.2f}×, "
                     f"{x['ratio_max']:.2f}× | {x['iterations']:.0f} | {f1(x['eval_ms'])} "
                     f"({f1(x['hess_ms'])}, {f1(x['jac_ms'])}, {f1(x['g_ms'])}) | "
                     f"{f1(x['ipopt_own_ms'])} ({x['per_iteration_own_ms']:.2f}) | "
                     f"{f1(x['python_ms'])} |")
        o = s["opti"]
        L += [f"| plain Opti | {f1(o['total_ms'])} | 1 | {o['iterations']:.0f} | "
              f"{f1(o['eval_ms'])} ({f1(o['hess_ms'])}, {f1(o['jac_ms'])}, {f1(o['g_ms'])}) | "
              f"{f1(o['ipopt_own_ms'])} ({o['per_iteration_own_ms']:.2f}) | - |", ""]
        if not {"nlp_always", "interpreted", "compiled"} <= set(s["variants"]):
            continue
        x = s["nlp_always"]
        extra = x["total_ms"] - o["total_ms"]
        own = x["ipopt_own_ms"] - o["ipopt_own_ms"]
        fun = x["eval_ms"] - o["eval_ms"]
        L += [f"Where the NLP's extra {f1(extra)} ms (NLP always solved, medians) go: "
              "IPOPT's own "
              f"work {f1(own)} ms ({100 * own / extra:.0f} %: "
              f"{x['per_iteration_own_ms'] / o['per_iteration_own_ms']:.2f}× per iteration, "
              f"the KKT system has {nz['nlp']['jacobian'] / nz['opti']['jacobian']:.1f}× the "
              f"Jacobian and {nz['nlp']['hessian'] / nz['opti']['hessian']:.1f}× the Hessian "
              f"nonzeros: the pump rows and the limit checks between the nodes), "
              f"{x['iterations'] - o['iterations']:+.0f} iterations; the NLP's functions "
              f"{f1(fun)} ms ({100 * fun / extra:.0f} %, the exact Hessian "
              f"{f1(x['hess_ms'])} ms of them); the Python around the solver call "
              f"{f1(x['python_ms'])} ms ({100 * x['python_ms'] / extra:.0f} %: lower bound, "
              "Ruckig guess, exact-Ruckig check). With the certificate "
              f"{s['interpreted']['certified']} of {m['moves']} moves skip the NLP (their "
              "Ruckig move is feasible and lasts the lower bound). Compiling the functions (the "
              f"cache's C library, built with -O0) gives {f1(s['compiled']['eval_ms'])} ms in "
              f"them against {f1(s['interpreted']['eval_ms'])} ms interpreted. Median plan "
              f"duration {s['interpreted']['duration_s']:.4f} s (NLP always: "
              f"{x['duration_s']:.4f} s).", ""]
    L += trials_table()
    L += [f"Final run: `{m['command']}`, {m['date']}, load average {m['load_before']} before, "
          f"{m['load_after']} after (2 shared cores).", ""]
    return "\n".join(L)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--moves", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--machines", default="umea-lab")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help=f"NLP variants to time, of {', '.join(VARIANTS)}")
    ap.add_argument("--ab", nargs="+", metavar="OPTIONS",
                    help="instead: A/B of IPOPT option sets (JSON objects, the first the "
                         "reference), the NLP always solved, interleaved; printed only")
    ap.add_argument("--seed", type=int, default=SEED, help="moves' seed (--ab)")
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args(argv)
    if args.ab:
        specs = [json.loads(x) for x in args.ab]
        print(f"| machine | IPOPT options | ms (median) | time / reference's | iterations | ok "
              f"| NLP's own duration vs reference (max rel.) |\n|{' --- |' * 7}")
        for c in args.machines.split(","):
            for r in ab_rows(c.strip(), args.moves, args.rounds, args.seed, specs):
                print(f"| {c} | {json.dumps(r['spec'])} | {r['ms']:.1f} | {r['ratio']:.3f} | "
                      f"{r['iterations']} | {r['ok']}/{args.moves} | {r['own_rel']:.1e} |")
        return 0
    variants = tuple(v.strip() for v in args.variants.split(","))
    bad = [v for v in variants if v not in VARIANTS]
    if bad or not variants:
        ap.error(f"--variants {args.variants!r}: allowed {', '.join(VARIANTS)}")
    os.environ.setdefault("CRANE_PLANNER_CACHE", tempfile.mkdtemp(prefix="crane-nlp-ovh-"))
    load_before = [round(x, 2) for x in os.getloadavg()]
    date = datetime.now(timezone.utc).isoformat(timespec="seconds")
    machines = [machine_rows(c.strip(), args.moves, args.rounds, variants)
                for c in args.machines.split(",")]
    extra = "" if variants == tuple(VARIANTS) else f" --variants {','.join(variants)}"
    meta = dict(command=f"python benchmarks/bench_nlp_overhead.py --moves {args.moves} "
                        f"--rounds {args.rounds} --machines {args.machines}{extra}",
                platform=platform.platform(), cpus=os.cpu_count(), casadi=ca.__version__,
                date=date, load_before=load_before,
                load_after=[round(x, 2) for x in os.getloadavg()], moves=args.moves,
                rounds=args.rounds)
    res = dict(meta=meta, machines=machines)
    res["summary"] = summary(res)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "nlp_overhead.json").write_text(json.dumps(res, indent=1))
    (out / "nlp_overhead.md").write_text(report(res) + "\n")
    print(report(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
