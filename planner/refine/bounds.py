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
           "closed_valves", "command_bounds", "for_objective", "start_openings"]

#: the start of a command that is exactly 0 (a closed valve is a kink of the flow whose
#: adjoint slope is 0: see :func:`planner.refine.refine_commands`)
DITHER = 1e-6
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




def start_openings(start, t0: float, Ku: int, db, lo, hi, rate: float) -> np.ndarray:
    """(Ku, n): the openings to start a refinement from, given commands ``start`` = (t_s,
    u_s) held on the ``rate`` grid from the plan's start ``t0`` (an earlier refinement: it may
    end before or after the Ku rows — rows past them dropped, missing ones closed); as
    openings past the dead bands ``db`` (:func:`~planner.model.valves.within_deadband`),
    inside the bounds (``lo``, ``hi``), a closed free one cracked by the dither (module doc of
    :mod:`planner.refine`). ValueError for commands off that grid or of another width."""
    from planner.model.valves import within_deadband
    t_s = np.asarray(start[0], float).ravel()
    u_s = np.atleast_2d(np.asarray(start[1], float))
    n = lo.shape[1]
    dt = 1.0 / rate
    if u_s.shape != (t_s.size, n) or t_s.size < 1 or abs(t_s[0] - t0) > 1e-9 or (
            t_s.size > 1 and np.max(np.abs(np.diff(t_s) - dt)) > 1e-6):
        raise ValueError(f"refine: start commands of shape {u_s.shape} from t = "
                         f"{t_s[0] if t_s.size else float('nan'):g} s; expected ({t_s.size}, "
                         f"{n}) on the {rate:g} Hz grid from the plan's start t = {t0:g} s")
    U = np.zeros((Ku, n))
    m = min(Ku, t_s.size)
    U[:m] = within_deadband(np.clip(u_s[:m], -1.0, 1.0), db)
    U = np.clip(U, lo, hi)
    shut = (lo == 0.0) & (hi == 0.0)
    crack = (U == 0.0) & ~shut
    U[crack] = np.where(hi > 0.0, DITHER, -DITHER)[crack]
    return U
