"""Seed 003's telescope as a function of the path parameter, q4 = φ4(θ), and its optimisation.

A truncated Fourier series of order M on the periodic circle (:class:`FourierTele`, seed
eq. 14), a Bézier polynomial of order N in the normalised parameter u = (θ − θ0)/(θ1 − θ0) on
the parabola (:class:`BezierTele`, seed eq. 15). :func:`optimise_telescope` chooses the
coefficients that maximise the area under the phase-plane envelope
(:mod:`planner.methods.phase.envelope`; Nelder–Mead, deterministic starts; infeasible
coefficients — IK failure, a joint or the telescope outside its limits — are penalised by
their distance to the feasible telescope band). :func:`seed_setup` gives the seed's two test
paths with their telescope models.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time as _time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from planner.geometry.paths import SeedPath, circle_path, parabola_path
from planner.methods.phase.envelope import (Envelope, constant_scan, envelope, feasible_band,
                                            tele_grid)

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["FourierTele", "BezierTele", "TeleOpt", "optimise_telescope", "seed_setup"]


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


@dataclass
class TeleOpt:
    """The optimised telescope function, its envelope and the constant-telescope comparison."""
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


def optimise_telescope(crane: Crane, path: SeedPath, tele, *, n_theta: int = 241,
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
    tg = tele_grid(crane, tele_step)
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


def seed_setup(name: str, *, alpha: float | None = None, order: int | None = None):
    """(path, telescope model) of the seed's test paths: "circle" (Fourier order 3 by default)
    or "parabola" (Bézier order 5 by default; ``alpha`` overrides the seed's −π/3)."""
    if name == "circle":
        return circle_path(), FourierTele(3 if order is None else order)
    if name == "parabola":
        p = parabola_path(alpha=-math.pi / 3 if alpha is None else alpha)
        return p, BezierTele(5 if order is None else order, p.theta0, p.theta1)
    raise ValueError(f"unknown seed-003 path {name!r}: circle or parabola")
