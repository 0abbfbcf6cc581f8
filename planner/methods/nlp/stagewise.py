"""The move NLP solved by FATROP (ships with CasADi): a structure-exploiting interior-point
solver for optimal control problems, its linear algebra a Riccati recursion over the stages
instead of a sparse factorisation of the whole KKT system.

FATROP needs the problem ordered stage by stage (per stage its states, its controls; the
dynamics that close the gap to the next stage, the stage's path constraints) with every row
inside one stage. :meth:`~planner.methods.nlp.transcription.Layout.stage_order` gives that order
from the stage tags of the move NLP's blocks; :class:`StagewiseSolver` solves the permuted
problem and answers in the layout's own order, with IPOPT's call and result conventions (x0,
p, lbx, ubx, lbg, ubg → x; ``stats()`` with ``return_status`` and ``iter_count``), so the move
NLP uses it like its IPOPT solver.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["SOLVERS", "StagewiseSolver", "stagewise_solver", "fatrop_options"]

# "auto" (MoveNLP's default): FATROP for minimum time without the pump, with IPOPT when it
# fails; IPOPT for everything else. Measured (umea-lab + s100f, 12 tip moves each way, N = 40,
# loaded 2-core machine): pump off, FATROP 2.35 s in all vs IPOPT 3.03 s and 0.76× the plain
# Opti baseline on the benchmark move (IPOPT 1.6×); pump on, FATROP failed one move after 10 s
# and was 5× slower on another (IPOPT 6.95 s in all vs 14.3 s with the fallback).
SOLVERS = ("ipopt", "fatrop", "auto")


def stagewise_solver(problem: dict, layout, equality, ipopt: dict):
    """A :class:`StagewiseSolver` for ``problem`` ({x, p, f, g} in the layout's order), or None
    when the layout has rows without a stage. ``equality`` marks the equality rows; the
    tolerance and iteration limit follow the IPOPT options ``ipopt``."""
    try:
        wperm, gperm = layout.stage_order()
    except ValueError:
        return None
    eq = [bool(e) for e in np.asarray(equality)[gperm]]
    x, g = problem["x"], problem["g"]
    solver = ca.nlpsol("move_fatrop", "fatrop", {"x": x[wperm.tolist()], "p": problem["p"],
                                                 "f": problem["f"],
                                                 "g": g[gperm.tolist()]},
                       dict(fatrop_options(eq, ipopt), expand=True))
    return StagewiseSolver(solver, wperm, gperm, eq)


def fatrop_options(equality, ipopt: dict) -> dict:
    """FATROP's options: automatic stage detection, the stage-ordered ``equality`` rows, the
    tolerance and iteration limit of the IPOPT options ``ipopt``."""
    return {"structure_detection": "auto", "print_time": False, "equality": list(equality),
            "fatrop": {"print_level": 0, "tol": ipopt.get("tol", 1e-7),
                       "max_iter": ipopt.get("max_iter", 1000)}}


class StagewiseSolver:
    """A FATROP solver on the stage-ordered problem, called and answering in the layout's
    order: ``solver(x0=…, p=…, lbx=…, ubx=…, lbg=…, ubg=…)`` → {"x", "f"}; ``stats()`` gives
    ``return_status`` ("Solve_Succeeded" on success, else "FATROP: <status>"), ``iter_count``
    and FATROP's own statistics."""

    def __init__(self, solver, wperm, gperm, equality=()):
        self.solver, self.wperm, self.gperm = solver, wperm, gperm
        self.equality = list(equality)   # stage-ordered equality rows (kept for the cache)
        self._stats = {}

    def __call__(self, x0, p, lbx, ubx, lbg, ubg):
        w, g = self.wperm, self.gperm
        r = self.solver(x0=np.asarray(x0, float).ravel()[w], p=p,
                        lbx=np.asarray(lbx, float)[w], ubx=np.asarray(ubx, float)[w],
                        lbg=np.broadcast_to(lbg, (len(g),))[g],
                        ubg=np.broadcast_to(ubg, (len(g),))[g])
        x = np.empty(len(w))
        x[w] = np.asarray(r["x"]).ravel()
        st = dict(self.solver.stats())
        st["return_status"] = ("Solve_Succeeded" if st.get("success")
                               else f"FATROP: {st.get('unified_return_status', 'failed')}")
        self._stats = st
        return {"x": x, "f": r["f"]}

    def stats(self) -> dict:
        return self._stats
