"""Trajectory -> valve feed-forward commands, their kinematic replay, and seed 003's
pressure-based progress estimate.

The valve model is :mod:`planner.model.valves` (pressure-compensated proportional valves, dead
band, metered area by direction, the single-acting lowering rule); it is used in both directions
so that the round trip :func:`commands` -> :func:`predict_motion` is an exact inverse up to the
hold approximation. Stroke rate ẋ = dx/dq·q̇ from the crane's stroke map (each actuator depends
only on its own joint, so dx/dq is diagonal and the map is one-to-one over the joint range).
The optional hydraulic transformer of s100f (disabled by default) is not modelled here: with it
enabled, part of the target cylinder's flow bypasses its valve, which a valve-level
feed-forward would have to account for separately.

Commands are produced on a uniform grid at the control ``rate`` and held (zero-order hold) over
each period [t_k, t_k + 1/rate). Two ways of choosing the held value:

* ``hold="mean"`` (default): the command whose flow delivers exactly the stroke displacement of
  its period, ẋ_k = (x(t_{k+1}) − x(t_k))·rate. A controller that replays the commands at the
  same rate reproduces the planned joint positions exactly at every control instant (the
  remaining error is the intra-period deviation, O(a·Δt²/8)).
* ``hold="sample"``: the instantaneous stroke rate at t_k (the literal "sample and hold").
  This lags the plan by about half a period: O(q̇·Δt/2) during the move, returning to ~0 at
  the end of a rest-to-rest move.

``oil=True`` (the machine's feed-forward, where the crane has ``[dynamics]``): the flow a
command asks for also fills each function's oil spring to the chamber pressures the plan needs
(``evaluate()``'s p_a, p_b; :mod:`planner.model.twin.oil`), ẋ + ṗ_a/(κ_a·A_a) − ṗ_b/(κ_b·A_b).
Without it both flow-controlled valve edges leave no oil for the pressure a plan's acceleration
or load change needs: the function lags, overshoots and rings at its oil-spring frequency, and
the pump pushes against the choked outlet. The correction is applied only where the plain
command is open, in its direction: a valve the plan keeps closed is not cracked (a crept valve
would set the load-sensing pump's pressure, see :mod:`planner.methods.nlp.idle`) and none is
reversed (a reversal signals the other chamber). :func:`predict_motion` inverts the plain
commands only.

:func:`predict_motion` is the inverse: commands -> flows (inverting the dead band) -> stroke
rates -> joint positions, integrated exactly per period (the held command gives a constant
stroke rate, and q = joint_from_stroke(x)). It is purely kinematic: no pump sharing, no load
dependence, no dynamics — the open-loop replay of a perfect pressure-compensated valve.

:func:`progress_estimator` (seed 003): without joint sensors, pick the cylinder pressure
difference ΔP = p_a − p_b that is most monotone along the planned motion and use it as the path
parameter: q_j ≈ g_j(ΔP) (polynomial fits). Where ΔP is not monotone the estimate is ambiguous;
those intervals are reported.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import Polynomial

from planner.model.twin.oil import filled_commands, fills_oil, oil_stroke_rate
from planner.model.valves import (command_to_stroke_rate, stroke_rate_to_command,
                                  valve_params)
from planner.trajectory import Trajectory, evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["FeedForward", "SaturationInterval", "commands", "predict_motion", "round_trip",
           "stored_commands", "on_command_grid", "with_settle", "fills_oil",
           "ProgressEstimator", "progress_estimator"]

# ----------------------------------------------------------------------------- commands
@dataclass(frozen=True)
class SaturationInterval:
    """Commands of one joint clipped at ±1 over [t_start, t_end) (hold periods)."""
    joint: str
    t_start: float          # [s] first saturated control instant
    t_end: float            # [s] end of the last saturated hold period
    peak_command: float     # largest |u| before clipping (> 1)
    peak_flow: float        # [m³/s] largest flow asked of the valve
    flow_gain: float        # [m³/s] what the valve delivers at |u| = 1

    @property
    def excess(self) -> float:
        """Relative flow excess at the worst instant (0.25 = 25 % more than the valve gives)."""
        return self.peak_flow / self.flow_gain - 1.0

    def __str__(self):
        return (f"{self.joint}: saturated {self.t_start:.3f}–{self.t_end:.3f} s, needs "
                f"{100 * self.excess:.1f} % more flow than the valve's "
                f"{self.flow_gain * 6e4:.1f} L/min (peak |u| = {self.peak_command:.3f})")


@dataclass
class FeedForward:
    """Valve commands on a uniform control grid.

    t (M,) [s], u (M, n) in [−1, 1]: u[k] is held over [t[k], t[k] + 1/rate). ``saturated``:
    joint name -> list of :class:`SaturationInterval` (empty dict: no saturation).
    ``u_raw``: commands before clipping; ``flow``: signed valve flows asked for [m³/s]."""
    t: np.ndarray
    u: np.ndarray
    saturated: dict
    rate: float
    joint_names: tuple = ()
    hold: str = "mean"
    u_raw: np.ndarray | None = None
    flow: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when no command had to be clipped."""
        return not self.saturated

    def attach(self, traj: Trajectory, knots: bool = False) -> Trajectory:
        """``traj`` resampled on the control grid, with ``u`` set (ready for ``to_csv``).

        Control instants past the trajectory's end (the grid is uniform, so the last one may
        overshoot by less than a period) hold its final state. ``knots=True`` also keeps the
        trajectory's own sample times (e.g. an NLP's nodes, where its jerk switches): the
        quintic interpolation through the result then reproduces ``traj`` exactly (a 50 Hz
        resampling alone can overshoot the jerk limit by ~20 % where a switch falls inside a
        period); the rows between control instants carry the command held over that period, so
        a zero-order-hold replay of the rows is the same signal as the control grid's."""
        t = self.t
        if knots:
            inside = traj.t[(traj.t > self.t[0]) & (traj.t < self.t[-1])]
            t = np.union1d(self.t, inside)
            # drop knots within a microsecond of a control instant (no near-duplicate rows)
            k = np.searchsorted(self.t, t)
            near = np.minimum(np.abs(t - self.t[np.clip(k, 0, len(self.t) - 1)]),
                              np.abs(t - self.t[np.clip(k - 1, 0, len(self.t) - 1)]))
            t = t[(near > 1e-6) | np.isin(t, self.t)]
        held = np.clip(np.searchsorted(self.t, t + 1e-12, side="right") - 1, 0, len(self.t) - 1)
        q, qd, qdd, _ = traj.sample(t)
        names = tuple(traj.joint_names) or self.joint_names
        meta = dict(traj.meta)
        meta.update(feedforward=dict(rate=self.rate, hold=self.hold,
                                     saturated={k: [str(s) for s in v]
                                                for k, v in self.saturated.items()}))
        meta["feedforward"]["knots"] = bool(knots)
        meta["feedforward"]["oil"] = bool(self.meta.get("oil", False))
        return Trajectory(t.copy(), q, qd, qdd, joint_names=names, method=traj.method,
                          objective=traj.objective, interpolation="quintic", limits=traj.limits,
                          u=self.u[held].copy(), meta=meta)

    def to_csv(self, path, traj: Trajectory) -> Trajectory:
        """Write the trajectory CSV (CONTRACT: t, q_*, qd_*, qdd_*, u_*) at the control rate;
        returns the resampled trajectory that was written."""
        out = self.attach(traj)
        out.to_csv(path)
        return out

    def summary(self) -> dict:
        """JSON-ready: rate, hold, peak |u| per joint, saturation intervals."""
        return dict(rate_hz=self.rate, hold=self.hold,
                    peak_command={j: float(np.max(np.abs(self.u_raw[:, i])))
                                  for i, j in enumerate(self.joint_names)},
                    saturated={k: [dict(t_start=s.t_start, t_end=s.t_end,
                                        peak_command=s.peak_command, excess=s.excess)
                                   for s in v] for k, v in self.saturated.items()})


def _runs(mask):
    """(start, stop) index pairs (stop exclusive) of the True runs of a 1-D bool array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(int)))
    return list(zip(d[::2], d[1::2]))


def commands(crane: Crane, traj: Trajectory, rate: float = 50.0,
             hold: str = "mean", oil: bool = False) -> FeedForward:
    """Valve feed-forward of ``traj`` at the control ``rate`` [Hz] (see the module doc).

    The grid is t0 + k/rate, k = 0 … ceil(duration·rate) (the last instant may lie up to one
    period past the end; the trajectory then holds its final state). ``hold`` = "mean"
    (stroke displacement per period, default) or "sample" (instantaneous rate at t_k).
    ``oil=True`` (cranes with ``[dynamics]``, :func:`fills_oil`) adds the flow that fills each
    function's oil spring to the pressures the plan needs (module doc); a valve the plain
    command keeps closed stays closed and none is reversed."""
    if traj.n != crane.n:
        raise ValueError(f"trajectory has {traj.n} joints, crane '{crane.spec.id}' has {crane.n}")
    if not (rate > 0 and math.isfinite(rate)):
        raise ValueError(f"rate must be a positive number of Hz, got {rate}")
    if hold not in ("mean", "sample"):
        raise ValueError(f"hold = {hold!r}; allowed: 'mean', 'sample'")
    vp = valve_params(crane)
    dt = 1.0 / rate
    M = max(1, int(math.ceil(traj.duration * rate - 1e-9)))
    t = traj.t[0] + dt * np.arange(M + 1)
    q, qd, _, _ = traj.sample(t)
    x, dxdq = crane.stroke(q)
    xd = dxdq * qd                     # instantaneous stroke rate at every control instant
    if hold == "mean":
        # past the end sample() clips: the final state is held, which is what we want
        xd[:-1] = np.diff(x, axis=0) / dt
        if t[-1] > traj.t[-1]:         # past the end: hold the final state's rate (rest: 0)
            _, qd_end, _, _ = traj.sample(traj.t[-1:])
            xd[-1] = crane.stroke(q[-1])[1] * qd_end[0]
    if oil:
        if not fills_oil(crane):
            raise ValueError(f"oil=True: crane '{crane.spec.id}' has no [dynamics] (hose "
                             "volumes, bulk modulus) or an enabled transformer; allowed: "
                             "oil=False")
        ev = evaluate(crane, traj)      # the plan's chamber pressures, on its 1 kHz grid
        r = oil_stroke_rate(crane, ev.t, ev.hyd["x"], ev.hyd["p_a"], ev.hyd["p_b"], t, hold)
        u_raw, flow = filled_commands(vp, xd, r)
    else:
        u_raw, flow = stroke_rate_to_command(vp, xd)
    u = np.clip(u_raw, -1.0, 1.0)
    names = tuple(crane.names)
    sat = {}
    for i, name in enumerate(names):
        over = np.abs(u_raw[:, i]) > 1.0
        for a, b in _runs(over):
            k = a + int(np.argmax(np.abs(u_raw[a:b, i])))
            sat.setdefault(name, []).append(SaturationInterval(
                joint=name, t_start=float(t[a]), t_end=float(t[b - 1] + dt),
                peak_command=float(abs(u_raw[k, i])), peak_flow=float(abs(flow[k, i])),
                flow_gain=float(vp.flow_gain[i])))
    return FeedForward(t=t, u=u, saturated=sat, rate=float(rate), joint_names=names, hold=hold,
                       u_raw=u_raw, flow=flow, meta=dict(crane=crane.spec.id, oil=bool(oil)))


def stored_commands(traj: Trajectory, rate: float = 50.0):
    """(t_u, u) of a stored entry: its ``u`` at the samples on the ``rate`` grid (a library
    entry keeps the 50 Hz control grid plus the plan's own knots); None when the trajectory
    carries no commands or its samples do not cover that grid."""
    if traj.u is None:
        return None
    k = np.round((traj.t - traj.t[0]) * rate)
    on = np.abs((traj.t - traj.t[0]) * rate - k) < 1e-6
    kk = k[on].astype(int)
    if kk.size < 2 or not np.array_equal(kk, np.arange(kk.size)):
        return None
    return traj.t[on], np.asarray(traj.u)[on]


def on_command_grid(traj: Trajectory, t_u, u) -> Trajectory:
    """``traj`` resampled on the command times ``t_u`` (M,) carrying the commands ``u`` (M, n):
    what a replay of other commands for the same plan takes (e.g. the twin-refined commands,
    which may run past the plan's end: the plan is held at its goal there)."""
    from dataclasses import replace
    t_u = np.asarray(t_u, float).ravel()
    q, qd, qdd, _ = traj.sample(np.clip(t_u, traj.t[0], traj.t[-1]))
    past = t_u > traj.t[-1]
    qd[past], qdd[past] = 0.0, 0.0
    return replace(traj, t=t_u, q=q, qd=qd, qdd=qdd, u=np.asarray(u, float))


def with_settle(crane: Crane, traj: Trajectory, settle: float, rate: float = 50.0,
                oil: bool = False) -> Trajectory:
    """The replay of ``traj``'s commands (its own ``u`` on a uniform grid, else the
    feed-forward at ``rate``, the oil filled with ``oil``) followed by ``settle`` [s] with every
    valve closed, on one uniform command grid (the plan held at its goal): the arrival and its
    ringing recorded."""
    if not (math.isfinite(settle) and 0.0 <= settle <= 600.0):
        raise ValueError(f"settle = {settle!r} s; allowed: 0 .. 600 s")
    if traj.u is not None and len(traj.t) > 2 and np.ptp(np.diff(traj.t)) < 1e-9:
        t_u, u = np.asarray(traj.t, float), np.asarray(traj.u, float)
        dt = float(t_u[1] - t_u[0])
    else:
        ff = commands(crane, traj, rate, oil=oil)
        t_u, u, dt = np.asarray(ff.t, float), np.asarray(ff.u, float), 1.0 / rate
    k = int(math.ceil(settle / dt - 1e-9))
    t_all = np.concatenate([t_u, t_u[-1] + dt * np.arange(1, k + 1)])
    u_all = np.vstack([u, np.zeros((k, u.shape[1]))])
    return on_command_grid(traj, t_all, u_all)


# ----------------------------------------------------------------------------- replay
def predict_motion(crane: Crane, t, u, q0, flow_scale=1.0, substeps: int = 1,
                   joint_names=None) -> Trajectory:
    """Kinematic open-loop replay of valve commands (the inverse of :func:`commands`).

    ``t`` (M,) strictly increasing [s], ``u`` (M, n): u[k] is held over [t[k], t[k+1]) (the last
    row is not used). Commands are clipped to [−1, 1]; |u| ≤ deadband gives no flow;
    ``flow_scale`` (scalar or per joint) multiplies every valve's flow (a gain error for
    robustness studies). Within a period the stroke rate is constant, so the strokes are
    integrated exactly and mapped back with the inverse stroke map. ``substeps`` > 1 also
    returns that many equally spaced points inside every period. Returns a Trajectory with
    piecewise-linear interpolation (joint positions from q0)."""
    t = np.asarray(t, float).ravel()
    u = np.atleast_2d(np.asarray(u, float))
    q0 = np.asarray(q0, float).ravel()
    n = crane.n
    if u.shape != (t.size, n) or q0.shape != (n,):
        raise ValueError(f"predict_motion: expected t (M,), u (M, {n}), q0 ({n},); got "
                         f"{t.shape}, {u.shape}, {q0.shape}")
    if t.size < 2 or np.any(np.diff(t) <= 0):
        raise ValueError("predict_motion: t needs at least two strictly increasing instants")
    substeps = int(substeps)
    if substeps < 1:
        raise ValueError("predict_motion: substeps must be >= 1")
    vp = valve_params(crane)
    xd = command_to_stroke_rate(vp, u[:-1], flow_scale)         # (M-1, n) per period
    h = np.diff(t)
    frac = np.arange(substeps) / substeps
    tt = np.concatenate([(t[:-1, None] + h[:, None] * frac[None, :]).ravel(), t[-1:]])
    dx = np.repeat(xd * (h / substeps)[:, None], substeps, axis=0)
    x0, _ = crane.stroke(q0)
    x = x0[None, :] + np.vstack([np.zeros((1, n)), np.cumsum(dx, axis=0)])
    q = crane.joint_from_stroke(x)
    q[0] = q0
    for _ in range(2):                 # polish (joint_from_stroke starts from a table look-up)
        xq, d = crane.stroke(q[1:])
        q[1:] -= (xq - x[1:]) / d
    # an actuator whose stroke did not change stands exactly still (no round-off drift)
    k = np.arange(len(x))[:, None]
    moved = np.vstack([np.ones((1, n), bool), x[1:] != x[:-1]])
    last = np.maximum.accumulate(np.where(moved, k, 0), axis=0)
    q = np.take_along_axis(q, last, axis=0)
    names = tuple(joint_names) if joint_names else tuple(crane.names)
    return Trajectory(tt, q, joint_names=names, method="feedforward-replay",
                      interpolation="linear",
                      meta=dict(flow_scale=np.asarray(flow_scale, float).tolist(),
                                substeps=substeps))


def round_trip(crane: Crane, traj: Trajectory, rate: float = 50.0, hold: str = "mean",
               substeps: int = 8) -> dict:
    """commands -> predict_motion -> compare with ``traj``. Returns max |q_pred − q_plan| per
    joint at the control instants (``at_samples``) and on the ``substeps``-refined grid
    (``overall``), plus the FeedForward."""
    ff = commands(crane, traj, rate, hold=hold)
    pred = predict_motion(crane, ff.t, ff.u, traj.q[0], substeps=substeps)
    q_plan = traj.sample(pred.t)[0]
    err = np.abs(pred.q - q_plan)
    at = err[::substeps]
    return dict(at_samples=at.max(axis=0), overall=err.max(axis=0), feedforward=ff,
                prediction=pred)


# ----------------------------------------------------------------------------- progress (seed 003)
def _spearman(a, b) -> float:
    """Spearman rank correlation (average ranks for ties); 0 when either input is constant."""
    from scipy.stats import rankdata
    ra, rb = rankdata(a), rankdata(b)
    sa, sb = np.std(ra), np.std(rb)
    if sa == 0 or sb == 0:
        return 0.0
    return float(np.mean((ra - ra.mean()) * (rb - rb.mean())) / (sa * sb))


def _intervals(t, mask_seg, min_gap: float = 0.0):
    """Merge flagged segments [t_k, t_{k+1}] (mask over N-1 segments) into sample-index pairs
    (a, b) covering t[a]..t[b]; runs separated by less than ``min_gap`` [s] are joined."""
    out = []
    for a, b in _runs(mask_seg):
        if out and t[a] - t[out[-1][1]] < min_gap:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


@dataclass
class ProgressEstimator:
    """q_j ≈ g_j(ΔP) for the chosen actuator's ΔP = p_a − p_b (seed 003).

    ``non_monotone``: time intervals (t0, t1) [s] where ΔP moves against its overall direction
    (``reversals``: by how much, Pa, same order); ``ambiguous``: time intervals where the ΔP
    value is taken more than once along the motion (g cannot tell those instants apart).
    ``rms``: fit residual per joint (rad | m); ``max_error``: largest residual per joint.
    ``spearman``: |rank correlation of ΔP with time| of every candidate actuator."""
    cylinder: str
    index: int
    direction: int                # +1: ΔP rises along the motion, −1: falls
    polys: list
    rms: dict
    max_error: dict
    spearman: dict
    non_monotone: list
    reversals: list
    ambiguous: list
    dp_range: tuple
    t: np.ndarray
    dp: np.ndarray
    q: np.ndarray
    joint_names: tuple

    @property
    def monotone(self) -> bool:
        return not self.non_monotone

    def estimate(self, dp_value):
        """Joint positions for ΔP value(s) [Pa]: scalar -> (n,), array (N,) -> (N, n).
        ΔP is clipped to the fitted range (no polynomial extrapolation)."""
        d = np.clip(np.asarray(dp_value, float), *self.dp_range)
        return np.stack([p(d) for p in self.polys], axis=-1)

    def summary(self) -> dict:
        """JSON-ready description (SI)."""
        return dict(cylinder=self.cylinder, direction=self.direction, monotone=self.monotone,
                    non_monotone_s=[list(iv) for iv in self.non_monotone],
                    reversals_Pa=list(self.reversals),
                    ambiguous_s=[list(iv) for iv in self.ambiguous],
                    dp_range_Pa=list(self.dp_range), rms=dict(self.rms),
                    max_error=dict(self.max_error), spearman=dict(self.spearman))

    def __str__(self):
        mono = "monotone" if self.monotone else \
            "NOT monotone in " + ", ".join(f"{a:.2f}–{b:.2f} s" for a, b in self.non_monotone)
        rms = ", ".join(f"{k} {v:.2e}" for k, v in self.rms.items())
        return f"progress from ΔP of '{self.cylinder}' ({mono}); fit RMS: {rms}"


def progress_estimator(crane: Crane, traj: Trajectory, degree: int = 5, rate: float = 200.0,
                       candidates=None, tol: float = 1e-3, min_range: float = 1e5,
                       payload=None) -> ProgressEstimator:
    """Seed 003's position estimate from pressures along the planned motion of ``traj``.

    ΔP_i = p_a − p_b of every candidate actuator (names or indices; default: all) comes from
    :func:`~planner.trajectory.evaluate` at ``rate`` [Hz] (its grid also holds every sample of
    ``traj``). A *reversal* is a stretch where ΔP moves against its overall direction (the sign
    of its Spearman rank correlation with time) by more than ``tol``·(its range) in total —
    smaller wiggles (default 0.1 % of the range) are below any pressure transducer's
    resolution. The chosen ΔP is, first, one without reversals, then the one with the largest
    |Spearman correlation| with time. Candidates whose ΔP spans less than ``min_range`` [Pa]
    (default 1 bar: e.g. an unloaded slew drive, whose ΔP is numerical noise) are skipped
    unless none is left. Polynomials of ``degree`` map it to every joint
    (numpy Polynomial.fit, least squares); they are fitted on the whole motion even where ΔP is
    not monotone (those intervals are reported, and the fit there is a compromise)."""
    ev = evaluate(crane, traj, rate=rate, payload=payload)
    t, q = ev.t, ev.q
    dp_all = np.atleast_2d(ev.hyd["p_a"] - ev.hyd["p_b"])
    names = tuple(crane.names)
    idx = list(range(crane.n)) if candidates is None else [
        int(c) if isinstance(c, (int, np.integer)) else names.index(c) for c in candidates]
    gap = 0.5 / rate

    def reversals(dp, s):
        span = float(np.ptp(dp))
        sd = s * dp
        out = []
        for a, b in _intervals(t, np.diff(sd) < 0, gap):
            drop = float(np.max(sd[a:b + 1]) - np.min(sd[a:b + 1]))
            if drop > tol * span:
                out.append((a, b, drop))
        return out

    usable = [i for i in idx if np.ptp(dp_all[:, i]) >= min_range] or idx
    scores, best = {}, None
    for i in usable:
        dp = dp_all[:, i]
        rho = _spearman(t, dp) if np.ptp(dp) > 0 else 0.0
        scores[names[i]] = abs(rho)
        s = 1 if rho >= 0 else -1
        key = (np.ptp(dp) > 0 and not reversals(dp, s), abs(rho))
        if best is None or key > best[0]:
            best = (key, i, s)
    _, c, s = best
    dp = dp_all[:, c]
    span = float(np.ptp(dp))
    rev = reversals(dp, s)
    # ambiguity: a value already passed (running extreme) or to be passed again later
    sd = s * dp
    back = sd < np.maximum.accumulate(sd) - tol * span
    ahead = sd > np.minimum.accumulate(sd[::-1])[::-1] + tol * span
    amb = back | ahead
    ambiguous = [(float(t[a]), float(t[b]))
                 for a, b in _intervals(t, amb[:-1] | amb[1:], gap)]
    polys, rms, emax = [], {}, {}
    for j, name in enumerate(names):
        p = Polynomial.fit(dp, q[:, j], degree)
        polys.append(p)
        r = p(dp) - q[:, j]
        rms[name] = float(np.sqrt(np.mean(r ** 2)))
        emax[name] = float(np.max(np.abs(r)))
    return ProgressEstimator(cylinder=names[c], index=c, direction=s, polys=polys, rms=rms,
                             max_error=emax, spearman=scores,
                             non_monotone=[(float(t[a]), float(t[b])) for a, b, _ in rev],
                             reversals=[d for _, _, d in rev], ambiguous=ambiguous,
                             dp_range=(float(dp.min()), float(dp.max())), t=t, dp=dp, q=q,
                             joint_names=names)
