"""The grapple pendulum driven by a boom motion on the twin's step grid: the swing it leaves.

The load hangs on the passive two-axis link of :mod:`planner.model.pendulum` (the model's one
definition of the swing: its ``swing_rhs``, the same states α, β, α̇, β̇). Here the link is
driven one way — the tip drives the swing, the swing does not act back — by a joint motion
given on a fine uniform grid (a twin run, a plant's record), as the planner's own swing
model is driven by a plan:

* over step k (h) the drive (:data:`planner.model.pendulum.DRIVE`) is held at the step's
  means: the tip's acceleration a_k = (v(q_{k+1}, q̇_{k+1}) − v(q_k, q̇_k)) / h, v = J(q)·q̇
  the tip velocity of the model's forward kinematics
  (:func:`planner.model.pendulum.tip_motion`), the last link's ω̇ likewise from its ω, the
  pin axis and ω at the mean of the two ends: second-order accurate at the step's middle;
* one RK4 step of ``swing_rhs`` with that drive advances (α, β, α̇, β̇) (ω₀h ≈ 0.005 at
  2 ms: far below the twin's own error).

The step is compiled over a chunk of steps (``mapaccum``,
:func:`planner.model.numeric.jit_function`). The twin that carries the load on its link, the
swing acting back on the boom, is :mod:`planner.model.twin.coupled`; this module also holds
what both share: the twin's ``grapple`` argument (:func:`grapple_of`), the swing amplitude
that :func:`planner.refine.refine_commands` puts a cost on (:func:`amplitude2`) and the
swing's measures of a run (:func:`swing_measures`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from planner.model.numeric import jit_function
from planner.model.pendulum import Pendulum, tip_motion

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["TwinSwing", "grapple_of", "amplitude2", "amplitude2_gradient", "swing_measures"]

_COMPILED: dict = {}     # (bodies, pendulum, step, chunk) -> the compiled chunk


def grapple_of(crane: Crane, grapple, mass: float | None = None) -> Pendulum | None:
    """The twin's pendulum from a ``grapple`` argument: None or False (no pendulum), True (the
    spec's ``[dynamics.grapple]``), a link length [m] (a number > 0; no pin damping) or a
    :class:`Pendulum`; ``mass`` [kg] (default the spec's payload) for the first two."""
    if grapple is None or grapple is False:
        return None
    if isinstance(grapple, Pendulum):
        return grapple
    if grapple is True:
        return Pendulum.of(crane, mass=mass)
    try:
        L = float(grapple)
    except (TypeError, ValueError):
        L = float("nan")
    if not (np.isfinite(L) and 0.0 < L <= 20.0):
        raise ValueError(f"twin `grapple` = {grapple!r}: allowed True (the spec's "
                         "[dynamics.grapple]), a link length in (0, 20] m or a Pendulum")
    return Pendulum.of(crane, L, mass=mass)


def _chunk_function(crane: Crane, pend: Pendulum, h: float, chunk: int):
    """The swing's step mapped over ``chunk`` twin steps, compiled."""
    key = (repr(crane.spec.joints), repr(crane.spec.gravity), pend, float(h), int(chunk))
    got = _COMPILED.get(key)
    if got is not None:
        return got
    n = crane.n
    tm = tip_motion(crane)
    s = ca.SX.sym("s", 4)
    x0, x1 = ca.SX.sym("x0", 2 * n), ca.SX.sym("x1", 2 * n)    # (q, q̇) at k and k + 1
    z = ca.SX.zeros(n)
    m0, m1 = tm(x0[:n], x0[n:], z), tm(x1[:n], x1[n:], z)
    a = ca.vertcat((m1[1] - m0[1]) / h, 0.5 * (m0[4] + m1[4]), 0.5 * (m0[5] + m1[5]),
                   (m1[5] - m0[5]) / h)
    f = pend.f_swing
    k1 = f(s, a)
    k2 = f(s + 0.5 * h * k1, a)
    k3 = f(s + 0.5 * h * k2, a)
    k4 = f(s + h * k3, a)
    step = ca.Function("twin_swing_step", [s, x0, x1],
                       [s + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)], {"cse": True})
    got = _COMPILED[key] = jit_function(step.mapaccum("twin_swing_chunk", int(chunk)))
    return got


class TwinSwing:
    """The pendulum ``pendulum`` driven one way by a boom motion on a step grid of ``h`` [s]
    (module doc): the swing a recorded or simulated joint motion leaves."""

    def __init__(self, crane: Crane, pendulum: Pendulum, h: float, chunk: int = 50):
        self.crane, self.pendulum, self.h, self.chunk = crane, pendulum, float(h), int(chunk)
        self.n = crane.n
        self._fwd = _chunk_function(crane, pendulum, self.h, self.chunk)

    def integrate(self, q, qd, s0=(0.0, 0.0, 0.0, 0.0)) -> np.ndarray:
        """(K + 1, 4) swing states along the boom's ``q``, ``qd`` (K + 1, n) on the step
        grid, from ``s0`` (default hanging at rest)."""
        X = np.hstack([np.asarray(q, float), np.asarray(qd, float)])
        K = X.shape[0] - 1
        Kp = -(-K // self.chunk) * self.chunk
        if Kp > K:                 # whole chunks: the last state held (no acceleration)
            X = np.vstack([X, np.repeat(X[-1:], Kp - K, axis=0)])
        X = np.ascontiguousarray(X.T)
        C = self.chunk
        out = np.empty((Kp + 1, 4))
        out[0] = s = np.asarray(s0, float)
        for a in range(0, Kp, C):
            S = np.asarray(self._fwd(s, X[:, a:a + C], X[:, a + 1:a + C + 1]))
            out[a + 1:a + C + 1] = S.T
            s = S[:, -1]
        return out[:K + 1]


def amplitude2(pend: Pendulum, swing) -> np.ndarray:
    """(…,) the small-angle swing amplitude squared [m²], L²·(α² + β² + (α̇² + β̇²)/ω₀²) of
    swing states (…, 4): constant along a free undamped swing with the tip at rest, so its
    integral after arrival measures the swing left (refine's swing term)."""
    s = np.asarray(swing, float)
    L2, w2 = pend.length ** 2, pend.omega ** 2
    return L2 * (s[..., 0] ** 2 + s[..., 1] ** 2 + (s[..., 2] ** 2 + s[..., 3] ** 2) / w2)


def amplitude2_gradient(pend: Pendulum, swing) -> np.ndarray:
    """∂(:func:`amplitude2`)/∂s (…, 4)."""
    s = np.asarray(swing, float)
    L2, w2 = pend.length ** 2, pend.omega ** 2
    return 2.0 * L2 * s * np.array([1.0, 1.0, 1.0 / w2, 1.0 / w2])


def swing_measures(pend: Pendulum, t, swing, t_end: float) -> dict:
    """The swing of a run (``swing`` (K, 4) at ``t`` (K,)) against the plan's end ``t_end``
    [s]: ``swing_during_m`` / ``swing_after_m`` the largest horizontal load offset before /
    after it, ``swing_final_m`` the free swing's amplitude at the end of the record
    (:meth:`planner.model.pendulum.Pendulum.amplitude`)."""
    t = np.asarray(t, float)
    r = np.linalg.norm(pend.offset(swing), axis=1)
    after = t >= t_end - 1e-9
    return dict(swing_during_m=float(r[~after].max()) if (~after).any() else 0.0,
                swing_after_m=float(r[after].max()) if after.any() else float("nan"),
                swing_final_m=float(pend.amplitude(np.asarray(swing)[-1])))
