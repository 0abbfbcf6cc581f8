"""Resampling of logged arrays onto a uniform grid: the readings interpolated linearly, the
valve commands held (a change of rate) or taken from the nearest sample (timestamp jitter)."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["resample_arrays"]


def resample_arrays(t, arrays, rate: float, commands: str = "hold"):
    """(t_new, arrays on it): a uniform grid from t[0] at ``rate`` [Hz] up to t[-1] (within
    1e-9 of a step); ``arrays`` (u, q, p_a, p_b) — the readings interpolated linearly, the
    commands u ``"hold"`` (the command in effect at each new time: a change of rate) or
    ``"nearest"`` (the sample nearest in time: timestamp jitter, where the command logged
    with a sample belongs to that sample's controller tick); None stays None."""
    t = np.asarray(t, float)
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate = {rate!r} Hz; allowed: a positive number of Hz")
    h = 1.0 / rate
    m = int(math.floor((t[-1] - t[0]) / h + 1e-9)) + 1
    if m < 2:
        raise ValueError(f"rate = {rate:g} Hz gives fewer than 2 samples over "
                         f"{t[-1] - t[0]:g} s")
    tn = t[0] + np.arange(m) * h
    k = np.clip(np.searchsorted(t, tn + 1e-9 * h, side="right") - 1, 0, len(t) - 1)
    if commands == "nearest":
        k = np.clip(np.searchsorted(t, tn), 1, len(t) - 1)
        k = np.where(np.abs(t[k - 1] - tn) <= np.abs(t[k] - tn), k - 1, k)
    elif commands != "hold":
        raise ValueError(f"commands = {commands!r}; allowed: 'hold', 'nearest'")
    out = []
    for i, Y in enumerate(arrays):
        if Y is None:
            out.append(None)
        elif i == 0:
            out.append(np.asarray(Y, float)[k])
        else:
            Y = np.asarray(Y, float)
            out.append(np.column_stack([np.interp(tn, t, Y[:, c]) for c in range(Y.shape[1])]))
    return tn, tuple(out)
