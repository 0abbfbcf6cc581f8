"""A log cut for a fit (:mod:`planner.calibration.twin_fit`): segments at its holds, each
started from the state measured over the hold's last samples, and the first stage's windows of
about a second inside each segment (that module's doc says why both).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Segment", "segments", "windows"]


@dataclass
class Segment:
    """Samples ``k0 … k1`` (inclusive) of recording ``rec`` simulated from the state measured
    at ``k0`` (``q0``, pressures ``p_a0``, ``p_b0`` or None, their spreads ``sd_a``,
    ``sd_b`` over the anchor window)."""
    rec: int
    k0: int
    k1: int
    q0: np.ndarray
    p_a0: np.ndarray | None
    p_b0: np.ndarray | None
    sd_a: np.ndarray | None = None     # spread of the pressures over the anchor window
    sd_b: np.ndarray | None = None
    window: bool = False               # a window of the first stage (module doc)


def segments(rec: Recording, index: int = 0, hold: float = 0.5,
             anchor: float = 0.2) -> list[Segment]:
    """The segments of ``rec`` (module doc): cut at the last sample of every hold of at least
    ``hold`` s, the start state averaged over the hold's last ``anchor`` s."""
    t, u = rec.t, rec.u
    still = np.all(np.abs(u) < 1e-9, axis=1)
    cuts = []
    k, N = 0, len(t)
    while k < N:
        if still[k]:
            e = k
            while e + 1 < N and still[e + 1]:
                e += 1
            if t[e] - t[k] >= hold - 1e-9 or k == 0:
                cuts.append((k, e))
            k = e + 1
        else:
            k += 1
    if not cuts or cuts[0][0] != 0:
        cuts.insert(0, (0, 0))
    out = []
    for i, (s, e) in enumerate(cuts):
        k1 = cuts[i + 1][1] if i + 1 < len(cuts) else N - 1
        if k1 <= e:
            continue
        a = max(s, int(np.searchsorted(t, t[e] - anchor)))
        q0 = rec.q[a:e + 1].mean(axis=0)
        pa = pb = sa = sb = None
        if rec.p_a is not None:
            pa, sa = rec.p_a[a:e + 1].mean(axis=0), rec.p_a[a:e + 1].std(axis=0)
            pb, sb = rec.p_b[a:e + 1].mean(axis=0), rec.p_b[a:e + 1].std(axis=0)
        out.append(Segment(index, e, k1, q0, pa, pb, sa, sb))
    return out


def windows(recs, segs: list[Segment], length: float) -> list[Segment]:
    """``segs`` cut into windows of about ``length`` s (module doc); a segment's first window
    keeps its start, a last piece shorter than a fifth of ``length`` joins the window before."""
    out = []
    for s in segs:
        t = recs[s.rec].t
        k, first = s.k0, True
        while k < s.k1:
            e = min(int(np.searchsorted(t, t[k] + length - 1e-9)), s.k1)
            if t[s.k1] - t[e] < 0.2 * length:
                e = s.k1
            e = max(e, k + 1)
            out.append(s if first and e == s.k1 else
                       Segment(s.rec, k, e, s.q0, s.p_a0, s.p_b0, s.sd_a, s.sd_b)
                       if first else Segment(s.rec, k, e, recs[s.rec].q[k], None, None,
                                             window=True))
            k, first = e, False
    return out
