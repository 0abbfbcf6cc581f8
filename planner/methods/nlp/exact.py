"""The exact jerk-limited move a minimum-time move NLP answers with when it is feasible
(:class:`~planner.methods.nlp.move.MoveNLP`, free path, objective "time").

Ruckig's rest-to-rest move between the ends (at the lower bound's best telescopes, or the given
joint ends) is the time-optimal move of the kinematic limits alone: every joint on its own
jerk-limited profile, synchronised to the slowest — the rest-to-rest bound of
:func:`~planner.bounds.lower_bound` at those ends. Where the pump and the obstacles let it
through (every limit of the NLP on a 1 kHz resampling, clear of every obstacle) it is feasible,
and then:

- **certified**: when its duration is the combined lower bound itself (rest to rest and pump,
  minimised over the telescopes on the fine search, :func:`certifying_bound`), no plan can be
  faster — the NLP is not solved at all (its equal intervals could only land up to about one
  interval slower; measured on 40 random moves per machine: 24 umea-lab and 33 s100f moves,
  where the NLP's 15–80 IPOPT iterations were thrown away);
- **swapped in**: otherwise (a Ruckig move above the bound: the guess's coarse telescopes,
  blocked intervals) the NLP is solved and the faster of the two is returned.

The move is kept at its switch times only: between them every joint is a cubic, which the
quintic interpolation reproduces exactly. Its limit check (:func:`limit_violation`: the
kinematic limits and the pump's draw from the stroke rates, evaluate()'s numbers without its
inverse dynamics and pressures) runs only where it decides something (:class:`ExactMove`): for
a certificate once the move lasts the bound, after the NLP once the move is faster than its
result (issue 31: the Python around the solver call).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.bounds import lower_bound
from planner.methods.base import PlanStatus
from planner.methods.nlp.transcription import nlp_result
from planner.model.flows import pump_draw
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["CERTIFY_REL", "ExactMove", "exact_move", "limit_violation", "feasible",
           "feasible_exact", "certified", "certifying_bound", "exact_result"]

CERTIFY_REL = 1e-4   # the exact move "attains" the bound within this relative margin (the
# fine search approaches the minimum from above by ~1e-5: planner.bounds)
LIMIT_TOL = 1e-4     # the largest limit violation (evaluate()'s measure) the exact move may have


def exact_move(nlp, start, goal, lb, q_ends=(None, None)) -> Trajectory | None:
    """The Ruckig rest-to-rest move of ``nlp`` (a :class:`~planner.methods.nlp.move.MoveNLP`)
    between ``start`` and ``goal`` at the telescopes of the lower bound ``lb`` (or the joint
    ends ``q_ends``) as a trajectory at its switch times, not checked against any limit (see
    :func:`feasible`); None for an unreachable end."""
    try:
        exact = nlp.guesses.plain_traj(start, goal, lb, q_ends)[1]
    except ValueError:
        return None
    ts = np.asarray(exact.meta["switch_times"])
    q, qd, qdd, _ = exact.sample(ts)
    kinds = ("position", "velocity", "acceleration", "jerk") + (
        ("pump_flow",) if nlp.pump else ())
    return Trajectory(ts, q, qd, qdd, joint_names=tuple(nlp.crane.names), method="nlp",
                      objective="time", limits=kinds,
                      meta=dict(N=nlp.N, path="free", winner="rest-to-rest (Ruckig)"))


def limit_violation(crane: Crane, tr: Trajectory, rate: float = 1000.0) -> float:
    """The largest relative excess over the limits ``tr.limits`` (position, velocity,
    acceleration, jerk, pump flow) on ``tr.resample(rate)``: evaluate()'s
    ``max_limit_violation`` for these kinds, computed without the rest of its judgement (no
    inverse dynamics, pressures or energy: the pump's draw from the stroke rates alone,
    :func:`~planner.model.flows.pump_draw`)."""
    t = tr.resample(rate)
    q, qd, qdd, qddd = tr.sample(t)
    L = crane.limit_arrays()
    kinds = set(tr.limits)
    worst = [0.0]
    if "position" in kinds:
        worst.append(np.max(np.maximum(q - L["q_max"], L["q_min"] - q)
                            / (L["q_max"] - L["q_min"])))
    if "velocity" in kinds:
        worst.append(np.max(np.maximum(qd / L["qd_max"], qd / L["qd_min"])) - 1.0)
    if "acceleration" in kinds:
        worst.append(np.max(np.abs(qdd) / L["qdd_max"]) - 1.0)
    has_jerk = np.isfinite(L["qddd_max"])
    if "jerk" in kinds and has_jerk.any():
        worst.append(np.max(np.abs(qddd[:, has_jerk]) / L["qddd_max"][has_jerk]) - 1.0)
    if "pump_flow" in kinds:
        _, dxdq = crane.stroke(q)
        draw = pump_draw(crane.spec, dxdq * qd).sum(axis=-1)
        worst.append(np.max(draw) / crane.spec.pump.max_flow - 1.0)
    return float(max(worst))


def feasible(nlp, tr: Trajectory | None) -> bool:
    """Whether the exact move ``tr`` (:func:`exact_move`) keeps every limit of the NLP (its
    pump too) on a 1 kHz resampling (within :data:`LIMIT_TOL`) and clears the NLP's obstacles.
    Its switch times first (a rate of ~0 samples them only): the 1 kHz resampling contains
    them, so a violation there rejects the move as the full check would, for a fraction of its
    cost (a move the pump limits draws the most at a switch)."""
    if tr is None:
        return False
    for rate in (1e-9, 1000.0):
        if limit_violation(nlp.crane, tr, rate) > LIMIT_TOL:
            return False
    return not (nlp.obstacles and not nlp.clears(tr))


def feasible_exact(nlp, start, goal, lb, q_ends=(None, None)) -> Trajectory | None:
    """The exact move (:func:`exact_move`) when it is :func:`feasible`, else None (also for an
    unreachable end)."""
    tr = exact_move(nlp, start, goal, lb, q_ends)
    return tr if feasible(nlp, tr) else None


class ExactMove:
    """The exact move of one solve (a :func:`exact_move` trajectory, or None) whose limit check
    (:func:`feasible`) runs at most once, and only when it decides something: a certificate
    needs it only for a move that lasts the bound, the swap after the NLP only for a move
    faster than the NLP's (the decisions are those of checking it up front)."""

    def __init__(self, nlp, tr: Trajectory | None):
        self.nlp, self.tr, self._ok = nlp, tr, None

    def feasible(self) -> bool:
        if self._ok is None:
            self._ok = feasible(self.nlp, self.tr)
        return self._ok

    def faster_than(self, duration_s: float) -> bool:
        """Whether the move exists and is faster than ``duration_s`` (by more than 1e-6)."""
        return self.tr is not None and self.tr.duration < duration_s * (1 - 1e-6)


def certified(exact: Trajectory | None, lb) -> bool:
    """True when the exact move ``exact`` lasts no longer than the combined lower bound
    ``lb.combined_s`` (within :data:`CERTIFY_REL`): when it is also :func:`feasible`, no move
    can be faster — when ``lb`` comes from the fine telescope search
    (:func:`certifying_bound`)."""
    return exact is not None and exact.duration <= lb.combined_s * (1 + CERTIFY_REL)


def certifying_bound(crane: Crane, start, goal, q_ends=(None, None)):
    """The combined lower bound on :func:`~planner.bounds.lower_bound`'s default (fine)
    telescope search, what a certificate is checked against. The guess's coarse search
    (:data:`~planner.methods.nlp.guess.GUESS_BOUND`) can miss a basin: on one of 40 random
    umea-lab moves it stopped 0.28 % above the fine bound, and the NLP found a move 0.065 %
    faster than the exact move at its telescopes."""
    qs, qg = q_ends
    return lower_bound(crane, None if qs is not None else start,
                       None if qg is not None else goal, q_start=qs, q_goal=qg,
                       combined_only=True)


def exact_result(exact: Trajectory, res, t0: float, now: float):
    """The result returning the feasible exact move ``exact`` instead of the NLP's result
    ``res`` (None: the NLP was not solved, the move being certified); ``t0``/``now`` the
    solve's start and the current ``time.perf_counter()``."""
    tr = Trajectory(exact.t, exact.q, exact.qd, exact.qdd, joint_names=exact.joint_names,
                    method=exact.method, objective=exact.objective, limits=exact.limits,
                    meta=dict(exact.meta))
    if res is None:
        tr.meta["nlp"] = "not solved: the move attains the lower bound"
        return nlp_result(PlanStatus.OK, trajectory=tr, duration_s=tr.duration,
                          stats=dict(winner="ruckig", certified=True),
                          solve_time_s=now - t0)
    tr.meta["nlp"] = f"{res.duration_s:.4f} s" if res.ok else res.status
    return nlp_result(PlanStatus.OK, trajectory=tr, duration_s=tr.duration,
                      iterations=res.iterations, ipopt_status=res.ipopt_status,
                      stats=dict(winner="ruckig", solver=res.stats.get("solver"),
                                 nlp_duration_s=res.duration_s if res.ok else float("nan")),
                      solve_time_s=now - t0)
