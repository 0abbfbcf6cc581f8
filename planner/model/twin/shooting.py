"""Single shooting on the twin: a command sequence's cost and its gradient by the adjoint.

The twin's integrator (:mod:`planner.model.twin.integrator`) solves, every step k,
G(y) = y − 4/3·x_k + 1/3·x_{k−1} − c·f(y, u_k) = 0 for y = x_{k+1} (BDF2, c = 2h/3). At the
solution the implicit function theorem gives the step's linearisation,
A_k·dx_{k+1} = 4/3·dx_k − 1/3·dx_{k−1} + c·∂f/∂u·du_k with A_k = I − c·∂f/∂y, so a cost J on
the states has the discrete adjoint (backwards from the last step)

    ā_{k+1} = ∂J/∂x_{k+1} + 4/3·μ_{k+1} − 1/3·μ_{k+2},   A_kᵀ·μ_k = ā_{k+1},
    ∂J/∂u_k = c·(∂f/∂u)ᵀ·μ_k.

One adjoint step is an SX function (the twin's right-hand side differentiated once, a sparse
symbolic solve in scaled states — 1 rad, 1 MPa, … — since the symbolic solve does not pivot and
the unscaled matrix mixes entries of 1 and 1e10); mapped backwards over a chunk of steps with
``mapaccum`` and compiled once per user like the forward chunk. A gradient with respect to
every step's command costs about one forward run, whatever the number of commands (a
finite-difference or forward-sensitivity gradient costs one run per command).

The gradient is exact where the step's Newton iteration converged (every step of an ordinary
run: tests/model/test_shooting.py checks it against central differences); where a chunk had
to be redone in substeps it is that of the coarse step at the substeps' states (counted in
``ShotRun.unconverged``). :func:`planner.refine.refine_commands` uses it to compute
feed-forward commands on the twin.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass

import numpy as np

from planner.model.commands import shift_steps, shift_steps_transposed
from planner.model.numeric import bound_buffer, jit_function
from planner.model.twin.integrator import state_scale
from planner.model.twin.linsolve import sparse_lu

if TYPE_CHECKING:
    from planner.model.twin.twin import Twin

__all__ = ["Shooting", "ShotRun"]

_REVERSE: dict = {}


@dataclass
class ShotRun:
    """One forward pass: the states ``x`` (K + 1, nx) on the step grid from x0 on, and how
    many steps ended with a Newton update above the stepper's tolerance (``unconverged``:
    there the gradient is that of the step as if it had converged)."""
    x: np.ndarray
    unconverged: int


class Shooting:
    """Forward runs and adjoint gradients of per-step commands on ``twin`` (its compiled
    chunk of steps and that chunk's compiled reverse-mode derivative)."""

    def __init__(self, twin: Twin):
        self.twin = twin
        st = twin.stepper
        self.stepper, self.n, self.nx, self.C, self.h = st, twin.crane.n, st.nx, st.chunk, st.h
        key = id(st._f)     # one adjoint per compiled chunk (whatever the stepper's step)
        rev = _REVERSE.get(key)
        if rev is None or rev[0] is not st._f:
            rev = _REVERSE[key] = (st._f, jit_function(_adjoint_step(twin.f_rhs, self.n, st)
                                                    .mapaccum("twin_adjoint", st.chunk)))
        self._adj = rev[1]
        C, n, nx = self.C, self.n, self.nx
        # the adjoint chunk's call buffer, bound to arrays filled in place: row-major (C, k)
        # is the column-major (k, C) CasADi reads and writes (no conversion per call)
        self._buffer = bound_buffer(
            self._adj, [np.zeros(2 * nx), np.zeros((C, nx)), np.zeros((C, n)),
                        np.zeros((C, n)),
                        np.repeat(np.append(np.asarray(twin.P, float), st.h)[None, :], C, 0),
                        np.zeros((C, nx))], [np.zeros((C, 2 * nx)), np.zeros((C, n))])

    def steps(self, K: int) -> int:
        """K rounded up to whole chunks (the length :meth:`run` integrates)."""
        return -(-int(K) // self.C) * self.C

    def run(self, x0, u_steps) -> ShotRun:
        """Integrate from the state ``x0`` with the commands ``u_steps`` (K, n), one per step
        (K a multiple of the chunk; see :meth:`steps`), as the twin integrates (a chunk whose
        Newton iteration does not converge is redone in substeps); the twin's command delay
        shifts them (the valves closed before the first)."""
        u_steps = shift_steps(u_steps, self.twin.delay, self.h)
        K = u_steps.shape[0]
        if K % self.C:
            raise ValueError(f"Shooting.run: {K} steps; a multiple of the chunk ({self.C}) "
                             "needed")
        xs, err = self.stepper.run(np.asarray(x0, float), u_steps, np.zeros_like(u_steps),
                                   self.twin.P)
        return ShotRun(xs, int(np.sum(~(err <= self.stepper.tol))))

    def gradient(self, run: ShotRun, u_steps, dJdx) -> np.ndarray:
        """∂J/∂u per step (K, n) of a cost J whose derivative with respect to each state of
        ``run`` is ``dJdx`` (K + 1, nx) (row 0, the fixed start, is ignored); ``u_steps``
        the commands of the run (before the delay, as :meth:`run` took them)."""
        C, nx = self.C, self.nx
        K = run.x.shape[0] - 1
        dJdx = np.asarray(dJdx, float)
        u_steps = shift_steps(u_steps, self.twin.delay, self.h)
        g = np.empty((K, self.n))
        _, ev, (carry, y, u, _fx, _P, seed), (R, gu) = self._buffer
        carry[:] = 0.0
        for s in range(K - C, -1, -C):
            ks = np.arange(s + C - 1, s - 1, -1)        # the chunk's steps, last first
            y[:], u[:], seed[:] = run.x[ks + 1], u_steps[ks], dJdx[ks + 1]
            ev()
            carry[:] = R[-1]
            g[ks] = gu
        return shift_steps_transposed(g, self.twin.delay, self.h)


def _adjoint_step(rhs, n: int, st):
    """One step of the adjoint, backwards. The step k solved G(y) = y − 4/3·x_k + 1/3·x_{k−1}
    − c·f(y, u_k) = 0 for y = x_{k+1} (c = 2h/3) on the BDF2 rows, and y = ū_k + (x_k −
    ū_k)·E on the exactly stepped spool rows (E = e^{−h/τ}, ū the clipped command; see
    :mod:`planner.model.twin.integrator`). With A = ∂G/∂y at the solution (I − c·∂f/∂y on the
    BDF2 rows, I on the spool rows), the implicit function theorem gives A·dy = W₁·dx_k +
    W₂·dx_{k−1} + B·du_k, W₁ = diag(4/3 | E), W₂ = diag(−1/3 | 0), B = (c·∂f/∂u | (1 −
    E)·∂ū/∂u). Carrying (μ_{k+1}, μ_{k+2}), the total adjoint of x_{k+1} is ā = ∂J/∂x_{k+1}
    + W₁·μ_{k+1} + W₂·μ_{k+2}; then μ_k = A⁻ᵀ·ā and ∂J/∂u_k = Bᵀ·μ_k. Inputs (carry (2nx), y,
    u, f_x, (P, h), seed); outputs (carry (μ_k, μ_{k+1}), ∂J/∂u_k)."""
    import casadi as ca
    nx = st.nx
    y, u, fx = ca.SX.sym("y", nx), ca.SX.sym("u", n), ca.SX.sym("f_x", n)
    Pe = ca.SX.sym("P", rhs.size1_in(3) + 1)     # the parameters and the step h, as the
    P, h = Pe[:-1], Pe[-1]                       # forward chunk takes them (one compile)
    c = 2.0 / 3.0 * h
    carry, seed = ca.SX.sym("carry", 2 * nx), ca.SX.sym("seed", nx)
    m = ca.DM(st.spool_mask())
    keep = 1.0 - m
    E = st.spool_decay(P, h)
    f = rhs(y, u, fx, P)
    A = ca.SX.eye(nx) - c * ca.mtimes(ca.diag(keep), ca.jacobian(f, y))
    w1 = 4.0 / 3.0 * keep + E * m
    w2 = -1.0 / 3.0 * keep
    a = seed + w1 * carry[:nx] + w2 * carry[nx:]
    # in scaled states (1 rad, 1 MPa, …): the symbolic solve does not pivot, and A mixes
    # entries of 1 and 1e10 unscaled (the adjoint recursion then amplifies the rounding)
    d = ca.DM(state_scale(n, nx))
    As = A * ca.mtimes(1.0 / d, d.T)             # D⁻¹·A·D
    mu = sparse_lu(As.T)(d * a) / d
    ub = ca.fmin(ca.fmax(u, -1.0), 1.0)
    B = (c * ca.mtimes(ca.diag(keep), ca.jacobian(f, u))
         + (1.0 - E) * ca.jacobian(_spool_rows(ub, n, nx), u))
    gu = ca.mtimes(B.T, mu)
    return ca.Function("twin_adjoint_step", [carry, y, u, fx, Pe, seed],
                       [ca.vertcat(mu, carry[:nx]), gu], {"cse": True})


def _spool_rows(ub, n, nx):
    """The clipped commands placed on the spool rows of a state vector (zeros elsewhere)."""
    import casadi as ca
    return ca.vertcat(ca.SX.zeros(4 * n + 1), ub, ca.SX.zeros(nx - 5 * n - 1))
