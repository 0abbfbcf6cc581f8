"""``crane-planner bench``: global planners vs local laws on the seeds' moves, judged only by
:func:`planner.trajectory.evaluate`.

Suites (:mod:`planner.bench.suites`) → moves → every method (:mod:`planner.bench.methods`) →
trajectory pieces → ``evaluate()`` of every piece on the limit kinds the method claims plus
position, velocity and pump flow (what the laws claim) → one row per (suite, move, method):
``duration_s`` [s] (a cycle's clock for timed cycles), ``energy_J`` (pump energy, summed over
pieces), ``peak_pump_flow_m3s``, ``max_limit_violation`` (largest relative excess of a judged
kind), ``gap_pct`` to the lower bound (:func:`planner.bounds.lower_bound`: the pump-aware ramp bound
when the method claims acceleration and pump limits, rest-to-rest + pump with acceleration
limits alone, else velocity + pump), ``solve_time_s``
(median, min, max over the repeats; a method is repeated only while one solve takes less than
:data:`REPEAT_BELOW_S`, slower ones run once; NLP construction is excluded and reported under
``build_s``), and ``success``: status ok, ``max_limit_violation`` ≤ 0.1 %, clear of the suite's
obstacles (≥ 0.96 × clearance on the 1 kHz resampling), and the pieces of a cycle joining
without a jump. Per suite and method: success rate and medians. Outputs
(:mod:`planner.bench.report`, :mod:`planner.bench.figures`): ``bench.md``, ``bench.json`` and
figures in ``out``.

Python API: :func:`run_bench`.
"""
from __future__ import annotations

import os
import platform
import statistics
import time as _time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np


from planner.bench.context import BASE_KINDS, Ctx, Outcome, Settings
from planner.bench.methods import method_names
from planner.io import progress as progress_bar
from planner.bench.report import DEFAULT_RESULTS, global_vs_local, nlp_vs_laws, write_outputs
from planner.bench.suites import SUITE_NAMES, build_suite
from planner.bounds import lower_bound
from planner.geometry.obstacles import tip_clearance
from planner.methods.base import PlanStatus
from planner.model import Crane, UnreachableError
from planner.trajectory import LIMIT_KINDS, evaluate

DEFAULT_OUT = Path("benchmarks/results/bench")   # relative to the current directory
REPEAT_BELOW_S = 2.0      # [s] solves faster than this are repeated (``repeats`` times)
OK_TOL = 1e-3             # relative limit excess counted as within the limits (0.1 %)
JUMP_TOL = 1e-6           # [rad | m] largest joint jump between pieces of one cycle
CLEAR_FRACTION = 0.96     # of an obstacle's clearance, as MoveNLP.clears


def parse_suites(suites) -> list[str]:
    """None (all), 'a,b' or a list of names (each may be a comma list) -> validated names: the
    shipped suites of SUITE_NAMES, or paths to task files with a ``[bench]`` table."""
    if suites is None:
        return list(SUITE_NAMES)
    if isinstance(suites, str):
        suites = [suites]
    names = [x.strip() for s in suites for x in str(s).split(",") if x.strip()]
    bad = [n for n in names if n not in SUITE_NAMES
           and not (n.endswith(".toml") and Path(n).is_file())]
    if bad or not names:
        raise ValueError(f"unknown suite {', '.join(map(repr, bad)) or '(none given)'}; "
                         f"known suites: {', '.join(SUITE_NAMES)} (or a task file .toml "
                         "with a [bench] table)")
    return list(dict.fromkeys(names))


def machine_info() -> dict:
    return dict(platform=platform.platform(), cpu_count=os.cpu_count(),
                python=platform.python_version(), processor=platform.processor() or None,
                date_utc=datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"))


# ------------------------------------------------------------------------------ one run
def _status_of(e: Exception) -> PlanStatus:
    return PlanStatus.UNREACHABLE if isinstance(e, UnreachableError) else \
        PlanStatus.INVALID if isinstance(e, ValueError) else PlanStatus.ERROR


def timed_run(runner, ctx, move, repeats: int):
    """(first Outcome, solve times [s]) — exceptions become a failure status, NLP build time
    is subtracted, repeats stop after a solve slower than REPEAT_BELOW_S."""
    first, times = None, []
    for _ in range(max(1, repeats)):
        b0 = sum(ctx.build_s.values())
        t0 = _time.perf_counter()
        try:
            out = runner(ctx, move)
        except Exception as e:  # a benchmark row records why, never a traceback
            out = Outcome(_status_of(e), f"{type(e).__name__}: {e}")
        times.append(_time.perf_counter() - t0 - (sum(ctx.build_s.values()) - b0))
        first = first or out
        if times[-1] >= REPEAT_BELOW_S:
            break
    return first, times


def implied_accel(crane: Crane, traj):
    """Largest |Δq̇|/Δt over the limit (ratio) of a piecewise-linear trajectory at its own
    sample spacing, from rest and back to rest (evaluate() sees q̈ = 0 on such trajectories:
    the velocity steps of laws and DP are invisible to it). None for smooth trajectories."""
    if traj.interpolation != "linear":
        return None
    h = np.diff(traj.t)
    v = np.diff(traj.q, axis=0) / h[:, None]
    z = np.zeros((1, traj.n))
    v = np.vstack([z, v, z])
    hm = np.concatenate([[h[0]], 0.5 * (h[1:] + h[:-1]), [h[-1]]])
    a = np.abs(np.diff(v, axis=0)) / hm[:, None]
    return float(np.max(a / crane.limit_arrays()["qdd_max"]))


def _bound(ctx, move, checked, cache):
    """(lower bound [s], its kind) for the limit kinds a method is judged on: rest-to-rest +
    pump with acceleration limits (jerk-free when the method ignores jerk, e.g. TOPP-RA), else
    velocity + pump; None for timed cycles and closed paths."""
    if move.cycle:
        return None, "n/a (timed cycle)"
    if move.closed:
        return None, "n/a (closed path: start = goal)"
    jerk = "jerk" in checked
    ramps = "acceleration" in checked and "pump_flow" in checked
    key = (move.id, jerk, ramps)
    if key not in cache:
        crane = ctx.crane if jerk else ctx.variant(1.0, float("inf"))
        cache[key] = lower_bound(crane, move.start, move.goal, ramps=ramps)
    lb = cache[key]
    if "acceleration" in checked:
        kind = "pump ramps" if lb.ramps_s is not None else "rest-to-rest + pump"
        return lb.certified_s, kind + ("" if jerk else " (no jerk limit)")
    return max(lb.velocity_s, lb.pump_s), "velocity + pump"


def judge(ctx, move, method, out: Outcome, times, cache) -> dict:
    """One benchmark row: evaluate() of every piece, the bound gap, the verdict."""
    crane = ctx.crane
    row = dict(suite=ctx.suite.name, move=move.id, method=method, status=out.status,
               reason=out.reason, success=False, verdict=f"{out.status}: {out.reason}",
               duration_s=None, energy_J=None, peak_pump_flow_m3s=None,
               max_limit_violation=None, violations=None, checked=None, lower_bound_s=None,
               bound_kind=None, gap_pct=None, clearance_m=None, junction_jump=None,
               implied_accel_over_limit=None,
               solve_time_s=dict(median=statistics.median(times), min=min(times),
                                 max=max(times), runs=len(times)) if times else None,
               notes=list(out.notes), info=dict(out.info))
    if not out.ok:
        return row
    evs = [evaluate(crane, tr, kinds=tuple(dict.fromkeys(tuple(tr.limits) + BASE_KINDS)))
           for _, tr in out.pieces]
    trs = [tr for _, tr in out.pieces]
    end = max(t0 + tr.duration for t0, tr in out.pieces)
    checked = sorted(set().union(*(e.checked for e in evs)))
    row.update(duration_s=move.duration_s or sum(tr.duration for tr in trs),
               energy_J=sum(e.energy_J for e in evs),
               peak_pump_flow_m3s=max(e.peak_pump_flow for e in evs),
               max_limit_violation=max(e.max_limit_violation for e in evs),
               violations={k: max(e.violations[k] for e in evs) for k in LIMIT_KINDS},
               checked=checked)
    acc = [a for a in (implied_accel(crane, tr) for tr in trs) if a is not None]
    row["implied_accel_over_limit"] = max(acc) if acc else None
    problems = []
    if row["max_limit_violation"] > OK_TOL:
        k = max(checked, key=lambda k: row["violations"][k])
        problems.append(f"exceeds {k} by {100 * row['violations'][k]:.2f} %")
    if ctx.obstacles:
        clear = min(tip_clearance(e.tip, ctx.obstacles) for e in evs)
        row["clearance_m"] = clear
        need = CLEAR_FRACTION * min(ob.clearance for ob in ctx.obstacles)
        if clear < need:
            problems.append(f"comes within {clear:.3f} m of an obstacle (needs ≥ {need:.3f} m)")
    if len(trs) > 1:
        jump = max(float(np.max(np.abs(b.q[0] - a.q[-1]))) for a, b in zip(trs[:-1], trs[1:]))
        row["junction_jump"] = jump
        if jump > JUMP_TOL:
            problems.append(f"not one executable motion: the joints jump by up to {jump:.3g} "
                            "(rad or m) where sections meet")
    if move.duration_s and end > move.duration_s + 1e-6:
        problems.append(f"overruns the cycle by {end - move.duration_s:.3g} s ({end:.3f} s > "
                        f"{move.duration_s:.3f} s)")
    bound, kind = _bound(ctx, move, checked, cache)
    row.update(lower_bound_s=bound, bound_kind=kind,
               gap_pct=None if not bound else 100.0 * (row["duration_s"] / bound - 1.0))
    row["success"] = not problems
    row["verdict"] = "ok" if not problems else "; ".join(problems)
    return row


def _med(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def summarise(rows, methods) -> dict:
    """Per method of ``methods``: runs, successes, success rate and medians over the
    successful rows."""
    out = {}
    for m in methods:
        rs = [r for r in rows if r["method"] == m]
        att = [r for r in rs if r["status"] != "n/a"]
        if not att:
            out[m] = dict(applicable=False, reason=rs[0]["reason"] if rs else "")
            continue
        ok = [r for r in att if r["success"]]
        out[m] = dict(applicable=True, runs=len(att), successes=len(ok),
                      success_rate=len(ok) / len(att),
                      median_duration_s=_med(r["duration_s"] for r in ok),
                      median_energy_J=_med(r["energy_J"] for r in ok),
                      median_gap_pct=_med(r["gap_pct"] for r in ok),
                      median_solve_s=_med(r["solve_time_s"]["median"] for r in att),
                      worst_violation=max((r["max_limit_violation"] for r in att
                                           if r["max_limit_violation"] is not None),
                                          default=None))
    return out


def select_methods(methods=None) -> list[str]:
    """None (every method of :func:`planner.bench.methods.method_names`), 'a,b' or a list of
    names -> validated names in the bench's order."""
    known = method_names()
    if methods is None:
        return known
    if isinstance(methods, str):
        methods = [methods]
    names = {x.strip() for s in methods for x in str(s).split(",") if x.strip()}
    bad = sorted(names - set(known))
    if bad or not names:
        raise ValueError(f"unknown bench method {', '.join(map(repr, bad)) or '(none given)'}; "
                         f"known: {', '.join(known)}")
    return [m for m in known if m in names]


def run_suite(name: str, settings: Settings, repeats: int, progress: bool = True,
              methods=None):
    """Run one suite with ``methods`` (None: all, see :func:`select_methods`). Returns (result
    dict, {method: Outcome} of its profile move, suite, crane)."""
    meths = select_methods(methods)
    suite = build_suite(name, settings)
    crane = Crane.from_id(suite.crane_id)
    ctx = Ctx(crane, settings, suite)
    rows, keep, cache = [], {}, {}
    t0 = _time.perf_counter()
    bar = progress_bar(len(suite.moves) * len(meths), name, unit="run", enabled=progress)
    for move in suite.moves:
        for m in meths:
            runner = suite.methods[m]
            bar.set_postfix_str(f"{move.id} {m}", refresh=False)
            if isinstance(runner, str):
                rows.append(dict(suite=name, move=move.id, method=m, status="n/a", reason=runner,
                                 success=False, verdict=f"n/a: {runner}"))
            else:
                out, times = timed_run(runner, ctx, move, repeats)
                rows.append(judge(ctx, move, m, out, times, cache))
                if move.id == suite.profile_move and out.ok:
                    keep[m] = out
            bar.update(1)
    bar.close()
    res = dict(crane=suite.crane_id, description=suite.description, kind=suite.kind,
               notes=suite.notes, profile_move=suite.profile_move,
               moves=[dict(id=mv.id, start=list(mv.start), goal=list(mv.goal),
                           path=getattr(mv.path, "name", None) if mv.path else "line",
                           cycle=list(mv.cycle) if mv.cycle else None,
                           duration_s=mv.duration_s) for mv in suite.moves],
               build_s=ctx.build_s, wall_time_s=_time.perf_counter() - t0,
               rows=rows, summary=summarise(rows, meths))
    return res, keep, suite, crane


# ------------------------------------------------------------------------------ acceptance
def acceptance(res: dict) -> dict:
    """The issue's three acceptance items, measured on this run (None when not run)."""
    S = res["suites"]
    acc = dict(seed002_global_energy=global_vs_local(S["seed002-hvd"])
               if "seed002-hvd" in S else None,
               seed000_nlp_vs_laws=nlp_vs_laws(S["seed000-abc"]) if "seed000-abc" in S else None)
    wall = dict(total_s=res["wall_time_s"], total_limit_s=1200.0,
                all_suites=set(S) == set(SUITE_NAMES))
    if "seed000-abc" in S:
        wall.update(seed000_s=S["seed000-abc"]["wall_time_s"], seed000_limit_s=120.0,
                    seed000_pass=S["seed000-abc"]["wall_time_s"] <= 120.0)
    if wall["all_suites"]:
        wall["total_pass"] = res["wall_time_s"] <= 1200.0
    acc["wall_time"] = wall
    return acc


def run_bench(suites=None, out=DEFAULT_OUT, repeats: int | None = None, quick: bool = False,
              progress: bool = True, results=DEFAULT_RESULTS, methods=None) -> dict:
    """Run the benchmark on ``suites`` (None: all of SUITE_NAMES; names or comma lists) and
    write bench.md, bench.json and the figures into ``out``. ``repeats`` (default 3, 1 with
    ``quick``) times every solve faster than REPEAT_BELOW_S that often; ``results``: the folder
    of the committed reports the seed tables compare with (default benchmarks/results relative
    to the current directory; the CLI's ``--results DIR``); ``methods``: the methods to run
    (None: every one of :func:`planner.bench.methods.method_names`). Returns the JSON dict."""
    names = parse_suites(suites)
    meths = select_methods(methods)
    settings = Settings.make(quick)
    repeats = (1 if quick else 3) if repeats is None else int(repeats)
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    t0 = _time.perf_counter()
    res = dict(benchmark="crane-planner bench", machine=machine_info(),
               settings=dict(suites=names, repeats=repeats, repeat_below_s=REPEAT_BELOW_S,
                             ok_tolerance=OK_TOL, **{k: v for k, v in vars(settings).items()}),
               suites={})
    if methods is not None:   # a partial run says which methods it ran
        res["settings"]["methods"] = meths
    keep = {}
    for name in names:
        r, kp, suite, crane = run_suite(name, settings, repeats, progress, meths)
        res["suites"][name] = r
        keep[name] = (kp, suite, crane)
    res["wall_time_s"] = _time.perf_counter() - t0
    res["acceptance"] = acceptance(res)
    write_outputs(res, keep, Path(out), t0, results)   # figures, then bench.md, bench.json
    return res


__all__ = ["run_bench", "run_suite", "parse_suites", "select_methods", "SUITE_NAMES",
           "DEFAULT_OUT", "DEFAULT_RESULTS"]
