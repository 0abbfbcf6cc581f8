"""Least pump energy and the time–energy trade-off on top of the move NLP.

:func:`energy_optimal` (least energy within a time budget, never above the time-optimal
move's energy) and :func:`pareto_front` (the budgets k·T_min) judge every candidate with
:func:`~planner.trajectory.evaluate`; :func:`stretch` (a move slowed uniformly) gives the
always-feasible incumbents and the warm starts.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time as _time

from planner.methods.base import PlanResult, PlanStatus
from planner.methods.nlp.guess import stretch
from planner.methods.nlp.move import MoveNLP
from planner.methods.nlp.transcription import nlp_result
from planner.trajectory import evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["energy_optimal", "pareto_front", "stretch"]


def pareto_front(crane: Crane, start, goal, factors=(1.0, 1.1, 1.2, 1.5, 2.0), N: int = 40,
                 time_nlp: MoveNLP | None = None, energy_nlp: MoveNLP | None = None):
    """Time–energy trade-off: the minimum time T_min, then the least pump energy with a time
    budget T ≤ k·T_min for each factor k. Each point is the best candidate within the limits
    (judged by evaluate()): the energy NLP warm-started from the previous point stretched to the
    budget, or the previous point itself (it meets any larger budget) — so the front is
    non-increasing by construction, as min-energy-under-a-budget must be. Returns a list of
    (duration [s], pump energy [J], PlanResult, source) with source "nlp" or "carried"."""
    tn = time_nlp or MoveNLP(crane, "time", "free", N=N)
    en = energy_nlp or MoveNLP(crane, "energy", "free", N=N)
    rt = tn.solve(start, goal)
    if not rt.ok:
        return [(float("nan"), float("nan"), rt, "failed")]
    best = (evaluate(crane, rt.trajectory).energy_J, rt)
    out = [(rt.duration_s, best[0], rt, "nlp")]
    for k in factors:
        if k <= 1.0:
            continue
        T = k * rt.duration_s
        src = "carried"
        r = en.solve(start, goal, T_max=T, w0=en.guess_from(stretch(best[1].trajectory, T)))
        if r.ok:
            ev = evaluate(crane, r.trajectory)
            if ev.max_limit_violation <= 1e-3 and ev.energy_J < best[0]:
                best, src = (ev.energy_J, r), "nlp"
        out.append((best[1].duration_s, best[0], best[1], src))
    return out


def energy_optimal(crane: Crane, start, goal, T_max: float, *,
                   time_result: PlanResult | None = None,
                   time_nlp: MoveNLP | None = None, energy_nlp: MoveNLP | None = None,
                   N: int = 40) -> tuple[PlanResult, dict]:
    """Least pump energy with duration ≤ T_max: the energy NLP warm-started from the
    time-optimal move stretched to T_max (and, if that does not converge to a move within the
    limits, from the Ruckig guess),
    judged by evaluate() against two always-feasible
    incumbents — that stretched move and the time-optimal move itself (T_min ≤ T_max); the lowest
    judged energy within the limits wins, so the result never costs more than the time-optimal
    move. With obstacles (``energy_nlp`` built with them) every NLP result must clear them on a
    fine resampling; the incumbents inherit the time-optimal move's clearance (stretching keeps
    the path). Returns (result, info), info["winner"] in {"nlp", "stretched", "time_optimal"}."""
    t0 = _time.perf_counter()
    rt = time_result or (time_nlp or MoveNLP(crane, "time", "free", N=N)).solve(start, goal)
    if not rt.ok:
        return rt, dict(winner=None)
    if T_max < rt.duration_s * (1 - 1e-9):
        return nlp_result(PlanStatus.INFEASIBLE, f"T_max = {T_max:.3f} s is below the minimum time "
                            f"{rt.duration_s:.3f} s"), dict(winner=None)
    en = energy_nlp or MoveNLP(crane, "energy", "free", N=N)
    inc = stretch(rt.trajectory, T_max)
    e_inc = evaluate(crane, inc)
    best = (e_inc.energy_J, nlp_result(PlanStatus.OK, trajectory=inc, duration_s=T_max),
            "stretched")
    e_t = evaluate(crane, rt.trajectory).energy_J
    if e_t < best[0]:
        best = (e_t, rt, "time_optimal")
    tries = []

    def consider(r):
        nonlocal best
        if r.ok and en.obstacles and not en.clears(r.trajectory):
            r = nlp_result(PlanStatus.OBSTACLE, "passes through an obstacle between check points")
        status = r.status
        if r.ok:
            ev = evaluate(crane, r.trajectory)
            if ev.max_limit_violation > 1e-3:
                status = PlanStatus.LIMITS  # converged, but a limit broken between check points
            elif ev.energy_J < best[0]:
                best = (ev.energy_J, r, "nlp")
        tries.append(status)

    consider(en.solve(start, goal, T_max=T_max, w0=en.guess_from(inc)))
    if tries[-1] != PlanStatus.OK:  # a second start from the independent Ruckig guess
        # (only when the first did not converge to a clear, within-limit move: on 36 forwarder
        # moves a converged first start that lost to the incumbents was never beaten by it)
        consider(en.solve(start, goal, T_max=T_max))
    res = best[1]
    res.solve_time_s = _time.perf_counter() - t0
    return res, dict(winner=best[2], energy_J=best[0], stretched_energy_J=e_inc.energy_J,
                     nlp_status=tries)
