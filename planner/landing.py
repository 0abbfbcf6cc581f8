"""How a run lands against its plan: the tip measures the refinement's cost and its reports
use (:mod:`planner.refine`), and that ``simulate --settle`` reports for a plant's replay.

* :func:`tip_levers` — each joint's lever at the tip, |∂tip/∂q_j| (m per rad | m);
* :func:`landing_measures` — the largest tip error during the move, the rest offset from the
  goal, the residual oscillation after the plan's end, the final error.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["landing_measures", "tip_levers"]


def tip_levers(crane: Crane, q) -> np.ndarray:
    """|∂tip/∂q_j| at ``q`` (n,) or at each row of ``q`` (K, n) [m per rad | m] (central
    differences of the forward kinematics); the shape of ``q``."""
    n, eps = crane.n, 1e-6
    q = np.asarray(q, float)
    Qs = np.atleast_2d(q)
    Q = np.repeat(Qs[:, None, :], 2 * n, axis=1)       # (K, 2n, n)
    for j in range(n):
        Q[:, 2 * j, j] += eps
        Q[:, 2 * j + 1, j] -= eps
    tip = crane.fk(Q.reshape(-1, n)).reshape(Qs.shape[0], 2 * n, -1)
    L = np.linalg.norm(tip[:, 0::2] - tip[:, 1::2], axis=2) / (2 * eps)
    return L.reshape(q.shape)


def landing_measures(crane: Crane, t, q, traj: Trajectory, rest_window: float = 1.0) -> dict:
    """How a run lands (the twin's prediction here, a plant's replay in ``simulate
    --settle``): tip measures of the run (joints ``q`` (K, n) at ``t`` (K,)) against the plan ``traj``:
    ``track_m`` the largest tip error during the move, ``rest_offset_m`` the distance from the
    goal of the rest point (mean tip over the last ``rest_window`` s),
    ``residual_oscillation_m`` the largest distance from the rest point after the plan's end,
    ``final_m`` the tip error at the end of the record."""
    t = np.asarray(t, float)
    tip = crane.fk(np.asarray(q, float))
    ref = crane.fk(traj.sample(np.clip(t, traj.t[0], traj.t[-1]))[0])
    goal = crane.fk(traj.q[-1:])[0]
    t_end = traj.t[-1]
    err = np.linalg.norm(tip - ref, axis=1)
    rest = tip[t >= t[-1] - rest_window].mean(axis=0)
    after = t >= t_end - 1e-9
    return dict(track_m=float(err[t <= t_end + 1e-9].max()),
                rest_offset_m=float(np.linalg.norm(rest - goal)),
                residual_oscillation_m=float(np.linalg.norm(tip[after] - rest, axis=1).max())
                if after.any() else float("nan"),
                final_m=float(err[-1]))
