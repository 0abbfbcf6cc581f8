"""Where a residual lives: channels, time windows and operating conditions (direction of
motion, speed, load, pump saturation) — for the report (:func:`locate`) and for telling
ambiguous candidates apart (:func:`operating_conditions`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import math

import numpy as np

from planner.simulation.replay import stroke_rates

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["operating_conditions", "locate"]


def operating_conditions(crane: Crane, u, state) -> dict:
    """joint -> condition -> row mask (N,): extending / retracting / still, slow / fast (of
    the moving samples, below or above half the peak stroke rate), high / low load (actuator
    force above or below its median), pump saturated or not (the replay's sharing factor).
    ``u``: commands (N, n) at the samples, ``state``: the nominal plant's
    :class:`planner.simulation.plant.PlantState`."""
    share = stroke_rates(crane, u)[2]
    out = {}
    for i, j in enumerate(crane.names):
        xd = state.xd[:, i]
        vmax = max(np.abs(xd).max(), 1e-12)
        moving = np.abs(xd) > 0.02 * vmax
        F = np.abs(state.force[:, i])
        out[j] = {
            "extending": xd > 0.02 * vmax, "retracting": xd < -0.02 * vmax, "still": ~moving,
            "slow": moving & (np.abs(xd) < 0.5 * vmax), "fast": moving & (np.abs(xd) >= 0.5 * vmax),
            "high_load": F >= np.median(F), "low_load": F < np.median(F),
            "pump_saturated": share < 1.0, "pump_not_saturated": share >= 1.0}
    return out


def locate(crane: Crane, t, R, columns, conditions, has_pressures: bool,
           window_s: float = 2.0) -> dict:
    """Where the nominal residual ``R`` (N, C) in noise units lives: channels (RMS / σ), time
    windows with an excess above 2 (RMS/σ over the window, worst channel), and per joint the
    residual excess split by operating condition (``conditions``: :func:`operating_conditions`)
    — ratios of mean squared normalised residual to 1 (noise)."""
    ms = np.mean(R * R, axis=0)
    channels = sorted(({"channel": c, "rms_over_noise": float(math.sqrt(m))}
                       for c, m in zip(columns, ms)), key=lambda x: -x["rms_over_noise"])
    dt = float(np.median(np.diff(t)))
    w = max(2, int(round(window_s / dt)))
    windows = []
    for a in range(0, len(t) - w + 1, w):
        m = np.sqrt(np.mean(R[a:a + w] ** 2, axis=0))
        k = int(np.argmax(m))
        if m[k] > 2.0:
            windows.append(dict(t0=float(t[a]), t1=float(t[a + w - 1]), channel=columns[k],
                                rms_over_noise=float(m[k])))
    n = crane.n
    split_ms = {}
    for i, j in enumerate(crane.names):
        idx = [i] + ([n + 2 * i, n + 2 * i + 1] if has_pressures else [])
        e2 = np.mean(R[:, idx] ** 2, axis=1)
        split_ms[j] = {k: (float(np.mean(e2[m])) if m.sum() >= 10 else None)
                       for k, m in conditions[j].items()}
    return dict(channels=channels, windows=windows[:20], n_windows=len(windows),
                conditions=split_ms)
