"""The Exudyn plant's rigid-body data from a spec: the kinematic tree (joint types, constant
transforms, link masses, centres of mass and inertias, the payload at the tip) and the stroke
map as dense tables cheap enough for the integrator's Newton iterations."""
from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from planner.model.dynamics import lumped_links
from planner.model.kinematics import joint_transforms

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["StrokeTable", "tree_parameters"]


class StrokeTable:
    """Stroke map x(q) and dx/dq of every actuator as dense tables (linear interpolation,
    linear extrapolation beyond the table) from the model's exact map — cheap enough to call
    inside the integrator's Newton iterations.

    The table runs past the joint limits to as far as the exact map stays finite and
    monotonic, up to ``beyond`` × the joint's range on either side: a joint driven past its
    limit runs on to its cylinder's stroke end, where the end stop takes it, and its lever arm
    changes on the way (s100f's boom: dx/dq −0.469 m/rad at its limit of 0.349 rad, −0.43 at
    its stroke end 0.045 rad further). Tabled over the joint range only, dx/dq was held at the
    limit's value there, and the plant and the twin (the exact map) parted: a boom lowered onto
    its stroke end with an 839 kg load by the trials' excitation (s100f, seed 1000), the same
    machine to 0.001 MPa for 18.6 s, 0.7 σ apart on the slew and boom pressures from the
    crossing on (2026-11-28). The spacing is at most the joint range / (``points`` − 1)."""

    def __init__(self, crane: Crane, points: int = 4001, beyond: float = 0.2):
        L = crane.limit_arrays()
        lo, hi = np.array(L["q_min"], float), np.array(L["q_max"], float)
        span = hi - lo
        n = crane.n
        # probe the exact map past the limits; keep the monotonic, finite run that holds
        # the joint range
        m = int(round(2 * beyond * (points - 1))) + points
        G = np.linspace(lo - beyond * span, hi + beyond * span, m)
        with np.errstate(invalid="ignore", divide="ignore"):
            Xg, Dg = crane.stroke(G)
        a, b = lo.copy(), hi.copy()
        for i in range(n):
            inside = (G[:, i] >= lo[i]) & (G[:, i] <= hi[i])
            sgn = np.sign(np.nanmedian(Dg[inside, i]))
            ok = np.isfinite(Xg[:, i]) & np.isfinite(Dg[:, i]) & (Dg[:, i] * sgn > 0)
            k0, k1 = np.flatnonzero(inside)[[0, -1]]
            if not ok[k0:k1 + 1].all():
                continue            # not monotonic within its own range: the range only
            while k0 > 0 and ok[k0 - 1]:
                k0 -= 1
            while k1 < m - 1 and ok[k1 + 1]:
                k1 += 1
            a[i], b[i] = G[k0, i], G[k1, i]
        # K points per joint over [a, b]: no coarser than the joint range's old spacing
        K = int(np.max(np.ceil((b - a) / span * (points - 1)))) + 1
        self.Q = np.linspace(a, b, K)
        self.X, self.D = crane.stroke(self.Q)
        self.n = n
        self._h = (self.Q[1] - self.Q[0]).tolist()
        self._q0 = self.Q[0].tolist()
        self._last = K - 1
        self._x = [self.X[:, i].tolist() for i in range(n)]
        self._d = [self.D[:, i].tolist() for i in range(n)]

    def __call__(self, q):
        """(x, dx/dq) at one configuration q (n floats) as lists (the grid is uniform per
        joint; plain Python: called inside the integrator's Newton iterations)."""
        xs, ds = [], []
        for i in range(self.n):
            z = (q[i] - self._q0[i]) / self._h[i]
            k = min(max(int(z), 0), self._last - 1)
            w = z - k
            X, D = self._x[i], self._d[i]
            xs.append(X[k] + w * (X[k + 1] - X[k]))
            ds.append(D[k] + min(max(w, 0.0), 1.0) * (D[k + 1] - D[k]))
        return xs, ds

    def columns(self):
        """The tables as plain lists for lookups in plain Python: per joint (first grid point,
        spacing, stroke column, dx/dq column), and the index of the last interval."""
        return ([(self._q0[i], self._h[i], self._x[i], self._d[i]) for i in range(self.n)],
                self._last - 1)

    def batch(self, q):
        """(x, dx/dq) for configurations (N, n) (within the table: clamped beyond it)."""
        q = np.atleast_2d(q)
        x = np.column_stack([np.interp(q[:, i], self.Q[:, i], self.X[:, i])
                             for i in range(self.n)])
        d = np.column_stack([np.interp(q[:, i], self.Q[:, i], self.D[:, i])
                             for i in range(self.n)])
        return x, d


def tree_parameters(spec, payload: float, bodies=None) -> dict:
    """Kinematic-tree data of a spec: joint types ('revolute' | 'prismatic'), the constant
    transformation from each parent link frame to the joint frame (4×4), link masses, COMs
    and inertias (about the COM) in the link frames, and the tip point in the last link frame;
    the payload [kg] is merged into the last link as a point mass at the tip."""
    n = spec.n
    C = [np.array(ca.DM(A)) for A in joint_transforms(spec, ca.DM.zeros(n))]
    bodies = lumped_links(spec) if bodies is None else bodies
    hts, masses, coms, inertias = [], [], [], []
    for i in range(n):
        hts.append(np.eye(4) if i == 0 else C[i - 1])
        m, c, inertia = bodies[i]
        R, t = C[i][:3, :3], C[i][:3, 3]
        cc = R @ np.asarray(c) + t
        II = R @ np.asarray(inertia) @ R.T
        if i == n - 1 and payload > 0:
            M = m + payload
            cn = (m * cc + payload * t) / M
            d1, d2 = cc - cn, t - cn
            II = (II + m * (d1 @ d1 * np.eye(3) - np.outer(d1, d1))
                  + payload * (d2 @ d2 * np.eye(3) - np.outer(d2, d2)))
            m, cc = M, cn
        masses.append(float(m))
        coms.append(cc)
        inertias.append(II)
    return dict(types=["revolute" if j.revolute else "prismatic" for j in spec.joints],
                hts=hts, masses=masses, coms=coms, inertias=inertias, tip=C[-1][:3, 3].copy())
