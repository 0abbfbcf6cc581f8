"""The move NLP's twins: the same formulation under other solver settings, built on first use.

- the IPOPT twin: the fallback of ``solver="auto"`` when FATROP fails (the same variables and
  rows);
- the warm twin: IPOPT started from a previous solution and its multipliers
  (:data:`WARM_ROUND`), for the energy/blend NLP's later activity rounds. A cold start put the
  barrier back at its start and walked the whole path again (~70 iterations per round on the
  forwarder moves); warm, the rounds after the first take 10-40.
"""
from __future__ import annotations

import os

__all__ = ["SolverTwins", "WARM_ROUND", "warm_rounds"]

#: IPOPT options of the warm twin: start at the given point and multipliers, pushed off the
#: bounds by little (the previous round's solution is already interior)
WARM_ROUND = {"warm_start_init_point": "yes", "mu_init": 1e-4, "warm_start_bound_push": 1e-6,
              "warm_start_mult_bound_push": 1e-6, "warm_start_slack_bound_push": 1e-6}


def warm_rounds() -> bool:
    """Whether the later activity rounds start warm (default) or cold
    (``CRANE_PLANNER_NLP_WARM_ROUNDS=0``: the earlier behaviour, for comparisons)."""
    return os.environ.get("CRANE_PLANNER_NLP_WARM_ROUNDS", "1") != "0"


class SolverTwins:
    """Mixin of :class:`~planner.methods.nlp.move.MoveNLP`: its twins, built on first use
    from the constructor arguments it keeps in ``_twin_args``."""

    def _twin_of(self, **change):
        c, o, p, N, pump, reg, pm, obs, io, cache = self._twin_args
        kw = dict(N=N, pump=pump, reg=reg, pump_margin=pm, obstacles=obs, ipopt_options=io,
                  cache=cache, solver="ipopt")
        return type(self)(c, o, p, **dict(kw, **change))

    def _ipopt_twin(self):
        """The IPOPT solver of the same formulation: ``solver="auto"``'s fallback."""
        if self._twin is None:
            self._twin = self._twin_of()
        return self._twin.solver

    def _warm_twin(self):
        """The IPOPT solver of the same formulation with the :data:`WARM_ROUND` options."""
        if self._warm is None:
            io = self._twin_args[8]
            self._warm = self._twin_of(ipopt_options=dict(io or {}, **WARM_ROUND))
            self.build_time_s += self._warm.build_time_s
        return self._warm.solver

    def build_twins(self) -> float:
        """Build now the twins this NLP's solves will use (the warm twin of an energy or blend
        NLP), so that a worker's set-up pays for them, not its first move. Returns seconds."""
        if self.objective == "time" or not warm_rounds() or self._warm is not None:
            return 0.0
        self._warm_twin()
        return self._warm.build_time_s

    def _name(self, solver) -> str:
        """How an error names ``solver``: this NLP's own solver, or the IPOPT twin."""
        return self.solver_name.upper() if solver is self.solver else "IPOPT"
