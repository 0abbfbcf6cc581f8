"""The end stops of a stroke: the one code path through which every replay of this package
(the recording plant, the replay a diagnosis fits) takes a cylinder to its stroke end.

A cylinder commanded beyond its end stays at the end, and comes off it as soon as the command
turns back: with ``dx`` the stroke change each step would make on its own (what the valves
meter, plus any pressure-driven drift) and ``x_start`` the start stroke, the stroke is the
sequential clip

    x[0] = clip(x_start, lo, hi),    x[k+1] = clip(x[k] + dx[k], lo, hi),

the discrete two-sided reflection (Skorokhod map) of the free path. After the first contact
the stroke no longer depends on where it started: the stop has absorbed the difference. So a
model whose start is off by δ reaches the end at a different time and leaves it δ away from
where a shifted-but-unclipped path would be — differencing a clipped run and re-anchoring it
at another start (what the diagnosis did before) invents a step at the stroke end that the
machine never made. Every start, fitted or not, goes through :func:`run_to_stops`.

Computed without a per-step loop: between two contacts with opposite ends the clip acts on
one side only, where it is the Lindley recursion x = y + max(0, max_{i≤k}(lo − y_i)) of the
free path y (the mirror image at the upper end); a column changes side a handful of times.
"""
from __future__ import annotations

import numpy as np

__all__ = ["run_to_stops", "StopPath", "StopRun"]

_TOL = 1e-12     # [m] a free path within this of an end is not clipped (round-off)


class StopRun:
    """Strokes at the end stops: ``x`` (K+1, n); ``at_stop`` (K+1, n) True where the step into
    that sample was clipped (the cylinder was pushed against its end); ``free`` (K+1, n) True
    until the first contact with an end (there x moves one for one with the start stroke;
    after it, not at all: the sensitivity ∂x/∂x_start)."""

    __slots__ = ("x", "at_stop", "free")

    def __init__(self, x, at_stop, free):
        self.x, self.at_stop, self.free = x, at_stop, free


def _reflect(y, bound, lower):
    """One-sided reflection of the free path ``y`` (m,) at ``bound`` (lower or upper end):
    (path, pushed): the path exactly on the bound where it is held there."""
    gap = (bound - y) if lower else (y - bound)
    push = np.maximum.accumulate(np.maximum(gap, 0.0))
    x = np.where(push == gap, bound, (y + push) if lower else (y - push))
    pushed = np.empty(len(y), bool)
    pushed[0] = push[0] > 0
    pushed[1:] = push[1:] > push[:-1]
    return x, pushed


def _column(x0, dx, lo, hi):
    K = len(dx)
    D = np.concatenate([[0.0], np.cumsum(dx)])
    x = np.empty(K + 1)
    at = np.zeros(K + 1, bool)
    k, xk = 0, x0
    while True:
        y = xk + (D[k:] - D[k])
        below = y < lo - _TOL
        above = y > hi + _TOL
        if not (below.any() or above.any()):
            x[k:] = y
            x[k] = xk
            break
        i_lo = int(np.argmax(below)) if below.any() else K + 1
        i_hi = int(np.argmax(above)) if above.any() else K + 1
        lower = i_lo < i_hi
        z, pushed = _reflect(y, lo if lower else hi, lower)
        z[0] = xk
        # valid until the reflected path crosses the other end
        cross = (z > hi + _TOL) if lower else (z < lo - _TOL)
        m = int(np.argmax(cross)) if cross.any() else len(z)
        x[k:k + m] = z[:m]
        at[k + 1:k + m] = pushed[1:m]     # at[k]: set where the stage began
        if m == len(z):
            break
        k += m
        xk = hi if lower else lo
        x[k], at[k] = xk, True
    return x, at


class StopPath:
    """The free stroke changes ``dx`` (K, n) per step and the end stops ``lo``, ``hi`` (n,),
    prepared for runs from many starts (a fit of the start): :meth:`run` (x_start) ->
    :class:`StopRun`. A column whose free path stays inside the stops from that start is the
    free path itself; the others are clipped (:func:`run_to_stops`)."""

    def __init__(self, dx, lo, hi):
        self.dx = np.atleast_2d(np.asarray(dx, float))
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)
        K, n = self.dx.shape
        self.D = np.vstack([np.zeros((1, n)), np.cumsum(self.dx, axis=0)])
        self.d_min, self.d_max = self.D.min(axis=0), self.D.max(axis=0)

    def run(self, x_start) -> StopRun:
        lo, hi = self.lo, self.hi
        x_start = np.clip(np.asarray(x_start, float), lo, hi)
        x = x_start[None, :] + self.D
        at = np.zeros(x.shape, bool)
        free = np.ones(x.shape, bool)
        out = np.flatnonzero((x_start + self.d_min < lo - _TOL) |
                             (x_start + self.d_max > hi + _TOL))
        for i in out:
            x[:, i], at[:, i] = _column(x_start[i], self.dx[:, i], lo[i], hi[i])
            free[int(np.argmax(at[:, i])):, i] = False
        return StopRun(x, at, free)


def run_to_stops(x_start, dx, lo, hi) -> StopRun:
    """Strokes (K+1, n) from the start strokes ``x_start`` (n,) (clipped into [lo, hi] first)
    and the free stroke changes ``dx`` (K, n) per step, held at the end stops ``lo``, ``hi``
    (n,) — the sequential clip of the module doc, exactly."""
    return StopPath(dx, lo, hi).run(x_start)
