"""Least pump energy and the time–energy trade-off on top of the move NLP.

:func:`energy_optimal` (least energy within a time budget, never above the time-optimal
move's energy) and :func:`pareto_front` (the budgets k·T_min) judge every candidate with
:func:`~planner.trajectory.evaluate` (``energy_optimal(judge="twin")``, as the library builder
asks: then by the dynamic twin's pump energy, :mod:`planner.methods.nlp.twin_judge`);
:func:`stretch` (a move slowed uniformly) gives the always-feasible incumbents and the warm
starts. :func:`hold_creep` re-solves the energy NLP with the functions its move creeps along
held still (:mod:`planner.methods.nlp.idle`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time as _time

import numpy as np

from planner.methods.base import PlanResult, PlanStatus
from planner.methods.nlp.guess import stretch
from planner.methods.nlp.idle import creep_nodes, pinned
from planner.methods.nlp.move import MoveNLP
from planner.methods.nlp.transcription import nlp_result
from planner.methods.nlp.twin_judge import has_twin, twin_pump_energy
from planner.model.twin import Twin
from planner.trajectory import evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["JUDGES", "energy_optimal", "hold_creep", "pareto_front", "stretch"]

#: the prices energy_optimal can compare its candidates under (see its doc)
JUDGES = ("evaluate", "twin")


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
                   N: int = 40, judge: str = "evaluate") -> tuple[PlanResult, dict]:
    """Least pump energy with duration ≤ T_max: the energy NLP warm-started from the
    time-optimal move stretched to T_max (and, if that does not converge to a move within the
    limits, from the Ruckig guess),
    judged by evaluate() against two always-feasible
    incumbents — that stretched move and the time-optimal move itself (T_min ≤ T_max); the lowest
    judged energy within the limits wins, so the result never costs more than the time-optimal
    move. With obstacles (``energy_nlp`` built with them) every NLP result must clear them on a
    fine resampling; the incumbents inherit the time-optimal move's clearance (stretching keeps
    the path). Then the creep of the NLP's move (:mod:`planner.methods.nlp.idle`: functions
    carried along below a useful valve opening, which the machine's load-sensing pump and
    ``evaluate()`` charge their holding pressure for) is held still and the NLP solved again
    from that move, up to ``HOLD_ROUNDS`` times while new creep appears; the held moves compete
    as "nlp" under the same judge. ``judge`` = "twin" (where the crane has one,
    :func:`planner.methods.nlp.twin_judge.has_twin`): the candidates within the limits are
    then compared once more by the dynamic twin's pump energy of their feed-forward
    (:mod:`planner.methods.nlp.twin_judge`: the oil spring's ringing, which the quasi-static
    price cannot see) and the cheapest there wins — so the result never costs the twin more
    than the time-optimal move; info["judge"] says which price chose, info["twin_J"] the
    twin's figure per candidate. Returns (result, info), info["winner"] in {"nlp",
    "stretched", "time_optimal"}, info["energy_J"] the winner's ``evaluate()`` energy,
    info["held"] the node-joints held still in the last round (0: none)."""
    if judge not in JUDGES:
        raise ValueError(f"judge: {judge!r} is not a judge; allowed: {', '.join(JUDGES)}")
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
    cands = [best, (e_t, rt, "time_optimal")]
    if e_t < best[0]:
        best = cands[1]
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
            else:
                cands.append((ev.energy_J, r, "nlp"))
                if ev.energy_J < best[0]:
                    best = cands[-1]
        tries.append(status)
        return r if status == PlanStatus.OK else None

    moved = consider(en.solve(start, goal, T_max=T_max, w0=en.guess_from(inc)))
    if moved is None:  # a second start from the independent Ruckig guess
        # (only when the first did not converge to a clear, within-limit move: on 36 forwarder
        # moves a converged first start that lost to the incumbents was never beaten by it)
        moved = consider(en.solve(start, goal, T_max=T_max))
    held = hold_creep(crane, en, moved, start, goal, T_max, consider)
    info = dict(judge="evaluate")
    if judge == "twin" and has_twin(crane):
        tw = Twin(crane)
        priced = [(twin_pump_energy(crane, c[1].trajectory, twin=tw), k)
                  for k, c in enumerate(cands)]
        ok = [(w, k) for w, k in priced if w is not None]
        if ok:
            best = cands[min(ok)[1]]
            info = dict(judge="twin", twin_J=[(cands[k][2], w) for w, k in priced])
    res = best[1]
    res.solve_time_s = _time.perf_counter() - t0
    return res, dict(winner=best[2], energy_J=best[0], stretched_energy_J=e_inc.energy_J,
                     nlp_status=tries, held=held, **info)


HOLD_ROUNDS = 2  # solves with the creep held still (each one from the move before)


def hold_creep(crane: Crane, en: MoveNLP, r, start, goal, T_max: float, consider) -> int:
    """Solve ``en`` again with the creeping joints of its move ``r`` (a result on the NLP's
    nodes, or None) held still — the union of every round's creep, each round warm-started
    from the move before — while new creep appears; ``consider`` (the caller's judge) takes
    each result and returns it when usable, else None. Returns the node-joints held in the
    last round (0: the move did not creep, or there was none)."""
    idle = None
    for _ in range(HOLD_ROUNDS):
        if r is None or len(r.trajectory.t) != en.N + 1:
            break
        new = creep_nodes(crane, r.trajectory.q, r.trajectory.qd)
        if not np.any(new & ~idle if idle is not None else new):
            break
        idle = new if idle is None else (idle | new)
        with pinned(en, idle, en.guess_from(r.trajectory)) as w0:
            r = consider(en.solve(start, goal, T_max=T_max, w0=w0))
    return 0 if idle is None else int(idle.sum())
