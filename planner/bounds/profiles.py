"""Time-optimal motion of one joint from rest under velocity, acceleration and jerk limits: the
rest-to-rest minimum time (the analytic bound's per-joint term, equal to Ruckig's independent
minimum) and the largest distance covered from rest in a given time (the ramp bound's caps,
:mod:`planner.bounds.ramps`). Both vectorised over every argument; j = inf drops the jerk
limit (the bang-bang / trapezoid profile)."""
from __future__ import annotations

import numpy as np

__all__ = ["rest_to_rest_time", "from_rest_distance"]


def rest_to_rest_time(d, v, a, j=np.inf):
    """Minimum time [s] to move a distance d ≥ 0 from rest to rest under |v|, |a|, |j| limits.

    Vectorised over all arguments. With j = inf this is the bang-bang (trapezoid) profile."""
    d, v, a, j = np.broadcast_arrays(*(np.asarray(x, float) for x in (d, v, a, j)))
    d = np.abs(d)
    inv_j = np.where(np.isfinite(j), 1.0 / j, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        # accelerating from 0 to speed w: time and distance (symmetric S-curve or trapezoid)
        def acc_phase(w):
            reach_a = w >= a * a * inv_j   # the profile reaches full acceleration
            t_full = w / a + a * inv_j
            t_tri = 2.0 * np.sqrt(w * inv_j)
            t = np.where(reach_a, t_full, t_tri)
            return t, 0.5 * w * t
        t_v, d_v = acc_phase(v)
        cruise = d >= 2 * d_v
        T_cruise = 2 * t_v + (d - 2 * d_v) / v
        # peak speed w < v: solve d = 2·d_acc(w)
        w1 = 0.5 * a * (-a * inv_j + np.sqrt((a * inv_j) ** 2 + 4 * d / a))   # w ≥ a²/j case
        w2 = np.where(inv_j > 0, (d / (2.0 * np.sqrt(inv_j))) ** (2.0 / 3.0), np.inf)  # w < a²/j
        w = np.where(w1 >= a * a * inv_j, w1, w2)
        t_w, _ = acc_phase(w)
        T = np.where(cruise, T_cruise, 2 * t_w)
    return np.where(d == 0, 0.0, T)


def from_rest_distance(t, v, a, j=np.inf):
    """Largest distance [rad | m] a joint can cover from rest (q̇ = q̈ = 0) in time t ≥ 0 under
    |q̇| ≤ v, |q̈| ≤ a, |q⃛| ≤ j: full effort (jerk up to a, hold a, cruise at v). Vectorised."""
    t, v, a, j = np.broadcast_arrays(*(np.asarray(x, float) for x in (t, v, a, j)))
    fin = np.isfinite(j)
    inv_j = np.where(fin, 1.0 / np.where(fin, j, 1.0), 0.0)
    jf = np.where(fin, j, 0.0)
    t1 = a * inv_j                                   # end of the jerk phase
    short = v <= 0.5 * a * t1                        # v reached before full acceleration
    with np.errstate(divide="ignore", invalid="ignore"):
        t_v = np.where(short, np.sqrt(2.0 * v / np.where(fin, j, 1.0)), v / a + 0.5 * t1)

    def effort(s):   # distance at full effort (no speed cap) after time s
        return np.where(s <= t1, jf * s ** 3 / 6.0,
                        a * t1 ** 2 / 6.0 + 0.5 * a * (s * s - t1 * t1) - 0.5 * a * t1 * (s - t1))
    return effort(np.minimum(t, t_v)) + v * np.maximum(t - t_v, 0.0)
