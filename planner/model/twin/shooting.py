"""Single shooting on the twin: a command sequence's cost and its exact gradient (the adjoint).

The twin's integrator (:mod:`planner.model.twin.integrator`) is a map from the state at a step
and the one before it, and the step's command, to the next state: BDF2 with a fixed number of
simplified-Newton iterations, compiled as chunks of steps (``mapaccum``). Its reverse-mode
derivative — CasADi's ``reverse(1)`` of the same chunk, compiled once per user like the
chunk itself — carries the adjoint λ backwards through a chunk in one call: given the seed
∂J/∂x_k of a cost on the chunk's states and λ of the state the chunk hands on, it returns λ
of the chunk's incoming state pair and ∂J/∂u_k of every step's command. Walking the chunks
from the last to the first gives the gradient of a cost on the whole trajectory with respect
to every step's command for the price of about six forward runs, whatever the number of
commands (a finite-difference or forward-sensitivity gradient would cost one run per command).

It is the derivative of the integrator as it runs (the fixed Newton iterations included),
so the gradient is exact for the discrete model the optimiser sees; the forward pass here
does not take the integrator's recovery substeps (a chunk whose Newton iteration did not
converge is kept as computed and counted in ``unconverged``), so cost and gradient always
belong to the same map. :func:`planner.refine.refine_commands` uses it to compute
feed-forward commands on the twin.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np

from planner.model.numeric import jit_function
from planner.model.twin.integrator import state_scale

if TYPE_CHECKING:
    from planner.model.twin.twin import Twin

__all__ = ["Shooting", "ShotRun"]

_REVERSE: dict = {}


@dataclass
class ShotRun:
    """One forward pass: the states ``x`` (K + 1, nx) on the step grid from x0 on, the chunk
    records the adjoint needs, and how many chunks ended with an unconverged Newton update
    (``unconverged``, above the stepper's tolerance)."""
    x: np.ndarray
    chunks: list
    unconverged: int


class Shooting:
    """Forward runs and adjoint gradients of per-step commands on ``twin`` (its compiled
    chunk of steps and that chunk's compiled reverse-mode derivative)."""

    def __init__(self, twin: Twin):
        self.twin = twin
        st = twin.stepper
        self.stepper, self.n, self.nx, self.C, self.h = st, twin.crane.n, st.nx, st.chunk, st.h
        key = id(st)
        rev = _REVERSE.get(key)
        if rev is None or rev[0] is not st:
            rev = _REVERSE[key] = (st, jit_function(_adjoint_step(twin.f_rhs, self.n, st)
                                                    .mapaccum("twin_adjoint", st.chunk)))
        self._adj = rev[1]
        self._P = np.repeat(np.asarray(twin.P, float).reshape(-1, 1), self.C, axis=1)
        self._fx = np.zeros((self.n, self.C))

    def steps(self, K: int) -> int:
        """K rounded up to whole chunks (the length :meth:`run` integrates)."""
        return -(-int(K) // self.C) * self.C

    def run(self, x0, u_steps) -> ShotRun:
        """Integrate from the state ``x0`` with the commands ``u_steps`` (K, n), one per step
        (K a multiple of the chunk; see :meth:`steps`)."""
        u_steps = np.asarray(u_steps, float)
        K, C, nx = u_steps.shape[0], self.C, self.nx
        if K % C:
            raise ValueError(f"Shooting.run: {K} steps; a multiple of the chunk ({C}) needed")
        x0 = np.asarray(x0, float)
        xx = np.concatenate([x0, x0])
        xs = np.empty((K + 1, nx))
        xs[0] = x0
        chunks, bad = [], 0
        for s in range(0, K, C):
            uc = np.ascontiguousarray(u_steps[s:s + C].T)
            X, E = self.stepper._f(xx, uc, self._fx, self._P)
            X, E = np.asarray(X), np.asarray(E)
            bad += int(not (np.all(np.isfinite(X)) and E.max() <= self.stepper.tol))
            chunks.append((xx, uc, X, E))
            xs[s + 1:s + C + 1] = X[:nx].T
            xx = X[:, -1]
        return ShotRun(xs, chunks, bad)

    def gradient(self, run: ShotRun, u_steps, dJdx) -> np.ndarray:
        """∂J/∂u per step (K, n) of a cost J whose derivative with respect to each state of
        ``run`` is ``dJdx`` (K + 1, nx) (row 0, the fixed start, is ignored); ``u_steps``
        the commands of the run."""
        C, nx = self.C, self.nx
        K = len(run.chunks) * C
        dJdx = np.asarray(dJdx, float)
        u_steps = np.asarray(u_steps, float)
        g = np.empty((K, self.n))
        carry = np.zeros(2 * nx)
        for s in range(K - C, -1, -C):
            ks = np.arange(s + C - 1, s - 1, -1)        # the chunk's steps, last first
            r = self._adj(carry, np.ascontiguousarray(run.x[ks + 1].T),
                          np.ascontiguousarray(u_steps[ks].T), self._fx, self._P,
                          np.ascontiguousarray(dJdx[ks + 1].T))
            R = np.asarray(r[0])
            carry = R[:, -1]
            g[ks] = np.asarray(r[1]).T
        return g


def _adjoint_step(rhs, n: int, st):
    """One step of the BDF2 adjoint, backwards: the step k solved G(y) = y − 4/3·x_k +
    1/3·x_{k−1} − c·f(y, u_k) = 0 for y = x_{k+1} (c = 2h/3). With A = I − c·∂f/∂y at the
    solution, the implicit function theorem gives dy = A⁻¹(4/3·dx_k − 1/3·dx_{k−1} +
    c·∂f/∂u·du_k). Carrying (μ_{k+1}, μ_{k+2}), the total adjoint of x_{k+1} is
    ā = ∂J/∂x_{k+1} + 4/3·μ_{k+1} − 1/3·μ_{k+2}; then μ_k = A⁻ᵀ·ā and ∂J/∂u_k = c·(∂f/∂u)ᵀ·μ_k.
    Inputs (carry (2nx), y, u, f_x, P, seed); outputs (carry (μ_k, μ_{k+1}), ∂J/∂u_k)."""
    import casadi as ca
    nx = st.nx
    c = 2.0 / 3.0 * st.h
    y, u, fx = ca.SX.sym("y", nx), ca.SX.sym("u", n), ca.SX.sym("f_x", n)
    P = ca.SX.sym("P", rhs.size1_in(3))
    carry, seed = ca.SX.sym("carry", 2 * nx), ca.SX.sym("seed", nx)
    f = rhs(y, u, fx, P)
    A = ca.SX.eye(nx) - c * ca.jacobian(f, y)
    a = seed + 4.0 / 3.0 * carry[:nx] - 1.0 / 3.0 * carry[nx:]
    # in scaled states (1 rad, 1 MPa, …): the symbolic solve does not pivot, and A mixes
    # entries of 1 and 1e10 unscaled (the adjoint recursion then amplifies the rounding)
    d = ca.DM(state_scale(n))
    As = A * ca.mtimes(1.0 / d, d.T)             # D⁻¹·A·D
    mu = ca.solve(As.T, d * a) / d
    gu = c * ca.mtimes(ca.jacobian(f, u).T, mu)
    return ca.Function("twin_adjoint_step", [carry, y, u, fx, P, seed],
                       [ca.vertcat(mu, carry[:nx]), gu], {"cse": True})
