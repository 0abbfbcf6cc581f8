"""The solver of :func:`planner.refine.refine_commands`: L-BFGS-B over the valve openings,
restarted with a fresh memory where it stops early.

Why restarts: the twin's cost is smooth almost everywhere, but not everywhere — a check valve
that opens, a chamber that cavitates and is refilled, a spool crossing its dead band, a step
whose Newton iteration takes another path — and L-BFGS-B's curvature pairs, learnt on one side
of such a kink, can point its line search nowhere on the other: it ends ``ABNORMAL`` (the
line search failed) or with one step's relative reduction below its tolerance, tens of
iterations into its budget. On the s100f part-0 misses of ``refine_s100f-400-p0.md`` it ended
so after 6–80 of 150 iterations with the twin itself predicting 5–125 mm of ringing. A restart
from the best point, its memory cleared, starts again along −g and learns the curvature
there; restarts go on while the budget lasts and each one gains at least ``MIN_GAIN`` of the
cost."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Solved", "minimize_commands", "STEP", "FTOL", "MEMORY", "MIN_GAIN"]

#: the optimiser's first step, in valve-command units (see :func:`minimize_commands`)
STEP = 0.05
#: L-BFGS-B stops when one iteration lowers the cost by less than this fraction: scipy's default
#: (2.2e-9) ended slow energy entries after 18-121 iterations with the twin itself predicting
#: 5-76 mm of ringing (bench_refine's 20 energy entries: 13 -> 14 land on Exudyn with this one)
FTOL = 1e-12
#: L-BFGS-B's memory (scipy's default 10): the twin's lightly damped hydraulic modes make the
#: cost ill-conditioned, and a longer memory of curvature pairs costs nothing beside a twin run
#: (an s100f entry, 150 iterations: cost 311 -> 198 mm²·s, the largest tip error 23 -> 18 mm)
MEMORY = 50
#: a restart is worth another only when it lowered the cost by at least this fraction
MIN_GAIN = 1e-3


@dataclass
class Solved:
    """Where the solver ended: the openings ``x`` (flat), the cost ``fun`` there, the
    iterations ``nit`` over all runs, L-BFGS-B's last ``message`` and the ``restarts``."""
    x: np.ndarray
    fun: float
    nit: int
    message: str
    restarts: int = 0


def _early(message: str) -> bool:
    """L-BFGS-B stopped before its budget for a reason a fresh memory may cure."""
    return message.startswith("ABNORMAL") or message.startswith("CONVERGENCE: REL")


def minimize_commands(cost, z0, iterations: int, shut=None, restarts: bool = True,
                      bounds=None) -> Solved:
    """L-BFGS-B on ``cost`` (z -> (J, dJ/dz)) from the openings ``z0`` (flat), |z| ≤ 1 (0
    where ``shut``; within ``bounds`` = (lo, hi), flat, where given), at most ``iterations`` iterations and twice as many cost evaluations over
    all runs; with ``restarts`` a run that stops early (module doc) is followed by another from
    its best point with a fresh memory, while the budget lasts and the last run gained at least
    ``MIN_GAIN``. The unknowns are scaled: L-BFGS-B's first step is a unit step along −g, which
    in command units can swing a valve across its range (the twin then leaves its range);
    ``STEP`` is the size of that first step in commands, later steps follow the curvature it
    learns."""
    from scipy.optimize import minimize
    s = STEP
    calls = [0]

    def f(z):
        calls[0] += 1
        J, g = cost(z * s)
        return J, g * s

    lo, hi = (np.full(len(z0), -1.0), np.full(len(z0), 1.0)) if bounds is None else \
        (np.asarray(bounds[0], float).ravel(), np.asarray(bounds[1], float).ravel())
    if shut is not None:
        lo, hi = np.where(shut, 0.0, lo), np.where(shut, 0.0, hi)
    bounds = list(zip(lo / s, hi / s))
    z = np.asarray(z0, float) / s
    best, nit, runs, message = None, 0, 0, ""
    while nit < iterations and calls[0] < 2 * iterations:
        left_it, left_fun = int(iterations) - nit, 2 * int(iterations) - calls[0]
        res = minimize(f, z, jac=True, method="L-BFGS-B", bounds=bounds,
                       options=dict(maxiter=left_it, maxfun=left_fun, ftol=FTOL,
                                    maxcor=MEMORY))
        nit += max(int(res.nit), 1)
        runs += 1
        message = str(res.message)
        gain = (best.fun - float(res.fun)) / max(abs(best.fun), 1e-300) if best else np.inf
        if best is None or res.fun < best.fun:
            best = res
        if not (restarts and _early(message) and gain >= MIN_GAIN):
            break
        z = best.x
    return Solved(best.x * s, float(best.fun), nit, message, runs - 1)
