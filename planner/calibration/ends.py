"""Where the model makes no claim: the samples near a stroke end.

The diagnosis fits the start pose to the noisy positions; the fitted start is off by a little
(σ/√N of the samples before the first contact). Away from the ends that shifts the prediction
by as little; near an end it does not: a cylinder arriving slowly at its end stop reaches it
earlier or later by δ/v, and while one of the model and the machine is held at the stop and the
other still decelerates, the pressures differ by the whole decelerating force. That residual is
the model's own (where the start lies within its uncertainty), not the machine's, and it must
not be fitted, scored or reported as a signature. So the rows where the nominal model's stroke
lies within ``k`` position-noise σ of an end stop (and ``pad`` samples on either side: the
differences span them) are left out of the fit, the held-out scores and the verdict.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.simulation.plant import stroke_map

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["near_stroke_end"]


def near_stroke_end(crane: Crane, q, sigma_q, k: float = 3.0, pad: int = 2) -> np.ndarray:
    """(N,) rows where some joint of ``q`` (N, n) lies within ``k``·``sigma_q`` (n,) [rad | m]
    of the stroke at one of its limits (the end stops), widened by ``pad`` samples."""
    sm = stroke_map(crane)
    lo, hi = sm.stops
    q = np.atleast_2d(q)
    x = sm.x(q)
    margin = k * np.asarray(sigma_q, float) * np.abs(sm.dxdq(q))
    near = np.any((x - lo <= margin) | (hi - x <= margin), axis=1)
    if near.any() and pad > 0:
        idx = np.flatnonzero(near)
        near = np.zeros(len(q), bool)
        for s in range(-pad, pad + 1):
            near[np.clip(idx + s, 0, len(q) - 1)] = True
    return near
