"""The planning-method interface: a plain request, one verb, a result code and a trajectory.

Every planning method (local laws, Bellman DP, TOPP-RA, Ruckig, the NLPs) is a
:class:`Planner`: it names itself, says which objectives and path kinds it plans, and turns a
:class:`PlanRequest` into a :class:`PlanResult`::

    from planner import Crane
    from planner.methods import PlanRequest, plan
    res = plan(Crane.from_id("s100f"), PlanRequest((6, -1, 0), (3, 2.5, 1.5)), method="nlp")
    if res.ok:
        res.trajectory          # planner.trajectory.Trajectory, judged by evaluate()

A result's ``status`` is ``"ok"`` or a short code (``"infeasible"``, ``"unreachable"``,
``"stalled"``, ``"max_iter"``, …) with a human ``reason``; method-specific figures (iterations,
the DP's joint path, the laws' β statistics, …) live in ``stats`` and read as attributes
(``res.iterations`` is ``res.stats["iterations"]``).

A request the method cannot plan at all (an objective or path kind it does not support, a
missing option) raises :class:`UnsupportedRequest` — a usage error, not an infeasible plan.
Registering a planner once (:func:`planner.methods.registry.register`) makes it available to
``crane-planner plan --method``, the benchmark and ``library build``.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, ClassVar, Mapping

__all__ = ["OBJECTIVES", "PATHS", "PlanRequest", "PlanResult", "Planner", "UnsupportedRequest"]

OBJECTIVES = ("time", "energy")
PATHS = ("free", "line")


class UnsupportedRequest(ValueError):
    """The method does not plan this kind of request (objective, path kind, missing option)."""


@dataclass(frozen=True)
class PlanRequest:
    """One move to plan. ``start``/``goal``: tip positions (r [m], z [m], slew [rad]) in the
    spec's frame 0 (DESIGN.md, CONTRACT: tip coordinates). ``objective``: "time" or "energy";
    ``path``: "free" (any joint path) or "line" (the straight tip line start → goal);
    ``duration`` [s]: fixed or maximum duration where the method takes one; ``tip_speed``
    [m/s]: the path speed of path-following methods; ``obstacles``: objects of
    :mod:`planner.geometry.obstacles`; ``options``: method-specific settings (grid sizes,
    intervals, control rate, …), each method documents the ones it reads."""
    start: tuple
    goal: tuple
    objective: str = "time"
    path: str = "free"
    duration: float | None = None
    tip_speed: float | None = None
    obstacles: tuple = ()
    options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "start", tuple(float(v) for v in self.start))
        object.__setattr__(self, "goal", tuple(float(v) for v in self.goal))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        object.__setattr__(self, "options", MappingProxyType(dict(self.options)))
        if self.objective not in OBJECTIVES:
            raise UnsupportedRequest(f"objective {self.objective!r}: allowed "
                                     f"{', '.join(OBJECTIVES)}")
        if self.path not in PATHS:
            raise UnsupportedRequest(f"path {self.path!r}: allowed {', '.join(PATHS)}")

    def option(self, name: str, default: Any = None) -> Any:
        """The method option ``name``, or ``default`` when absent or None."""
        v = self.options.get(name)
        return default if v is None else v


class PlanResult:
    """What every method returns: ``status`` ("ok" or a short failure code), ``reason``,
    ``trajectory`` (:class:`~planner.trajectory.Trajectory` when ok), ``duration_s`` [s],
    ``solve_time_s`` [s], ``method`` (registry name, set by :func:`plan`), ``warnings`` and
    ``stats`` (method-specific figures; any other keyword given to the constructor lands there
    and reads back as an attribute)."""

    def __init__(self, status: str, reason: str = "", trajectory=None, *,
                 duration_s: float = math.nan, solve_time_s: float = 0.0, method: str = "",
                 warnings=(), stats: Mapping[str, Any] | None = None, **extra: Any):
        self.status = status
        self.reason = reason
        self.trajectory = trajectory
        self.duration_s = duration_s
        self.solve_time_s = solve_time_s
        self.method = method
        self.warnings = list(warnings)
        self.stats = dict(stats or {})
        self.stats.update(extra)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def __getattr__(self, name: str):
        # only reached when normal lookup fails: method-specific figures live in ``stats``
        stats = self.__dict__.get("stats")
        if stats is not None and name in stats:
            return stats[name]
        raise AttributeError(f"{type(self).__name__} has no attribute or stat {name!r}")

    def __repr__(self) -> str:
        head = f"PlanResult({self.method or '?'}: {self.status}"
        if self.ok:
            return head + f", {self.duration_s:.3f} s, solved in {self.solve_time_s:.3f} s)"
        return head + f": {self.reason})"


class Planner(ABC):
    """A planning method. Subclasses set ``name`` (the registry key, e.g. ``"dp"`` or
    ``"law:jla"``), ``objectives`` and ``paths`` (the first is the default path kind),
    ``obstacles`` (True when it honours :attr:`PlanRequest.obstacles`), ``uses_duration`` /
    ``uses_tip_speed`` (whether it reads those fields), and implement :meth:`plan`."""
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    objectives: ClassVar[tuple] = ("time",)
    paths: ClassVar[tuple] = ("line",)
    obstacles: ClassVar[bool] = False
    uses_duration: ClassVar[bool] = False
    uses_tip_speed: ClassVar[bool] = False

    @property
    def default_path(self) -> str:
        return self.paths[0]

    def check(self, request: PlanRequest) -> None:
        """Raise :class:`UnsupportedRequest` when this method cannot plan ``request``."""
        if request.objective not in self.objectives:
            raise UnsupportedRequest(f"--objective {request.objective}: {self.name} plans "
                                     f"{' or '.join(self.objectives)}")
        if request.path not in self.paths:
            raise UnsupportedRequest(f"--path {request.path}: {self.name} plans "
                                     f"{' or '.join(self.paths)} paths")
        if request.obstacles and not self.obstacles:
            raise UnsupportedRequest(f"{self.name} does not keep clear of obstacles; "
                                     "use --method nlp")

    def clear(self) -> None:
        """Forget anything built and kept between calls (built solvers); default: nothing."""

    @abstractmethod
    def plan(self, crane, request: PlanRequest) -> PlanResult:
        """Plan ``request`` on ``crane``; failures come back as a status, not an exception."""

    def __repr__(self) -> str:
        return f"<planner {self.name}: {'/'.join(self.objectives)}, {'/'.join(self.paths)} path>"
