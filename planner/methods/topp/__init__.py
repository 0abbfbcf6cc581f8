"""Time-optimal retiming of a fixed joint path with TOPP-RA (kept behind this one module).

Constraints: joint velocity (asymmetric), joint acceleration, and the shared pump flow — along a
fixed path the pump demand is ṡ·Σ A_dir,i |dx_i/ds| (piston area extending, annulus
retracting, single-acting lowering free), so Q ≤ Q_max is an upper bound on x = ṡ² at each grid
point. Jerk is not supported by TOPP-RA: use :mod:`planner.methods.ruckig`.

TOPP-RA enforces its limits at the grid points only; between them the path's curvature can
break them (on a crane's DP path raw toppra overshoots the acceleration limit by up to 3×).
:func:`time_path` therefore verifies every grid interval exactly — with constant path
acceleration u on an interval and a cubic-spline path, q̈(s) is a quadratic in s on each piece
between spline knots and grid points, so its extremum is a vertex or an end, and q̇ peaks where
q̈ = 0 or at an end (the pump flow is checked at those points and the pieces' midpoints) — and
tightens the limits only at the two grid points around an interval that breaks one (by the
measured excess, for that joint), then solves again. In the same solves the grid is refined
where its coarseness costs time (next to the path speed's minima and where the path
acceleration jumps), so 100 starting intervals come within 1 % of a fine grid's duration.
The trajectory is sampled once, at the end, with numpy (``ParametrizeConstAccel``'s formula:
s quadratic in t on each interval).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time as _time

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint

from planner.geometry.paths import Line
from planner.methods.base import Planner, PlanRequest, PlanResult, PlanStatus
from planner.methods.dp import DPPlanner, dp
from planner.methods.registry import register
from planner.methods.topp.constraints import (PumpFlowConstraint, ScaledAcceleration,
                                              SpeedCap, pump_flow_per_speed)
from planner.methods.topp.solve import TimedPath, time_path
from planner.methods.topp.verify import PathTiming, Peaks, interval_peaks
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["PumpFlowConstraint", "ScaledAcceleration", "SpeedCap", "PathTiming", "Peaks",
           "interval_peaks", "time_path", "TimedPath", "retime", "ToppPlanner"]


def retime(crane: Crane, path_q, *, ss=None, gridpoints: int = 100,
           limits=("velocity", "acceleration", "pump_flow"), duration: float | None = None,
           sample_rate: float = 500.0, tol: float = 1e-3, max_iter: int = 8,
           adapt: int = 3) -> PlanResult:
    """Fastest (or, with ``duration`` [s], fixed-duration) rest-to-rest timing of the joint
    path ``path_q`` (K, n) of ``crane`` under the selected limit kinds (:func:`time_path`,
    verified between grid points).

    ``ss`` (K,) path parameter of the samples (default: cumulative joint-space distance);
    ``gridpoints`` the TOPP-RA discretisation's uniform starting grid, refined ``adapt``
    times where it costs time (:func:`time_path`; 0: uniform). The trajectory is sampled
    once, at ``sample_rate`` [Hz] (at least 200 samples). Statuses: "ok", "infeasible",
    "violation" (a limit still exceeded by more than ``tol`` after ``max_iter`` solves);
    stats ``iterations`` (TOPP-RA solves), ``intervals`` (the final grid's) and
    ``max_limit_violation`` (the verification's worst excess: judge the trajectory with
    :func:`~planner.trajectory.evaluate`)."""
    t0 = _time.perf_counter()
    path_q = np.asarray(path_q, float)
    if path_q.ndim != 2 or path_q.shape[1] != crane.n or path_q.shape[0] < 2:
        raise ValueError(f"path_q must be (K >= 2, {crane.n}), got {path_q.shape}")
    bad = [k for k in limits if k not in ("velocity", "acceleration", "pump_flow")]
    if bad:
        raise ValueError(f"unsupported limit kind(s) {bad}; TOPP-RA handles velocity, "
                         "acceleration, pump_flow")
    if ss is None:
        seg = np.linalg.norm(np.diff(path_q, axis=0), axis=1)
        keep = np.concatenate([[True], seg > 1e-12])  # drop repeated points
        path_q = path_q[keep]
        ss = np.concatenate([[0.0], np.cumsum(seg[keep[1:]])])
    ss = np.asarray(ss, float)
    if ss[-1] <= 0:
        return PlanResult(PlanStatus.INFEASIBLE, "the path has zero length", iterations=0,
                          max_limit_violation=float("nan"),
                          solve_time_s=_time.perf_counter() - t0)
    L = crane.limit_arrays()
    res = time_path(path_q, ss, np.column_stack([L["qd_min"], L["qd_max"]]), L["qdd_max"],
                    gridpoints=gridpoints, kinds=tuple(limits),
                    flow=lambda q, dq: pump_flow_per_speed(crane, q, dq),
                    qmax=crane.spec.pump.max_flow, duration=duration, tol=tol,
                    max_iter=max_iter, adapt=adapt)
    stats = dict(iterations=res.iterations, max_limit_violation=res.max_limit_violation,
                 intervals=len(res.timing.s) - 1 if res.timing is not None else 0)
    if res.timing is None or res.status == PlanStatus.INFEASIBLE:
        return PlanResult(res.status, res.reason, solve_time_s=_time.perf_counter() - t0,
                          **stats)
    T = res.timing.duration
    t, q, qd, qdd = res.samples(sample_rate)
    traj = Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names), method="topp",
                      objective="time" if duration is None else "duration",
                      limits=("position",) + tuple(limits),
                      meta=dict(gridpoints=gridpoints, intervals=stats["intervals"],
                                parametrizer="ParametrizeConstAccel",
                                verified="interval extrema"))
    return PlanResult(res.status, res.reason, trajectory=traj if res.ok else None,
                      duration_s=T, solve_time_s=_time.perf_counter() - t0, **stats)


def raw_retime(crane: Crane, path_q, gridpoints: int = 200, rate: float = 500.0) -> Trajectory:
    """The peer: toppra as its documentation shows it, on the same path parameter, limits
    (velocity, acceleration, pump) and grid as :func:`retime` — ConstAccel, then toppra's own
    sampling at ``rate`` [Hz], nothing verified between grid points. For comparisons only
    (benchmarks/bench_peers.py, the tests): it can break the acceleration limit between points."""
    seg = np.linalg.norm(np.diff(path_q, axis=0), axis=1)
    keep = np.concatenate([[True], seg > 1e-12])
    ss = np.concatenate([[0.0], np.cumsum(seg[keep[1:]])])
    L = crane.limit_arrays()
    cons = [constraint.JointVelocityConstraint(np.column_stack([L["qd_min"], L["qd_max"]])),
            constraint.JointAccelerationConstraint(np.column_stack([-L["qdd_max"],
                                                                    L["qdd_max"]])),
            PumpFlowConstraint(crane)]
    jt = algo.TOPPRA(cons, toppra.SplineInterpolator(ss, path_q[keep]),
                     gridpoints=np.linspace(0, ss[-1], gridpoints + 1),
                     parametrizer="ParametrizeConstAccel").compute_trajectory(0.0, 0.0)
    t = np.linspace(0.0, jt.duration, max(200, int(np.ceil(jt.duration * rate)) + 1))
    return Trajectory(t, jt(t), jt(t, 1), jt(t, 2), joint_names=tuple(crane.names),
                      limits=("position", "velocity", "acceleration", "pump_flow"))


class ToppPlanner(Planner):
    """``topp``: the minimum-time DP's joint path along the tip line, retimed by TOPP-RA under
    velocity, acceleration and pump limits (fastest, or the request's ``duration``). Options:
    the DP's (``step``, ``tele_step``, ``window``)."""
    name = "topp"
    description = "the DP's joint path retimed by TOPP-RA (velocity, acceleration, pump)"
    objectives = ("time",)
    paths = ("line",)
    uses_duration = True

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        res = dp(crane, Line(request.start, request.goal), objective="time",
                 **DPPlanner.grid(request))
        if not res.ok:
            return res
        return retime(crane, res.path_q, duration=request.duration)


register(ToppPlanner())
