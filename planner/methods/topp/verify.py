"""A constant-path-acceleration timing of a cubic-spline path (:class:`PathTiming`) and its
exact check between grid points (:func:`interval_peaks`): with constant path acceleration u
on an interval, q̈(s) is a quadratic in s on each piece between spline knots and grid points,
so its extremum is a vertex or an end, and q̇ peaks where q̈ = 0 or at an end."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PathTiming", "Peaks", "interval_peaks"]


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
