"""The twin with its load hanging on the grapple link, both ways: the swing drives the boom too.

:mod:`planner.model.twin.pendulum` drives the model's pendulum by the boom and stops there,
like the planner's own swing model. On the Exudyn plant that is not enough: the swinging load
pulls the boom tip about, the slew's trapped oil gives, and the boom's motion differs from the
twin's by up to 0.1 m at the tip on a forwarder move with 880 kg on a 1.5 m link — enough to
double the swing left at arrival (measured: the one-way swing on the twin 52 mm, the plant's
113 mm, the same one-way pendulum on the plant's recorded joints 114 mm). Here the load's
reaction acts on the boom:

* **State** x = (twin state (5n + 1), α, β, α̇, β̇): the twin's state (:mod:`.ode`) and the
  swing's four (:data:`planner.model.pendulum.STATE`).
* **Reaction.** The twin's rigid bodies carry the payload m as a point mass at the tip, which
  pushes on it with m·(g − a_tip). Hanging on the link, the load's centre of mass accelerates
  with a_tip + d̈ (d the link vector, :func:`planner.model.pendulum` coordinates), so the pivot
  carries m·(g − a_tip − d̈): the difference ΔF = −m·d̈ is the extra force on the tip (frame 0),
  τ = J_tipᵀ·ΔF on the joints, handed to the twin's right-hand side as the actuator forces the
  actuators work against, f_x = −τ_i / (dx_i/dq_i) (:func:`planner.model.actuators.stroke_expr`).
  The pendulum's mass is the twin's payload (the spec's load + tool unless told otherwise).
* **Inputs.** The link's data (length, mass, gyration, pin damping) follow the twin's
  parameter vector, so one compiled step serves every grapple on the same rigid bodies.
* **The algebraic loop.** d̈ depends on the boom's acceleration (the tip's, and the last
  link's turning that carries the pins: the swing's drive), which depends on ΔF. Both are
  affine: the swing's θ̈ in q̈ (its Lagrange equations, the drive affine in q̈), the boom's
  q̈ in the actuator forces (q̈ = q̈₀ + B·δ, B = ∂q̈/∂f_x = −M⁻¹·diag(dx/dq)), so the extra
  actuator force δ solves one n×n linear system, (I + D⁻¹·Jtᵀ·K·B)·δ = −D⁻¹·Jtᵀ·ΔF(q̈₀)
  (K = ∂ΔF/∂q̈, q̈₀ the boom's acceleration with the load a point at the tip, Jt the tip's
  Jacobian, D the stroke derivatives): exact, the load's apparent mass included (hanging on
  its link it follows a quick horizontal push of the tip with only k²/(L² + k²) of its
  mass). At rest the state is still an equilibrium.
* **Left out:** the torque the pins pass to the last link — the grapple's spin inertia m k²
  about the link (79 kg·m² for 880 kg, k = 0.3 m, against the slew's ~10⁴ kg·m² with the load
  out on the boom) and the pins' damping torques (c × the pin rates: a few hundred N·m). The
  force at the pivot is whole.

The stepper is the twin's own (:class:`planner.model.twin.integrator.Stepper`: BDF2, the
spools stepped exactly) on the longer state, the swing's states scaled by 1 rad; the twin's
adjoint (:mod:`planner.model.twin.shooting`) runs on it unchanged, so :func:`planner.refine`
can put a cost on the swing's states directly.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca

from planner.model.actuators import stroke_expr
from planner.model.pendulum import swing_rhs_expr, tip_motion
from planner.model.twin.integrator import Stepper
from planner.model.twin.ode import build_rhs, state_size
from planner.model.twin.params import param_index

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["SWING_STATES", "LINK_PARAMETERS", "coupled_rhs", "coupled_stepper"]

SWING_STATES = 4       # α, β, α̇, β̇
LINK_PARAMETERS = 4    # length, mass, gyration, damping: inputs of the compiled step
_BUILT: dict = {}


def _link_acceleration(L, s, sdot):
    """d̈ (3,) of the link vector d(α, β) (length ``L``) for swing state ``s`` and its
    derivative ``sdot``."""
    th, thd, thdd = s[:2], s[2:], sdot[2:]
    d = ca.vertcat(ca.sin(th[1]) * L, -ca.sin(th[0]) * ca.cos(th[1]) * L,
                   -ca.cos(th[0]) * ca.cos(th[1]) * L)
    J = ca.jacobian(d, th)
    return J @ thdd + ca.jacobian(J @ thd, th) @ thd


def coupled_rhs(crane: Crane, spec) -> ca.Function:
    """``twin_swing_rhs(x, u, f_x, P) -> ẋ`` on the state (5n + 1 + 4) of the module doc;
    P the twin's parameter vector followed by the link's (length, mass, gyration, damping)
    (:meth:`planner.model.pendulum.Pendulum.values`): one compiled step for every grapple."""
    n = crane.n
    base = build_rhs(crane, spec)["rhs"]
    nb, npar = state_size(n), base.size1_in(3)
    X = ca.SX.sym("x", nb + SWING_STATES)
    U, FX = ca.SX.sym("u", n), ca.SX.sym("f_x", n)
    P = ca.SX.sym("P", npar + LINK_PARAMETERS)
    x, s, Pt = X[:nb], X[nb:], P[:npar]
    L, m, k, c = (P[npar + i] for i in range(LINK_PARAMETERS))
    q, qd = x[:n], x[n:2 * n]
    tm = tip_motion(crane)

    def f(s_, a_):
        return swing_rhs_expr(s_, a_, L, m, k, c, spec.gravity)
    xdot0 = base(x, U, FX, Pt)                  # the boom with the load a point at the tip
    qdd0 = xdot0[n:2 * n]
    B = ca.jacobian(qdd0, FX)                   # ∂q̈/∂f_x = −M⁻¹·diag(dx/dq): q̈ is affine in f_x
    Jt = ca.jacobian(tm(q, qd, ca.SX.zeros(n))[0], q)
    aa = ca.SX.sym("qdd", n)
    dF = -m * _link_acceleration(L, s, f(s, tm(q, qd, aa)[3]))   # ΔF(q̈): affine in q̈
    K = ca.substitute(ca.jacobian(dF, aa), aa, qdd0)
    dF0 = ca.substitute(dF, aa, qdd0)
    dxdq = ca.vertcat(*[ca.jacobian(stroke_expr(j, q[i]), q[i])
                        for i, j in enumerate(spec.joints)])
    Dinv = ca.diag(1.0 / dxdq)
    # δ: the extra actuator force, δ = −D⁻¹·Jtᵀ·ΔF(q̈0 + B·δ), solved (linear in δ)
    A = ca.SX.eye(n) + Dinv @ Jt.T @ K @ B
    delta = ca.solve(A, -Dinv @ (Jt.T @ dF0))
    qdd = qdd0 + B @ delta
    xdot = ca.vertcat(xdot0[:n], qdd, xdot0[2 * n:])
    return ca.Function("twin_swing_rhs", [X, U, FX, P], [ca.vertcat(xdot, f(s, tm(q, qd, qdd)[3]))],
                       ["x", "u", "f_x", "P"], ["xdot"])


def coupled_stepper(crane: Crane, spec, step: float, newton: int, chunk: int):
    """(stepper, rhs) of the coupled twin, built once per process and (bodies, step) and
    compiled once per user (:func:`planner.model.numeric.jit_function`); the grapple's data
    are inputs."""
    key = (repr(spec.joints), repr(spec.gravity), step, newton, chunk)
    got = _BUILT.get(key)
    if got is None:
        rhs = coupled_rhs(crane, spec)
        got = _BUILT[key] = (Stepper(rhs, crane.n, step, newton, chunk,
                                     tau_index=param_index(crane.n, "tau_spool")), rhs)
    return got
