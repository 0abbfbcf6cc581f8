"""Geometric tip paths: one family, two faces of a curve.

A :class:`Path` is parametrised by arc length s ∈ [0, length] (m) and gives Cartesian points
in frame 0 (``xyz(s)``) and the CONTRACT tip coordinates (``tip(s)`` = (r, z, slew)): what the
DP, the local laws and TOPP-RA walk along. Lines and waypoint polylines are exact.

A smooth curve is defined once, in its own parameter θ, as a :class:`SeedPath`: p(θ) with its
analytic derivative, the inverse θ(p) and (optionally) a CasADi face for the NLP — the
phase-plane method of seed 003 works in that parameter (its velocity bound is on θ̇, seed
eq. 11). :class:`Curve` is the arc-length :class:`Path` of any p(u) (re-parametrised
numerically by dense sampling); :meth:`SeedPath.arc_length` gives it for a seed curve, and the
:func:`circle` / :func:`parabola` curves are built that way from the same definitions as
:func:`circle_path` / :func:`parabola_path`. They stay two classes because ``xyz`` means a
point at arc length s on a Path and at parameter θ on a SeedPath.

Only numpy is loaded with the module: scipy when a :class:`Curve` is built, CasADi when a seed
curve's symbolic face is evaluated (the NLP), so a command that walks a line pays for neither.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

__all__ = ["tip_to_xyz", "xyz_to_tip", "Path", "Line", "Waypoints", "Curve", "SeedPath",
           "circle_path", "parabola_path", "circle", "parabola"]


def tip_to_xyz(tip) -> np.ndarray:
    """(r, z, slew) -> (x, y, z); vectorised over leading axes."""
    t = np.asarray(tip, float)
    r, z, s = t[..., 0], t[..., 1], t[..., 2]
    return np.stack([r * np.cos(s), r * np.sin(s), z], axis=-1)


def xyz_to_tip(p) -> np.ndarray:
    """(x, y, z) -> (r, z, slew); vectorised over leading axes."""
    p = np.asarray(p, float)
    return np.stack([np.hypot(p[..., 0], p[..., 1]), p[..., 2], np.arctan2(p[..., 1], p[..., 0])],
                    axis=-1)


class Path(ABC):
    """Base: subclasses set ``length`` and implement ``xyz(s)``."""
    length: float = 0.0
    name: str = "path"

    @abstractmethod
    def xyz(self, s) -> np.ndarray:
        """Cartesian points (..., 3) [m] at arc lengths s."""

    def tip(self, s) -> np.ndarray:
        """(r, z, slew) at arc lengths s (array)."""
        return xyz_to_tip(self.xyz(s))

    def stations(self, step: float | None = None, n: int | None = None) -> np.ndarray:
        """n + 1 equally spaced arc lengths (or the fewest with spacing ≤ step)."""
        if n is None:
            if step is None or step <= 0:
                raise ValueError("give a positive step [m] or a number of steps n")
            n = max(1, int(math.ceil(self.length / step - 1e-9)))
        return np.linspace(0.0, self.length, int(n) + 1)

    def tangent(self, s) -> np.ndarray:
        """Unit tangent dxyz/ds (central differences)."""
        s = np.asarray(s, float)
        h = 1e-6 * max(self.length, 1.0)
        a = self.xyz(np.clip(s + h, 0, self.length))
        b = self.xyz(np.clip(s - h, 0, self.length))
        d = a - b
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def __repr__(self):
        return f"{type(self).__name__}(length={self.length:.3f} m)"


class Line(Path):
    """Straight line in Cartesian space between two tips (r, z, slew)."""
    name = "line"

    def __init__(self, start, goal):
        self.start_tip, self.goal_tip = np.asarray(start, float), np.asarray(goal, float)
        self.a, self.b = tip_to_xyz(self.start_tip), tip_to_xyz(self.goal_tip)
        self.length = float(np.linalg.norm(self.b - self.a))
        if self.length == 0:
            raise ValueError("a line needs distinct start and goal")

    def xyz(self, s):
        u = np.asarray(s, float)[..., None] / self.length
        return self.a + u * (self.b - self.a)


class Waypoints(Path):
    """Polyline through tips (r, z, slew) — straight in Cartesian space between them."""
    name = "waypoints"

    def __init__(self, tips):
        tips = np.asarray(tips, float)
        if tips.ndim != 2 or tips.shape[0] < 2 or tips.shape[1] != 3:
            raise ValueError("waypoints: give at least two tips (r, z, slew)")
        self.points = tip_to_xyz(tips)
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        if np.any(seg == 0):
            raise ValueError("waypoints: consecutive tips must differ")
        self.cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self.cum[-1])

    def xyz(self, s):
        s = np.clip(np.asarray(s, float), 0, self.length)
        k = np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.cum) - 2)
        u = ((s - self.cum[k]) / (self.cum[k + 1] - self.cum[k]))[..., None]
        return self.points[k] + u * (self.points[k + 1] - self.points[k])


class Curve(Path):
    """Smooth curve p(u), u ∈ [u0, u1] (vectorised callable returning (..., 3) xyz),
    re-parametrised by arc length from ``samples`` points (cubic interpolation of u(s)).
    ``p_sym``: optional CasADi face θ -> xyz 3-vector (for the NLP's curve mode); ``source``:
    the :class:`SeedPath` it was built from, if any."""
    name = "curve"

    def __init__(self, p, u0: float, u1: float, samples: int = 4001, p_sym=None, source=None):
        self.p = p
        self.p_sym = p_sym
        self.source = source
        self.u_range = (float(u0), float(u1))
        u = np.linspace(u0, u1, samples)
        pts = np.asarray(p(u), float)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(cum[-1])
        from scipy.interpolate import CubicSpline   # scipy: only for a curve's arc length
        self._u_of_s = CubicSpline(cum, u)

    def xyz(self, s):
        return np.asarray(self.p(self._u_of_s(np.clip(np.asarray(s, float), 0, self.length))))


@dataclass(frozen=True)
class SeedPath:
    """Tip curve p(θ) in frame 0 in its own parameter θ ∈ [theta0, theta1] (not arc length),
    with its analytic derivative ``dp``, the inverse ``theta_of`` (the curve's definition of
    the parameter), ``periodic`` (closed curve), ``params`` (the defining numbers) and an
    optional CasADi face ``p_sym`` (θ -> xyz 3-vector)."""
    name: str
    theta0: float
    theta1: float
    periodic: bool
    p: object          # θ (K,) -> xyz (K, 3)
    dp: object         # θ (K,) -> dxyz/dθ (K, 3)
    theta_of: object   # xyz (K, 3) -> θ (K,)
    params: dict = field(default_factory=dict)
    p_sym: object = None

    @property
    def span(self) -> float:
        return self.theta1 - self.theta0

    def xyz(self, theta) -> np.ndarray:
        """Points p(θ) (K, 3) [m]."""
        return np.asarray(self.p(np.atleast_1d(np.asarray(theta, float))), float)

    def dxyz(self, theta) -> np.ndarray:
        """Derivatives dp/dθ (K, 3)."""
        return np.asarray(self.dp(np.atleast_1d(np.asarray(theta, float))), float)

    def tip(self, theta) -> np.ndarray:
        """CONTRACT tip coordinates (r, z, slew) at θ."""
        return xyz_to_tip(self.xyz(theta))

    def grid(self, n: int) -> np.ndarray:
        """n equally spaced parameter values from theta0 to theta1."""
        return np.linspace(self.theta0, self.theta1, int(n))

    def arc_length(self, samples: int = 4001) -> Curve:
        """This curve as an arc-length :class:`Curve` (a :class:`Path`), keeping p_sym."""
        cv = Curve(self.p, self.theta0, self.theta1, samples=samples, p_sym=self.p_sym,
                   source=self)
        cv.name = self.name
        return cv


_PLANES = {"xz": (np.array([1.0, 0, 0]), np.array([0, 0, 1.0])),
           "xy": (np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))}


def _circle(center_xyz, radius: float, theta0: float, theta1: float, plane: str,
            params: dict) -> SeedPath:
    """Circle p(θ) = c + R(cos θ·e1 + sin θ·e2), θ = atan2((p − c)·e2, (p − c)·e1)."""
    if plane not in _PLANES:
        raise ValueError(f"circle plane {plane!r}: allowed {', '.join(_PLANES)}")
    c = np.asarray(center_xyz, float)
    e1, e2 = _PLANES[plane]
    R = float(radius)

    def p(th):
        return c + R * (np.cos(th)[..., None] * e1 + np.sin(th)[..., None] * e2)

    def dp(th):
        return R * (-np.sin(th)[..., None] * e1 + np.cos(th)[..., None] * e2)

    def theta_of(xyz):
        d = np.asarray(xyz, float) - c
        return np.arctan2(d @ e2, d @ e1)

    def p_sym(th):
        import casadi as ca
        return ca.DM(c) + R * (ca.cos(th) * ca.DM(e1) + ca.sin(th) * ca.DM(e2))

    periodic = abs(abs(theta1 - theta0) - 2 * math.pi) < 1e-12
    return SeedPath("circle", float(theta0), float(theta1), periodic, p, dp, theta_of, params,
                    p_sym)


def circle_path(R: float = 0.7, center=(3.0, 2.5)) -> SeedPath:
    """Seed 003 eq. 4–5: circle in the x–z plane, θ = atan2(z − zC, x − xC) ∈ [−π, π]."""
    xc, zc = map(float, center)
    return _circle((xc, 0.0, zc), R, -math.pi, math.pi, "xz",
                   dict(R=R, xC=xc, zC=zc, plane="xz"))


def parabola_path(x0: float = 1.6, x1: float = 3.07, z_min: float = 1.5, z_max: float = 3.0,
                  alpha: float = -math.pi / 3, vertex: str = "minus") -> SeedPath:
    """Seed 003 eq. 6–8, its 3-D lift: θ = x ∈ [x0, x1], p(θ) = (θ, tan α·θ, (θ ∓ h)²/(4a) + k),
    h = (x0 + x1)/2, k = z_max, a = (x0 − h)²/(4(z_min − k)) < 0.

    ``vertex="minus"`` uses (θ − h) (vertex z_max at θ = h, z_min at both ends: what the seed
    means); ``"plus"`` the printed (θ + h), kept for the vertex check."""
    if vertex not in ("minus", "plus"):
        raise ValueError(f"vertex {vertex!r}: allowed 'minus' ((θ − h), the intended form) or "
                         "'plus' ((θ + h), as printed in the seed)")
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

    def p_sym(x):
        import casadi as ca
        return ca.vertcat(x, ta * x, (x + sh) ** 2 / (4 * a) + k)

    return SeedPath("parabola", float(x0), float(x1), False, p, dp, theta_of,
                    dict(x0=x0, x1=x1, z_min=z_min, z_max=z_max, alpha=alpha, h=h, k=k, a=a,
                         vertex=vertex), p_sym)


def circle(center_xyz, radius: float, theta0: float = -math.pi, theta1: float = math.pi,
           plane: str = "xz") -> Curve:
    """Circle p(θ) = c + R(cos θ·e1 + sin θ·e2) in the 'xz' (vertical, seed 003) or 'xy' plane,
    θ from theta0 to theta1, by arc length."""
    c = np.asarray(center_xyz, float)
    return _circle(c, radius, theta0, theta1, plane,
                   dict(R=float(radius), center=c.tolist(), plane=plane)).arc_length()


def parabola(x0: float, x1: float, z_min: float, z_max: float, azimuth: float) -> Curve:
    """Seed 003's 3-D lift (:func:`parabola_path`, (x − h) meant) by arc length: x from x0 to
    x1, y = tan(azimuth)·x, z a parabola with its vertex z_max mid-way and z_min at both
    ends."""
    return parabola_path(x0, x1, z_min, z_max, alpha=azimuth).arc_length()
