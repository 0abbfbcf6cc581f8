"""A log's state at one of its samples, from the samples around it: positions, velocities and
chamber pressures, as a fit's window starts from them (:mod:`planner.calibration.twin_fit`).

A Savitzky–Golay fit: a parabola in time least-squares fitted to the ``samples`` samples
centred on the one asked for (shifted inward at the log's ends), its value there and, for the
positions, its slope. At 50 Hz and 9 samples it averages the sensor noise over 0.16 s (the
value's noise × 0.6, the slope's about σ / 0.14 s) and follows a pressure step within a few
samples.
"""
from __future__ import annotations

import numpy as np

__all__ = ["log_state"]


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
