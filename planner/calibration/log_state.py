"""A log's state at one of its samples, from the samples around it: positions, velocities and
chamber pressures, as a fit's window starts from them (:mod:`planner.calibration.twin_fit`).

A Savitzky–Golay fit: a parabola in time least-squares fitted to the ``samples`` samples
centred on the one asked for (shifted inward at the log's ends), its value there and, for the
positions, its slope. At 50 Hz and 9 samples it averages the sensor noise over 0.16 s (the
value's noise × 0.6, the slope's about σ / 0.14 s) and follows a pressure step within a few
samples.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["log_state", "on_stroke_end", "agrees_over_window", "END_BAND"]


def log_state(rec, k: int, samples: int = 9) -> dict:
    """``q``, ``qd`` (n,) and, where logged, ``p_a``, ``p_b`` (n,) of recording ``rec`` at
    sample ``k`` (module doc)."""
    N = len(rec.t)
    if not 0 <= k < N:
        raise ValueError(f"sample: {k}; allowed: 0 .. {N - 1} (the log's samples)")
    w = max(min(int(samples), N if N % 2 else N - 1), 1)
    a = int(np.clip(k - w // 2, 0, max(N - w, 0)))
    tt = rec.t[a:a + w] - rec.t[k]
    P = np.linalg.pinv(np.vander(tt, min(3, w)))   # columns t², t, 1 (fewer on a short log)
    out = {}
    for name in ("q", "p_a", "p_b"):
        Y = getattr(rec, name)
        if Y is None:
            continue
        c = P @ np.asarray(Y[a:a + w], float)
        out[name] = c[-1]
        if name == "q":
            out["qd"] = c[-2] if len(c) > 1 else np.zeros_like(c[-1])
    return out


#: [m] a cylinder whose twin state lies within this of a stroke end (or past it) rests on it
END_BAND = 1e-3


def on_stroke_end(crane: Crane, q_log, q_twin, sig_q) -> np.ndarray:
    """(n,) bool: the joints whose cylinder rests on a stroke end at a segment's start — the
    twin's own state there within :data:`END_BAND` of the end or past it, and the log's
    anchor position within 3 of its noise (``sig_q``, in stroke units by dx/dq) of it. On its
    stop a cylinder's position is set by the stop's stiffness, not by the anchor: an anchor a
    noise σ off puts the twin's stop a few kN off its load or the joint a fall off its stop
    (an s100f boom lowered onto its stroke end with 839 kg aboard: 1.33 σ RMS left on its
    pressure by the fitted truth; twin_fit's start takes the twin's own state there)."""
    from planner.model.actuators import stroke_range
    ends = np.array([stroke_range(j.actuator) for j in crane.spec.joints], float)
    x_l, d = crane.stroke(np.atleast_2d(np.asarray(q_log, float)))
    x_t, _ = crane.stroke(np.atleast_2d(np.asarray(q_twin, float)))
    x_l, d, x_t = x_l[0], d[0], x_t[0]
    tol = 3.0 * np.asarray(sig_q, float) * np.abs(d)
    with np.errstate(invalid="ignore"):
        log_end = (x_l <= ends[:, 0] + tol) | (x_l >= ends[:, 1] - tol)
        twin_end = (x_t <= ends[:, 0] + END_BAND) | (x_t >= ends[:, 1] - END_BAND)
    return log_end & twin_end


def agrees_over_window(rec, k0: int, run, sig_p, vented, window: float = 0.2) -> np.ndarray:
    """Per joint: a twin run carried up to sample ``k0`` of ``rec`` and the log agree on the
    chamber pressures over the ``window`` [s] before it — the mean of log − twin over the
    window's samples within 3 σ/√m on both chambers (``sig_p``: the noise of the p_a then the
    p_b channels; a ``vented`` rod side always agrees): the same ringing, sample by sample,
    where the window's *average* differs from either at the cut
    (:meth:`planner.calibration.twin_fit.TwinFit.start_state`)."""
    n = len(vented)
    ts = rec.t[max(int(np.searchsorted(rec.t, rec.t[k0] - window)), 0):k0 + 1]
    ts = ts[ts >= run.t[0] - 1e-9]
    if ts.size == 0:
        return np.zeros(n, bool)
    _, pa, pb, _ = run.sample(ts)
    k = int(np.searchsorted(rec.t, ts[0] - 1e-9))
    da = np.mean(rec.p_a[k:k + ts.size] - pa, axis=0)
    db = np.mean(rec.p_b[k:k + ts.size] - pb, axis=0)
    e = 3.0 * np.asarray(sig_p, float) / np.sqrt(ts.size)
    return (np.abs(da) <= e[:n]) & ((np.abs(db) <= e[n:]) | np.asarray(vented, bool))
