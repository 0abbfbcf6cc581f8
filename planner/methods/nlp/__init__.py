"""Point-to-point moves as CasADi NLPs (IPOPT), built once and solved many times, and the
``nlp`` planner.

- :mod:`~planner.methods.nlp.transcription`: the variable/constraint/parameter layout
  (:class:`Layout`) and IPOPT's status as a result code;
- :mod:`~planner.methods.nlp.move`: :class:`MoveNLP` (minimum time, least energy or a blend;
  free path, tip line or a curve; obstacles); :mod:`~planner.methods.nlp.exact`: the
  exact-Ruckig move it returns when feasible and faster, without solving the NLP when that move
  lasts the lower bound;
- :mod:`~planner.methods.nlp.limits`: its velocity check with each interval's own jerk and
  the smooth conservative pump draw; :mod:`~planner.methods.nlp.tip`: its tip constraints
  (obstacles, line, curve); :mod:`~planner.methods.nlp.stagewise`: the FATROP solver on the
  stage-ordered problem (``MoveNLP(solver="auto" | "ipopt" | "fatrop")``);
- :mod:`~planner.methods.nlp.guess`: its warm starts (and :func:`stretch`);
  :mod:`~planner.methods.nlp.activity`: the load-sensing activity mask of its energy rounds;
  :mod:`~planner.methods.nlp.twins`: the same NLP under other solver settings;
  :mod:`~planner.methods.nlp.pump`: its pump rows and pump energy — collaborators that
  MoveNLP holds and gives what they use (its layout, bounds, crane, options);
- :mod:`~planner.methods.nlp.energy`: :func:`energy_optimal`, :func:`pareto_front`;
- :mod:`~planner.methods.nlp.kinematic`: :func:`kinematic_line_nlp` (seed 000's setting).

:class:`NLPPlanner` is registered as ``nlp`` when this package is imported. A minimum-time
move whose chambers would pass the relief pressure less the LS margin (:func:`relief_excess`)
is solved again with :func:`~planner.methods.nlp.limits.add_relief_rows` (stats ``relief``).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time
from dataclasses import replace

import numpy as np

from planner.geometry.obstacles import Plate, Wall
from planner.methods.base import (Planner, PlanRequest, PlanResult, PlanStatus,
                                  UnsupportedRequest)
from planner.methods.nlp.energy import energy_optimal, pareto_front
from planner.methods.nlp.guess import stretch
from planner.methods.nlp.kinematic import kinematic_line_nlp
from planner.methods.nlp.limits import relief_limit
from planner.methods.nlp.move import MoveNLP
from planner.methods.nlp.transcription import STATUS_OK, Layout
from planner.methods.registry import register
from planner.trajectory import evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["MoveNLP", "Layout", "energy_optimal", "pareto_front", "stretch",
           "kinematic_line_nlp", "OBSTACLE_TYPES", "Wall", "Plate", "STATUS_OK", "NLPPlanner",
           "relief_excess"]

OBSTACLE_TYPES = (Wall, Plate)   # the obstacles MoveNLP accepts (re-exported here)
RELIEF_AUDIT = 1e-3     # the limit excess a relieved move may keep (the library build's audit)
RELIEF_STRETCHES = 3    # uniform slow-downs tried when it keeps more


class NLPPlanner(Planner):
    """``nlp``: the CasADi/IPOPT move NLP (:class:`MoveNLP`), minimum time or least pump energy
    within ``duration`` (required for energy; free path: :func:`energy_optimal`, never above the
    time-optimal move's energy), free path or on the tip line, clear of the request's
    obstacles. Options: ``intervals`` (N, 40); ``time_result`` (energy: the time-optimal
    result of the same move, reused instead of solved again); ``nlp_cache`` (off | use | build,
    default ``$CRANE_PLANNER_NLP_CACHE`` or use: :mod:`planner.methods.nlp.cache`). Each NLP is
    built once per (machine, objective, path, N, obstacles) in this process and solved many
    times; across processes the compiled cache serves it. Stats ``build_time_s`` (the builds
    this call paid, 0 when reused) and ``nlp_cache`` (hit, miss, stored, off, …)."""
    name = "nlp"
    description = "CasADi/IPOPT NLP: time or energy, free path or tip line, obstacles"
    objectives = ("time", "energy")
    paths = ("free", "line")
    obstacles = True
    uses_duration = ("energy",)   # the time objective has no duration to honour

    def __init__(self):
        self._built: dict = {}

    def check(self, request: PlanRequest) -> None:
        super().check(request)
        if request.objective == "energy" and request.duration is None:
            raise UnsupportedRequest("`method` nlp with `objective` energy needs `duration` "
                                     "[s] (e.g. 1.2 × the minimum time)")

    def built(self, crane: Crane, objective: str, path: str = "free", N: int = 40,
              obstacles: tuple = (), cache: str | None = None, paid: list | None = None,
              relief: bool = False) -> MoveNLP:
        """The MoveNLP for this formulation, built (or loaded from the disk cache) on first use
        and kept for the process; a new build appends itself to ``paid``."""
        # keyed by the crane object (kept alive with its NLP, so its id is never reused):
        # variants of one machine with other limits share the spec id but not the NLP
        key = (id(crane), objective, path, int(N), tuple(obstacles), bool(relief))
        if key not in self._built:
            nlp = MoveNLP(crane, objective, path, N=N, obstacles=tuple(obstacles), cache=cache,
                          relief=relief)
            self._built[key] = (crane, nlp)
            if paid is not None:
                paid.append(nlp)
        return self._built[key][1]

    def prepare(self, crane: Crane, request: PlanRequest, compile: bool = False) -> float:
        """Build the NLPs ``request`` needs (``compile``: into the per-user cache, so worker
        processes load them instead of building their own). Returns the seconds it took."""
        N, obs, paid = request.option("intervals", 40), request.obstacles, []
        cache = "build" if compile else request.option("nlp_cache")
        objectives = ("time", "energy") if request.objective == "energy" else ("time",)
        path = request.path if request.objective == "time" else "free"
        for o in objectives:
            self.built(crane, o, path, N, obs, cache, paid)
        for n in paid:
            n.build_twins()   # adds its seconds to the NLP's build_time_s
        return sum(n.build_time_s for n in paid)

    def library_request(self, crane: Crane, move, objective: str, *, time_result=None,
                        settings) -> PlanRequest:
        """The plain library request (:meth:`Planner.library_request`) with the NLP's own
        options: ``intervals`` (``settings.intervals``) and, for an entry after the move's
        minimum-time one, ``time_result`` (the energy NLP's warm start and incumbent, reused
        instead of solved again)."""
        req = super().library_request(crane, move, objective, time_result=time_result,
                                      settings=settings)
        return replace(req, options=dict(req.options, intervals=settings.intervals,
                                         time_result=time_result, energy_judge="twin"))

    def clear(self) -> None:
        """Forget the NLPs built in this process (a timed build then starts from scratch)."""
        self._built.clear()

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        N = request.option("intervals", 40)
        obs = request.obstacles
        cache, paid = request.option("nlp_cache"), []
        if request.objective == "energy" and request.path == "free":
            time_nlp = self.built(crane, "time", "free", N, obs, cache, paid)
            energy_nlp = self.built(crane, "energy", "free", N, obs, cache, paid)
            time_result = request.option("time_result")
            if time_result is None:   # the minimum time within the relief, as for "time"
                time_result = self._within_relief(
                    crane, request, time_nlp.solve(request.start, request.goal), "free", N,
                    obs, cache, paid)
            res, info = energy_optimal(crane, request.start, request.goal, request.duration,
                                       time_result=time_result,
                                       time_nlp=time_nlp, energy_nlp=energy_nlp,
                                       judge=request.option("energy_judge", "evaluate"))
            res.stats["energy_winner"] = info.get("winner")
            res.stats["energy_judge"] = info.get("judge")
            main = energy_nlp
        else:
            main = self.built(crane, request.objective, request.path, N, obs, cache, paid)
            res = main.solve(request.start, request.goal, T_max=request.duration)
            if request.objective == "time":
                res = self._within_relief(crane, request, res, request.path, N, obs, cache,
                                          paid)
        res.stats.update(build_time_s=sum(n.build_time_s for n in paid),
                         nlp_cache=main.cache_status)
        return res

    def _within_relief(self, crane: Crane, request: PlanRequest, res: PlanResult, path: str,
                       N: int, obs, cache, paid) -> PlanResult:
        """The minimum-time result ``res`` when it asks no chamber for more than
        :func:`~planner.methods.nlp.limits.relief_limit` (:func:`relief_excess`); else the
        move solved again with the relief rows (:func:`~planner.methods.nlp.limits.add_relief_rows`), warm from ``res``
        slowed by √(1 + excess). Most moves of most machines never reach the relief, so the
        rows (an inverse dynamics per node) are paid only by the moves that need them.
        Stats ``relief``: the excess before and after, and whether the move was solved again.
        A relieved solve that fails gives status "limits" with both reasons."""
        if not res.ok or not math.isfinite(relief_limit(crane.spec)):
            return res
        over = relief_excess(crane, res.trajectory)
        if over <= 0.0:
            return res
        nlp = self.built(crane, "time", path, N, obs, cache, paid, relief=True)
        t0 = time.perf_counter()
        w0 = nlp.guess_from(stretch(res.trajectory, res.duration_s * math.sqrt(1.0 + over)))
        res2 = nlp.solve(request.start, request.goal, w0=w0)
        info = dict(excess_before=over, resolved=True, stretched_by=1.0)
        if res2.ok:
            # between its check points the relieved move can overshoot the pump limit by a few
            # per cent (cat215b: up to 4.3 % where a joint reverses at the end); slowed
            # uniformly, every draw falls by the factor and the inertial pressures with it
            for _ in range(RELIEF_STRETCHES):
                worst = evaluate(crane, res2.trajectory).max_limit_violation
                if worst <= RELIEF_AUDIT:
                    break
                k = 1.0 + 1.05 * worst
                tr = res2.trajectory
                res2.trajectory = replace(stretch(tr, tr.duration * k), objective=tr.objective,
                                          meta=dict(tr.meta, relief_stretch=info[
                                              "stretched_by"] * k))
                res2.duration_s = res2.trajectory.duration
                info["stretched_by"] *= k
            info["excess_after"] = relief_excess(crane, res2.trajectory)
        info["solve_time_s"] = time.perf_counter() - t0
        if not res2.ok:
            p_lim = relief_limit(crane.spec)
            out = PlanResult(PlanStatus.LIMITS,
                             f"the minimum-time move asks a chamber for {1 + over:.2f} × the "
                             f"relief pressure less the LS margin ({p_lim / 1e5:.0f} bar); "
                             f"solved again within it: {res2.reason}", None)
            out.stats.update(res.stats, relief=info)
            return out
        res2.solve_time_s = (res.solve_time_s or 0.0) + (res2.solve_time_s or 0.0)
        res2.stats["relief"] = info
        return res2


def relief_excess(crane: Crane, traj, rate: float = 200.0) -> float:
    """How far the highest chamber pressure of ``traj`` (evaluate()'s hydraulics at ``rate``
    [Hz]) rises above :func:`~planner.methods.nlp.limits.relief_limit`, as a fraction of it (0
    when below): above it the meter-in compensator starves and the machine lags the plan."""
    p_lim = relief_limit(crane.spec)
    if not math.isfinite(p_lim):
        return 0.0
    hyd = evaluate(crane, traj, rate=rate).hyd
    return max(0.0, float(np.max(np.maximum(hyd["p_a"], hyd["p_b"]))) / p_lim - 1.0)


register(NLPPlanner())
