"""The twin's integrator: fixed-step BDF2 with Newton's method on the compiled Jacobian, a
chunk of steps per call in machine code.

One step solves G(y) = y − (4/3·x_k − 1/3·x_{k−1}) − 2/3·h·f(y, u_k, f_x,k) = 0 for
y = x_{k+1} (the second-order backward differentiation formula: L-stable, so the stiff modes —
the oil in a nearly closed valve, an end stop — are damped, not rung, while the 0.5–5 Hz
hydraulic modes keep their amplitude to (ωh)⁴: 0.02 % per period at 3 Hz and 2 ms) — for every
state but the spools. A spool is a first-order lag behind a command held over the step, so it
is stepped exactly, s_{k+1} = ū + (s_k − ū)·e^{−h/τ} (ū the command clipped to ±1, τ the spool
time constant): BDF2 carries its history across the 50 Hz command steps, and that history
lagged every spool, and so every valve flow, by h/2 (1 ms at 2 ms steps: 0.6 mrad of a slew
turning at 0.6 rad/s, 4 mm at the s100f tip on the fast validation move against the Exudyn
plant, whose spool is stepped exactly too).
Newton starts from the extrapolation 2x_k − x_{k−1} with the Jacobian I − 2/3·h·∂f/∂x
evaluated there and kept for ``newton`` iterations (simplified Newton); the size of the last
update, scaled per state (1 rad, 1 rad/s, 1 MPa, one spool range), comes back per step so that
a step that did not converge is seen. A run that starts without a history (the first step, a
chunk redone in substeps) takes x_{k−1} = x_k − h·f(x_k): BDF2 is then consistent at once
(at rest, x_{k−1} = x_k; a bare x_{k−1} = x_k would make the first step an implicit Euler step
of 2h/3 — a lag of h/3 for a run that starts moving).

The step is an SX function (the sparse linear system solved by symbolic elimination over its
structure, :mod:`planner.model.twin.linsolve`), mapped
over ``chunk`` steps with :meth:`casadi.Function.mapaccum` and compiled as a whole
(:func:`planner.model.numeric.jit_function`): one call from Python integrates ``chunk`` steps,
the commands and extra forces given per step, through the function's call buffer bound once to
numpy arrays that are filled in place (converting the arrays to CasADi matrices and back on
every call cost as much as the integration: 85–141 × real time against 144–277 ×,
``benchmarks/results/twin_speed.md``). Commands are held from the step that starts at
or after their time (the step grid is fine against the 50 Hz commands: both are multiples of
the step there, as in the Exudyn plant).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from planner.model.numeric import bound_buffer, jit_function
from planner.model.twin.linsolve import sparse_lu

__all__ = ["Stepper", "STATE_SCALE", "state_scale"]

_CHUNKS: dict = {}   # per process: (rhs, n, newton, chunk, spool) → (rhs, step, compiled chunk)

#: per-state scale of the Newton update check: q, q̇ (1), pressures (1 MPa), spools (1)
STATE_SCALE = {"q": 1.0, "qd": 1.0, "p": 1e6, "spool": 1.0}


def state_scale(n: int, nx: int | None = None) -> np.ndarray:
    """The per-state scale of :data:`STATE_SCALE` as a vector (5n + 1,), padded with 1 up
    to ``nx`` states (extra states: rad, rad/s)."""
    s = np.concatenate([np.full(2 * n, 1.0), np.full(2 * n + 1, 1e6), np.full(n, 1.0)])
    return s if nx is None or nx <= s.size else np.concatenate([s, np.ones(nx - s.size)])


class Stepper:
    """BDF2 steps of ``rhs`` (the twin's ``rhs(x, u, f_x, P)``) of size ``h`` [s], ``newton``
    simplified-Newton iterations each, ``chunk`` steps per compiled call.

    :meth:`run` integrates from x0 over K steps with per-step commands and extra forces;
    ``compiled`` says whether machine code runs (False without a C compiler)."""

    def __init__(self, rhs: ca.Function, n: int, h: float, newton: int = 3, chunk: int = 50,
                 tol: float = 1e-2, refine: int = 4, depth: int = 2, tau_index: int | None = None):
        self.n, self.h, self.newton, self.chunk = n, float(h), int(newton), int(chunk)
        self.tol, self.refine, self.depth = float(tol), int(refine), int(depth)
        self._rhs = rhs
        self._fine = None
        self.refined = 0
        self.tau_index = tau_index
        self.nx = rhs.size1_in(0)
        self._npar = rhs.size1_in(3)
        # the step size is an input of the chunk (below), so every stepper of this right-hand
        # side — another step, the substeps of :meth:`_refined` — shares one symbolic build and
        # one compiled chunk in a process (building and hashing it alone takes about a second)
        key = (id(rhs), self.n, self.newton, self.chunk, tau_index)
        got = _CHUNKS.get(key)
        if got is None or got[0] is not rhs:
            got = _CHUNKS[key] = (rhs, *self._build())
        _, self.step_sx, self._f = got
        self.compiled = self._f is not None and self._f.is_a("External")
        self._buffer = None     # the chunk's call buffer, bound on first use (:meth:`_chunk`)

    def _build(self):
        """(the step as an SX function, the compiled chunk of ``chunk`` steps)."""
        rhs, n, nx, npar = self._rhs, self.n, self.nx, self._npar
        xk, xm, ys = ca.SX.sym("xk", nx), ca.SX.sym("xm", nx), ca.SX.sym("y", nx)
        u, fx = ca.SX.sym("u", n), ca.SX.sym("f_x", n)
        # the parameters and the step size h: an input, not a constant (see __init__)
        Pe = ca.SX.sym("P", npar + 1)
        P, hs = Pe[:npar], Pe[npar]
        jac = ca.Function("twin_jac", [ys, u, fx, P], [ca.jacobian(rhs(ys, u, fx, P), ys)])
        c = 2.0 / 3.0 * hs
        m = self.spool_mask()                   # 1 on the exactly stepped spool rows
        keep = ca.DM(1.0 - m)
        y = 2 * xk - xm
        exact = self.exact_spools(xk, u, P, hs)
        y = keep * y + ca.DM(m) * exact
        J = ca.SX.eye(nx) - c * ca.mtimes(ca.diag(keep), jac(y, u, fx, P))
        # solved in scaled states (1 rad, 1 MPa, …; D⁻¹·J·D): the symbolic solve does not
        # pivot, and unscaled its rounding reaches the small states; factored once
        d = ca.DM(state_scale(n, nx))
        solve = sparse_lu(J * ca.mtimes(1.0 / d, d.T))
        b = 4.0 / 3.0 * xk - 1.0 / 3.0 * xm
        inv_scale = ca.DM(1.0 / state_scale(n, nx))
        dy = ca.SX.zeros(nx)
        for _ in range(self.newton):
            G = keep * (y - b - c * rhs(y, u, fx, P))
            dy = keep * d * solve(G / d)            # the spool rows stay exact
            y = y - dy
        err = ca.mmax(ca.fabs(dy) * inv_scale)
        step = ca.Function("twin_bdf2", [ca.vertcat(xk, xm), u, fx, Pe],
                           [ca.vertcat(y, xk), err], {"cse": True})
        return step, jit_function(step.mapaccum("twin_chunk", self.chunk))

    def spool_mask(self) -> np.ndarray:
        """1 on the spool rows (4n + 1 … 5n, stepped exactly), 0 elsewhere (BDF2); all 0 when
        the stepper was given no spool time constant."""
        m = np.zeros(self.nx)
        if self.tau_index is not None:
            m[4 * self.n + 1:5 * self.n + 1] = 1.0
        return m

    def spool_decay(self, P, h=None):
        """e^{−h/τ}, the exact step of a spool's lag (SX or float ``P``; ``h`` SX or float,
        default the stepper's); 0 without τ."""
        if self.tau_index is None:
            return 0.0
        return ca.exp(-(self.h if h is None else h) / P[self.tau_index])

    def exact_spools(self, xk, u, P, h=None):
        """The state vector with the spool rows at their exact value after one step (the other
        rows: zero) — ū + (s_k − ū)·e^{−h/τ}."""
        if self.tau_index is None:
            return ca.SX.zeros(self.nx)
        n = self.n
        ub = ca.fmin(ca.fmax(u, -1.0), 1.0)
        E = self.spool_decay(P, h)
        s = ub + (xk[4 * n + 1:5 * n + 1] - ub) * E
        return ca.vertcat(ca.SX.zeros(4 * n + 1), s, ca.SX.zeros(self.nx - 5 * n - 1))

    def run(self, x0, u, f_x, P, x_prev=None):
        """Integrate K steps from ``x0`` (nx,) with commands ``u`` (K, n) and extra forces
        ``f_x`` (K, n) held over each step: (states (K + 1, nx) from x0 on, the scaled size
        of each step's last Newton update (K,))."""
        u = np.asarray(u, float)
        f_x = np.asarray(f_x, float)
        K = u.shape[0]
        C = self.chunk
        Kp = -(-K // C) * C
        up = np.zeros((Kp, self.n))
        fp = np.zeros((Kp, self.n))
        up[:K], fp[:K] = u, f_x
        x0 = np.asarray(x0, float)
        if x_prev is None:          # no history: a consistent one (see the module doc)
            f0 = np.asarray(self._rhs(x0, up[0], fp[0], np.asarray(P, float)), float).ravel()
            x_prev = x0 - self.h * f0 if np.all(np.isfinite(f0)) else x0
        _, ev, (xx, ub, fb, pb), (Xb, Eb) = self._chunk_buffer()
        xx[:self.nx], xx[self.nx:] = x0, x_prev
        pb[:] = np.append(np.asarray(P, float), self.h).reshape(1, -1)   # h: the last input
        out = np.empty((Kp + 1, self.nx))
        err = np.empty(Kp)
        out[0] = x0
        for s in range(0, Kp, C):
            ub[:], fb[:] = up[s:s + C], fp[s:s + C]
            ev()
            X, E = Xb, Eb
            if self.depth > 0 and not (np.all(np.isfinite(X)) and E.max() <= self.tol):
                X, E = self._refined(xx, up[s:s + C], fp[s:s + C], P)
            out[s + 1:s + C + 1] = X[:, :self.nx]
            err[s:s + C] = E
            xx[:] = X[-1]
            if not np.all(np.isfinite(xx)):
                out[s + C + 1:] = np.nan
                err[s + C:] = np.inf
                break
        return out[:K + 1], err[:K]

    def _chunk_buffer(self):
        """The compiled chunk's call buffer bound to arrays filled in place (no conversion per
        call): inputs the history (2nx,), commands and forces (chunk, n), parameters and the
        step (chunk, npar + 1); outputs the states with their history (chunk, 2nx), the
        updates (chunk,) — row-major (chunk, k) is the column-major (k, chunk) CasADi reads and writes."""
        if self._buffer is None:
            C, n = self.chunk, self.n
            self._buffer = bound_buffer(
                self._f, [np.zeros(2 * self.nx), np.zeros((C, n)), np.zeros((C, n)),
                          np.zeros((C, self._npar + 1))],
                [np.zeros((C, 2 * self.nx)), np.zeros(C)])
        return self._buffer

    def _refined(self, xx, u, f_x, P):
        """A chunk whose Newton iteration did not converge (a stop hit at speed, a command
        step that swaps the pump's load): again with ``refine`` substeps per step (restarted
        from x_k, the BDF2 history dropped), recursively up to ``depth`` times; the states at
        the coarse grid and each coarse step's worst update."""
        if self._fine is None:
            self._fine = Stepper(self._rhs, self.n, self.h / self.refine, self.newton,
                                 self.chunk, self.tol, self.refine, self.depth - 1,
                                 self.tau_index)
        self.refined += 1
        r = self.refine
        Xf, Ef = self._fine.run(xx[:self.nx], np.repeat(u, r, axis=0),
                                np.repeat(f_x, r, axis=0), P)
        X = Xf[r::r]
        prev = np.vstack([xx[None, :self.nx], X[:-1]])   # the coarse grid's history
        E = Ef.reshape(-1, r).max(axis=1)
        return np.hstack([X, prev]), E
