"""The load-sensing activity mask of the energy/blend move NLP and when a round of it ends.

A load-sensing pump raises its pressure only for the functions that draw flow; which ones do at
each node is a parameter of the NLP (the mask), taken from the guess and grown from each
solution, re-solving while it grows (≤ 4 rounds, :meth:`MoveNLP._solve_from
<planner.methods.nlp.move.MoveNLP>`). A grown mask needs no new round when the solution already
meets the pressure rows it switches on.

The mask's order: per node, first every actuator extending (piston side), then every
double-acting one retracting (annulus side): :func:`mask_size` entries in all.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Activity", "mask_size"]


def mask_size(n: int, acts, N: int) -> int:
    """Entries of the activity mask of an NLP with ``N`` intervals on ``n`` joints with the
    actuators ``acts`` (:func:`~planner.model.flows.actuator_table`): per node one per joint
    and one more per double-acting actuator."""
    return (N + 1) * (n + int((~acts.single).sum()))


class Activity:
    """The activity mask of one built move NLP: its ``crane``, its variable ``layout``
    (:class:`~planner.methods.nlp.transcription.Layout`: the node states "X" and the
    "pressure" rows) and its actuator table ``acts``."""

    def __init__(self, crane: Crane, layout, acts):
        self.crane, self.layout = crane, layout
        self.Aa, self.Ab, self.dbl = acts.area_a, acts.area_b, ~acts.single

    def mask(self, w) -> np.ndarray:
        """Which functions draw pump flow at each node (per direction) in the primal ``w``:
        the load-sensing activity mask (threshold as in the evaluator: the crane's pricing,
        :mod:`planner.model.pricing` — 1e-4 of Q_max (seed), the valve's opening (machine))."""
        crane, n = self.crane, self.crane.n
        X = self.layout.unpack(w, "X")
        _, dxdq = crane.stroke(X[:n].T)
        xd = dxdq * X[n:2 * n].T
        eps = crane.prices.active
        pos = (self.Aa * xd > eps).astype(float)
        neg = (-self.Ab[self.dbl] * xd[:, self.dbl] > eps[self.dbl]).astype(float)
        return np.hstack([pos, neg]).ravel()

    def still_optimal(self, sol, mask, new) -> bool:
        """True when the solution ``sol`` (solved with activity ``mask``) already meets the
        load-sensing pressure rows of the functions ``new`` switches on: those rows were
        relaxed by the big M, so without it their value is theirs minus 1e3 [MPa]; if each is
        ≥ 0 the point is feasible for the new mask and its KKT conditions hold with zero
        multipliers there — a re-solve would return it (up to the tolerance)."""
        if "pressure" not in self.layout.con_names:   # no load-sensing rows: nothing changes
            return True
        rows = self.layout.rows("pressure")            # one per mask entry, in its order
        on = np.flatnonzero((new > 0) & (mask == 0))
        g = np.asarray(sol["g"]).ravel()[rows[on]] - 1e3
        return bool(np.all(g >= -1e-6))
