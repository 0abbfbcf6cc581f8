"""Geometric tip paths parametrised by arc length s ∈ [0, length] (m).

Every path gives Cartesian points in frame 0 (``xyz(s)``) and the CONTRACT tip coordinates
(``tip(s)`` = (r, z, slew)). Lines and waypoint polylines are exact; circles and parabolas are
any smooth curve p(u) re-parametrised by arc length numerically (dense sampling).
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np


def tip_to_xyz(tip) -> np.ndarray:
    """(r, z, slew) -> (x, y, z); vectorised over leading axes."""
    t = np.asarray(tip, float)
    r, z, s = t[..., 0], t[..., 1], t[..., 2]
    return np.stack([r * np.cos(s), r * np.sin(s), z], axis=-1)


def xyz_to_tip(p) -> np.ndarray:
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
    re-parametrised by arc length from ``samples`` points (cubic interpolation of u(s))."""
    name = "curve"

    def __init__(self, p, u0: float, u1: float, samples: int = 4001, p_sym=None):
        from scipy.interpolate import CubicSpline
        self.p = p
        self.p_sym = p_sym  # optional CasADi face: θ (SX/MX) -> xyz 3-vector (for the NLP)
        self.u_range = (float(u0), float(u1))
        u = np.linspace(u0, u1, samples)
        pts = np.asarray(p(u), float)
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(cum[-1])
        self._u_of_s = CubicSpline(cum, u)

    def xyz(self, s):
        return np.asarray(self.p(self._u_of_s(np.clip(np.asarray(s, float), 0, self.length))))


def circle(center_xyz, radius: float, theta0: float = -math.pi, theta1: float = math.pi,
           plane: str = "xz") -> Curve:
    """Circle p(θ) = c + R(cos θ·e1 + sin θ·e2) in the 'xz' (vertical, seed 003) or 'xy' plane."""
    import casadi as ca
    c = np.asarray(center_xyz, float)
    e1, e2 = {"xz": (np.array([1.0, 0, 0]), np.array([0, 0, 1.0])),
              "xy": (np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))}[plane]
    cv = Curve(lambda th: c + radius * (np.cos(th)[..., None] * e1 + np.sin(th)[..., None] * e2),
               theta0, theta1,
               p_sym=lambda th: ca.DM(c) + radius * (ca.cos(th) * ca.DM(e1)
                                                       + ca.sin(th) * ca.DM(e2)))
    cv.name = "circle"
    return cv


def parabola(x0: float, x1: float, z_min: float, z_max: float, azimuth: float) -> Curve:
    """Seed 003's 3-D lift: x from x0 to x1, y = tan(azimuth)·x, z a parabola with its vertex
    z_max mid-way and z_min at both ends (the digest's vertex check: (x − h) is meant)."""
    import casadi as ca
    h = 0.5 * (x0 + x1)
    a = (x0 - h) ** 2 / (4 * (z_min - z_max))
    cv = Curve(lambda x: np.stack([x, math.tan(azimuth) * x, (x - h) ** 2 / (4 * a) + z_max],
                                  axis=-1), x0, x1,
               p_sym=lambda x: ca.vertcat(x, math.tan(azimuth) * x, (x - h) ** 2 / (4 * a) + z_max))
    cv.name = "parabola"
    return cv
