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
measured excess, for that joint), then solves again. The trajectory is sampled once, at the
end, with numpy (``ParametrizeConstAccel``'s formula: s quadratic in t on each interval).
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint
from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

from planner.geometry.paths import Line
from planner.methods.base import Planner, PlanRequest, PlanResult
from planner.methods.dp import DPPlanner, dp
from planner.methods.registry import register
from planner.model.flows import swept_volume
from planner.trajectory import Trajectory

__all__ = ["PumpFlowConstraint", "ScaledAcceleration", "SpeedCap", "PathTiming", "Peaks",
           "interval_peaks", "time_path", "TimedPath", "retime", "ToppPlanner"]

toppra.setup_logging("ERROR")  # failures are reported as statuses, not log lines

SCHEMES = {"interpolation": constraint.DiscretizationType.Interpolation,
           "collocation": constraint.DiscretizationType.Collocation}


class PumpFlowConstraint(constraint.LinearConstraint):
    """Σ A_dir,i |dx_i/ds| · ṡ ≤ Q_max as a bound on x = ṡ² (first order, direction-aware)."""

    def __init__(self, crane, scale: float = 1.0):
        super().__init__()
        self.crane = crane
        self.dof = crane.n
        self.scale = scale  # fraction of the pump's max flow to plan with

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        flow_per_sd = pump_flow_per_speed(self.crane, path(gridpoints), path(gridpoints, 1))
        qmax = self.scale * self.crane.spec.pump.max_flow
        with np.errstate(divide="ignore"):
            xmax = np.where(flow_per_sd > 1e-15, (qmax / flow_per_sd) ** 2, 1e12)
        xbound = np.column_stack([np.zeros_like(xmax), xmax])
        return None, None, None, None, None, None, xbound


def pump_flow_per_speed(crane, q, dq) -> np.ndarray:
    """Pump flow [m³ per unit of s] of moving along a path at ṡ = 1: Σ A_dir |dx/ds| at the
    joint positions ``q`` (..., n) with path tangents ``dq`` = dq/ds (..., n)."""
    _, dxdq = crane.stroke(q)
    return swept_volume(crane.spec, dxdq * dq).sum(-1)


class SpeedCap(constraint.LinearConstraint):
    """ṡ ≤ cap_i at every grid point as toppra's ``xbound`` (x = ṡ² ≤ cap_i²): the joint
    velocity limits and the pump limit, each already turned into a cap on ṡ per grid point
    (the caller scales them per grid point)."""

    def __init__(self, cap):
        super().__init__()
        self.cap = np.asarray(cap, float)

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        xmax = np.minimum(self.cap ** 2, 1e12)
        return None, None, None, None, None, None, np.column_stack([0 * xmax, xmax])


class ScaledAcceleration(constraint.LinearConstraint):
    """|q'(s_i) u + q''(s_i) x| ≤ f_ij · a_j per joint j and grid point i: toppra's joint
    acceleration constraint with a factor per grid point and joint (``scale`` (N+1, n)),
    written as the rows a_i / f_i, b_i / f_i against the nominal limits."""

    def __init__(self, dq, ddq, alim, scale, scheme="interpolation"):
        super().__init__()
        self.a, self.b = dq / scale, ddq / scale
        n = dq.shape[1]
        self.dof = n
        self.F = np.vstack([np.eye(n), -np.eye(n)])
        self.g = np.concatenate([alim, alim])
        self.identical = True
        self.set_discretization_type(SCHEMES[scheme])

    def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
        c = np.zeros_like(self.a)
        if self.discretization_type == constraint.DiscretizationType.Collocation:
            return self.a, self.b, c, self.F, self.g, None, None
        return canlinear_colloc_to_interpolate(self.a, self.b, c, self.F, self.g, None, None,
                                               gridpoints, identical=True)


@dataclass
class PathTiming:
    """A constant-path-acceleration timing (toppra's ``ParametrizeConstAccel``) of a path:
    grid ``s`` (N+1,) and path speeds ``sd`` (N+1,) at the grid points; on interval i the path
    acceleration is u_i = (ṡ²_{i+1} − ṡ²_i) / (2 Δs_i) and it takes 2 Δs_i / (ṡ_i + ṡ_{i+1})."""
    s: np.ndarray
    sd: np.ndarray

    def __post_init__(self):
        ds = np.diff(self.s)
        x = self.sd ** 2
        self.u = 0.5 * (x[1:] - x[:-1]) / ds
        with np.errstate(divide="ignore"):
            dt = 2.0 * ds / (self.sd[1:] + self.sd[:-1])
        self.t = np.concatenate([[0.0], np.cumsum(dt)])

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, t) -> tuple:
        """(s, ṡ, s̈) at times ``t`` [s] (clipped to [0, duration])."""
        t = np.clip(np.asarray(t, float), 0.0, self.t[-1])
        i = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.u) - 1)
        dt = t - self.t[i]
        u = self.u[i]
        return self.s[i] + dt * (self.sd[i] + 0.5 * dt * u), self.sd[i] + dt * u, u


@dataclass
class Peaks:
    """Largest relative excess (value / limit − 1, ≤ 0 when inside) per grid interval:
    ``velocity`` and ``acceleration`` (N, n) per joint, ``pump_flow`` (N,)."""
    velocity: np.ndarray
    acceleration: np.ndarray
    pump_flow: np.ndarray

    def worst(self, kinds) -> float:
        """The largest excess over ``kinds`` (0 when every limit holds)."""
        return max([0.0] + [float(np.max(getattr(self, k))) for k in kinds])


def _piece_tables(spline, grid):
    """The pieces between the union of spline knots and grid points: start s_a, length h,
    grid interval i, and q', q'', q''' at s_a (q''' is constant on a piece)."""
    knots = spline.x
    b = np.union1d(grid, knots[(knots > grid[0]) & (knots < grid[-1])])
    sa, h = b[:-1], np.diff(b)
    keep = h > 0
    sa, h = sa[keep], h[keep]
    mid = sa + 0.5 * h
    i = np.clip(np.searchsorted(grid, mid, side="right") - 1, 0, len(grid) - 2)
    p = np.clip(np.searchsorted(knots, mid, side="right") - 1, 0, len(knots) - 2)
    c = spline.c[:, p, :]                 # (4, P, n): q = c0 σ³ + c1 σ² + c2 σ + c3
    z = (sa - knots[p])[:, None]
    d1 = (3 * c[0] * z + 2 * c[1]) * z + c[2]
    d2 = 6 * c[0] * z + 2 * c[1]
    return sa, h, i, d1, d2, 6 * c[0]


def interval_peaks(spline, timing: PathTiming, vlim, alim, flow=None, qmax=None) -> Peaks:
    """Exact per-interval peaks of the joint velocity and acceleration of ``timing`` along the
    cubic spline ``spline`` (scipy ``CubicSpline`` q(s)), against ``vlim`` (n, 2) and ``alim``
    (n,); with ``flow`` (a function (q, dq/ds) → pump flow per unit path speed [m³], as
    :func:`pump_flow_per_speed`) and ``qmax`` [m³/s] also the pump flow's, at the pieces'
    ends, midpoints and velocity peaks."""
    grid, N = timing.s, len(timing.s) - 1
    sa, h, i, d1, d2, d3 = _piece_tables(spline, grid)
    u = timing.u[i][:, None]
    xa = (timing.sd[i] ** 2 + 2 * timing.u[i] * (sa - grid[i]))[:, None]
    A0, A1, A2 = u * d1 + d2 * xa, 3 * u * d2 + d3 * xa, 2.5 * u * d3
    H = h[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        vert = np.where(A2 != 0, -A1 / (2 * A2), 0.0)
        disc = np.sqrt(np.maximum(A1 * A1 - 4 * A0 * A2, 0.0))
        lin = np.where(A1 != 0, -A0 / A1, 0.0)
        r1 = np.where(A2 != 0, (-A1 + disc) / (2 * A2), lin)
        r2 = np.where(A2 != 0, (-A1 - disc) / (2 * A2), lin)
    # candidates σ per piece and joint: both ends, the vertex of q̈ and the roots of q̈
    sig = np.stack([0 * H + 0 * A0, H + 0 * A0, vert, r1, r2], axis=-1)
    sig = np.clip(np.nan_to_num(sig), 0.0, H[..., None])
    dq = d1[..., None] + sig * (d2[..., None] + 0.5 * sig * d3[..., None])
    x = np.maximum(xa[..., None] + 2 * u[..., None] * sig, 0.0)
    qdd = A0[..., None] + sig * (A1[..., None] + sig * A2[..., None])
    qd = dq * np.sqrt(x)
    vmin, vmax = vlim[:, 0][None, :, None], vlim[:, 1][None, :, None]
    rel_v = np.maximum(qd / vmax, qd / vmin).max(axis=-1) - 1.0
    rel_a = (np.abs(qdd) / alim[None, :, None]).max(axis=-1) - 1.0
    vel, acc = np.full((N, len(alim)), -1.0), np.full((N, len(alim)), -1.0)
    np.maximum.at(vel, i, rel_v)
    np.maximum.at(acc, i, rel_a)
    pump = np.full(N, -1.0)
    if flow is not None:
        ss = np.concatenate([sa[:, None] + sig[..., 3:].reshape(len(sa), -1),
                             (sa + 0.5 * h)[:, None], (sa + h)[:, None], sa[:, None]], axis=1)
        ii = np.broadcast_to(i[:, None], ss.shape)
        xs = np.maximum(timing.sd[ii] ** 2 + 2 * timing.u[ii] * (ss - grid[ii]), 0.0)
        fl = flow(spline(ss.ravel()), spline(ss.ravel(), 1)).reshape(ss.shape) * np.sqrt(xs)
        np.maximum.at(pump, i, fl.max(axis=1) / qmax - 1.0)
    return Peaks(vel, acc, pump)


@dataclass
class TimedPath:
    """What :func:`time_path` returns: ``status`` ("ok" | "infeasible" | "violation"),
    ``reason``, the ``timing`` (:class:`PathTiming`, None when infeasible) of the ``path``
    (toppra ``SplineInterpolator``), ``iterations`` (TOPP-RA solves), the last verification's
    ``peaks`` (None unverified) and ``max_limit_violation`` (their worst excess, ≥ 0)."""
    status: str
    reason: str
    path: object
    timing: PathTiming | None = None
    iterations: int = 0
    peaks: Peaks | None = None
    max_limit_violation: float = float("nan")

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def sample(self, t) -> tuple:
        """(q, q̇, q̈) (len(t), n) at times ``t`` [s], vectorised."""
        s, sd, sdd = self.timing.at(t)
        dq = self.path(s, 1)
        return (self.path(s), dq * sd[:, None],
                dq * sdd[:, None] + self.path(s, 2) * (sd * sd)[:, None])

    def samples(self, rate: float, min_samples: int = 200, ramp: float = 1e-5) -> tuple:
        """(t, q, q̇, q̈) for a :class:`~planner.trajectory.Trajectory`: uniform at ``rate``
        [Hz] (at least ``min_samples``), plus both ends of a window of ±``ramp`` [s] around
        every grid time.

        The path acceleration jumps at the grid times, so q̈ does; a quintic interpolant
        across a jump overshoots it (by up to 16 % of a reversal), which the judge would see.
        Inside each window the stored motion is the linear acceleration ramp instead (the
        window's end states are consistent with it, so the interpolation reproduces it
        exactly and q̈ stays between the two sides); that moves the path by ramp²·Δq̈/6 per
        jump (≈ 1e-10 rad), and the sum of those shifts is spread smoothly over the move so
        that it still ends exactly at the path's end."""
        tm = self.timing
        T = tm.duration
        jumps = tm.t[1:-1]
        u = np.linspace(0.0, T, max(min_samples, int(np.ceil(T * rate)) + 1))
        if jumps.size == 0:
            return (u,) + self.sample(u)
        e = min(ramp, 0.25 * float(np.min(np.diff(tm.t))))
        k = np.clip(np.searchsorted(jumps, u), 1, jumps.size)
        near = np.minimum(np.abs(u - jumps[k - 1]), np.abs(u - jumps[k % jumps.size]))
        t = np.sort(np.concatenate([u[near >= 3 * e], jumps - e, jumps + e]))
        q, qd, qdd = self.sample(t)
        lo = np.searchsorted(t, jumps - e)
        hi = lo + 1
        ramp_q = q[lo] + 2 * e * qd[lo] + e * e * (4 / 3 * qdd[lo] + 2 / 3 * qdd[hi])
        shift = np.zeros_like(q)
        shift[hi] = ramp_q - q[hi]
        shift = np.cumsum(shift, axis=0)
        tau = (t / T)[:, None]
        drift = shift[-1]   # spread back with a smoothstep w(τ) (w', w'' = 0 at both ends)
        w = tau ** 3 * (10 - 15 * tau + 6 * tau * tau)
        w1 = 30 * tau ** 2 * (1 - tau) ** 2 / T
        w2 = 60 * tau * (1 - tau) * (1 - 2 * tau) / T ** 2
        return t, q + shift - drift * w, qd - drift * w1, qdd - drift * w2


def _speed_caps(dq, vlim) -> np.ndarray:
    """(N+1, n) largest ṡ [1/s] each joint's velocity limits allow at the grid points (inf
    where the joint does not move along the path)."""
    with np.errstate(divide="ignore"):
        cap = np.where(dq > 0, vlim[:, 1] / dq, np.where(dq < 0, vlim[:, 0] / dq, np.inf))
    return np.abs(cap)


def time_path(path_q, ss, vlim, alim, *, gridpoints: int = 200,
              kinds=("velocity", "acceleration"), flow=None, qmax: float | None = None,
              duration: float | None = None, scheme: str = "interpolation",
              verify: bool = True, tol: float = 1e-3, max_iter: int = 8,
              refine: int = 2) -> TimedPath:
    """Fastest (or, with ``duration`` [s], fixed-duration) rest-to-rest timing of the path
    through ``path_q`` (K, n) at path parameters ``ss`` (K,) (a not-a-knot cubic spline, as
    toppra's ``SplineInterpolator``) under joint velocity limits ``vlim`` (n, 2: min ≤ 0 ≤
    max), acceleration limits ``alim`` (n,) and, with ``"pump_flow"`` in ``kinds``, the flow
    ``flow(q, dq/ds)`` · ṡ ≤ ``qmax`` (:func:`pump_flow_per_speed`); ``gridpoints`` TOPP-RA
    intervals, discretisation ``scheme`` ("interpolation" | "collocation", toppra's).

    With ``verify`` every interval is checked exactly (:func:`interval_peaks`); while a limit
    is exceeded by more than ``tol`` (relative) the limits at the grid points around each
    offending interval (that joint, that kind) are tightened by the measured excess and the
    path solved again, at most ``max_iter`` solves; still exceeded then → status "violation".
    The first ``refine`` of those rounds split the offending intervals in two instead (a
    finer grid only where the path needs it, so a coarse grid loses little time)."""
    path_q, ss = np.asarray(path_q, float), np.asarray(ss, float)
    vlim, alim = np.asarray(vlim, float), np.asarray(alim, float)
    if scheme not in SCHEMES:
        raise ValueError(f"scheme = {scheme!r}; allowed: {sorted(SCHEMES)}")
    if "pump_flow" in kinds and (flow is None or qmax is None):
        raise ValueError("kind 'pump_flow' needs flow(q, dq) and qmax")
    path = toppra.SplineInterpolator(ss, path_q)
    spline = path.cspl
    grid = np.linspace(ss[0], ss[-1], gridpoints + 1)

    def grid_data(grid):
        dq = path(grid, 1)
        caps = _speed_caps(dq, vlim) if "velocity" in kinds else np.full(dq.shape, np.inf)
        pcap = None
        if "pump_flow" in kinds:
            fl = flow(path(grid), dq)
            with np.errstate(divide="ignore"):
                pcap = np.where(fl > 1e-15, qmax / fl, np.inf)
        return dq, path(grid, 2), caps, pcap

    dq, ddq, caps, pcap = grid_data(grid)
    fv, fa, fp = np.ones(dq.shape), np.ones(dq.shape), np.ones(len(grid))
    peaks, worst = None, float("nan")
    for it in range(1, max_iter + 1):
        cap = (fv * caps).min(axis=1)
        if pcap is not None:
            cap = np.minimum(cap, fp * pcap)
        cons = [SpeedCap(cap)]
        if "acceleration" in kinds:
            cons.append(ScaledAcceleration(dq, ddq, alim, fa, scheme))
        if duration is None:
            inst = algo.TOPPRA(cons, path, gridpoints=grid)
        else:
            inst = algo.TOPPRAsd(cons, path, gridpoints=grid)
            inst.set_desired_duration(duration)
        _, sd, _ = inst.compute_parameterization(0.0, 0.0)
        if sd is None or not np.all(np.isfinite(sd)):
            what = f"a duration of {duration} s" if duration is not None else "the limits"
            return TimedPath("infeasible", f"TOPP-RA found no rest-to-rest timing of this "
                             f"path under {what} (the path may need a non-zero speed where a "
                             "limit is zero, or the duration is too short)", path,
                             iterations=it)
        timing = PathTiming(grid, np.maximum(sd, 0.0))
        if duration is not None and timing.duration > duration * (1 + 1e-3):
            # TOPPRAsd returns the fastest timing when the duration is unachievable
            return TimedPath("infeasible", f"a duration of {duration} s is too short: the "
                             f"fastest timing of this path under the limits takes "
                             f"{timing.duration:.3f} s", path, iterations=it)
        if not verify:
            return TimedPath("ok", "", path, timing, it)
        peaks = interval_peaks(spline, timing, vlim, alim, flow if pcap is not None else None,
                               qmax)
        for k in ("velocity", "acceleration", "pump_flow"):
            if k not in kinds:   # measured, but not a limit of this timing
                setattr(peaks, k, np.minimum(getattr(peaks, k), -1.0))
        worst = peaks.worst(kinds)
        if worst <= tol:
            return TimedPath("ok", "", path, timing, it, peaks, worst)
        if it <= refine:   # first split every offending interval in two
            bad = np.flatnonzero(np.maximum.reduce([peaks.velocity.max(axis=1),
                                                    peaks.acceleration.max(axis=1),
                                                    peaks.pump_flow]) > tol)
            grid = np.union1d(grid, 0.5 * (grid[bad] + grid[bad + 1]))
            dq, ddq, caps, pcap = grid_data(grid)
            fv, fa, fp = np.ones(dq.shape), np.ones(dq.shape), np.ones(len(grid))
            continue
        # tighten at the two grid points of every interval over its limit: to the level the
        # motion uses there (so the constraint binds) divided by the excess, for that joint
        x = timing.sd ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            use_v = np.sqrt(x)[:, None] / caps
            use_a = np.abs(dq * np.append(timing.u, timing.u[-1])[:, None] +
                           ddq * x[:, None]) / alim
            use_a[1:] = np.maximum(use_a[1:], np.abs(dq[1:] * timing.u[:, None] +
                                                      ddq[1:] * x[1:, None]) / alim)
            use_p = np.sqrt(x) / pcap if pcap is not None else np.ones_like(fp)
        for f, use, ex in ((fv, use_v, peaks.velocity), (fa, use_a, peaks.acceleration),
                           (fp, use_p, peaks.pump_flow)):
            over = 1.0 + np.maximum(ex, 0.0) + np.where(ex > 0, tol, 0.0)
            level = np.ones_like(f)   # per grid point: the larger excess of its intervals
            level[:-1] = over
            level[1:] = np.maximum(level[1:], over)
            bad = level > 1.0
            target = np.maximum(np.nan_to_num(use, nan=0.0, posinf=0.0), 0.5 * f) / level
            f[bad] = np.minimum(f, target)[bad]
    return TimedPath("violation", f"a limit is still exceeded by {100 * worst:.2f} % between "
                     f"TOPP-RA's grid points after {max_iter} tightened solves", path,
                     timing, max_iter, peaks, worst)


def retime(crane, path_q, *, ss=None, gridpoints: int = 200,
           limits=("velocity", "acceleration", "pump_flow"), duration: float | None = None,
           sample_rate: float = 500.0, tol: float = 1e-3, max_iter: int = 8) -> PlanResult:
    """Fastest (or, with ``duration`` [s], fixed-duration) rest-to-rest timing of the joint
    path ``path_q`` (K, n) of ``crane`` under the selected limit kinds (:func:`time_path`,
    verified between grid points).

    ``ss`` (K,) path parameter of the samples (default: cumulative joint-space distance);
    ``gridpoints`` the TOPP-RA discretisation. The trajectory is sampled once, at
    ``sample_rate`` [Hz] (at least 200 samples). Statuses: "ok", "infeasible", "violation"
    (a limit still exceeded by more than ``tol`` after ``max_iter`` solves); stats
    ``iterations`` (TOPP-RA solves) and ``max_limit_violation`` (the verification's worst
    excess: judge the trajectory with :func:`~planner.trajectory.evaluate`)."""
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
        return PlanResult("infeasible", "the path has zero length", iterations=0,
                          max_limit_violation=float("nan"),
                          solve_time_s=_time.perf_counter() - t0)
    L = crane.limit_arrays()
    res = time_path(path_q, ss, np.column_stack([L["qd_min"], L["qd_max"]]), L["qdd_max"],
                    gridpoints=gridpoints, kinds=tuple(limits),
                    flow=lambda q, dq: pump_flow_per_speed(crane, q, dq),
                    qmax=crane.spec.pump.max_flow, duration=duration, tol=tol,
                    max_iter=max_iter)
    stats = dict(iterations=res.iterations, max_limit_violation=res.max_limit_violation)
    if res.timing is None or res.status == "infeasible":
        return PlanResult(res.status, res.reason, solve_time_s=_time.perf_counter() - t0,
                          **stats)
    T = res.timing.duration
    t, q, qd, qdd = res.samples(sample_rate)
    traj = Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names), method="topp",
                      objective="time" if duration is None else "duration",
                      limits=("position",) + tuple(limits),
                      meta=dict(gridpoints=gridpoints, parametrizer="ParametrizeConstAccel",
                                verified="interval extrema"))
    return PlanResult(res.status, res.reason, trajectory=traj if res.ok else None,
                      duration_s=T, solve_time_s=_time.perf_counter() - t0, **stats)


def raw_retime(crane, path_q, gridpoints: int = 200, rate: float = 500.0) -> Trajectory:
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

    def plan(self, crane, request: PlanRequest) -> PlanResult:
        res = dp(crane, Line(request.start, request.goal), objective="time",
                 **DPPlanner.grid(request))
        if not res.ok:
            return res
        return retime(crane, res.path_q, duration=request.duration)


register(ToppPlanner())
