"""The plain CasADi Opti baseline the move NLP is compared with (issue 15, issue 17): shared by
benchmarks/bench_peers.py (solve time, in process) and benchmarks/bench_nlp_cache.py (a fresh
process per call).

A triple integrator per joint with piecewise-constant jerk, integrated exactly on N equal
intervals, minimum time, rest to rest between two joint configurations, the crane's limits
(position, velocity, acceleration at the nodes, jerk per interval) — what a user writes in
Opti without the project's model. ``pump=True`` adds the pump limit as a user would write it:
Σ A_a·max(ẋ, 0) + A_b·max(−ẋ, 0) ≤ Q_max at the nodes (``fmax``, the crane's symbolic stroke
Jacobian). No velocity check between the nodes, no pump margin: it is allowed to be slightly
infeasible between nodes, which the project's NLP is not.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["PlainOpti"]


class PlainOpti:
    """The baseline problem for one move, built once; :meth:`solve` → (duration [s], IPOPT
    iterations). ``variables``/``constraints`` give its size."""

    def __init__(self, crane, q0, q1, N: int = 40, pump: bool = False, guess_T: float = 1.0):
        L = crane.limit_arrays()
        n = crane.n
        jmax = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], 1e3)
        opti = ca.Opti()
        X = opti.variable(3 * n, N + 1)
        U = opti.variable(n, N)
        T = opti.variable()
        h = T / N
        for k in range(N):
            q, v, a, j = X[:n, k], X[n:2 * n, k], X[2 * n:, k], U[:, k]
            opti.subject_to(X[:, k + 1] == ca.vertcat(q + h * v + h ** 2 / 2 * a + h ** 3 / 6 * j,
                                                       v + h * a + h ** 2 / 2 * j, a + h * j))
        opti.subject_to(X[:n, 0] == q0)
        opti.subject_to(X[:n, N] == q1)
        opti.subject_to(X[n:, 0] == 0)
        opti.subject_to(X[n:, N] == 0)
        for k in range(N + 1):
            opti.subject_to(opti.bounded(L["q_min"], X[:n, k], L["q_max"]))
            opti.subject_to(opti.bounded(L["qd_min"], X[n:2 * n, k], L["qd_max"]))
            opti.subject_to(opti.bounded(-L["qdd_max"], X[2 * n:, k], L["qdd_max"]))
        for k in range(N):
            opti.subject_to(opti.bounded(-jmax, U[:, k], jmax))
        opti.subject_to(opti.bounded(1e-3, T, 1e3))
        if pump:
            from planner.model.flows import actuator_table
            acts = actuator_table(crane.spec)
            Ab = np.where(acts.single, 0.0, acts.area_b)
            for k in range(N + 1):
                xd = crane.f_stroke(X[:n, k])[1] * X[n:2 * n, k]
                draw = ca.sum1(acts.area_a * ca.fmax(xd, 0) + Ab * ca.fmax(-xd, 0))
                opti.subject_to(draw <= crane.spec.pump.max_flow)
        opti.minimize(T + 1e-6 * h * ca.sumsqr(U))
        opti.set_initial(T, max(guess_T, 0.1))
        for k in range(N + 1):
            opti.set_initial(X[:n, k], q0 + (q1 - q0) * k / N)
        opti.solver("ipopt", {"print_time": False, "expand": True},
                    {"print_level": 0, "sb": "yes", "tol": 1e-7, "mu_strategy": "adaptive"})
        self.opti, self.T, self.X, self.n, self.N = opti, T, X, n, N
        self.variables, self.constraints = int(opti.nx), int(opti.ng)

    def solve(self) -> tuple:
        """(duration [s], iterations); NaN duration when IPOPT fails. The last solution's
        node states are kept for :meth:`trajectory`."""
        try:
            sol = self.opti.solve()
        except RuntimeError:
            self._last = None
            return float("nan"), int(self.opti.stats().get("iter_count", 0))
        self._last = (float(sol.value(self.T)), np.asarray(sol.value(self.X)))
        return self._last[0], int(sol.stats()["iter_count"])

    def trajectory(self, crane):
        """The last solution as a planner Trajectory (node states; between nodes each joint is
        the cubic of its constant jerk, which the quintic interpolation reproduces), for
        ``evaluate()``; None after a failed solve."""
        from planner.trajectory import Trajectory
        if getattr(self, "_last", None) is None:
            return None
        T, X = self._last
        n = self.n
        return Trajectory(np.linspace(0.0, T, self.N + 1), X[:n].T, X[n:2 * n].T, X[2 * n:].T,
                          joint_names=tuple(crane.names), method="opti", objective="time")
