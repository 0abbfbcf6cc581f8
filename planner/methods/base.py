"""The planning-method interface: a plain request, one verb, a result code and a trajectory.

Every planning method (local laws, Bellman DP, TOPP-RA, Ruckig, the NLPs) is a
:class:`Planner`: it names itself, says which objectives and path kinds it plans, and turns a
:class:`PlanRequest` into a :class:`PlanResult`::

    from planner import Crane
    from planner.methods import PlanRequest, plan
    res = plan(Crane.from_id("s100f"), PlanRequest((6, -1, 0), (3, 2.5, 1.5)), method="nlp")
    if res.ok:
        res.trajectory          # planner.trajectory.Trajectory, judged by evaluate()

A result's ``status`` is a :class:`PlanStatus` — a ``str`` enum, so ``res.status == "ok"``
holds and JSON writes the plain code — with a human ``reason`` when it is not ``ok``; an unknown
code is refused when the result is made. The codes (the JSON ``status`` key, docs/json-keys.md):

- ``ok``: a trajectory that keeps the limits the method plans with;
- ``infeasible``: the method shows that no trajectory meets its limits or the duration asked
  for (no path through the DP graph, no TOPP-RA timing, IPOPT's infeasibility verdict, a time
  budget below the minimum time);
- ``unreachable``: the start, the goal or a point of the path lies outside the workspace;
- ``stalled``: a local law stopped moving along its path (joints saturated or at a limit);
- ``timeout``: the method ran past its time limit (a law's move time, IPOPT's wall time);
- ``max_iter``: the solver reached its iteration limit;
- ``restoration_failed``: IPOPT's restoration phase failed;
- ``failed``: the solver stopped without a solution for another reason, named in ``reason``;
- ``error``: the solver raised an error, its message in ``reason``;
- ``invalid``: the solver refused the problem it was given (Ruckig's input check);
- ``obstacle``: the solution passes through an obstacle between the check points;
- ``violation``: a limit is still exceeded beyond the method's tolerance after its refinement
  rounds (TOPP-RA);
- ``limits``: the solver converged, but evaluate() finds a limit broken between the check
  points (the energy NLP's candidates, library entries);
- ``unsupported``: the method does not plan the request — a library entry's code; ``plan()``
  raises :class:`UnsupportedRequest` instead.

Method-specific figures (iterations, the DP's joint path, the laws' β statistics, …) live in
``stats`` and read as attributes (``res.iterations`` is ``res.stats["iterations"]``).

A request the method cannot plan at all (an objective or path kind it does not support, a
missing option, an option it would ignore, a value outside what is allowed) raises
:class:`UnsupportedRequest` — a usage error, not an infeasible plan. Field values are checked
where the request is made (:class:`PlanRequest`: finite tips with the slew in ±π, positive
finite duration and tip speed, the common options in :data:`OPTION_RULES`), the method's own
conditions in :meth:`Planner.check`; the CLI, ``library build`` and the bench all go through
both. Messages name a field as the Python caller writes it, in backticks (```tip_speed` = -1
m/s: allowed a finite number > 0``); the CLI prints the flag instead (:mod:`planner.cli.wording`).
Registering a planner once (:func:`planner.methods.registry.register`) makes it available to
``crane-planner plan --method``, the benchmark and ``library build``.
"""
from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar, Mapping

from planner.units import check_tip

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["OBJECTIVES", "PATHS", "OPTION_RULES", "PlanRequest", "PlanResult", "PlanStatus",
           "Planner", "UnsupportedRequest"]

OBJECTIVES = ("time", "energy")
PATHS = ("free", "line")

# The options several methods read, checked when a request is made (None means "not given"):
# name -> (integer?, smallest allowed, largest allowed, what it is). The bounds keep every
# method's work finite: the NLP's size grows with ``intervals``, a law's step count with
# ``rate``; the DP's grid (``step``, ``tele_step``, ``window``) is sized by DPPlanner.check.
OPTION_RULES = {
    "intervals": (True, 2, 2000, "NLP intervals N"),
    "rate": (False, 1.0, 10000.0, "control rate [Hz]"),
    "step": (False, 1e-4, 100.0, "DP stage spacing [m]"),
    "tele_step": (False, 1e-4, 100.0, "DP telescope grid [m]"),
    "window": (True, 1, 1000, "DP telescope steps per stage"),
    "tele0": (False, -100.0, 100.0, "start telescope [m]"),
}


class PlanStatus(enum.StrEnum):
    """The result code of a plan (the JSON ``status`` key): ``ok`` or why there is no
    trajectory. A ``str``: it compares equal to its code and JSON writes the code; each member's
    ``meaning`` is its one-line description (the list in the module doc)."""
    OK = "ok", "a trajectory that keeps the limits the method plans with"
    INFEASIBLE = "infeasible", "no trajectory meets the limits or the duration asked for"
    UNREACHABLE = "unreachable", "the start, the goal or a point of the path is out of reach"
    STALLED = "stalled", "a local law stopped moving along its path"
    TIMEOUT = "timeout", "the method ran past its time limit"
    MAX_ITER = "max_iter", "the solver reached its iteration limit"
    RESTORATION_FAILED = "restoration_failed", "IPOPT's restoration phase failed"
    FAILED = "failed", "the solver stopped without a solution for another reason"
    ERROR = "error", "the solver raised an error"
    INVALID = "invalid", "the solver refused the problem it was given"
    OBSTACLE = "obstacle", "the solution passes through an obstacle between the check points"
    VIOLATION = "violation", "a limit is still exceeded after the refinement rounds"
    LIMITS = "limits", "converged, but evaluate() finds a limit broken between check points"
    UNSUPPORTED = "unsupported", "the method does not plan the request (library entries)"

    def __new__(cls, code: str, meaning: str):
        member = str.__new__(cls, code)
        member._value_ = code
        member.meaning = meaning
        return member

    @classmethod
    def of(cls, code) -> "PlanStatus":
        """``code`` as a member; ValueError naming it and the allowed codes otherwise."""
        try:
            return cls(code)
        except ValueError:
            raise ValueError(f"status {code!r}: allowed {', '.join(m.value for m in cls)}") \
                from None


class UnsupportedRequest(ValueError):
    """The method does not plan this request (objective, path kind, missing option, an option
    it would ignore), or a field of the request is outside what is allowed."""


def _positive(name: str, unit: str, value):
    """``value`` as a finite float > 0, or None when not given; UnsupportedRequest otherwise."""
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise UnsupportedRequest(f"`{name}` = {value!r} {unit}: allowed a finite number > 0")
    return v


def _option(name: str, value):
    """Check one option against :data:`OPTION_RULES` (unknown names pass unchanged)."""
    if value is None or name not in OPTION_RULES:
        return value
    integer, lo, hi, what = OPTION_RULES[name]
    kind = "an integer" if integer else "a number"
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and \
        math.isfinite(value) and lo <= value <= hi and (not integer or value == int(value))
    if not ok:
        raise UnsupportedRequest(f"`{name}` = {value!r} ({what}): allowed {kind} in "
                                 f"[{lo:g}, {hi:g}]")
    return int(value) if integer else float(value)


@dataclass(frozen=True)
class PlanRequest:
    """One move to plan. ``start``/``goal``: tip positions (r [m], z [m], slew [rad]) in the
    spec's frame 0 (docs/design.md, "CONTRACT: tip coordinates"). ``objective``: "time" or
    "energy"; ``path``: "free" (any joint path) or "line" (the straight tip line start → goal);
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
        for name in ("start", "goal"):
            try:
                tip = check_tip(getattr(self, name), name)
            except ValueError as e:
                raise UnsupportedRequest(str(e)) from None
            object.__setattr__(self, name, tip)
        object.__setattr__(self, "duration",
                           _positive("duration", "s", self.duration))
        object.__setattr__(self, "tip_speed",
                           _positive("tip_speed", "m/s", self.tip_speed))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        object.__setattr__(self, "options", MappingProxyType(
            {k: _option(k, v) for k, v in dict(self.options).items()}))
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
    """What every method returns: ``status`` (a :class:`PlanStatus`: ok or why not), ``reason``,
    ``trajectory`` (:class:`~planner.trajectory.Trajectory` when ok), ``duration_s`` [s],
    ``solve_time_s`` [s], ``method`` (registry name, set by :func:`plan`), ``warnings`` and
    ``stats`` (method-specific figures; any other keyword given to the constructor lands there
    and reads back as an attribute)."""

    def __init__(self, status: PlanStatus | str, reason: str = "", trajectory=None, *,
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
    def status(self) -> PlanStatus:
        return self.__dict__["_status"]

    @status.setter
    def status(self, code: PlanStatus | str) -> None:
        self.__dict__["_status"] = PlanStatus.of(code)   # an unknown code is refused here

    @property
    def ok(self) -> bool:
        return self.status is PlanStatus.OK

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
    ``uses_tip_speed`` (whether it reads those fields: True for every objective, or the tuple
    of objectives it reads them for; :meth:`check` refuses a field it would ignore),
    ``tolerance`` (the largest relative limit excess, evaluate()'s ``max_limit_violation`` at
    1 kHz, that an ``ok`` trajectory of the method may show; 1e-3 unless it says otherwise),
    and implement :meth:`plan`."""
    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    objectives: ClassVar[tuple] = ("time",)
    paths: ClassVar[tuple] = ("line",)
    obstacles: ClassVar[bool] = False
    uses_duration: ClassVar[bool | tuple] = False
    uses_tip_speed: ClassVar[bool | tuple] = False
    tolerance: ClassVar[float] = 1e-3

    @property
    def default_path(self) -> str:
        return self.paths[0]

    def reads(self, field_name: str, objective: str) -> bool:
        """Whether this method reads the request field ``field_name`` ("duration" or
        "tip_speed") when planning ``objective``."""
        uses = getattr(self, f"uses_{field_name}")
        return uses if isinstance(uses, bool) else objective in uses

    def check(self, request: PlanRequest) -> None:
        """Raise :class:`UnsupportedRequest` when this method cannot plan ``request``."""
        if request.objective not in self.objectives:
            raise UnsupportedRequest(f"`objective` {request.objective}: {self.name} plans "
                                     f"{' or '.join(self.objectives)}")
        if request.path not in self.paths:
            raise UnsupportedRequest(f"`path` {request.path}: {self.name} plans "
                                     f"{' or '.join(self.paths)} paths")
        if request.obstacles and not self.obstacles:
            raise UnsupportedRequest(f"{self.name} does not keep clear of obstacles; "
                                     "use `method` nlp")
        for fld in ("duration", "tip_speed"):
            if getattr(request, fld) is not None and not self.reads(fld, request.objective):
                uses = getattr(self, f"uses_{fld}")
                where = (f" (it reads it for `objective` {' or '.join(uses)})"
                         if isinstance(uses, tuple) and uses else "")
                raise UnsupportedRequest(f"`{fld}` {getattr(request, fld):g}: {self.name} "
                                         f"`objective` {request.objective} does not read it"
                                         f"{where}; leave it out rather than have it ignored")

    def clear(self) -> None:
        """Forget anything built and kept between calls (built solvers); default: nothing."""

    def prepare(self, crane: Crane, request: PlanRequest, compile: bool = False) -> float:
        """Build (``compile``: and store for other processes) whatever planning ``request``
        will need, before the first plan — e.g. a library build's driver before its workers
        start. Returns the seconds it took; default: nothing to build."""
        return 0.0

    def library_request(self, crane: Crane, move, objective: str, *, time_result: PlanResult | None
                        = None, settings) -> PlanRequest:
        """The request a library build (:mod:`planner.library.build`) plans for the
        ``objective`` entry of ``move`` (its ``start`` and ``goal`` tips) on ``crane``.
        ``settings``: the build's fixed settings (:class:`planner.library.build.BuildSettings`;
        read here: ``obstacles``, ``energy_budget``); ``time_result``: the move's minimum-time
        result, given for every entry after it. Default: the plain request — free path, the
        suite's obstacles, and for an objective other than time whose duration this method
        reads (:meth:`reads`) the limit ``energy_budget`` × the minimum time (before that time
        is known, when the build checks or prepares the method, × 1 s). A method overrides
        it to add its own options."""
        duration = None
        if objective != "time" and self.reads("duration", objective):
            t_min = time_result.duration_s if time_result is not None else 1.0
            duration = settings.energy_budget * t_min
        return PlanRequest(move.start, move.goal, objective=objective, path="free",
                           duration=duration, obstacles=settings.obstacles)

    @abstractmethod
    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        """Plan ``request`` on ``crane``; failures come back as a status, not an exception."""

    def __repr__(self) -> str:
        return f"<planner {self.name}: {'/'.join(self.objectives)}, {'/'.join(self.paths)} path>"
