"""Seed 003's phase plane: the joint path Φ(θ) along a tip path, the velocity envelope, and the
time-efficient profile θ̇ = fraction·envelope.

The tip follows a path p(θ) (:class:`~planner.geometry.paths.SeedPath`) in the seed's own
parameter θ; the telescope is q4 = φ4(θ) (:mod:`planner.methods.phase.telescope`). IK gives
q = Φ(θ); Φ'(θ) is analytic: J_xyz(q)·Φ' = dp/dθ with Φ'_4 = φ4' (:func:`joint_path`). Each
joint's velocity limits q̇_min,i ≤ Φ'_i θ̇ ≤ q̇_max,i bound θ̇ > 0 from above (seed eq. 11,
:func:`rate_bounds`); the envelope is the lowest of these curves (:func:`envelope`).
:func:`time_efficient_profile` is the seed's θ̇ = f(θ) = 0.9·envelope, timed by t = ∫ dθ/f,
and gives a common :class:`~planner.trajectory.Trajectory`. The nominal profile claims position
and velocity limits only (:data:`CLAIMS`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass

import numpy as np

from planner.geometry.paths import SeedPath
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["CLAIMS", "joint_path", "rate_bounds", "Envelope", "envelope", "feasible_band",
           "tele_grid", "constant_scan", "path_states", "Profile", "time_efficient_profile"]

CLAIMS = ("position", "velocity")  # what the phase-plane profiles guarantee
_H = 1e-5                          # finite-difference step in θ for Φ'' and f'


def joint_path(crane: Crane, path: SeedPath, tele, coef, theta, explain: bool = False):
    """q = Φ(θ) (IK with q4 = φ4(θ)) and Φ'(θ) (analytic: J_xyz(q)·Φ' = dp/dθ, Φ'_4 = φ4').

    Returns (q (K, n), dq (K, n), reasons (K,)); failing rows are NaN with a reason."""
    theta = np.atleast_1d(np.asarray(theta, float))
    it = crane.chain.tele
    t = tele.value(coef, theta)
    q, reasons = crane.ik_batch(path.tip(theta), t, explain=explain)
    dq = np.full_like(q, np.nan)
    ok = np.all(np.isfinite(q), axis=1)
    if np.any(ok):
        J = crane.jacobian(q[ok], "xyz")               # (k, 3, n)
        dt = tele.value(coef, theta[ok], 1)
        rhs = path.dxyz(theta[ok]) - J[:, :, it] * dt[:, None]
        others = [i for i in range(crane.n) if i != it]
        with np.errstate(all="ignore"):
            sol = np.linalg.solve(J[:, :, others], rhs[..., None])[..., 0]
        d = np.empty((ok.sum(), crane.n))
        d[:, others] = sol
        d[:, it] = dt
        dq[ok] = d
    return q, dq, reasons


def rate_bounds(dq, qd_min, qd_max, eps: float = 1e-12) -> np.ndarray:
    """Per-joint upper bound on θ̇ > 0 from q̇_min ≤ Φ'·θ̇ ≤ q̇_max (seed eq. 11):
    q̇_max/Φ' where Φ' > 0, q̇_min/Φ' where Φ' < 0, +inf where Φ' = 0; NaN rows stay NaN."""
    dq = np.asarray(dq, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(dq > eps, qd_max / dq, np.where(dq < -eps, qd_min / dq, np.inf))
    return np.where(np.isnan(dq), np.nan, b)


@dataclass
class Envelope:
    """The phase-plane velocity envelope along a path and what bounds it."""
    theta: np.ndarray        # (K,)
    tele: np.ndarray         # φ4(θ) (K,)
    q: np.ndarray            # Φ(θ) (K, n)
    dq: np.ndarray           # Φ'(θ) (K, n)
    bounds: np.ndarray       # per-joint θ̇ bounds (K, n)
    envelope: np.ndarray     # lowest bound (K,) (0 where infeasible)
    feasible: np.ndarray     # (K,) bool
    reasons: np.ndarray      # (K,) IK failure texts ("" where feasible)
    area: float              # ∫ envelope dθ (infeasible points count 0)
    binding: np.ndarray      # (K,) index of the lowest curve (-1 where infeasible)

    @property
    def ok(self) -> bool:
        return bool(np.all(self.feasible))

    @property
    def time_at_envelope(self) -> float:
        """∫ dθ / envelope: the traversal time riding the envelope itself (inf if infeasible)."""
        if not self.ok:
            return math.inf
        return float(np.trapezoid(1.0 / self.envelope, self.theta))


def envelope(crane: Crane, path: SeedPath, tele, coef, theta=None, n: int = 401,
             explain: bool = False) -> Envelope:
    """Phase-plane velocity envelope along ``theta`` (default: n points over the path)."""
    theta = path.grid(n) if theta is None else np.asarray(theta, float)
    L = crane.limit_arrays()
    q, dq, reasons = joint_path(crane, path, tele, coef, theta, explain=explain)
    b = rate_bounds(dq, L["qd_min"], L["qd_max"])
    feas = np.all(np.isfinite(q), axis=1)
    env = np.where(feas, np.min(np.where(np.isnan(b), np.inf, b), axis=1), 0.0)
    binding = np.where(feas, np.argmin(np.where(np.isnan(b), np.inf, b), axis=1), -1)
    area = float(np.trapezoid(env, theta)) if theta.size > 1 else 0.0
    return Envelope(theta, tele.value(coef, theta), q, dq, b, env, feas, reasons, area, binding)


def feasible_band(crane: Crane, path: SeedPath, theta, tele_grid) -> np.ndarray:
    """(K, M) mask: IK succeeds (reachable, all joints and the telescope within limits) at θ_k
    with telescope tele_grid[m]."""
    theta = np.asarray(theta, float)
    tele_grid = np.asarray(tele_grid, float)
    K, M = theta.size, tele_grid.size
    tips = np.repeat(path.tip(theta), M, axis=0)
    q, _ = crane.ik_batch(tips, np.tile(tele_grid, K), explain=False)
    return np.all(np.isfinite(q), axis=1).reshape(K, M)


def tele_grid(crane: Crane, step: float) -> np.ndarray:
    """The telescope range [m] on a grid of spacing ``step`` [m] (both ends included)."""
    lo, hi = crane.tele_range
    return np.linspace(lo, hi, int(round((hi - lo) / step)) + 1)


def constant_scan(crane: Crane, path: SeedPath, theta, tele_grid):
    """Envelope area for every constant telescope in tele_grid (NaN when infeasible somewhere)."""
    theta = np.asarray(theta, float)
    L = crane.limit_arrays()
    K, M = theta.size, len(tele_grid)
    th = np.tile(theta, M)
    t = np.repeat(tele_grid, K)
    q, _ = crane.ik_batch(np.tile(path.tip(theta), (M, 1)), t, explain=False)
    ok = np.all(np.isfinite(q), axis=1)
    dq = np.full_like(q, np.nan)
    if ok.any():
        J = crane.jacobian(q[ok], "xyz")
        it = crane.chain.tele
        others = [i for i in range(crane.n) if i != it]
        with np.errstate(all="ignore"):
            sol = np.linalg.solve(J[:, :, others], path.dxyz(th[ok])[..., None])[..., 0]
        d = np.zeros((ok.sum(), crane.n))
        d[:, others] = sol
        dq[ok] = d
    b = rate_bounds(dq, L["qd_min"], L["qd_max"])
    env = np.min(np.where(np.isnan(b), np.inf, b), axis=1).reshape(M, K)
    feas = ok.reshape(M, K).all(axis=1)
    areas = np.where(feas, np.trapezoid(np.where(np.isfinite(env), env, 0.0), theta, axis=1),
                     np.nan)
    return areas


def path_states(crane: Crane, path, tele, coef, theta, fraction, side=0):
    """q, Φ', Φ'', f = fraction·envelope and f' at θ; derivatives by finite differences of the
    analytic Φ' and of f: central (side=0), or one-sided second order forward (+1) / back (−1).
    Points where a central stencil would leave a non-periodic path use the inward one-sided."""
    theta = np.atleast_1d(np.asarray(theta, float))
    h = _H * max(path.span, 1.0)
    L = crane.limit_arrays()

    def ev(th):
        q, dq, _ = joint_path(crane, path, tele, coef, th)
        b = rate_bounds(dq, L["qd_min"], L["qd_max"])
        return q, dq, fraction * np.min(np.where(np.isnan(b), np.inf, b), axis=1)

    q, dq, f = ev(theta)
    s = np.full(theta.shape, side, dtype=int)
    if not path.periodic:
        s = np.where((s == 0) & (theta - h < path.theta0), 1, s)
        s = np.where((s == 0) & (theta + h > path.theta1), -1, s)
    sd = np.where(s == 0, 1, s).astype(float)
    _, dq1, f1 = ev(theta + sd * h)
    _, dq2, f2 = ev(theta + sd * 2 * h)
    _, dqm, fm = ev(theta - h)
    cen = (s == 0)
    ddq = np.where(cen[:, None], (dq1 - dqm) / (2 * h),
                   sd[:, None] * (-3 * dq + 4 * dq1 - dq2) / (2 * h))
    df = np.where(cen, (f1 - fm) / (2 * h), sd * (-3 * f + 4 * f1 - f2) / (2 * h))
    return q, dq, ddq, f, df


@dataclass
class Profile:
    """θ̇ = f(θ) = fraction·envelope(θ) along the path, timed by t(θ) = ∫ dθ/f."""
    path: SeedPath
    tele: object
    coef: np.ndarray
    fraction: float
    theta: np.ndarray
    f: np.ndarray
    df: np.ndarray
    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def envelope(self) -> np.ndarray:
        return self.f / self.fraction

    def joint_state(self, crane: Crane, theta, theta_dot, theta_ddot, side=0):
        """Joint (q, q̇, q̈) for path states (θ, θ̇, θ̈)."""
        q, dq, ddq, _, _ = path_states(crane, self.path, self.tele, self.coef, theta,
                                   self.fraction, side)
        td, tdd = np.asarray(theta_dot, float), np.asarray(theta_ddot, float)
        return q, dq * td[..., None], ddq * (td ** 2)[..., None] + dq * tdd[..., None]

    def nominal_state(self, crane: Crane, theta, side=0):
        """((θ̇, θ̈) = (f, f·f'), (q, q̇, q̈)) of the nominal profile at θ (f' one-sided with
        ``side`` = ±1: the derivative on the side where the nominal motion continues)."""
        q, dq, ddq, f, df = path_states(crane, self.path, self.tele, self.coef, theta,
                                    self.fraction, side)
        return (f, f * df), (q, dq * f[:, None], ddq * (f ** 2)[:, None] + dq * (f * df)[:, None])

    def trajectory(self, crane: Crane) -> Trajectory:
        """The nominal profile as a Trajectory: q = Φ(θ), q̇ = Φ'f, q̈ = Φ''f² + Φ'f f'."""
        f, df = self.f, self.df
        qd = self.dq * f[:, None]
        qdd = self.ddq * (f ** 2)[:, None] + self.dq * (f * df)[:, None]
        return Trajectory(self.t, self.q, qd, qdd, joint_names=tuple(crane.names),
                          method="phase", objective="time", limits=CLAIMS,
                          meta=dict(path=self.path.name, fraction=self.fraction,
                                    profile="fraction of the phase-plane envelope"))


def time_efficient_profile(crane: Crane, path: SeedPath, tele, coef, fraction: float = 0.9,
                           n: int = 2001) -> Profile:
    """Seed IV.B: θ̇ = f(θ) = fraction·envelope(θ) on n points, time t = ∫ dθ/f (trapezoid)."""
    if not 0 < fraction <= 1:
        raise ValueError("fraction must be in (0, 1]")
    theta = path.grid(n)
    q, dq, ddq, f, df = path_states(crane, path, tele, coef, theta, fraction)
    if not np.all(np.isfinite(q)):
        k = int(np.flatnonzero(~np.all(np.isfinite(q), axis=1))[0])
        _, _, why = joint_path(crane, path, tele, coef, theta[k:k + 1], explain=True)
        raise ValueError(f"{path.name}: the telescope function leaves the feasible set at "
                         f"θ = {theta[k]:.4f}: {why[0]}")
    t = np.concatenate([[0.0], np.cumsum(0.5 * (1 / f[1:] + 1 / f[:-1]) * np.diff(theta))])
    return Profile(path, tele, np.asarray(coef, float), fraction, theta, f, df, t, q, dq, ddq)


