"""The benchmark's runners for point-to-point and path suites: ``f(ctx, move) -> Outcome``.

Methods are called through the registry (:func:`planner.methods.registry.plan` with a
:class:`~planner.methods.base.PlanRequest`) wherever the request says all a variant needs:
:func:`generic_runner` (every registered method outside the named variants, and ``ruckig``)
and the laws on a straight line. The other variants need settings a request does not carry (the
seed's DP stage count, curved tip paths, NLPs with their own limit sets and IPOPT caps, chained
sections) and call the method's functions directly. A runner may use ``evaluate()`` to choose
among its own candidates (as ``topp:law`` does); the verdict comes only from
:mod:`planner.bench.run`, which evaluates every piece again. Each runner is self-contained
(``topp:dp`` runs its DP), so its wall time is the method's whole cost; only NLP construction
(``Ctx.nlp``) is excluded and reported separately.
"""
from __future__ import annotations

from planner.bench.context import BASE_KINDS, Outcome, outcome_of
from planner.methods.base import PlanRequest, PlanStatus
from planner.methods.dp import dp
from planner.methods.laws import LAWS, follow, follow_command
from planner.methods.laws_energy import LAWS_ENERGY
from planner.methods.nlp import energy_optimal, kinematic_line_nlp
from planner.methods.registry import get, plan
from planner.methods.topp import retime
from planner.tasks.cycles import START, START_TELE, cycle
from planner.trajectory import evaluate

__all__ = ["generic_request", "generic_runner", "fit", "law_runner", "ruckig", "dp_time",
           "topp_dp", "topp_law", "nlp_time_free", "nlp_time_free_kin", "nlp_time_free_acc",
           "nlp_time_path", "nlp_energy_free", "nlp_kin_line"]


# ------------------------------------------------------------------------------ the registry
def fit(name: str, suite) -> str | None:
    """The path kind ("free" or "line") the registered method ``name`` plans this suite's
    moves with, or the reason (a sentence starting with a lower-case word) why it does not
    fit: timed cycles and curved tip paths are no single point-to-point request; a suite whose
    path-following methods leave the straight line (``[bench] path``) takes free-path methods
    only; obstacles need a method that keeps clear of them; the bench plans minimum time."""
    p = get(name)
    paths = "/".join(p.paths)
    if any(m.cycle for m in suite.moves):
        return (f"timed cycle: the registry's plan() takes single rest-to-rest moves; {name} "
                "has no cycle runner")
    curved = {getattr(m.path, "name", "path") for m in suite.moves if m.path is not None}
    if curved and suite.path == "line":
        return (f"path suite: the tip must stay on the {' / '.join(sorted(curved))}; {name} "
                f"plans {paths} paths")
    if "time" not in p.objectives:
        return f"{name} plans {' or '.join(p.objectives)}; the bench plans minimum time"
    if suite.obstacles and not p.obstacles:
        return f"{name} does not keep clear of obstacles (the suite has {len(suite.obstacles)})"
    kinds = ("free", "line") if suite.path == "line" else ("free",)
    ok = [k for k in (p.default_path,) + tuple(p.paths) if k in kinds]
    if not ok:
        return (f"{name} plans {paths} paths; the suite's tip path is {suite.path} "
                "(r, z, slew over the obstacles' via points), not the straight line")
    return ok[0]


def generic_request(ctx, move, name: str, path: str) -> PlanRequest:
    """The request the bench gives a registered method: minimum time from rest to rest,
    ``path``, the suite's obstacles when the method keeps clear of them, the laws' tip speed
    when it reads one, and the options ``rate`` (the laws' control rate) and ``intervals``
    (the NLP's N)."""
    p, s = get(name), ctx.settings
    return PlanRequest(move.start, move.goal, objective="time", path=path,
                       obstacles=ctx.obstacles if p.obstacles else (),
                       tip_speed=s.law_speed if p.uses_tip_speed else None,
                       options=dict(rate=s.law_rate, intervals=s.nlp_N))


def generic_runner(name: str, path: str):
    """Runner planning every move with the registered method ``name`` on ``path``."""
    def run(ctx, move):
        return outcome_of(plan(ctx.crane, generic_request(ctx, move, name, path), name))
    run.__name__ = f"generic_{name}"
    return run


# ------------------------------------------------------------------------------ local laws
def law_runner(name: str):
    """Runner of the law ``name``: on a straight line through the registry (``law:NAME`` at
    the laws' tip speed and rate), along any other path with ``follow``, on a cycle's clock
    with ``follow_command``."""
    cls = {**LAWS, **LAWS_ENERGY}[name]

    def run(ctx, move):
        s, crane = ctx.settings, ctx.crane
        if move.cycle:
            cmd, dur, _ = cycle(*move.cycle)
            c = move.cycle[0]
            res = follow_command(crane, cls(), cmd, dur, q0=crane.ik(START[c], tele=START_TELE[c]),
                                 rate=s.law_rate)
        elif move.path is None:   # the straight line
            res = plan(crane, PlanRequest(move.start, move.goal, path="line",
                                          tip_speed=s.law_speed, options=dict(rate=s.law_rate)),
                       f"law:{name}")
        else:
            res = follow(crane, move.path, cls(), s.law_speed, rate=s.law_rate)
        return outcome_of(res, min_beta=res.min_beta, max_tracking_error_m=res.max_path_error_m)
    run.__name__ = f"law_{name}"
    return run


# ------------------------------------------------------------------------------ Ruckig, DP, TOPP
def ruckig(ctx, move):
    """Rest-to-rest joint move between the ends at the lower bound's best telescope values
    (the registry's ``ruckig``; it ignores obstacles, the bench judges the clearance)."""
    return outcome_of(plan(ctx.crane, PlanRequest(move.start, move.goal, path="free"), "ruckig"))


def _dp(ctx, move):
    return dp(ctx.crane, move.line_or_path(), **ctx.suite.dp_kw(move))


def dp_time(ctx, move):
    r = _dp(ctx, move)
    return outcome_of(r, grid=r.grid)


def topp_dp(ctx, move):
    d = _dp(ctx, move)
    if not d.ok:
        return Outcome(d.status, f"DP: {d.reason}")
    return outcome_of(retime(ctx.crane, d.path_q))


def topp_law(ctx, move):
    """Every local law's joint path made feasible under the spec's limits: TOPP-RA rest to rest
    (velocity, acceleration, pump) on each law's path; the fastest that evaluate() passes wins.
    ``info["per_law_s"]`` holds each law's retimed duration (or why it has none)."""
    best, per = None, {}
    for name in ctx.suite.laws:   # the law variants this suite runs (max_lift needs a table)
        r = law_runner(name)(ctx, move)
        if not r.ok:
            per[name] = f"law: {r.status}"
            continue
        t = retime(ctx.crane, r.pieces[0][1].q)
        if not t.ok:
            per[name] = f"TOPP-RA: {t.status}"
            continue
        tr = t.trajectory
        ev = evaluate(ctx.crane, tr, kinds=tuple(dict.fromkeys(tuple(tr.limits) + BASE_KINDS)))
        if ev.max_limit_violation > 1e-3:
            per[name] = f"exceeds limits by {100 * ev.max_limit_violation:.2f} %"
            continue
        per[name] = t.trajectory.duration
        if best is None or t.trajectory.duration < best[1].trajectory.duration:
            best = (name, t)
    if best is None:
        return Outcome(PlanStatus.INFEASIBLE, "no law path could be retimed: " + "; ".join(
            f"{k}: {v}" for k, v in per.items()), info=dict(per_law_s=per))
    return outcome_of(best[1], law=best[0], per_law_s=per)


# ------------------------------------------------------------------------------ NLPs
def _winner_note(res, out):
    if out.ok and res.stats.get("winner") == "ruckig":
        out.info["winner"] = "ruckig"
        out.notes.append("the exact jerk-limited Ruckig move: feasible and faster than the "
                         f"N-interval solution ({res.trajectory.meta.get('nlp')})")
    return out


def nlp_time_free(ctx, move):
    res = ctx.nlp("time", "free", ctx.settings.nlp_N).solve(move.start, move.goal)
    return _winner_note(res, outcome_of(res))


def nlp_time_free_kin(ctx, move):
    res = ctx.nlp("time", "free", ctx.settings.nlp_N, kin=True).solve(move.start, move.goal)
    out = _winner_note(res, outcome_of(res))
    if out.ok:  # judged against the real crane on the laws' limit set
        out.pieces[0][1].limits = BASE_KINDS
        out.notes.append(f"acceleration and jerk limits ×{ctx.settings.kin_factor:g} (seed 000 "
                         "is kinematic); judged on position, velocity and pump flow like the laws")
    return out


def nlp_time_free_acc(ctx, move):
    """The free-path minimum-time NLP without a jerk limit: TOPP-RA's limit set (velocity,
    acceleration, pump), to compare with ``topp:law`` on equal limits."""
    res = ctx.nlp("time", "free", ctx.settings.nlp_N, acc=True).solve(move.start, move.goal)
    out = _winner_note(res, outcome_of(res))
    if out.ok:
        out.pieces[0][1].limits = ("position", "velocity", "acceleration", "pump_flow")
        out.notes.append("no jerk limit (TOPP-RA's limit set)")
    return out


def nlp_time_path(ctx, move):
    s = ctx.settings
    if move.path is None:
        nlp = ctx.nlp("time", "line", s.nlp_N)
        return outcome_of(nlp.solve(move.start, move.goal))
    nlp = ctx.nlp("time", move.path, s.curve_N, key=f"curve:{move.id}")
    return outcome_of(nlp.solve())


def nlp_energy_free(ctx, move):
    s = ctx.settings
    rt = ctx.nlp("time", "free", s.nlp_N).solve(move.start, move.goal)
    if not rt.ok:
        return Outcome(rt.status, f"time-optimal NLP: {rt.reason}")
    res, info = energy_optimal(ctx.crane, move.start, move.goal, s.energy_budget * rt.duration_s,
                               time_result=rt, energy_nlp=ctx.nlp("energy", "free", s.nlp_N))
    return outcome_of(res, winner=info.get("winner"), minimum_time_s=rt.duration_s)


def nlp_kin_line(ctx, move):
    return outcome_of(kinematic_line_nlp(ctx.crane, move.start, move.goal))
