"""Seed 003: path-constrained planning in the (θ, θ̇) phase plane with the telescope as a
function of the path parameter, and the re-planning to start (and end) at rest.

The tip follows a path p(θ) given in the seed's own parameter θ (not arc length):

- circle (seed eq. 4–5): p(θ) = (xC + R cos θ, 0, zC + R sin θ), θ = atan2(z − zC, x − xC)
  ∈ [−π, π], R = 0.7 m, (xC, zC) = (3, 2.5) m;
- parabola (seed eq. 6–8): θ = x ∈ [x0, xend] = [1.6, 3.07] m, p(θ) = (θ, tan α·θ,
  (θ − h)²/(4a) + k), h = (x0 + xend)/2, k = zmax, a = (x0 − h)²/(4(zmin − k)) < 0. The seed
  prints (θ + h); only (θ − h) puts the vertex (z = zmax) mid-path and z = zmin at both ends
  (``vertex="plus"`` gives the printed form, for the check).

The telescope is q4 = φ4(θ): a truncated Fourier series of order M on the periodic circle
(:class:`FourierTele`, seed eq. 14), a Bézier polynomial of order N in the normalised parameter
u = (θ − θ0)/(θ1 − θ0) on the parabola (:class:`BezierTele`, seed eq. 15). IK gives
q = Φ(θ); Φ'(θ) is analytic: J_xyz(q)·Φ' = dp/dθ with Φ'_4 = φ4' (:func:`joint_path`). Each joint's
velocity limits q̇_min,i ≤ Φ'_i θ̇ ≤ q̇_max,i bound θ̇ > 0 from above (seed eq. 11,
:func:`rate_bounds`); the envelope is the lowest of these curves (:func:`envelope`).

:func:`optimise_telescope` chooses the coefficients that maximise the area under the envelope
(Nelder–Mead, deterministic starts; infeasible coefficients — IK failure, a joint or the
telescope outside its limits — are penalised by their distance to the feasible telescope band).
:func:`time_efficient_profile` is the seed's θ̇ = f(θ) = 0.9·envelope, timed by t = ∫ dθ/f, and
gives a common :class:`~planner.trajectory.Trajectory`. :func:`from_rest` replaces the seed's
quintic transitions by Ruckig state-to-state transitions (community edition, no waypoints):
from rest at the path start into the nominal profile at θ_int = inf θ + 0.05·span and (non-periodic
paths) from the nominal profile at inf θ + 0.95·span back to rest at the path end, matching
position, velocity and acceleration at the junctions. By default the transition is planned for
the path parameter (1 DOF: the tip stays on the path, the phase-plane picture of the seed);
``space="joint"`` plans it for the four joints instead (the tip leaves the path in between).

Acceleration and jerk limits in the spec of umea-lab are assumptions (seed 003 gives none);
the nominal profile claims position and velocity limits only.
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np
import ruckig
from scipy.optimize import minimize

from planner.geometry.paths import xyz_to_tip
from planner.trajectory import Trajectory

__all__ = ["SeedPath", "circle_path", "parabola_path", "FourierTele", "BezierTele",
           "joint_path", "rate_bounds", "envelope", "Envelope", "feasible_band",
           "constant_scan", "optimise_telescope", "TeleOpt", "time_efficient_profile",
           "Profile", "from_rest", "FromRest", "Junction", "seed_setup"]

CLAIMS = ("position", "velocity")  # what the phase-plane profiles guarantee
_H = 1e-5                          # finite-difference step in θ for Φ'' and f'


# ====================================================================== paths p(θ)
@dataclass(frozen=True)
class SeedPath:
    """Tip path p(θ) in frame 0 with its analytic derivative, θ ∈ [theta0, theta1]."""
    name: str
    theta0: float
    theta1: float
    periodic: bool
    p: object          # θ (K,) -> xyz (K, 3)
    dp: object         # θ (K,) -> dxyz/dθ (K, 3)
    theta_of: object   # xyz (K, 3) -> θ (K,)   (the seed's definition of the parameter)
    params: dict = field(default_factory=dict)

    @property
    def span(self) -> float:
        return self.theta1 - self.theta0

    def xyz(self, theta) -> np.ndarray:
        return np.asarray(self.p(np.atleast_1d(np.asarray(theta, float))), float)

    def dxyz(self, theta) -> np.ndarray:
        return np.asarray(self.dp(np.atleast_1d(np.asarray(theta, float))), float)

    def tip(self, theta) -> np.ndarray:
        """CONTRACT tip coordinates (r, z, slew) at θ."""
        return xyz_to_tip(self.xyz(theta))

    def grid(self, n: int) -> np.ndarray:
        return np.linspace(self.theta0, self.theta1, int(n))


def circle_path(R: float = 0.7, center=(3.0, 2.5)) -> SeedPath:
    """Seed eq. 4–5: circle in the x–z plane, θ = atan2(z − zC, x − xC) ∈ [−π, π]."""
    xc, zc = map(float, center)

    def p(th):
        return np.stack([xc + R * np.cos(th), 0.0 * th, zc + R * np.sin(th)], axis=-1)

    def dp(th):
        return np.stack([-R * np.sin(th), 0.0 * th, R * np.cos(th)], axis=-1)

    def theta_of(xyz):
        xyz = np.asarray(xyz, float)
        return np.arctan2(xyz[..., 2] - zc, xyz[..., 0] - xc)

    return SeedPath("circle", -math.pi, math.pi, True, p, dp, theta_of,
                    dict(R=R, xC=xc, zC=zc, plane="xz"))


def parabola_path(x0: float = 1.6, x1: float = 3.07, z_min: float = 1.5, z_max: float = 3.0,
                  alpha: float = -math.pi / 3, vertex: str = "minus") -> SeedPath:
    """Seed eq. 6–8: θ = x ∈ [x0, x1], p(θ) = (θ, tan α·θ, (θ ∓ h)²/(4a) + k).

    ``vertex="minus"`` uses (θ − h) (vertex z_max at θ = h, z_min at both ends: what the seed
    means); ``"plus"`` the printed (θ + h), kept for the vertex check."""
    if vertex not in ("minus", "plus"):
        raise ValueError("vertex must be 'minus' ((θ − h), the intended form) or 'plus' "
                         "((θ + h), as printed in the seed)")
    h = 0.5 * (x0 + x1)
    k = z_max
    a = (x0 - h) ** 2 / (4.0 * (z_min - k))
    sh = -h if vertex == "minus" else h
    ta = math.tan(alpha)

    def p(th):
        return np.stack([th, ta * th, (th + sh) ** 2 / (4 * a) + k], axis=-1)

    def dp(th):
        return np.stack([np.ones_like(th), ta + 0.0 * th, 2 * (th + sh) / (4 * a)], axis=-1)

    def theta_of(xyz):
        return np.asarray(xyz, float)[..., 0]

    return SeedPath("parabola", float(x0), float(x1), False, p, dp, theta_of,
                    dict(x0=x0, x1=x1, z_min=z_min, z_max=z_max, alpha=alpha, h=h, k=k, a=a,
                         vertex=vertex))


# ====================================================================== telescope φ4(θ)
class FourierTele:
    """φ4(θ) = c0 + Σ_{i=1..M} (a_i cos iθ + b_i sin iθ); coefficients [c0, a1, b1, …, aM, bM]."""
    kind = "fourier"

    def __init__(self, M: int = 3):
        self.M = int(M)
        self.n = 2 * self.M + 1

    def value(self, c, theta, der: int = 0) -> np.ndarray:
        c = np.asarray(c, float)
        th = np.asarray(theta, float)
        out = np.full_like(th, c[0] if der == 0 else 0.0)
        for i in range(1, self.M + 1):
            a, b = c[2 * i - 1], c[2 * i]
            ci, si = np.cos(i * th), np.sin(i * th)
            if der == 0:
                out = out + a * ci + b * si
            elif der == 1:
                out = out + i * (-a * si + b * ci)
            elif der == 2:
                out = out - i * i * (a * ci + b * si)
            else:
                raise ValueError("der must be 0, 1 or 2")
        return out

    def basis(self, theta) -> np.ndarray:
        th = np.asarray(theta, float)
        cols = [np.ones_like(th)]
        for i in range(1, self.M + 1):
            cols += [np.cos(i * th), np.sin(i * th)]
        return np.stack(cols, axis=-1)

    def constant(self, t: float) -> np.ndarray:
        c = np.zeros(self.n)
        c[0] = t
        return c

    def bounds(self, lo: float, hi: float):
        w = 0.5 * (hi - lo)
        return [(lo, hi)] + [(-w, w)] * (2 * self.M)

    def describe(self, c) -> dict:
        c = np.asarray(c, float)
        return dict(kind=self.kind, order=self.M, phi40=float(c[0]),
                    a=[float(v) for v in c[1::2]], b=[float(v) for v in c[2::2]])


class BezierTele:
    """φ4(θ) = Σ_{i=0..N} C(N, i) (1 − u)^{N−i} u^i P_i with u = (θ − θ0)/(θ1 − θ0) ∈ [0, 1]
    (the seed writes the Bernstein basis in θ itself, which only makes sense on [0, 1]).
    The curve stays inside the hull of the control points: P_i ∈ [0, 1.55] keeps the telescope
    in range."""
    kind = "bezier"

    def __init__(self, N: int, theta0: float, theta1: float):
        self.N = int(N)
        self.n = self.N + 1
        self.theta0, self.theta1 = float(theta0), float(theta1)

    def _bern(self, u, N):
        return np.stack([math.comb(N, i) * (1 - u) ** (N - i) * u ** i for i in range(N + 1)],
                        axis=-1)

    def value(self, c, theta, der: int = 0) -> np.ndarray:
        P = np.asarray(c, float)
        L = self.theta1 - self.theta0
        u = (np.asarray(theta, float) - self.theta0) / L
        N = self.N
        if der == 0:
            return self._bern(u, N) @ P
        if der == 1:
            return N * (self._bern(u, N - 1) @ np.diff(P)) / L
        if der == 2:
            if N < 2:
                return np.zeros_like(u)
            return N * (N - 1) * (self._bern(u, N - 2) @ np.diff(P, 2)) / L ** 2
        raise ValueError("der must be 0, 1 or 2")

    def basis(self, theta) -> np.ndarray:
        u = (np.asarray(theta, float) - self.theta0) / (self.theta1 - self.theta0)
        return self._bern(u, self.N)

    def constant(self, t: float) -> np.ndarray:
        return np.full(self.n, float(t))

    def bounds(self, lo: float, hi: float):
        return [(lo, hi)] * self.n

    def describe(self, c) -> dict:
        return dict(kind=self.kind, order=self.N, control_points=[float(v) for v in c],
                    u="(θ − θ0)/(θ1 − θ0)", theta0=self.theta0, theta1=self.theta1)


# ====================================================================== Φ(θ), Φ'(θ), envelope
def joint_path(crane, path: SeedPath, tele, coef, theta, explain: bool = False):
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


def envelope(crane, path: SeedPath, tele, coef, theta=None, n: int = 401,
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


# ====================================================================== telescope optimisation
def feasible_band(crane, path: SeedPath, theta, tele_grid) -> np.ndarray:
    """(K, M) mask: IK succeeds (reachable, all joints and the telescope within limits) at θ_k
    with telescope tele_grid[m]."""
    theta = np.asarray(theta, float)
    tele_grid = np.asarray(tele_grid, float)
    K, M = theta.size, tele_grid.size
    tips = np.repeat(path.tip(theta), M, axis=0)
    q, _ = crane.ik_batch(tips, np.tile(tele_grid, K), explain=False)
    return np.all(np.isfinite(q), axis=1).reshape(K, M)


def _tele_grid(crane, step):
    lo, hi = crane.tele_range
    return np.linspace(lo, hi, int(round((hi - lo) / step)) + 1)


def constant_scan(crane, path: SeedPath, theta, tele_grid):
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


@dataclass
class TeleOpt:
    tele: object
    coef: np.ndarray
    area: float                  # on the fine grid
    env: Envelope                # fine grid
    const_best: float | None     # best constant telescope [m] (None: no constant is feasible)
    const_area: float            # its envelope area on the fine grid (nan if none)
    const_scan: tuple            # (tele grid, areas on the fine grid; NaN: infeasible)
    band: np.ndarray             # (K_coarse, M) feasibility mask
    band_theta: np.ndarray
    band_tele: np.ndarray
    starts: list                 # per start: name, x0, area, nfev
    nfev: int
    solve_time_s: float

    @property
    def ok(self) -> bool:
        return self.env.ok

    def summary(self) -> dict:
        tg, areas = self.const_scan
        ok = np.isfinite(areas)
        rng = [float(tg[ok].min()), float(tg[ok].max())] if ok.any() else None
        return dict(telescope=self.tele.describe(self.coef), area=self.area,
                    feasible=self.ok, constant_best_m=self.const_best,
                    constant_feasible_range_m=rng,
                    constant_area=self.const_area,
                    area_gain_vs_constant=(self.area / self.const_area - 1.0
                                           if self.const_best is not None else None),
                    time_at_envelope_s=self.env.time_at_envelope,
                    tele_range_m=[float(self.env.tele.min()), float(self.env.tele.max())],
                    starts=self.starts, nfev=self.nfev, solve_time_s=self.solve_time_s)


def optimise_telescope(crane, path: SeedPath, tele, *, n_theta: int = 241,
                       n_fine: int = 2001, tele_step: float = 0.01, maxfev: int = 3000,
                       penalty: float = 10.0, restarts: int = 2,
                       margin: float = 1e-3) -> TeleOpt:
    """Telescope coefficients that maximise the area under the envelope (deterministic).

    The objective on ``n_theta`` points is −area + penalty·Σ_k Δθ_k·(d_k + step + 1) over
    the points where IK fails, d_k the distance of φ4(θ_k) to the nearest feasible telescope
    value there (from a scan on a ``tele_step`` grid), so infeasible coefficients are pushed
    back into the feasible band; joints (the telescope included) closer than ``margin``·range
    to a limit are penalised in proportion to the intrusion, so that the optimum keeps a small
    distance to the limits and stays feasible between the grid points. Starts: the best
    constant telescope (if one is feasible) and the least-squares fit to the middle of the
    feasible band; Nelder–Mead (adaptive, bounded), restarted ``restarts`` times from its own
    result. The winner is re-judged on ``n_fine`` points."""
    t0 = _time.perf_counter()
    lo, hi = crane.tele_range
    theta = path.grid(n_theta)
    w = np.gradient(theta)  # quadrature weights for the penalty
    tg = _tele_grid(crane, tele_step)
    band = feasible_band(crane, path, theta, tg)
    empty = np.flatnonzero(~band.any(axis=1))
    if empty.size:
        k = int(empty[0])
        _, why = crane.ik_batch(path.tip(theta[k:k + 1]), np.array([0.5 * (lo + hi)]))
        raise ValueError(f"{path.name}: no telescope value in [{lo}, {hi}] m reaches the path "
                         f"at θ = {theta[k]:.4f} (p = {np.round(path.xyz(theta[k])[0], 3)}); "
                         f"e.g. {why[0]}")
    nfev = 0

    L = crane.limit_arrays()
    delta = margin * (L["q_max"] - L["q_min"])

    def objective(c):
        nonlocal nfev
        nfev += 1
        e = envelope(crane, path, tele, c, theta)
        bad = ~e.feasible
        qf = e.q[~bad]
        intr = np.maximum(0.0, np.maximum(L["q_min"] + delta - qf, qf - L["q_max"] + delta))
        val = -e.area + penalty * float(np.sum(w[~bad] * np.sum(intr / delta, axis=1)))
        if bad.any():
            t = e.tele[bad]
            d = np.min(np.where(band[bad], np.abs(t[:, None] - tg[None, :]), np.inf), axis=1)
            val += penalty * float(np.sum(w[bad] * (d + tele_step + 1.0)))
        return val

    areas = constant_scan(crane, path, theta, tg)
    starts = []
    if np.any(np.isfinite(areas)):
        kc = int(np.nanargmax(areas))
        starts.append(("best_constant", tele.constant(tg[kc])))
    # middle of the feasible band (between its lowest and highest telescope value per θ)
    mid = np.array([0.5 * (tg[m].min() + tg[m].max()) for m in band])
    B = tele.basis(theta)
    c_fit = np.linalg.lstsq(B, mid, rcond=None)[0]
    starts.append(("band_middle_fit", c_fit))
    bnds = tele.bounds(lo, hi)
    best = None
    info = []
    for name, x0 in starts:
        x0 = np.clip(x0, [b[0] for b in bnds], [b[1] for b in bnds])
        x, fx, n0 = x0, objective(x0), nfev
        for _ in range(restarts + 1):
            r = minimize(objective, x, method="Nelder-Mead", bounds=bnds,
                         options=dict(maxfev=maxfev, xatol=1e-5, fatol=1e-9, adaptive=True))
            if r.fun < fx - 1e-12:
                x, fx = r.x, float(r.fun)
            else:
                break
        info.append(dict(start=name, x0=[float(v) for v in x0], objective=fx,
                         nfev=nfev - n0))
        if best is None or fx < best[1]:
            best = (x, fx)
    coef = np.asarray(best[0], float)
    thf = path.grid(n_fine)
    env = envelope(crane, path, tele, coef, thf, explain=True)
    # the best constant telescope, judged on the same fine grid as the optimum
    areas_f = constant_scan(crane, path, thf, tg)
    if np.any(np.isfinite(areas_f)):
        kc = int(np.nanargmax(areas_f))
        cb, ca = float(tg[kc]), float(areas_f[kc])
    else:
        cb, ca = None, float("nan")
    return TeleOpt(tele, coef, env.area, env, cb, ca, (tg, areas_f), band, theta, tg, info,
                   nfev, _time.perf_counter() - t0)


# ====================================================================== time-efficient profile
def _states(crane, path, tele, coef, theta, fraction, side=0):
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

    def joint_state(self, crane, theta, theta_dot, theta_ddot, side=0):
        """Joint (q, q̇, q̈) for path states (θ, θ̇, θ̈)."""
        q, dq, ddq, _, _ = _states(crane, self.path, self.tele, self.coef, theta,
                                   self.fraction, side)
        td, tdd = np.asarray(theta_dot, float), np.asarray(theta_ddot, float)
        return q, dq * td[..., None], ddq * (td ** 2)[..., None] + dq * tdd[..., None]

    def nominal_state(self, crane, theta, side=0):
        """((θ̇, θ̈) = (f, f·f'), (q, q̇, q̈)) of the nominal profile at θ (f' one-sided with
        ``side`` = ±1: the derivative on the side where the nominal motion continues)."""
        q, dq, ddq, f, df = _states(crane, self.path, self.tele, self.coef, theta,
                                    self.fraction, side)
        return (f, f * df), (q, dq * f[:, None], ddq * (f ** 2)[:, None] + dq * (f * df)[:, None])

    def trajectory(self, crane) -> Trajectory:
        """The nominal profile as a Trajectory: q = Φ(θ), q̇ = Φ'f, q̈ = Φ''f² + Φ'f f'."""
        f, df = self.f, self.df
        qd = self.dq * f[:, None]
        qdd = self.ddq * (f ** 2)[:, None] + self.dq * (f * df)[:, None]
        return Trajectory(self.t, self.q, qd, qdd, joint_names=tuple(crane.names),
                          method="phase", objective="time", limits=CLAIMS,
                          meta=dict(path=self.path.name, fraction=self.fraction,
                                    profile="fraction of the phase-plane envelope"))


def time_efficient_profile(crane, path: SeedPath, tele, coef, fraction: float = 0.9,
                           n: int = 2001) -> Profile:
    """Seed IV.B: θ̇ = f(θ) = fraction·envelope(θ) on n points, time t = ∫ dθ/f (trapezoid)."""
    if not 0 < fraction <= 1:
        raise ValueError("fraction must be in (0, 1]")
    theta = path.grid(n)
    q, dq, ddq, f, df = _states(crane, path, tele, coef, theta, fraction)
    if not np.all(np.isfinite(q)):
        k = int(np.flatnonzero(~np.all(np.isfinite(q), axis=1))[0])
        _, _, why = joint_path(crane, path, tele, coef, theta[k:k + 1], explain=True)
        raise ValueError(f"{path.name}: the telescope function leaves the feasible set at "
                         f"θ = {theta[k]:.4f}: {why[0]}")
    t = np.concatenate([[0.0], np.cumsum(0.5 * (1 / f[1:] + 1 / f[:-1]) * np.diff(theta))])
    return Profile(path, tele, np.asarray(coef, float), fraction, theta, f, df, t, q, dq, ddq)


# ====================================================================== from-rest redesign
NO_JERK = 1e6      # stands for "no jerk limit" (Ruckig needs a finite value)
V_HEADROOM = 1.02  # θ-space velocity cap at least 2 % above the junction speed (still < envelope)
SPEED_RATIO_MAX = 0.999  # θ-space transitions: θ̇ ≤ this × envelope at the samples
MIN_GAP = 1e-4     # [s] shortest interval kept between transition samples (jerk ∝ 1/h³)


@dataclass
class Junction:
    where: str           # "start" (rest -> nominal) or "end" (nominal -> rest)
    theta: float
    t: float             # time of the junction in the from-rest trajectory [s]
    pos_err: float       # max |Δq| between the transition's end state and the nominal [rad | m]
    vel_err: float       # max |Δq̇|
    acc_err: float       # max |Δq̈|
    path_err: tuple      # |Δθ|, |Δθ̇|, |Δθ̈| (theta space; NaN for joint-space transitions)

    @property
    def max_err(self) -> float:
        return max(self.pos_err, self.vel_err, self.acc_err)

    def as_dict(self):
        return dict(where=self.where, theta=self.theta, t=self.t, pos_err=self.pos_err,
                    vel_err=self.vel_err, acc_err=self.acc_err,
                    path_err=[float(v) for v in self.path_err])


@dataclass
class FromRest:
    trajectory: Trajectory
    duration: float
    space: str
    junctions: list            # Junction per joint-over point
    transitions: list          # dicts: where, duration, Ruckig limits, speed over envelope
    transition_trajectories: list  # the transitions alone (Trajectory each), for evaluate()
    phase: tuple               # (t, θ, θ̇) of the whole motion (θ̇ NaN in joint-space transitions)
    max_path_deviation: float  # max tip distance from the path [m]
    nominal_part: tuple        # (θ_start, θ_end) of the nominal section

    def summary(self) -> dict:
        return dict(space=self.space, duration_s=self.duration,
                    junctions=[j.as_dict() for j in self.junctions],
                    max_junction_error=max(j.max_err for j in self.junctions),
                    transitions=self.transitions,
                    max_path_deviation_m=self.max_path_deviation,
                    nominal_theta=[float(v) for v in self.nominal_part])


def _switch_times(tr) -> np.ndarray:
    out = [0.0, tr.duration]
    for prof in tr.profiles[0]:
        t0 = prof.brake.duration if prof.brake is not None else 0.0
        out.extend(t0 + np.cumsum(prof.t))
    t = np.asarray(out)
    return np.unique(t[(t >= 0) & (t <= tr.duration)])


def _jerk_for(v, a, vmin, vmax, forward: bool):
    """Smallest jerk with which a state (v, a) does not inevitably leave [vmin, vmax]: forward
    in time (a current state) or backward (a target state). Ruckig rejects such states."""
    v, a = np.asarray(v, float), np.asarray(a, float)
    grow = (a > 0) if forward else (a < 0)          # velocity keeps moving away from v
    room = np.where(grow, vmax - v, v - vmin)
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(a != 0, a * a / (2 * np.maximum(room, 1e-12)), 0.0)
    return need * (1 + 1e-6)


def _ruckig(cur, tgt, vmax, vmin, amax, jmax):
    n = len(cur[0])
    inp = ruckig.InputParameter(n)
    inp.current_position, inp.current_velocity, inp.current_acceleration = \
        [[float(x) for x in v] for v in cur]
    inp.target_position, inp.target_velocity, inp.target_acceleration = \
        [[float(x) for x in v] for v in tgt]
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


def _ruckig_relaxed(cur, tgt, vmax, vmin, amax, jmax, grow=1.25, tries=30):
    """Ruckig with the acceleration and jerk limits raised by ``grow`` until a transition
    exists (a junction state may be unreachable within the given distance under the nominal
    limits). Returns (trajectory, scale applied to amax and jmax)."""
    scale, last = 1.0, ""
    for _ in range(tries):
        try:
            return _ruckig(cur, tgt, vmax, vmin, np.asarray(amax) * scale,
                           np.asarray(jmax) * scale), scale
        except RuntimeError as e:
            last = str(e)
            scale *= grow
    raise RuntimeError(f"no Ruckig transition even with {scale / grow:.1f}× the acceleration "
                       f"and jerk limits ({last})")


def _sample(tr, rate):
    """Uniform samples plus every switching time (as in planner.methods.ruckig)."""
    T = tr.duration
    u = np.linspace(0.0, T, max(60, int(math.ceil(T * rate)) + 1))
    sw = _switch_times(tr)
    near = np.abs(u[:, None] - sw[None, :]).min(axis=1) < 0.25 / rate
    t = np.union1d(u[~near], sw)
    keep = [0]
    for k in range(1, len(t)):  # drop samples closer than MIN_GAP (switch times may cluster)
        if t[k] - t[keep[-1]] >= MIN_GAP:
            keep.append(k)
    t = t[keep]
    if T - t[-1] < MIN_GAP and len(t) > 1:
        t = t[:-1]
    t = np.append(t, T) if t[-1] < T else t
    s = [tr.at_time(x) for x in t]
    return (t, np.array([p[0] for p in s]), np.array([p[1] for p in s]),
            np.array([p[2] for p in s]))


def _transition(crane, profile, where, th_rest, th_j, junction, space, rate, accel_scale):
    """Ruckig transition between rest at θ = th_rest and the nominal state at θ = th_j.
    ``junction`` = ((f, f f'), (q, q̇, q̈)) of the nominal there. Returns samples in local
    time (t, q, qd, qdd, θ, θ̇), the Junction (with t relative to the transition) and info."""
    path = profile.path
    L = crane.limit_arrays()
    jmax_j = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], NO_JERK)
    (fj, aj), (qj, vj, accj) = junction
    fj, aj = float(fj[0]), float(aj[0])
    qj, vj, accj = qj[0], vj[0], accj[0]
    start = where == "start"
    if space == "theta":
        lo, hi = sorted((th_rest, th_j))
        m = (profile.theta >= lo) & (profile.theta <= hi)
        _, dq_ab, _, f_ab, _ = _states(crane, path, profile.tele, profile.coef,
                                       np.array([lo, hi]), profile.fraction)
        dmax = np.max(np.abs(np.vstack([profile.dq[m], dq_ab])), axis=0)
        env_min = float(min(profile.f[m].min(initial=np.inf), f_ab.min()))  # fraction·env
        vcap = max(env_min, V_HEADROOM * fj)
        with np.errstate(divide="ignore"):
            a_der = accel_scale * float(np.min(L["qdd_max"] / dmax))
            j_der = float(np.min(jmax_j / dmax))
        amax = max(a_der, abs(aj) * (1 + 1e-9))
        jmax = max(j_der, float(_jerk_for(fj, aj, 0.0, vcap, forward=not start)))
        j_req_state = float(_jerk_for(fj, aj, 0.0, vcap, forward=not start))
        rest = ([th_rest], [0.0], [0.0])
        nom = ([th_j], [fj], [aj])
        a_req, j_req = abs(aj) * (1 + 1e-9), j_req_state  # the junction state needs these
        slow = 1.0
        for _ in range(40):
            # the cap is a constant: where the envelope is lower than at the junction (e.g.
            # rising from the path start) the transition is slowed down (acceleration and jerk
            # limits × 0.8) until θ̇ stays under the envelope
            a_try, j_try = max(amax * slow, a_req), max(jmax * slow, j_req)
            tr, scale = _ruckig_relaxed(*((rest, nom) if start else (nom, rest)), [vcap],
                                        [0.0], [a_try], [j_try])
            t, th, thd, thdd = _sample(tr, rate)
            th, thd, thdd = th[:, 0], thd[:, 0], thdd[:, 0]
            env = _states(crane, path, profile.tele, profile.coef, th, 1.0)[3]
            if np.max(thd / env) <= SPEED_RATIO_MAX or (a_try <= a_req and j_try <= j_req):
                break
            slow *= 0.8
        amax, jmax = a_try, j_try
        q, qd, qdd = profile.joint_state(crane, th, thd, thdd)
        k = -1 if start else 0
        perr = (abs(th[k] - th_j), abs(thd[k] - fj), abs(thdd[k] - aj))
        info = dict(where=where, duration_s=tr.duration, space=space,
                    junction_theta_dot=fj, junction_theta_ddot=aj,
                    limits=dict(theta_dot_max=vcap, theta_dot_min=0.0,
                                theta_ddot_max=amax * scale, theta_dddot_max=jmax * scale,
                                theta_ddot_from_joints=a_der, theta_dddot_from_joints=j_der),
                    limit_scale=scale, slow_down=slow,
                    max_speed_over_envelope=float(np.max(thd / env)),
                    min_theta_dot=float(thd.min()),
                    theta_range=[float(th.min()), float(th.max())])
    else:
        q_rest = profile.joint_state(crane, np.array([th_rest]), np.zeros(1), np.zeros(1))[0][0]
        amax = np.maximum(L["qdd_max"], np.abs(accj) * (1 + 1e-9))
        jmax = np.maximum(jmax_j, _jerk_for(vj, accj, L["qd_min"], L["qd_max"],
                                            forward=not start))
        z = np.zeros(crane.n)
        rest, nom = (q_rest, z, z), (qj, vj, accj)
        tr, scale = _ruckig_relaxed(*((rest, nom) if start else (nom, rest)), L["qd_max"],
                                    L["qd_min"], amax, jmax)
        t, q, qd, qdd = _sample(tr, rate)
        th = path.theta_of(crane.fk(q))
        thd = np.full_like(th, np.nan)
        k = -1 if start else 0
        perr = (math.nan,) * 3
        info = dict(where=where, duration_s=tr.duration, space=space,
                    junction_theta_dot=fj, junction_theta_ddot=aj,
                    limits=dict(qdd_max=(amax * scale).tolist(),
                                qddd_max=(jmax * scale).tolist()),
                    limit_scale=scale)
    junc = Junction(where, float(th_j), float(t[k]), float(np.max(np.abs(q[k] - qj))),
                    float(np.max(np.abs(qd[k] - vj))), float(np.max(np.abs(qdd[k] - accj))),
                    tuple(float(v) for v in perr))
    return (t, q, qd, qdd, th, thd), junc, info


def from_rest(crane, profile: Profile, *, start_frac: float = 0.05,
              end_frac: float | None = None, space: str = "theta",
              sample_rate: float = 200.0, accel_scale: float = 1.0) -> FromRest:
    """Start from rest at the path start and join the nominal profile at
    θ_int = θ0 + start_frac·span; for non-periodic paths (or with ``end_frac``) leave it at
    θ0 + end_frac·span (default 0.95) and come to rest at the path end. A periodic path keeps
    the nominal profile to the end of the revolution (it "remains in a cycle"): the motion
    then ends moving.

    ``space="theta"`` (default): 1-DOF Ruckig on the path parameter (the tip stays on the
    path), θ̇ ∈ [0, max(fraction·min envelope on the transition, 1.02·f(θ_int))] (never backwards
    along the path), θ̈ and θ⃛ limits from the joints' (assumed) acceleration/jerk limits divided
    by max |Φ'_i| on the transition (``accel_scale`` scales the acceleration), each raised where
    the nominal junction state needs it (its acceleration; a jerk with which the state can be
    reached without leaving the velocity range — Ruckig rejects it otherwise).
    ``space="joint"``: 4-DOF Ruckig between the rest configuration Φ(θ0) (Φ(θ1)) and the
    nominal joint state under the joints' velocity/acceleration/jerk limits (raised likewise
    where the junction state needs it); the tip leaves the path during the transition.

    Junction errors compare the transition's own end state (Ruckig's ``at_time``, mapped to
    the joints) with the nominal joint state at the junction.
    """
    if space not in ("theta", "joint"):
        raise ValueError("space must be 'theta' or 'joint'")
    path = profile.path
    if end_frac is None and not path.periodic:
        end_frac = 0.95
    th_s = path.theta0 + start_frac * path.span
    th_e = path.theta0 + end_frac * path.span if end_frac is not None else None
    th_end = th_e if th_e is not None else path.theta1

    nom_s = profile.nominal_state(crane, np.array([th_s]), side=+1)
    nom_e = profile.nominal_state(crane, np.array([th_end]), side=-1 if th_e is not None else 0)

    # ---- rest at θ0 -> nominal at θ_s
    p1, j1, i1 = _transition(crane, profile, "start", path.theta0, th_s, nom_s, space,
                             sample_rate, accel_scale)
    T1 = p1[0][-1]
    pieces = [p1]
    trans = [p1]
    junctions, transitions = [j1], [i1]

    # ---- nominal θ_s .. θ_end (junction knots: the nominal's own states)
    k_in = np.flatnonzero((profile.theta > th_s + 1e-9) & (profile.theta < th_end - 1e-9))
    f_in = profile.f[k_in]
    thn = np.concatenate([[th_s], profile.theta[k_in], [th_end]])
    fn = np.concatenate([nom_s[0][0], f_in, nom_e[0][0]])
    tn = T1 + np.concatenate([[0.0], np.cumsum(0.5 * (1 / fn[1:] + 1 / fn[:-1]) * np.diff(thn))])
    qn = np.vstack([nom_s[1][0], profile.q[k_in], nom_e[1][0]])
    qdn = np.vstack([nom_s[1][1], profile.dq[k_in] * f_in[:, None], nom_e[1][1]])
    qddn = np.vstack([nom_s[1][2], profile.ddq[k_in] * (f_in ** 2)[:, None]
                      + profile.dq[k_in] * (f_in * profile.df[k_in])[:, None], nom_e[1][2]])
    # the start knot is the transition's last sample; replace it by the nominal state there
    pieces[0] = tuple(a[:-1] for a in p1)
    pieces.append((tn, qn, qdn, qddn, thn, fn))
    T2 = tn[-1]

    # ---- nominal at θ_e -> rest at θ1
    if th_e is not None:
        p2, j2, i2 = _transition(crane, profile, "end", path.theta1, th_e, nom_e, space,
                                 sample_rate, accel_scale)
        j2.t += T2
        pieces.append((T2 + p2[0][1:],) + tuple(a[1:] for a in p2[1:]))
        trans.append(p2)
        junctions.append(j2)
        transitions.append(i2)

    t = np.concatenate([p[0] for p in pieces])
    q = np.vstack([p[1] for p in pieces])
    qd = np.vstack([p[2] for p in pieces])
    qdd = np.vstack([p[3] for p in pieces])
    th = np.concatenate([p[4] for p in pieces])
    thd = np.concatenate([p[5] for p in pieces])
    meta = dict(path=path.name, fraction=profile.fraction, space=space, start_frac=start_frac,
                end_frac=end_frac)
    traj = Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names), method="phase+ruckig",
                      objective="time", limits=CLAIMS, meta=meta)
    ttraj = [Trajectory(p[0], p[1], p[2], p[3], joint_names=tuple(crane.names),
                        method="ruckig-transition", objective="time", limits=CLAIMS,
                        meta=meta)
             for p in trans]
    # tip deviation from the path: nearest point of a dense sample of the path
    from scipy.spatial import cKDTree
    dense = path.xyz(np.linspace(path.theta0, path.theta1, 20001))
    dev = float(np.max(cKDTree(dense).query(crane.fk(q))[0]))
    return FromRest(traj, traj.duration, space, junctions, transitions, ttraj, (t, th, thd),
                    dev, (th_s, th_end))


# ====================================================================== the seed's setup
def seed_setup(name: str, *, alpha: float | None = None, order: int | None = None):
    """(path, telescope model) of the seed's test paths: "circle" (Fourier order 3 by default)
    or "parabola" (Bézier order 5 by default; ``alpha`` overrides the seed's −π/3)."""
    if name == "circle":
        return circle_path(), FourierTele(3 if order is None else order)
    if name == "parabola":
        p = parabola_path(alpha=-math.pi / 3 if alpha is None else alpha)
        return p, BezierTele(5 if order is None else order, p.theta0, p.theta1)
    raise ValueError(f"unknown seed-003 path {name!r}: circle or parabola")
