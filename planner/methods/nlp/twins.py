"""The move NLP's twins: the same formulation under other solver settings, built on first use
(:class:`SolverTwins`, held by :class:`~planner.methods.nlp.move.MoveNLP` as ``twins``).

- the IPOPT twin: the fallback of ``solver="auto"`` when FATROP fails (the same variables and
  rows);
- the probing twin: IPOPT with Mehrotra's probing for the barrier parameter
  (:data:`PROBING`), a minimum-time solve's second try when the first fails: on a pump-starved
  umea-lab (9 L/min) one move wandered to max_iter under the default quality-function oracle
  from the plain guess (another took 227-917 iterations depending on round-off), probing solved
  the three moves of tests/methods/test_ramps.py in 40, 183 and 124;
- the warm twin: IPOPT started from a previous solution and its multipliers
  (:data:`WARM_ROUND`), for the energy/blend NLP's later activity rounds. A cold start put the
  barrier back at its start and walked the whole path again (~70 iterations per round on the
  forwarder moves); warm, the rounds after the first take 10-40.
"""
from __future__ import annotations

import os

__all__ = ["SolverTwins", "WARM_ROUND", "PROBING", "warm_rounds"]

#: IPOPT options of the warm twin: start at the given point and multipliers, pushed off the
#: bounds by little (the previous round's solution is already interior)
WARM_ROUND = {"warm_start_init_point": "yes", "mu_init": 1e-4, "warm_start_bound_push": 1e-6,
              "warm_start_mult_bound_push": 1e-6, "warm_start_slack_bound_push": 1e-6}

#: IPOPT options of the probing twin (a failed minimum-time solve's second try)
PROBING = {"mu_oracle": "probing"}


def warm_rounds() -> bool:
    """Whether the later activity rounds start warm (default) or cold
    (``CRANE_PLANNER_NLP_WARM_ROUNDS=0``: the earlier behaviour, for comparisons)."""
    return os.environ.get("CRANE_PLANNER_NLP_WARM_ROUNDS", "1") != "0"


class SolverTwins:
    """The twins of one move NLP, each built on first use by ``make(**change)`` (the NLP's own
    constructor with its arguments, ``change`` replacing some: a picklable
    ``functools.partial``), for an NLP of ``objective`` whose IPOPT options were
    ``ipopt_options``. ``build_time_s``: the seconds the twins built so far add to their NLP's
    build (the warm twin's; the IPOPT twin is a fallback, its cost is the failed solve's)."""

    def __init__(self, make, objective: str, ipopt_options: dict | None = None):
        self.make, self.objective, self.ipopt_options = make, objective, ipopt_options
        self.ipopt_nlp = self.warm_nlp = self.probing_nlp = None
        self.build_time_s = 0.0

    def ipopt(self):
        """The IPOPT solver of the same formulation: ``solver="auto"``'s fallback."""
        if self.ipopt_nlp is None:
            self.ipopt_nlp = self.make(solver="ipopt")
        return self.ipopt_nlp.solver

    def probing(self):
        """The IPOPT solver of the same formulation with the :data:`PROBING` options."""
        if self.probing_nlp is None:
            self.probing_nlp = self.make(solver="ipopt", ipopt_options=dict(
                self.ipopt_options or {}, **PROBING))
        return self.probing_nlp.solver

    def warm(self):
        """The IPOPT solver of the same formulation with the :data:`WARM_ROUND` options."""
        if self.warm_nlp is None:
            io = self.ipopt_options
            self.warm_nlp = self.make(solver="ipopt",
                                      ipopt_options=dict(io or {}, **WARM_ROUND))
            self.build_time_s += self.warm_nlp.build_time_s
        return self.warm_nlp.solver

    def build(self) -> float:
        """Build now the twins the NLP's solves will use (the warm twin of an energy or blend
        NLP), so that a worker's set-up pays for them, not its first move. Returns seconds."""
        if self.objective == "time" or not warm_rounds() or self.warm_nlp is not None:
            return 0.0
        self.warm()
        return self.warm_nlp.build_time_s
