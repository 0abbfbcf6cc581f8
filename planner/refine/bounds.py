"""Which openings the refinement may use (:func:`command_bounds`) and the options each kind of
move is refined with (:func:`for_objective`); the module doc of :mod:`planner.refine` says why
(``keep_closed``, ``keep_direction``, energy entries).

**Time entries** (``time_entries`` "priced", the default): a move planned for least time is
refined with its pump work in the cost too, weighed ``energy_weight`` or
:data:`TIME_ENTRY_WEIGHT` (10 mm²·s per kJ, a third of an energy entry's), its directions free.
Refined for tracking alone, time entries paid for their landing: on the 400-entry s100f run
their refined commands used 2.5 × their nominal pump work in the median of the 16 moves
checked (8 of the costliest, 8 drawn), d03-p16 174 kJ against 55 — short corrections signal
a holding pressure to the load-sensing pump, which every other flow then pays. Priced, the
same 16 used 1844 kJ instead of 2389 (−23 %; the costliest 8: −38 %), all 16 landing on
Exudyn as before (the spec's parameters), the tip error during the move a median 14 mm
instead of 10 (``benchmarks/results/refine_s100f-t16-p10f.md``; with the directions kept as
well 1850 kJ: no better, so not). ``"plain"``: tracking and landing only, as before.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

__all__ = ["ENERGY_ENTRIES", "ENERGY_ENTRY_WEIGHT", "TIME_ENTRIES", "TIME_ENTRY_WEIGHT",
           "closed_valves", "command_bounds", "for_objective"]

#: how a move planned for least energy is refined (:func:`for_objective`): "priced" (its pump
#: work in the cost, its joints kept to their directions) or "plain" (as a time move)
ENERGY_ENTRIES = ("priced", "plain")
#: [mm²·s per kJ] the pump work's weight for an energy move refined "priced" (module doc)
ENERGY_ENTRY_WEIGHT = 30.0
#: how a move planned for least time is refined: "priced" (its pump work in the cost) or "plain"
TIME_ENTRIES = ("priced", "plain")
#: [mm²·s per kJ] the pump work's weight for a time entry refined "priced" (module doc)
TIME_ENTRY_WEIGHT = 10.0


def closed_valves(u, Ku: int, opts) -> np.ndarray:
    """(Ku, n) True where a command must stay 0 (module doc, ``keep_closed``): the joints
    whose nominal commands ``u`` (M, n) are all at most ``idle``, up to ``lead`` s before
    the tail (rows M and on, free)."""
    u = np.atleast_2d(np.asarray(u, float))
    shut = np.zeros((Ku, u.shape[1]), bool)
    held = np.all(np.abs(u) <= opts.idle, axis=0)
    shut[:max(u.shape[0] - int(round(opts.lead * opts.rate)), 0), held] = True
    return shut


def for_objective(opts, objective: str | None):
    """The :class:`~planner.refine.RefineOptions` a move planned for ``objective`` ("time",
    "energy", …) is refined with:
    ``opts`` itself, but for a time move while ``time_entries`` is "priced" — the pump work
    weighed ``energy_weight`` or :data:`TIME_ENTRY_WEIGHT` (module doc) — and for an energy
    move while ``energy_entries`` is "priced" —
    ``keep_direction`` on and the pump work weighed ``energy_weight`` (or
    :data:`ENERGY_ENTRY_WEIGHT` where it is 0) (module doc)."""
    if objective == "time" and opts.time_entries == "priced":
        return replace(opts, energy_weight=opts.energy_weight or TIME_ENTRY_WEIGHT)
    if objective != "energy" or opts.energy_entries != "priced":
        return opts
    return replace(opts, keep_direction=True,
                   energy_weight=opts.energy_weight or ENERGY_ENTRY_WEIGHT)


def command_bounds(u, Ku: int, opts) -> tuple:
    """(lo, hi), each (Ku, n): the range of each refined opening (module doc): [−1, 1]; 0
    where ``keep_closed`` shuts a held joint's valve (:func:`closed_valves`); with
    ``keep_direction``, up to ``lead`` s before the tail, a row whose nominal command ``u``
    (M, n) opens past ``idle`` keeps its sign (or closes), and a joint the plan moves one way
    only keeps that way in its idle rows too."""
    u = np.atleast_2d(np.asarray(u, float))
    n = u.shape[1]
    lo, hi = np.full((Ku, n), -1.0), np.full((Ku, n), 1.0)
    end = max(u.shape[0] - int(round(opts.lead * opts.rate)), 0)
    if opts.keep_direction:
        pos, neg = u[:end] > opts.idle, u[:end] < -opts.idle
        one_way_up = pos.any(axis=0) & ~neg.any(axis=0)
        one_way_down = neg.any(axis=0) & ~pos.any(axis=0)
        back = -opts.idle_reverse
        lo[:end][one_way_up[None, :] & ~pos] = back
        hi[:end][one_way_down[None, :] & ~neg] = -back
        lo[:end][pos] = 0.0
        hi[:end][neg] = 0.0
    if opts.keep_closed:
        shut = closed_valves(u, Ku, opts)
        lo[shut], hi[shut] = 0.0, 0.0
    return lo, hi


