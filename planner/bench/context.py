"""The benchmark's shared pieces: :class:`Settings`, the runners' :class:`Outcome` and the
per-suite context :class:`Ctx` (the crane, its limit variants, the NLPs built once).

A runner ``f(ctx, move) -> Outcome`` plans one move of a suite with one method: status "ok"
with the trajectory pieces ``[(t0 [s], Trajectory)]`` (one piece for a move, one per section
for a timed seed-002 cycle), or a failure status with its reason.
"""
from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass, field

from planner.methods.base import PlanStatus
from planner.methods.nlp import MoveNLP
from planner.model import Crane

BASE_KINDS = ("position", "velocity", "pump_flow")  # every method is judged on at least these


@dataclass(frozen=True)
class Settings:
    """Benchmark settings (SI). ``quick``: smaller grids, fewer moves, shorter IPOPT caps."""
    quick: bool = False
    law_speed: float = 2.5        # [m/s] commanded tip speed of the laws (seed 000 Table 8.2)
    law_rate: float = 100.0       # [Hz] control rate of the laws
    nlp_N: int = 40               # MoveNLP intervals (free path, line)
    curve_N: int = 60             # MoveNLP intervals on seed 003's curves (N = 40 fails there)
    nlp_wall_s: float = 60.0      # [s] IPOPT max_wall_time per solve
    energy_budget: float = 1.2    # nlp:energy-free: duration ≤ budget × minimum time
    cycle_N: int = 20             # energy NLP intervals per cycle section
    cycle_wall_s: float = 10.0    # [s] IPOPT cap per cycle section
    cycle_dp_step: float = 0.02   # [m] DP stage spacing on the cycles (seed002_table.py)
    cycle_dp_window: int = 3      # telescope grid steps per stage on the cycles
    kin_factor: float = 10.0      # nlp:time-free-kin: acceleration and jerk limits × this
    forwarder_moves: int = 8
    seed: int = 0
    cycle_speeds: tuple = (0.5, 1.0)

    @classmethod
    def make(cls, quick: bool = False) -> "Settings":
        if not quick:
            return cls()
        return cls(quick=True, nlp_N=30, nlp_wall_s=2.0, cycle_dp_step=0.04, forwarder_moves=2,
                   cycle_speeds=(1.0,))


@dataclass
class Outcome:
    """What a runner returns: ``status`` (a :class:`~planner.methods.base.PlanStatus`) and
    ``reason``; when ok the trajectory ``pieces`` [(t0 [s], Trajectory)], ``notes`` for the
    report and ``info`` (method figures kept in the row)."""
    status: str
    reason: str = ""
    pieces: list = field(default_factory=list)    # [(t0 [s], Trajectory)]
    notes: list = field(default_factory=list)
    info: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def outcome_of(res, t0: float = 0.0, **info) -> Outcome:
    """The :class:`Outcome` of a method's :class:`~planner.methods.base.PlanResult`: its
    trajectory as the one piece (starting at ``t0`` [s]) with ``info``, or its failure."""
    if not res.ok:
        return Outcome(res.status, res.reason or res.status)
    return Outcome(PlanStatus.OK, pieces=[(t0, res.trajectory)], info=info)


class Ctx:
    """Per-suite context: the crane, settings, obstacles, the suite's DP grid and a cache of
    MoveNLP objects (built once; build times in ``build_s``)."""

    def __init__(self, crane: Crane, settings: Settings, suite):
        self.crane, self.settings, self.suite = crane, settings, suite
        self.obstacles = tuple(suite.obstacles)
        self.build_s: dict = {}
        self._nlp: dict = {}
        self._variants: dict = {}

    def variant(self, acc: float = 1.0, jerk: float = 1.0):
        """The crane with acceleration limits × ``acc`` and jerk limits × ``jerk`` (inf: no
        jerk limit), built once."""
        if (acc, jerk) not in self._variants:
            s = self.crane.spec
            joints = tuple(dataclasses.replace(j, limits=dataclasses.replace(
                j.limits, qdd=j.limits.qdd * acc, qddd=j.limits.qddd * jerk)) for j in s.joints)
            self._variants[(acc, jerk)] = Crane(dataclasses.replace(s, joints=joints))
        return self._variants[(acc, jerk)]

    def kin_crane(self):
        """Acceleration and jerk limits × kin_factor (seed 000 gives none: its setting is
        velocity limits only)."""
        k = self.settings.kin_factor
        return self.variant(k, k)

    def nlp(self, objective, path, N, *, kin=False, acc=False, obstacles=True, wall=None,
            key=None):
        """The MoveNLP, built once: on the spec's limits, ``kin`` the seed-000 limit set
        (:meth:`kin_crane`), ``acc`` the spec's limits without jerk (TOPP-RA's limit set)."""
        crane = self.kin_crane() if kin else self.variant(1.0, float("inf")) if acc else self.crane
        obs = self.obstacles if obstacles else ()
        wall = wall or self.settings.nlp_wall_s
        k = (objective, key or path, N, kin, acc, obs, wall)
        if k not in self._nlp:
            t0 = _time.perf_counter()
            self._nlp[k] = MoveNLP(crane, objective, path, N=N, obstacles=obs,
                                   ipopt_options={"max_wall_time": wall})
            label = f"{objective}/{key or path}/N={N}" + ("/kin" if kin else "/acc" if acc
                                                          else "")
            self.build_s[label] = _time.perf_counter() - t0
        return self._nlp[k]


__all__ = ["BASE_KINDS", "Settings", "Outcome", "Ctx", "outcome_of"]
