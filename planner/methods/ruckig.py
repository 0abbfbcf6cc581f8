"""Ruckig (community edition, state to state only): the one wrapper of the Ruckig library.

- :func:`state_to_state`: a time-optimal, time-synchronised jerk-limited move between two
  states (position, velocity, acceleration per degree of freedom) under velocity (asymmetric:
  ``vmin``), acceleration and jerk limits; :func:`state_to_state_relaxed` raises the
  acceleration and jerk limits until such a move exists (a state may be unreachable within
  the given distance under the nominal limits).
- :class:`JerkProfile`: a Ruckig trajectory as a table of cubic pieces (brake, seven phases,
  constant-acceleration tail per DOF), sampled with numpy by Ruckig's own formula (no Python
  loop over samples; equal to ``Trajectory.at_time``, tested to 1e-12).
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

from typing import TYPE_CHECKING

import itertools
import math
import threading
import time as _time
import weakref

import numpy as np
import ruckig

from planner.bounds import lower_bound
from planner.methods.base import Planner, PlanRequest, PlanResult, PlanStatus
from planner.methods.registry import register
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["NO_JERK", "MIN_GAP", "state_to_state", "state_to_state_relaxed", "JerkProfile",
           "switch_times", "sample_times", "states_at", "thin", "sample", "rest_to_rest",
           "RuckigPlanner"]

NO_JERK = 1e6   # stands for "no jerk limit" (Ruckig needs a finite value) [unit/s³]
MIN_GAP = 1e-4  # [s] shortest interval :func:`sample` keeps between samples (jerk ∝ 1/h³)

_local = threading.local()  # one Ruckig calculator per DOF count and thread, made once
_TWO_ZEROS = (0.0, 0.0)     # the two empty brake pieces of a DOF without a brake
_chain = itertools.chain.from_iterable


_RUCKIG_LIMITS = weakref.WeakKeyDictionary()  # crane -> {scale: limit lists}, see below


def _ruckig_limits(crane: Crane, scale: float) -> tuple:
    """(vmax, vmin, amax, jmax) lists of the crane's joint limits times ``scale`` (jerk: the
    crane's, or :data:`NO_JERK` where it has none), then the position range (lower, upper,
    each widened by 1e-9), made once per crane and scale."""
    per = _RUCKIG_LIMITS.setdefault(crane, {})
    if scale not in per:
        L = crane.limit_arrays()
        per[scale] = ((scale * L["qd_max"]).tolist(), (scale * L["qd_min"]).tolist(),
                      (scale * L["qdd_max"]).tolist(),
                      np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], NO_JERK).tolist(),
                      (L["q_min"] - 1e-9).tolist(), (L["q_max"] + 1e-9).tolist())
    return per[scale]


def _calculator(n: int) -> ruckig.Ruckig:
    otg = getattr(_local, "otg", None)
    if otg is None:
        otg = _local.otg = {}
    if n not in otg:
        otg[n] = ruckig.Ruckig(n)
    return otg[n]


def _rest_input(n: int, limits: tuple):
    """(calculator, input, trajectory) for rest-to-rest moves of ``n`` DOF, made once per
    thread: the velocities and accelerations of a fresh input are zero and stay so (only this
    function's caller sets the positions), the limits are set again when ``limits`` (a cached
    tuple of :func:`_ruckig_limits`) is not the one they were last set from."""
    r2r = getattr(_local, "r2r", None)
    if r2r is None:
        r2r = _local.r2r = {}
    e = r2r.get(n)
    if e is None:
        e = r2r[n] = [_calculator(n), ruckig.InputParameter(n), ruckig.Trajectory(n), None]
    if e[3] is not limits:
        inp = e[1]
        inp.max_velocity, inp.min_velocity, inp.max_acceleration, inp.max_jerk = limits[:4]
        e[3] = limits
    return e


def _switch_list(traj: ruckig.Trajectory, merge: float) -> list:
    """:meth:`JerkProfile.switch_times` (same knots, same arithmetic) read straight from the
    Ruckig trajectory, as a list: no table, for a move sampled at its switches only."""
    T = float(traj.duration)
    knots = []
    put = knots.extend
    for prof in traj.profiles[0]:
        brake = prof.brake
        tb = brake.duration if brake is not None else 0.0
        if tb > 0:
            put((brake.t[0], tb))
            put([tb + x for x in itertools.accumulate(prof.t)])
        else:          # no brake (every rest-to-rest move): the phase ends as they are
            put(itertools.accumulate(prof.t))
    knots.sort()
    out, last = [0.0], 0.0
    keep = out.append
    for x in knots:
        if x - last > merge and x <= T:
            keep(x)
            last = x
    if T - last > merge:
        keep(T)
    return out


def state_to_state(current, target, vmax, vmin, amax, jmax) -> ruckig.Trajectory:
    """Time-optimal synchronised jerk-limited move from ``current`` to ``target``, each a
    triple (position, velocity, acceleration) of per-DOF sequences; ``vmax`` / ``vmin``
    (≤ 0), ``amax``, ``jmax`` per DOF. Returns the Ruckig trajectory; raises RuntimeError
    ("Ruckig: …") when the input is invalid or no profile exists."""
    def vec(x):  # one C-level conversion per vector, no per-element Python
        return x if type(x) is list else np.asarray(x, float).tolist()
    n = len(current[0])
    inp = ruckig.InputParameter(n)
    inp.current_position, inp.current_velocity, inp.current_acceleration = map(vec, current)
    inp.target_position, inp.target_velocity, inp.target_acceleration = map(vec, target)
    inp.max_velocity = vec(vmax)
    inp.min_velocity = vec(vmin)
    inp.max_acceleration = vec(amax)
    inp.max_jerk = vec(jmax)
    tr = ruckig.Trajectory(n)
    try:
        res = _calculator(n).calculate(inp, tr)
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


class JerkProfile:
    """The motion of a (single-section) Ruckig trajectory as a table of cubic pieces, for
    sampling with numpy.

    Per DOF the motion is: the optional two-phase brake pre-trajectory, the seven phases of
    the profile, then constant acceleration from the profile's end state (what Ruckig's
    ``at_time`` returns after a DOF has finished). Piece ``k`` of DOF ``d`` starts at
    ``knots[d, k]`` [s] from the state ``p, v, a`` with constant jerk ``j`` (arrays (DOF, 10));
    a DOF without a brake has two empty pieces at t = 0 instead, so every DOF has ten."""

    PIECES = 10  # 2 brake + 7 profile phases + the constant-acceleration tail

    def __init__(self, traj: ruckig.Trajectory):
        self.duration = float(traj.duration)
        flat = []          # per DOF: knots, p, v, a, j (10 each), one flat list for numpy
        put = flat.extend
        for prof in traj.profiles[0]:
            brake = prof.brake
            tb = brake.duration if brake is not None else 0.0
            # Ruckig's own running sum of the phase durations, in the same order
            knots = [tb + s for s in itertools.accumulate(prof.t, initial=0.0)]
            if tb > 0:
                put((0.0, brake.t[0]))
                put(knots)
                for b, x in ((brake.p, prof.p), (brake.v, prof.v), (brake.a, prof.a)):
                    put(b)
                    put(x)
                put(brake.j)
            else:
                put(_TWO_ZEROS)
                put(knots)
                for x in (prof.p, prof.v, prof.a):
                    put(_TWO_ZEROS)
                    put(x)
                put(_TWO_ZEROS)
            put(prof.j)
            flat.append(0.0)   # the tail: no jerk
        #: (5, DOF, PIECES): knots [s], then p, v, a, j at the start of each piece
        self.table = np.array(flat).reshape(-1, 5, self.PIECES).transpose(1, 0, 2)

    @property
    def dof(self) -> int:
        return self.table.shape[1]

    @property
    def knots(self) -> np.ndarray:
        """(DOF, PIECES) start time [s] of every piece."""
        return self.table[0]

    def switch_times(self, merge: float = 0.0) -> np.ndarray:
        """Sorted times [s] where some DOF's jerk may switch (brake and profile phases), with
        the start 0 and the end (the duration); the pieces between them are cubics in time.
        A time within ``merge`` [s] (≥ 0) of the previous one kept is left out (0: exact
        duplicates only)."""
        T = self.duration
        out, last = [0.0], 0.0     # a short sorted list: plain Python beats numpy here
        for x in sorted(self.table[0, :, 1:].ravel().tolist()):
            if x - last > merge and x <= T:
                out.append(x)
                last = x
        if T - last > merge:
            out.append(T)
        return np.array(out)

    def at(self, t) -> tuple:
        """(q, q̇, q̈) arrays (len(t), DOF) at the times ``t`` [s] (t < 0 read as 0), each
        sample on its piece by Ruckig's own formula: the same values as ``at_time``."""
        t = np.maximum(np.asarray(t, float).ravel(), 0.0)
        n, K = self.table.shape[1:]
        # piece index = number of knots ≤ t, minus one (Ruckig's upper_bound), per DOF: one
        # broadcast comparison while small, else a binary search per DOF
        if t.size * n * K <= 1 << 16:
            k = (t[:, None, None] >= self.table[0][None]).sum(axis=2)
        else:
            k = np.column_stack([np.searchsorted(r, t, side="right") for r in self.table[0]])
        k += np.arange(-1, n * K - 1, K)
        t0, p, v, a, j = np.take(self.table.reshape(5, -1), k, axis=1)
        dt = t[:, None] - t0
        return (p + dt * (v + dt * (a / 2 + dt * j / 6)),
                v + dt * (a + dt * j / 2),
                a + dt * j)


def switch_times(traj: ruckig.Trajectory) -> np.ndarray:
    """Sorted, distinct phase-switching times [s] of every DOF of a Ruckig trajectory (brake
    and profile phases), with its start 0 and its end (the duration)."""
    return JerkProfile(traj).switch_times()


def sample_times(duration: float, switches, rate: float, min_samples: int) -> np.ndarray:
    """A uniform grid at ``rate`` [Hz] on [0, duration] (at least ``min_samples`` points)
    without the points closer than a quarter step to a switching time, joined with
    ``switches``: a very short interval would amplify round-off in the interpolant's jerk
    (∝ 1/h³)."""
    switches = np.sort(np.asarray(switches, float))
    u = np.linspace(0.0, duration, max(min_samples, int(math.ceil(duration * rate)) + 1))
    if switches.size == 0:
        return u
    k = np.clip(np.searchsorted(switches, u), 1, max(switches.size - 1, 1))
    near = np.minimum(np.abs(u - switches[k - 1]), np.abs(u - switches[k % switches.size]))
    return np.union1d(u[near >= 0.25 / rate], switches)


def states_at(traj: ruckig.Trajectory, t) -> tuple:
    """(q, q̇, q̈) arrays (len(t), DOF) of a Ruckig trajectory at the times t (vectorised:
    :class:`JerkProfile`)."""
    return JerkProfile(traj).at(t)


def thin(t, min_gap: float) -> np.ndarray:
    """Mask of the sorted times ``t`` to keep so that kept neighbours are at least ``min_gap``
    apart: greedily from the start, each sample kept when far enough from the last kept one
    (only the samples closer than ``min_gap`` to their predecessor need a decision)."""
    t = np.asarray(t, float)
    keep = np.ones(len(t), bool)
    for k in np.flatnonzero(np.diff(t) < min_gap) + 1:
        last = k - 1
        while not keep[last]:
            last -= 1
        keep[k] = t[k] - t[last] >= min_gap
    return keep


def sample(traj: ruckig.Trajectory, rate: float, min_samples: int = 60,
           min_gap: float = MIN_GAP) -> tuple:
    """(t, q, q̇, q̈) of a Ruckig trajectory on :func:`sample_times` (uniform at ``rate`` plus
    every switching time), samples closer than ``min_gap`` [s] dropped (switch times may
    cluster), the end always kept."""
    prof = JerkProfile(traj)
    T = prof.duration
    t = sample_times(T, prof.switch_times(), rate, min_samples)
    t = t[thin(t, min_gap)]
    if T - t[-1] < min_gap and len(t) > 1:
        t = t[:-1]
    t = np.append(t, T) if t[-1] < T else t
    return (t,) + prof.at(t)


def rest_to_rest(crane: Crane, q0, q1, *, sample_rate: float | None = 200.0,
                 scale: float = 1.0) -> PlanResult:
    """Time-optimal synchronised jerk-limited move from q0 to q1 (both at rest).

    ``scale`` ≤ 1 plans with that fraction of every velocity/acceleration limit. The result's
    trajectory is sampled at ``sample_rate`` [Hz] plus every switching time (kept in
    ``meta["switch_times"]``); with ``sample_rate=None`` at the switching times only, which
    the quintic interpolation of :class:`~planner.trajectory.Trajectory` already reproduces
    exactly (the motion is cubic between them)."""
    t0 = _time.perf_counter()
    q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
    limits = _ruckig_limits(crane, float(scale))
    lo_l, hi_l = limits[4], limits[5]
    n = crane.n
    ok = q0.shape == (n,) and q1.shape == (n,)
    if ok:
        l0, l1 = q0.tolist(), q1.tolist()
        le = float.__le__   # NaN fails every comparison
        ok = (all(map(le, lo_l, l0)) and all(map(le, l0, hi_l)) and all(map(le, lo_l, l1))
              and all(map(le, l1, hi_l)))
    if not ok:
        L = crane.limit_arrays()
        lo, hi = L["q_min"] - 1e-9, L["q_max"] + 1e-9
        for name, q in (("start", q0), ("goal", q1)):   # name the first bad value
            bad = (np.flatnonzero(~((q >= lo) & (q <= hi))) if q.shape == (crane.n,) else None)
            if bad is not None and not bad.size:
                continue
            what = (f"needs {crane.n} joint values" if bad is None else
                    f"{crane.names[bad[0]]} = {q[bad[0]]:.4f} is outside "
                    f"[{L['q_min'][bad[0]]:.4f}, {L['q_max'][bad[0]]:.4f}]")
            return PlanResult(PlanStatus.INVALID, f"{name} configuration: {what}",
                              solve_time_s=_time.perf_counter() - t0)
    if sample_rate is not None and not sample_rate > 0:
        raise ValueError(f"rest_to_rest: sample_rate = {sample_rate!r}; allowed: a rate > 0 "
                         "[Hz], or None for the switching times only")
    otg, inp, traj, _ = _rest_input(n, limits)
    inp.current_position = l0
    inp.target_position = l1
    try:
        res = otg.calculate(inp, traj)
    except (RuntimeError, ruckig.RuckigError) as e:  # invalid input or no profile found
        res = f"{str(e).strip().splitlines()[0]}"
    if res not in (ruckig.Result.Working, ruckig.Result.Finished):
        return PlanResult(PlanStatus.FAILED, f"Ruckig: {getattr(res, 'name', res)}",
                          solve_time_s=_time.perf_counter() - t0)
    T = float(traj.duration)
    if T <= 0:
        sw = [0.0, 1e-9]
    else:
        sw = _switch_list(traj, 1e-6)       # near-duplicates would add 1/h³ noise
        if sw[-1] < T:   # the end dropped as a near-duplicate: keep the end, not its neighbour
            sw[-1] = T
    if sample_rate is None and T > 0:
        # the move at its switching times only: Ruckig's own states there (a handful of
        # calls), no piece table; one flat conversion to (3, samples, DOF)
        flat = _chain(_chain(map(traj.at_time, sw)))
        block = np.fromiter(flat, float, 3 * n * len(sw)).reshape(len(sw), 3, n)
        q, qd, qdd = block.transpose(1, 0, 2)
        t = np.array(sw)
    else:
        t = np.array(sw) if sample_rate is None or T <= 0 else sample_times(T, sw,
                                                                            sample_rate, 50)
        q, qd, qdd = JerkProfile(traj).at(t)
        block = None
    tr = Trajectory.trusted(t, q, qd, qdd, block=block, joint_names=tuple(crane.names), method="ruckig",
                            objective="time",
                            limits=("position", "velocity", "acceleration", "jerk"),
                            meta=dict(independent_min_durations=list(
                                traj.independent_min_durations), switch_times=sw))
    return PlanResult(PlanStatus.OK, trajectory=tr, duration_s=T,
                      solve_time_s=_time.perf_counter() - t0)


class RuckigPlanner(Planner):
    """``ruckig``: the jerk-limited rest-to-rest joint move between the tip ends, each end at
    the telescope the analytic lower bound finds best (:func:`~planner.bounds.lower_bound`)."""
    name = "ruckig"
    description = "jerk-limited rest-to-rest joint move (Ruckig), free path"
    objectives = ("time",)
    paths = ("free",)

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        lb = lower_bound(crane, request.start, request.goal)
        return rest_to_rest(crane, crane.ik(request.start, lb.tele_start),
                            crane.ik(request.goal, lb.tele_goal))


register(RuckigPlanner())
