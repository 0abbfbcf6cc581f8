"""The grapple pendulum carried by the dynamic twin: the swing a command sequence leaves.

The load hangs on the passive two-axis link of :mod:`planner.model.pendulum` (the model's one
definition of the swing: its ``swing_rhs``, the same states α, β, α̇, β̇). In the twin the link
is driven by the tip motion the twin's boom really makes — oil, pump limit, spool lag and all
— instead of the planned one, so the swing a replay of open-loop commands leaves can be
predicted and, in :func:`planner.refine.refine_commands`, optimised away.

The coupling is one way, as in the model's pendulum: the tip drives the swing, the swing does
not act back on the boom (the twin carries the payload at the tip). The swing states are then
extra states of the twin whose equations read the boom's states but never feed them, and they
are integrated on the twin's own step grid after the boom's states of each step are known:

* over step k (h, the twin's step) the tip's acceleration is held at
  a_k = (v(q_{k+1}, q̇_{k+1}) − v(q_k, q̇_k)) / h, v = J(q)·q̇ the tip velocity of the model's
  forward kinematics (:func:`planner.model.pendulum.tip_motion`): the mean acceleration of the
  step, second-order accurate at its middle;
* one RK4 step of ``swing_rhs`` with that acceleration advances (α, β, α̇, β̇) (ω₀h ≈ 0.005 at
  2 ms: the swing's discretisation error is far below the twin's own).

So the twin's boom, pressures and spools are the same numbers with or without the pendulum
(the compiled boom stepper is not touched). The step is compiled over a chunk of steps
(``mapaccum``, :func:`planner.model.numeric.jit_function`), and so is its reverse-mode
derivative: :meth:`TwinSwing.gradient` turns a cost's derivative with respect to the swing
states into one with respect to the boom's states (q, q̇) of every step, which the twin's
adjoint (:mod:`planner.model.twin.shooting`) carries on to the commands — exact for the
discrete swing, like the boom's.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from planner.model.numeric import jit_function
from planner.model.pendulum import Pendulum, tip_motion

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["TwinSwing", "grapple_of"]

_COMPILED: dict = {}     # (bodies, pendulum, step, chunk) -> (forward chunk, reverse chunk)


def grapple_of(crane: Crane, grapple) -> Pendulum | None:
    """The twin's pendulum from a ``grapple`` argument: None or False (no pendulum), True (the
    spec's ``[dynamics.grapple]``), a link length [m] (a number > 0, with the payload's mass
    and no pin damping unless the spec has a grapple of that length) or a :class:`Pendulum`."""
    if grapple is None or grapple is False:
        return None
    if isinstance(grapple, Pendulum):
        return grapple
    if grapple is True:
        return Pendulum.of(crane)
    try:
        L = float(grapple)
    except (TypeError, ValueError):
        L = float("nan")
    if not (np.isfinite(L) and 0.0 < L <= 20.0):
        raise ValueError(f"twin `grapple` = {grapple!r}: allowed True (the spec's "
                         "[dynamics.grapple]), a link length in (0, 20] m or a Pendulum")
    return Pendulum.of(crane, L)


def _chunk_functions(crane: Crane, pend: Pendulum, h: float, chunk: int):
    """The swing's step over ``chunk`` twin steps and its reverse-mode derivative, compiled."""
    key = (repr(crane.spec.joints), repr(crane.spec.gravity), pend, float(h), int(chunk))
    got = _COMPILED.get(key)
    if got is not None:
        return got
    n = crane.n
    tm = tip_motion(crane)
    s = ca.SX.sym("s", 4)
    x0, x1 = ca.SX.sym("x0", 2 * n), ca.SX.sym("x1", 2 * n)    # (q, q̇) at k and k + 1
    z = ca.SX.zeros(n)
    v0 = tm(x0[:n], x0[n:], z)[1]
    v1 = tm(x1[:n], x1[n:], z)[1]
    a = (v1 - v0) / h
    f = pend.f_swing
    k1 = f(s, a)
    k2 = f(s + 0.5 * h * k1, a)
    k3 = f(s + 0.5 * h * k2, a)
    k4 = f(s + h * k3, a)
    step = ca.Function("twin_swing_step", [s, x0, x1],
                       [s + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)], {"cse": True})
    fwd = step.mapaccum("twin_swing_chunk", int(chunk))
    S, X0, X1 = ca.MX.sym("s", 4), ca.MX.sym("X0", 2 * n, chunk), ca.MX.sym("X1", 2 * n, chunk)
    Y = fwd(S, X0, X1)
    seed = ca.MX.sym("seed", 4, chunk)
    adj = ca.Function("twin_swing_chunk_rev", [S, X0, X1, seed],
                      list(ca.reverse([Y], [S, X0, X1], [[seed]])[0]))
    got = _COMPILED[key] = (jit_function(fwd), jit_function(adj))
    return got


class TwinSwing:
    """The pendulum ``pendulum`` driven by the boom of a twin of ``crane`` with step ``h``
    [s]: :meth:`integrate` the swing along the twin's states, :meth:`gradient` a cost's
    derivative carried back to them (module doc)."""

    def __init__(self, crane: Crane, pendulum: Pendulum, h: float, chunk: int = 50):
        self.crane, self.pendulum, self.h, self.chunk = crane, pendulum, float(h), int(chunk)
        self.n = crane.n
        self._fwd, self._rev = _chunk_functions(crane, pendulum, self.h, self.chunk)

    def _padded(self, q, qd):
        """(2n, K' + 1) boom states, K' the steps rounded up to whole chunks (the last state
        held: no acceleration)."""
        X = np.hstack([np.asarray(q, float), np.asarray(qd, float)])
        K = X.shape[0] - 1
        Kp = -(-K // self.chunk) * self.chunk
        if Kp > K:
            X = np.vstack([X, np.repeat(X[-1:], Kp - K, axis=0)])
        return np.ascontiguousarray(X.T), K, Kp

    def integrate(self, q, qd, s0=(0.0, 0.0, 0.0, 0.0)) -> np.ndarray:
        """(K + 1, 4) swing states along the boom's ``q``, ``qd`` (K + 1, n) on the twin's
        step grid, from ``s0`` (default hanging at rest)."""
        X, K, Kp = self._padded(q, qd)
        C = self.chunk
        out = np.empty((Kp + 1, 4))
        out[0] = s = np.asarray(s0, float)
        for a in range(0, Kp, C):
            S = np.asarray(self._fwd(s, X[:, a:a + C], X[:, a + 1:a + C + 1]))
            out[a + 1:a + C + 1] = S.T
            s = S[:, -1]
        return out[:K + 1]

    def gradient(self, q, qd, swing, dJds) -> np.ndarray:
        """∂J/∂(q, q̇) (K + 1, 2n) of a cost J whose derivative with respect to the swing
        states ``swing`` (K + 1, 4; :meth:`integrate` of the same ``q``, ``qd``) is ``dJds``
        (K + 1, 4) (row 0, the fixed start, is ignored)."""
        X, K, Kp = self._padded(q, qd)
        C = self.chunk
        S = np.asarray(swing, float)
        D = np.zeros((Kp + 1, 4))
        D[:K + 1] = np.asarray(dJds, float)
        if Kp > K:                       # the held tail: the swing goes on, its cost is nil
            S = self.integrate(X[:self.n].T, X[self.n:].T, S[0])
        g = np.zeros((Kp + 1, 2 * self.n))
        carry = np.zeros(4)
        for a in range(Kp - C, -1, -C):
            seed = D[a + 1:a + C + 1].T.copy()
            seed[:, -1] += carry
            r = self._rev(S[a], X[:, a:a + C], X[:, a + 1:a + C + 1], seed)
            carry = np.asarray(r[0]).ravel()
            g[a:a + C] += np.asarray(r[1]).T
            g[a + 1:a + C + 1] += np.asarray(r[2]).T
        return g[:K + 1]

    def offset(self, swing) -> np.ndarray:
        """(…, 2) the load's horizontal offset [m] from under the tip."""
        return self.pendulum.offset(swing)

    def amplitude2(self, swing) -> np.ndarray:
        """(…,) the small-angle swing amplitude squared [m²], L²·(α² + β² + (α̇² + β̇²)/ω₀²):
        constant along a free undamped swing with the tip at rest, so its integral after
        arrival measures the swing left (and ``d/ds`` of it is 2·L²·(α, β, α̇/ω₀², β̇/ω₀²))."""
        s = np.asarray(swing, float)
        L2, w2 = self.pendulum.length ** 2, self.pendulum.omega ** 2
        return L2 * (s[..., 0] ** 2 + s[..., 1] ** 2 + (s[..., 2] ** 2 + s[..., 3] ** 2) / w2)

    def amplitude2_gradient(self, swing) -> np.ndarray:
        """∂(:meth:`amplitude2`)/∂s (…, 4)."""
        s = np.asarray(swing, float)
        L2, w2 = self.pendulum.length ** 2, self.pendulum.omega ** 2
        return 2.0 * L2 * s * np.array([1.0, 1.0, 1.0 / w2, 1.0 / w2])

    # ------------------------------------------------------------------ refine's swing term
    def cost(self, x, weights, dJdx) -> float:
        """Σ_k w_k·A²(s_k) in mm² (:meth:`amplitude2`) along the twin states ``x`` (K + 1, nx;
        q and q̇ first) with per-step ``weights`` (K + 1,); adds its derivative with respect
        to the states into ``dJdx`` (K + 1, nx) in place."""
        n = self.n
        q, qd = x[:, :n], x[:, n:2 * n]
        S = self.integrate(q, qd)
        w = 1e6 * np.asarray(weights, float)
        J = float(np.sum(w * self.amplitude2(S)))
        if J > 0.0:
            dJds = w[:, None] * self.amplitude2_gradient(S)
            dJdx[:, :2 * n] += self.gradient(q, qd, S, dJds)
        return J

    def measures(self, t, swing, t_end: float) -> dict:
        """The swing of a run (``swing`` (K, 4) at ``t`` (K,)) against the plan's end
        ``t_end`` [s]: ``swing_during_m`` / ``swing_after_m`` the largest horizontal load
        offset before / after it, ``swing_final_m`` the free swing's amplitude at the end of
        the record (:meth:`planner.model.pendulum.Pendulum.amplitude`)."""
        t = np.asarray(t, float)
        r = np.linalg.norm(self.offset(swing), axis=1)
        after = t >= t_end - 1e-9
        return dict(swing_during_m=float(r[~after].max()) if (~after).any() else 0.0,
                    swing_after_m=float(r[after].max()) if after.any() else float("nan"),
                    swing_final_m=float(self.pendulum.amplitude(np.asarray(swing)[-1])))


def twin_swing(crane: Crane, twin, pendulum=None) -> TwinSwing:
    """The swing to use with ``twin``: ``pendulum`` (a :class:`Pendulum`, a length [m] or
    True) on the twin's step, else the twin's own, else the spec's ``[dynamics.grapple]``."""
    pend = grapple_of(crane, pendulum)
    if pend is None and twin.swing is not None:
        return twin.swing
    return TwinSwing(crane, pend or Pendulum.of(crane), twin.step, twin.stepper.chunk)
