"""Ruckig (community edition, state to state only): jerk-limited rest-to-rest joint moves.

``rest_to_rest`` is the simplest baseline method: every joint moves time-synchronised from rest
to rest under its velocity (asymmetric: ``min_velocity``), acceleration and jerk limits. The
trajectory is sampled on a uniform grid plus every phase-switching time of every joint, so the
piecewise-cubic profile is reproduced exactly by the quintic interpolation of the common
:class:`~planner.trajectory.Trajectory`.
"""
from __future__ import annotations

import time as _time
import numpy as np
import ruckig

from planner.bounds import lower_bound
from planner.methods.base import Planner, PlanRequest, PlanResult
from planner.methods.registry import register
from planner.trajectory import Trajectory

NO_JERK = 1e6  # stands for "no jerk limit" (Ruckig needs a finite value) [unit/s³]


def _switch_times(traj: ruckig.Trajectory) -> np.ndarray:
    out = [0.0, traj.duration]
    for prof in traj.profiles[0]:
        t0 = prof.brake.duration if prof.brake is not None else 0.0
        out.extend(t0 + np.cumsum(prof.t))
    t = np.asarray(out)
    return t[(t >= 0) & (t <= traj.duration)]


def rest_to_rest(crane, q0, q1, *, sample_rate: float = 200.0,
                 scale: float = 1.0) -> PlanResult:
    """Time-optimal synchronised jerk-limited move from q0 to q1 (both at rest).

    ``scale`` ≤ 1 plans with that fraction of every velocity/acceleration limit."""
    t0 = _time.perf_counter()
    q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
    L = crane.limit_arrays()
    for name, q in (("start", q0), ("goal", q1)):
        bad = np.flatnonzero((q < L["q_min"] - 1e-9) | (q > L["q_max"] + 1e-9))
        if q.shape != (crane.n,) or bad.size:
            what = (f"needs {crane.n} joint values" if q.shape != (crane.n,) else
                    f"{crane.names[bad[0]]} = {q[bad[0]]:.4f} is outside "
                    f"[{L['q_min'][bad[0]]:.4f}, {L['q_max'][bad[0]]:.4f}]")
            return PlanResult("invalid", f"{name} configuration: {what}",
                              solve_time_s=_time.perf_counter() - t0)
    n = crane.n
    inp = ruckig.InputParameter(n)
    inp.current_position, inp.target_position = q0.tolist(), q1.tolist()
    inp.current_velocity = inp.current_acceleration = [0.0] * n
    inp.target_velocity = inp.target_acceleration = [0.0] * n
    inp.max_velocity = (scale * L["qd_max"]).tolist()
    inp.min_velocity = (scale * L["qd_min"]).tolist()
    inp.max_acceleration = (scale * L["qdd_max"]).tolist()
    inp.max_jerk = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], NO_JERK).tolist()
    traj = ruckig.Trajectory(n)
    res = ruckig.Ruckig(n).calculate(inp, traj)
    if res not in (ruckig.Result.Working, ruckig.Result.Finished):
        return PlanResult("failed", f"Ruckig: {res.name}",
                          solve_time_s=_time.perf_counter() - t0)
    T = traj.duration
    sw = np.array([0.0, max(T, 1e-9)])
    if T <= 0:
        t = sw
    else:
        sw = np.unique(_switch_times(traj))
        sw = sw[np.concatenate([[True], np.diff(sw) > 1e-6])]  # near-duplicates: 1/h³ noise
        u = np.linspace(0.0, T, max(50, int(np.ceil(T * sample_rate)) + 1))
        # keep uniform samples away from switching times: a very short interval would amplify
        # round-off in the interpolant's jerk (∝ 1/h³)
        gap = 0.25 / sample_rate
        near = np.abs(u[:, None] - sw[None, :]).min(axis=1) < gap
        t = np.union1d(u[~near], sw)
    s = [traj.at_time(x) for x in t]
    tr = Trajectory(t, [p[0] for p in s], [p[1] for p in s], [p[2] for p in s],
                    joint_names=tuple(crane.names), method="ruckig", objective="time",
                    limits=("position", "velocity", "acceleration", "jerk"),
                    meta=dict(independent_min_durations=list(traj.independent_min_durations),
                              switch_times=sw.tolist()))
    return PlanResult("ok", trajectory=tr, duration_s=T,
                      solve_time_s=_time.perf_counter() - t0)


class RuckigPlanner(Planner):
    """``ruckig``: the jerk-limited rest-to-rest joint move between the tip ends, each end at
    the telescope the analytic lower bound finds best (:func:`~planner.bounds.lower_bound`)."""
    name = "ruckig"
    description = "jerk-limited rest-to-rest joint move (Ruckig), free path"
    objectives = ("time",)
    paths = ("free",)

    def plan(self, crane, request: PlanRequest) -> PlanResult:
        lb = lower_bound(crane, request.start, request.goal)
        return rest_to_rest(crane, crane.ik(request.start, lb.tele_start),
                            crane.ik(request.goal, lb.tele_goal))


register(RuckigPlanner())
