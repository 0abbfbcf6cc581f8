"""Obstacles the tip must keep clear of: the load bunk's headboard and similar.

Each obstacle gives the NLP smooth constraints on the tip (``constraints``), the exact distance
for verification on a fine resampling (``distance``), and via points for a guess that passes on
the right side (``vias``). Tips are (r, z, slew) in the crane's frame 0 [m, m, rad]; Cartesian
points (x, y, z) are in the same frame (x ahead, z up, from the slew base).

- :class:`Wall`: a vertical wall in the r–z plane at radius r from the slew axis (every slew
  angle) — the seed-003 setting and planar studies.
- :class:`Plate`: a vertical rectangular plate across the machine at x = const (a forwarder's
  headboard between the crane pillar and the load space), finite in y and z.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


def _check(name, clearance, lo, hi, what):
    if not clearance > 0:
        raise ValueError(f"{name}: clearance must be > 0 m, got {clearance}")
    if not hi > lo:
        raise ValueError(f"{name}: {what} must have top > bottom, got [{lo}, {hi}]")


@dataclass(frozen=True)
class Wall:
    """A vertical wall at horizontal distance ``r`` [m] from the slew axis, from ``z_bottom``
    up to ``z_top`` [m]; the tip keeps ``clearance`` [m]. Imposed smoothly as discs of radius
    ``clearance`` spaced ≤ clearance/2 along the wall: between two discs the distance to the
    wall is then at least clearance·√(1 − 1/16) ≈ 0.968·clearance."""
    r: float
    z_top: float
    z_bottom: float
    clearance: float = 0.3
    kind = "wall"

    def __post_init__(self):
        _check("wall", self.clearance, self.z_bottom, self.z_top, "z")

    def centres(self):
        k = max(2, int(np.ceil((self.z_top - self.z_bottom) / (0.5 * self.clearance))) + 1)
        return [(self.r, z) for z in np.linspace(self.z_bottom, self.z_top, k)]

    def constraints(self, xyz, cyl):
        """[(expression, lower bound)] on a symbolic tip, all ≥ their bound when clear."""
        return [((cyl[0] - rc) ** 2 + (cyl[1] - zc) ** 2, self.clearance ** 2)
                for rc, zc in self.centres()]

    def distance(self, xyz, cyl):
        """Distance [m] of tips (rows) to the wall."""
        cyl = np.atleast_2d(cyl)
        zc = np.clip(cyl[:, 1], self.z_bottom, self.z_top)
        return np.hypot(cyl[:, 0] - self.r, cyl[:, 1] - zc)

    def vias(self, start, goal):
        """Via tips (r, z, slew) 1.5 clearances above the wall where the move crosses its r."""
        if (start[0] - self.r) * (goal[0] - self.r) >= 0:
            return []
        f = (self.r - start[0]) / (goal[0] - start[0])
        return [np.array([self.r, self.z_top + 1.5 * self.clearance,
                          start[2] + f * (goal[2] - start[2])])]

    def to_dict(self):
        return dict(kind=self.kind, **asdict(self))


@dataclass(frozen=True)
class Plate:
    """A vertical plate across the machine at ``x`` [m] (frame 0, x ahead), spanning
    ``y_min..y_max`` and ``z_bottom..z_top`` [m]; the tip keeps ``clearance`` [m] from it.

    Imposed at the check points as one smooth (C¹) constraint: the squared distance to the
    rectangle, (x − x₀)² + max(y − y_max, y_min − y, 0)² + max(z − z_top, z_bottom − z, 0)²,
    ≥ clearance². Between check points the tip could in principle pass through; the NLP
    verifies every solution on a 1 kHz resampling (:meth:`distance`)."""
    x: float
    y_min: float
    y_max: float
    z_bottom: float
    z_top: float
    clearance: float = 0.3
    kind = "plate"

    def __post_init__(self):
        _check("plate", self.clearance, self.z_bottom, self.z_top, "z")
        _check("plate", self.clearance, self.y_min, self.y_max, "y")

    def constraints(self, xyz, cyl):
        import casadi as ca
        dy = ca.fmax(ca.fmax(xyz[1] - self.y_max, self.y_min - xyz[1]), 0)
        dz = ca.fmax(ca.fmax(xyz[2] - self.z_top, self.z_bottom - xyz[2]), 0)
        return [((xyz[0] - self.x) ** 2 + dy ** 2 + dz ** 2, self.clearance ** 2)]

    def distance(self, xyz, cyl):
        xyz = np.atleast_2d(xyz)
        dy = np.maximum(np.maximum(xyz[:, 1] - self.y_max, self.y_min - xyz[:, 1]), 0)
        dz = np.maximum(np.maximum(xyz[:, 2] - self.z_top, self.z_bottom - xyz[:, 2]), 0)
        return np.sqrt((xyz[:, 0] - self.x) ** 2 + dy ** 2 + dz ** 2)

    def vias(self, start, goal):
        """A via tip 1.5 clearances above the plate's top edge where the tip, moving with r, z
        and slew interpolated linearly (how a slewing crane moves), first comes within a
        clearance of the plate (none if it never does)."""
        from planner.geometry.paths import tip_to_xyz
        s = np.linspace(0.0, 1.0, 201)[:, None]
        cyl = np.asarray(start, float) + s * (np.asarray(goal, float) - np.asarray(start, float))
        xyz = tip_to_xyz(cyl)
        near = np.flatnonzero(self.distance(xyz, cyl) < self.clearance)
        if near.size == 0:
            return []
        r, _, slew = cyl[near[0]]
        return [np.array([r, self.z_top + 1.5 * self.clearance, slew])]

    def to_dict(self):
        return dict(kind=self.kind, **asdict(self))


KINDS = {"wall": Wall, "plate": Plate}


def from_dict(d: dict):
    """An obstacle from its dict (``kind`` plus the fields); errors name the bad key."""
    d = dict(d)
    kind = d.pop("kind", None)
    if kind not in KINDS:
        raise ValueError(f"obstacle kind must be one of {sorted(KINDS)}, got {kind!r}")
    cls = KINDS[kind]
    fields = set(cls.__dataclass_fields__)
    unknown = set(d) - fields
    if unknown:
        raise ValueError(f"{kind}: unknown keys {sorted(unknown)}; allowed: {sorted(fields)}")
    try:
        return cls(**{k: float(v) for k, v in d.items()})
    except TypeError as e:
        raise ValueError(f"{kind}: {e}") from None


def tip_clearance(cyl, obstacles) -> float:
    """The least distance [m] of the tips ``cyl`` ((K, 3): r, z, slew) to any of
    ``obstacles``; inf when there are none."""
    from planner.geometry.paths import tip_to_xyz
    cyl = np.atleast_2d(np.asarray(cyl, float))
    xyz = tip_to_xyz(cyl)
    return min((float(ob.distance(xyz, cyl).min()) for ob in obstacles), default=float("inf"))
