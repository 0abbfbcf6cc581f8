"""Ruckig (community edition, state to state only): the one wrapper of the Ruckig library.

- :func:`state_to_state`: a time-optimal, time-synchronised jerk-limited move between two
  states (position, velocity, acceleration per degree of freedom) under velocity (asymmetric:
  ``vmin``), acceleration and jerk limits; :func:`state_to_state_relaxed` raises the
  acceleration and jerk limits until such a move exists (a state may be unreachable within
  the given distance under the nominal limits).
- :func:`switch_times`, :func:`sample_times`, :func:`sample`: where a Ruckig profile switches
  phase, and samples on a uniform grid plus every switching time, so the piecewise-cubic
  profile is reproduced exactly by the quintic interpolation of the common
  :class:`~planner.trajectory.Trajectory`.
- :func:`rest_to_rest`: the simplest baseline method: every joint moves time-synchronised from
  rest to rest under the crane's limits, registered as the ``ruckig`` planner.

The seed-003 from-rest transitions (:mod:`planner.methods.phase.from_rest`) and the NLP's
default guess (:mod:`planner.methods.nlp.move`) use this module.
"""
from __future__ import annotations

import math
import time as _time

import numpy as np
import ruckig

from planner.bounds import lower_bound
from planner.methods.base import Planner, PlanRequest, PlanResult
from planner.methods.registry import register
from planner.trajectory import Trajectory

__all__ = ["NO_JERK", "MIN_GAP", "state_to_state", "state_to_state_relaxed", "switch_times",
           "sample_times", "sample", "rest_to_rest", "RuckigPlanner"]

NO_JERK = 1e6   # stands for "no jerk limit" (Ruckig needs a finite value) [unit/s³]
MIN_GAP = 1e-4  # [s] shortest interval :func:`sample` keeps between samples (jerk ∝ 1/h³)


def state_to_state(current, target, vmax, vmin, amax, jmax) -> ruckig.Trajectory:
    """Time-optimal synchronised jerk-limited move from ``current`` to ``target``, each a
    triple (position, velocity, acceleration) of per-DOF sequences; ``vmax`` / ``vmin``
    (≤ 0), ``amax``, ``jmax`` per DOF. Returns the Ruckig trajectory; raises RuntimeError
    ("Ruckig: …") when the input is invalid or no profile exists."""
    n = len(current[0])
    inp = ruckig.InputParameter(n)
    inp.current_position, inp.current_velocity, inp.current_acceleration = \
        [[float(x) for x in v] for v in current]
    inp.target_position, inp.target_velocity, inp.target_acceleration = \
        [[float(x) for x in v] for v in target]
    inp.max_velocity = [float(x) for x in vmax]
    inp.min_velocity = [float(x) for x in vmin]
    inp.max_acceleration = [float(x) for x in amax]
    inp.max_jerk = [float(x) for x in jmax]
    tr = ruckig.Trajectory(n)
    try:
        res = ruckig.Ruckig(n).calculate(inp, tr)
    except (RuntimeError, ruckig.RuckigError) as e:  # invalid input or no profile found
        raise RuntimeError(f"Ruckig: {str(e).strip().splitlines()[0]}") from None
    if res not in (ruckig.Result.Working, ruckig.Result.Finished):
        raise RuntimeError(f"Ruckig: {res.name}")
    return tr


def state_to_state_relaxed(current, target, vmax, vmin, amax, jmax, grow: float = 1.25,
                           tries: int = 30):
    """:func:`state_to_state` with the acceleration and jerk limits raised by the factor
    ``grow`` (up to ``tries`` times) until a move exists. Returns (trajectory, scale applied to
    ``amax`` and ``jmax``); RuntimeError naming the last Ruckig error when none exists."""
    scale, last = 1.0, ""
    for _ in range(tries):
        try:
            return state_to_state(current, target, vmax, vmin, np.asarray(amax) * scale,
                                  np.asarray(jmax) * scale), scale
        except RuntimeError as e:
            last = str(e)
            scale *= grow
    raise RuntimeError(f"no Ruckig transition even with {scale / grow:.1f}× the acceleration "
                       f"and jerk limits ({last})")


def switch_times(traj: ruckig.Trajectory) -> np.ndarray:
    """Sorted, distinct phase-switching times [s] of every DOF of a Ruckig trajectory, with
    its start 0 and its end (the duration)."""
    out = [0.0, traj.duration]
    for prof in traj.profiles[0]:
        t0 = prof.brake.duration if prof.brake is not None else 0.0
        out.extend(t0 + np.cumsum(prof.t))
    t = np.asarray(out)
    return np.unique(t[(t >= 0) & (t <= traj.duration)])


def sample_times(duration: float, switches, rate: float, min_samples: int) -> np.ndarray:
    """A uniform grid at ``rate`` [Hz] on [0, duration] (at least ``min_samples`` points)
    without the points closer than a quarter step to a switching time, joined with
    ``switches``: a very short interval would amplify round-off in the interpolant's jerk
    (∝ 1/h³)."""
    switches = np.asarray(switches, float)
    u = np.linspace(0.0, duration, max(min_samples, int(math.ceil(duration * rate)) + 1))
    near = np.abs(u[:, None] - switches[None, :]).min(axis=1) < 0.25 / rate
    return np.union1d(u[~near], switches)


def states_at(traj: ruckig.Trajectory, t) -> tuple:
    """(q, q̇, q̈) arrays (len(t), DOF) of a Ruckig trajectory at the times t."""
    s = [traj.at_time(x) for x in t]
    return (np.array([p[0] for p in s]), np.array([p[1] for p in s]),
            np.array([p[2] for p in s]))


def sample(traj: ruckig.Trajectory, rate: float, min_samples: int = 60,
           min_gap: float = MIN_GAP) -> tuple:
    """(t, q, q̇, q̈) of a Ruckig trajectory on :func:`sample_times` (uniform at ``rate`` plus
    every switching time), samples closer than ``min_gap`` [s] dropped (switch times may
    cluster), the end always kept."""
    T = traj.duration
    t = sample_times(T, switch_times(traj), rate, min_samples)
    keep = [0]
    for k in range(1, len(t)):
        if t[k] - t[keep[-1]] >= min_gap:
            keep.append(k)
    t = t[keep]
    if T - t[-1] < min_gap and len(t) > 1:
        t = t[:-1]
    t = np.append(t, T) if t[-1] < T else t
    return (t,) + states_at(traj, t)


def rest_to_rest(crane, q0, q1, *, sample_rate: float = 200.0,
                 scale: float = 1.0) -> PlanResult:
    """Time-optimal synchronised jerk-limited move from q0 to q1 (both at rest).

    ``scale`` ≤ 1 plans with that fraction of every velocity/acceleration limit. The result's
    trajectory is sampled at ``sample_rate`` [Hz] plus every switching time (kept in
    ``meta["switch_times"]``)."""
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
    z = np.zeros(crane.n)
    try:
        traj = state_to_state((q0, z, z), (q1, z, z), scale * L["qd_max"], scale * L["qd_min"],
                              scale * L["qdd_max"],
                              np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], NO_JERK))
    except RuntimeError as e:
        return PlanResult("failed", str(e), solve_time_s=_time.perf_counter() - t0)
    T = traj.duration
    sw = np.array([0.0, max(T, 1e-9)])
    if T <= 0:
        t = sw
    else:
        sw = switch_times(traj)
        sw = sw[np.concatenate([[True], np.diff(sw) > 1e-6])]  # near-duplicates: 1/h³ noise
        t = sample_times(T, sw, sample_rate, 50)
    q, qd, qdd = states_at(traj, t)
    tr = Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names), method="ruckig",
                    objective="time", limits=("position", "velocity", "acceleration", "jerk"),
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
