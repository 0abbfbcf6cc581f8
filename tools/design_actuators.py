"""Design assumed cylinder mountings that cover a joint range (provenance of the TOML numbers).

The seeds give no cylinder geometry except seed 001's triangles, so the shipped specs use
mountings produced here: a triangle with the cylinder angle φ swept symmetrically about a centre
angle, and, for jib ranges too wide for a triangle (> ~130°), a two-lever linkage found by a
seeded differential-evolution search maximising the smallest lever arm |dL/dq| over the range.

    python tools/design_actuators.py triangle --range 8deg 123deg --theta -90deg --a 0.55 --b 1.6 --extend-raises
    python tools/design_actuators.py lever --range 2deg 178deg --theta -90deg
"""
from __future__ import annotations

import argparse
import math

import numpy as np
from scipy.optimize import differential_evolution

from planner.units import parse_angle

MARGIN = 0.02  # assumed: 20 mm of stroke kept free at each end


def triangle(q_lo, q_hi, theta_off, a, b, centre=math.radians(90), lengthen_with_q=True):
    """Pins for L(q) = |B - Rot(θ_off + q)·R| with R = (b, 0), |B| = a; φ centred on ``centre``."""
    q_mid = 0.5 * (q_lo + q_hi)
    psi_b = theta_off + q_mid + (-centre if lengthen_with_q else centre)
    B = np.array([a * math.cos(psi_b), a * math.sin(psi_b)])
    R = np.array([b, 0.0])
    qs = np.linspace(q_lo, q_hi, 401)
    L = _tri_len(B, R, theta_off + qs)
    closed = L.min() - MARGIN
    return dict(base=B.round(4).tolist(), rod=R.round(4).tolist(),
                closed_length=round(float(closed), 4),
                stroke=round(float(L.max() - L.min() + 2 * MARGIN), 4))


def _tri_len(B, R, th):
    Rx = np.cos(th) * R[0] - np.sin(th) * R[1]
    Ry = np.sin(th) * R[0] + np.cos(th) * R[1]
    return np.hypot(B[0] - Rx, B[1] - Ry)


def lever_length(p, th, branch):
    Ax, Ay, Cx, Cy, Dx, Dy, l1, l2 = p
    Dxr = np.cos(th) * Dx - np.sin(th) * Dy
    Dyr = np.sin(th) * Dx + np.cos(th) * Dy
    vx, vy = Dxr - Cx, Dyr - Cy
    d = np.hypot(vx, vy)
    aa = (l1 ** 2 - l2 ** 2 + d ** 2) / (2 * d)
    h2 = l1 ** 2 - aa ** 2
    h = np.sqrt(np.maximum(h2, 0))
    ex, ey = vx / d, vy / d
    Px = Cx + aa * ex - branch * h * ey
    Py = Cy + aa * ey + branch * h * ex
    return np.hypot(Px - Ax, Py - Ay), h2


def lever(q_lo, q_hi, theta_off, lengthen_with_q=True, seed=1, max_stroke=1.6):
    qs = np.linspace(q_lo, q_hi, 241)
    th = theta_off + qs
    sgn = 1.0 if lengthen_with_q else -1.0
    best = None
    for branch in (1, -1):
        def cost(p):
            L, h2 = lever_length(p, th, branch)
            l1, l2 = p[6], p[7]
            bad = np.maximum(0.05 * l1 * l2 - h2, 0).sum() * 100
            dL = np.gradient(L, qs) * sgn
            arm = dL.min()
            stroke = L.max() - L.min()
            ratio = L.max() / max(L.min(), 1e-6)
            pen = (bad + 10 * max(0, stroke - max_stroke) + 10 * max(0, ratio - 1.85)
                   + 10 * max(0, 0.05 - arm))
            return -arm + pen
        bounds = [(-2.6, -1.0), (-0.6, 0.6), (-0.7, 0.1), (-0.6, 0.6), (-0.6, 0.6), (-0.6, 0.6),
                  (0.15, 0.8), (0.15, 0.8)]
        res = differential_evolution(cost, bounds, seed=seed, maxiter=400, tol=1e-8, polish=True)
        if best is None or res.fun < best[0]:
            best = (res.fun, res.x, branch)
    fun, p, branch = best
    L, h2 = lever_length(p, th, branch)
    return dict(base=p[0:2].round(4).tolist(), lever_pivot=p[2:4].round(4).tolist(),
                lever_link=p[4:6].round(4).tolist(), lever_lengths=p[6:8].round(4).tolist(),
                lever_branch=branch, closed_length=round(float(L.min() - MARGIN), 4),
                stroke=round(float(L.max() - L.min() + 2 * MARGIN), 4),
                min_arm_m=round(float(-fun), 4))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("kind", choices=["triangle", "lever"])
    ap.add_argument("--range", nargs=2, required=True)
    ap.add_argument("--theta", default="0")
    ap.add_argument("--a", type=float, default=0.6)
    ap.add_argument("--b", type=float, default=1.5)
    ap.add_argument("--centre", default="90deg")
    ap.add_argument("--shorten-with-q", action="store_true")
    a = ap.parse_args()
    lo, hi = (parse_angle(v) for v in a.range)
    th = parse_angle(a.theta)
    if a.kind == "triangle":
        print(triangle(lo, hi, th, a.a, a.b, parse_angle(a.centre), not a.shorten_with_q))
    else:
        print(lever(lo, hi, th, not a.shorten_with_q))


if __name__ == "__main__":
    main()
