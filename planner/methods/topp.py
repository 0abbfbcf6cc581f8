"""Time-optimal retiming of a fixed joint path with TOPP-RA (kept behind this one module).

Constraints: joint velocity (asymmetric), joint acceleration, and the shared pump flow — along a
fixed path the pump demand is ṡ·Σ A_dir,i |dx_i/ds| (piston area extending, annulus
retracting, single-acting lowering free), so Q ≤ Q_max is an upper bound on x = ṡ² at each grid
point (toppra's ``xbound``). Uses ``ParametrizeConstAccel`` (the spline parametrizer overshoots
acceleration limits by 5–12 %, ../shared/reference/anchors.md). Jerk is not supported by
TOPP-RA: use :mod:`planner.methods.ruckig`.
"""
from __future__ import annotations

import time as _time

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint

from planner.geometry.paths import Line
from planner.methods.base import Planner, PlanRequest, PlanResult
from planner.methods.dp import DPPlanner, dp
from planner.methods.registry import register
from planner.model.flows import swept_volume
from planner.trajectory import Trajectory, evaluate

toppra.setup_logging("ERROR")  # failures are reported as statuses, not log lines


class PumpFlowConstraint(constraint.LinearConstraint):
    """Σ A_dir,i |dx_i/ds| · ṡ ≤ Q_max as a bound on x = ṡ² (first order, direction-aware)."""

    def __init__(self, crane, scale: float = 1.0):
        super().__init__()
        self.crane = crane
        self.dof = crane.n
        self.scale = scale  # fraction of the pump's max flow to plan with

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        q = path(gridpoints)
        dq = path(gridpoints, 1)
        _, dxdq = self.crane.stroke(q)
        flow_per_sd = swept_volume(self.crane.spec, dxdq * dq).sum(-1)  # m³ per unit of s
        qmax = self.scale * self.crane.spec.pump.max_flow
        with np.errstate(divide="ignore"):
            xmax = np.where(flow_per_sd > 1e-15, (qmax / flow_per_sd) ** 2, 1e12)
        xbound = np.column_stack([np.zeros_like(xmax), xmax])
        return None, None, None, None, None, None, xbound


def _result(status: str, reason: str = "", **kw) -> PlanResult:
    """TOPP-RA's result: status "ok" | "infeasible"; stats ``iterations`` (verification
    passes) and ``max_limit_violation`` (of the returned trajectory, by evaluate())."""
    kw.setdefault("iterations", 0)
    kw.setdefault("max_limit_violation", float("nan"))
    return PlanResult(status, reason, **kw)


def retime(crane, path_q, *, ss=None, gridpoints: int = 200,
           limits=("velocity", "acceleration", "pump_flow"), duration: float | None = None,
           sample_rate: float = 500.0, tol: float = 1e-3, max_iter: int = 5) -> PlanResult:
    """Fastest (or, with ``duration`` [s], fixed-duration) rest-to-rest timing of the joint
    path ``path_q`` (K, n) under the selected limit kinds.

    ``ss`` (K,) path parameter of the samples (default: cumulative joint-space distance);
    ``gridpoints`` the TOPP-RA discretisation. TOPP-RA enforces limits at the grid points only;
    the result is therefore judged by :func:`~planner.trajectory.evaluate` on a fine resampling
    and, while a kind is exceeded by more than ``tol``, that kind's limits are tightened by the
    measured excess and the path retimed again (at most ``max_iter`` times). The trajectory is
    sampled at ``sample_rate`` [Hz] (at least 200 samples)."""
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
        return _result("infeasible", "the path has zero length",
                          solve_time_s=_time.perf_counter() - t0)
    path = toppra.SplineInterpolator(ss, path_q)
    L = crane.limit_arrays()
    grid = np.linspace(ss[0], ss[-1], gridpoints + 1)
    # per-joint factors for velocity/acceleration (an overshoot is usually one joint's),
    # one factor for the shared pump
    scale = {"velocity": np.ones(crane.n), "acceleration": np.ones(crane.n), "pump_flow": 1.0}
    checked = ("position",) + tuple(limits)
    for it in range(1, max_iter + 1):
        cons = []
        if "velocity" in limits:
            f = scale["velocity"]
            cons.append(constraint.JointVelocityConstraint(
                np.column_stack([f * L["qd_min"], f * L["qd_max"]])))
        if "acceleration" in limits:
            f = scale["acceleration"]
            cons.append(constraint.JointAccelerationConstraint(
                np.column_stack([-f * L["qdd_max"], f * L["qdd_max"]])))
        if "pump_flow" in limits:
            cons.append(PumpFlowConstraint(crane, scale["pump_flow"]))
        if duration is None:
            inst = algo.TOPPRA(cons, path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
        else:
            inst = algo.TOPPRAsd(cons, path, gridpoints=grid,
                                 parametrizer="ParametrizeConstAccel")
            inst.set_desired_duration(duration)
        jt = inst.compute_trajectory(0.0, 0.0)
        if jt is None:
            what = f"a duration of {duration} s" if duration is not None else "the limits"
            return _result("infeasible", f"TOPP-RA found no rest-to-rest timing of this "
                              f"path under {what} (the path may need a non-zero speed where a "
                              "limit is zero, or the duration is too short)",
                              solve_time_s=_time.perf_counter() - t0, iterations=it)
        T = float(jt.duration)
        if duration is not None and T > duration * (1 + 1e-3):
            # TOPPRAsd returns the fastest timing (with a log warning) when the duration is
            # unachievable: report that as a failure instead
            return _result("infeasible", f"a duration of {duration} s is too short: the "
                              f"fastest timing of this path under the limits takes {T:.3f} s",
                              solve_time_s=_time.perf_counter() - t0, iterations=it)
        n = max(200, int(np.ceil(T * sample_rate)) + 1)
        t = np.linspace(0.0, T, n)
        traj = Trajectory(t, jt(t), jt(t, 1), jt(t, 2), joint_names=tuple(crane.names),
                          method="topp", objective="time" if duration is None else "duration",
                          limits=checked,
                          meta=dict(gridpoints=gridpoints, parametrizer="ParametrizeConstAccel",
                                    limit_scale={k: np.atleast_1d(v).tolist()
                                                 for k, v in scale.items()}))
        ev = evaluate(crane, traj)
        if ev.max_limit_violation <= tol:
            break
        lim = {"velocity": (ev.qd, L["qd_min"], L["qd_max"]),
               "acceleration": (ev.qdd, -L["qdd_max"], L["qdd_max"])}
        for k in limits:
            if ev.violations[k] <= tol:
                continue
            if k == "pump_flow":
                scale[k] /= 1.0 + ev.violations[k] + tol
            else:
                v, lo, hi = lim[k]
                per = np.max(np.maximum(v / hi, v / lo), axis=0) - 1.0  # per joint excess
                bad = per > tol
                scale[k][bad] /= 1.0 + per[bad] + tol
    return _result("ok", trajectory=traj, duration_s=T, iterations=it,
                      max_limit_violation=ev.max_limit_violation,
                      solve_time_s=_time.perf_counter() - t0)


class ToppPlanner(Planner):
    """``topp``: the minimum-time DP's joint path along the tip line, retimed by TOPP-RA under
    velocity, acceleration and pump limits (fastest, or the request's ``duration``). Options:
    the DP's (``step``, ``tele_step``, ``window``)."""
    name = "topp"
    description = "the DP's joint path retimed by TOPP-RA (velocity, acceleration, pump)"
    objectives = ("time",)
    paths = ("line",)
    uses_duration = True

    def plan(self, crane, request: PlanRequest) -> PlanResult:
        res = dp(crane, Line(request.start, request.goal), objective="time",
                 **DPPlanner.grid(request))
        if not res.ok:
            return res
        return retime(crane, res.path_q, duration=request.duration)


register(ToppPlanner())
