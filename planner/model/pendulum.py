"""The hanging grapple as a pendulum driven by the boom tip: the swing the plan leaves behind.

The grapple and its load hang on a passive two-axis link below the boom tip (the spec's
``[dynamics.grapple]``): centre of mass at ``length`` L below the pivot, mass m (the payload:
load + tool), radius of gyration k about the centre of mass, viscous ``damping`` c about each
pin. The crane moves the pivot; the load follows only through the link. In the pivot's frame
(accelerating with the tip, not rotating) the load is a compound pendulum in the effective
gravity g_eff = (0, 0, −g) − a_tip, so the tip's Cartesian acceleration a_tip is all that drives
it.

Coordinates, world-aligned (not turning with the slew): α about the world x axis, then β about
the once-turned y axis; the link's direction from pivot to centre of mass is

    d(α, β) = L · (sin β, −sin α cos β, −cos α cos β),

so (0, 0) hangs straight down and the load's horizontal offset from under the tip is
(d_x, d_y) = (L sin β, −L sin α cos β). The body's angular speed is |ω|² = α̇² + β̇²
(the two pin axes stay perpendicular). With θ = (α, β) and J = ∂d/∂θ:

    M(θ) θ̈ + h(θ, θ̇) = m Jᵀ g_eff − c θ̇,      M = m (JᵀJ + k² I),
    h = (∂(M θ̇)/∂θ) θ̇ − ½ ∂(θ̇ᵀ M θ̇)/∂θ            (Lagrange's equations).

Small angles: ω₀ = √(g L / (L² + k²)) (1.5 m, k = 0.3 m: 2.51 rad/s, 0.40 Hz), damping ratio
ζ = c / (2 m √(g L (L² + k²))). The plant's pins damp the link's rate *relative to the boom*
(they turn with the slew); here they damp the world-aligned rates, which differs only while
the crane slews and by a share ζ of the swing.

The swing's right-hand side is written once in CasADi (:attr:`Pendulum.f_swing`, a named
``casadi.Function`` an NLP calls on symbols); :meth:`Pendulum.rhs` is its numeric face.
:func:`predict_swing` integrates it (RK4 on a fine grid, one CasADi ``mapaccum`` call) along a
planned trajectory's tip acceleration (:func:`tip_motion`: the crane's own forward kinematics
differentiated twice) and reports the swing during the move and the residual swing amplitude
after it: the largest horizontal offset the free, undamped pendulum reaches with the energy it
holds at the end of the move (the tip at rest), L·sin θ_max with m g L (1 − cos θ_max) = E
for a swing in one plane (an elliptic swing stays inside it).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from planner.model.dynamics_spec import GYRATION

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.trajectory import Trajectory

__all__ = ["Pendulum", "SwingPrediction", "predict_swing", "tip_motion", "swing_rhs_expr",
           "STATE"]

#: the swing state's entries, in order
STATE = ("alpha", "beta", "alpha_dot", "beta_dot")
_TIP_MOTION: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()   # crane -> functions


def _check(name: str, value, lo: float, hi: float, allow_lo: bool) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    ok = math.isfinite(v) and (v >= lo if allow_lo else v > lo) and v <= hi
    if not ok:
        raise ValueError(f"pendulum `{name}` = {value!r}: allowed a number in "
                         f"{'[' if allow_lo else '('}{lo:g}, {hi:g}]")
    return v


def _direction(L, a, b):
    """The link vector d(α, β) (pivot → centre of mass), CasADi or numpy."""
    lib = ca if isinstance(a, (ca.SX, ca.MX)) else np
    return lib.sin(b) * L, -lib.sin(a) * lib.cos(b) * L, -lib.cos(a) * lib.cos(b) * L


@dataclass(frozen=True)
class Pendulum:
    """The grapple link: ``length`` L [m] pivot to centre of mass, ``mass`` m [kg], pin
    ``damping`` c [N·m·s/rad], radius of ``gyration`` k [m], ``gravity`` g [m/s²]."""
    length: float
    mass: float
    damping: float = 0.0
    gyration: float = GYRATION
    gravity: float = 9.81
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        for name, lo, hi, closed in (("length", 0.0, 20.0, False), ("mass", 0.0, 1e6, False),
                                     ("damping", 0.0, 1e9, True), ("gyration", 0.0, 10.0, True),
                                     ("gravity", 0.0, 100.0, False)):
            object.__setattr__(self, name, _check(name, getattr(self, name), lo, hi, closed))

    @classmethod
    def of(cls, crane: Crane, length: float | None = None, *, damping: float | None = None,
           zeta: float | None = None, mass: float | None = None) -> "Pendulum":
        """The crane's grapple: the spec's ``[dynamics.grapple]`` unless ``length`` [m] is
        given; mass the payload (load + tool) unless given; damping the spec's, or ``zeta``
        (share of critical), or ``damping`` [N·m·s/rad], else none."""
        spec = crane.spec
        g = spec.dynamics.grapple if spec.dynamics is not None else None
        if length is None and g is None:
            raise ValueError(f"pendulum `length`: {spec.id} has no [dynamics.grapple]; give "
                             "the link length [m] (a number > 0)")
        L = float(g.length if length is None else length)
        k = g.gyration if g is not None else GYRATION
        m = spec.payload.total if mass is None else mass
        if zeta is not None:
            z = _check("zeta", zeta, 0.0, 1.0, True)
            c = 2 * z * float(m) * math.sqrt(spec.gravity * L * (L * L + k * k))
        elif damping is not None:
            c = damping
        else:
            c = g.damping if g is not None and length is None else 0.0
        return cls(length=L, mass=m, damping=c, gyration=k, gravity=spec.gravity)

    # ------------------------------------------------------------------ small-angle figures
    @property
    def inertia(self) -> float:
        """m (L² + k²) [kg·m²]: the link's inertia about the pivot."""
        return self.mass * (self.length ** 2 + self.gyration ** 2)

    @property
    def omega(self) -> float:
        """Small-angle natural angular frequency ω₀ = √(g L / (L² + k²)) [rad/s]."""
        return math.sqrt(self.gravity * self.length / (self.length ** 2 + self.gyration ** 2))

    @property
    def zeta(self) -> float:
        """Damping ratio c / (2 √(m g L · m (L² + k²))) (share of critical)."""
        return self.damping / (2 * math.sqrt(self.mass * self.gravity * self.length * self.inertia))

    @property
    def damped_period(self) -> float:
        """2π / (ω₀ √(1 − ζ²)) [s]."""
        return 2 * math.pi / (self.omega * math.sqrt(max(1e-12, 1 - self.zeta ** 2)))

    # ------------------------------------------------------------------ the dynamics, once
    @cached_property
    def f_swing(self) -> ca.Function:
        """``swing_rhs(x[4], a_tip[3]) -> xdot[4]``: the swing's ODE (x = α, β, α̇, β̇)."""
        x, a = ca.SX.sym("x", 4), ca.SX.sym("a_tip", 3)
        xdot = swing_rhs_expr(x, a, self.length, self.mass, self.gyration, self.damping,
                              self.gravity)
        return ca.Function("swing_rhs", [x, a], [xdot], ["x", "a_tip"], ["xdot"])

    def values(self) -> np.ndarray:
        """(length, mass, gyration, damping): the link's data in the order
        :func:`swing_rhs_expr` takes them (a compiled twin's parameter inputs)."""
        return np.array([self.length, self.mass, self.gyration, self.damping], float)

    def rhs(self, x, a_tip) -> np.ndarray:
        """Numeric face of :attr:`f_swing`: (4,) or (N, 4) states, (3,) or (N, 3) tip
        accelerations [m/s²] -> state derivatives of the same leading shape."""
        x, a = np.asarray(x, float), np.asarray(a_tip, float)
        single = x.ndim == 1 and a.ndim == 1
        X, A = np.atleast_2d(x), np.atleast_2d(a)
        N = max(len(X), len(A))
        out = np.array(self.f_swing.map(N)(np.broadcast_to(X, (N, 4)).T,
                                            np.broadcast_to(A, (N, 3)).T)).T
        return out[0] if single else out

    def link(self, x) -> np.ndarray:
        """(…, 3) link vector d(α, β) [m] from the pivot (the tip) to the load's centre of
        mass, world-aligned axes of frame 0 (the module doc's d)."""
        x = np.asarray(x, float)
        return np.stack(_direction(self.length, x[..., 0], x[..., 1]), -1)

    def offset(self, x) -> np.ndarray:
        """(…, 2) horizontal offset [m] of the load's centre of mass from under the tip."""
        x = np.asarray(x, float)
        dx, dy, _ = _direction(self.length, x[..., 0], x[..., 1])
        return np.stack([dx, dy], -1)

    def energy(self, x) -> np.ndarray:
        """(…,) swing energy [J] in the tip's frame with the tip at rest: kinetic
        ½ θ̇ᵀ M θ̇ plus m g (L + d_z) (zero hanging at rest)."""
        x = np.asarray(x, float)
        a, b, ad, bd = (x[..., i] for i in range(4))
        L, m, k = self.length, self.mass, self.gyration
        # JᵀJ = L² diag(cos² β, 1) (the columns of J are perpendicular)
        T = 0.5 * m * ((L * L * np.cos(b) ** 2 + k * k) * ad ** 2 + (L * L + k * k) * bd ** 2)
        return T + m * self.gravity * L * (1 - np.cos(a) * np.cos(b))

    def amplitude(self, x) -> np.ndarray:
        """(…,) largest horizontal offset [m] the free, undamped swing reaches from state
        ``x`` with the tip at rest: L sin θ_max, m g L (1 − cos θ_max) = energy (capped at a
        horizontal link)."""
        c = 1 - self.energy(x) / (self.mass * self.gravity * self.length)
        th = np.arccos(np.clip(c, 0.0, 1.0))
        return self.length * np.sin(th)

    # ------------------------------------------------------------------ integration
    def step_function(self) -> ca.Function:
        """``rk4(x, a0, a_half, a1, dt) -> x⁺``: one RK4 step of :attr:`f_swing`."""
        if "rk4" not in self._cache:
            x, dt = ca.SX.sym("x", 4), ca.SX.sym("dt")
            a0, ah, a1 = ca.SX.sym("a0", 3), ca.SX.sym("ah", 3), ca.SX.sym("a1", 3)
            f = self.f_swing
            k1 = f(x, a0)
            k2 = f(x + 0.5 * dt * k1, ah)
            k3 = f(x + 0.5 * dt * k2, ah)
            k4 = f(x + dt * k3, a1)
            self._cache["rk4"] = ca.Function("swing_rk4", [x, a0, ah, a1, dt],
                                             [x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
        return self._cache["rk4"]

    def integrate(self, t, a_of_t, x0=(0.0, 0.0, 0.0, 0.0)) -> np.ndarray:
        """(K, 4) states at the times ``t`` (K,) [s] from ``x0``, driven by the tip
        acceleration ``a_of_t(times) -> (…, 3)`` [m/s²] (RK4 on the steps of ``t``)."""
        t = np.asarray(t, float)
        mid = 0.5 * (t[1:] + t[:-1])
        A = np.asarray(a_of_t(t), float)
        Ah = np.asarray(a_of_t(mid), float)
        K = len(t)
        if K < 2:
            return np.asarray(x0, float)[None, :]
        run = self.step_function().mapaccum(K - 1)
        X = np.array(run(np.asarray(x0, float), A[:-1].T, Ah.T, A[1:].T, np.diff(t)[None, :]))
        return np.vstack([np.asarray(x0, float), X.T])


def swing_rhs_expr(x, a, length, mass, gyration, damping, gravity):
    """The swing's ODE as a CasADi expression (the module doc's Lagrange equations, the one
    definition): state ``x`` (α, β, α̇, β̇), tip acceleration ``a`` (3) [m/s²] and the link's
    data, numbers or symbols (a compiled twin takes them as inputs) -> ẋ (4)."""
    th, thd = x[:2], x[2:]
    m, k, c = mass, gyration, damping
    d = ca.vertcat(*_direction(length, th[0], th[1]))
    J = ca.jacobian(d, th)
    M = m * (J.T @ J + k * k * ca.SX.eye(2))
    Mv = M @ thd
    h = ca.jacobian(Mv, th) @ thd - 0.5 * ca.gradient(ca.dot(thd, Mv), th)
    g_eff = ca.vertcat(0, 0, -gravity) - a
    thdd = ca.solve(M, m * J.T @ g_eff - h - c * thd)
    return ca.vertcat(thd, thdd)


def tip_motion(crane: Crane) -> ca.Function:
    """``tip_motion(q, qd, qdd) -> (p, v, a)``: the tip's Cartesian position [m], velocity
    [m/s] and acceleration [m/s²] in frame 0 (the crane's forward kinematics, J q̈ + J̇ q̇)."""
    cache = _TIP_MOTION.setdefault(crane, {})
    if "tip_motion" not in cache:
        n = crane.n
        q, qd, qdd = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("qdd", n)
        p = crane.f_fk(q)[0]
        J = ca.jacobian(p, q)
        v = J @ qd
        a = J @ qdd + ca.jacobian(v, q) @ qd
        cache["tip_motion"] = ca.Function("tip_motion", [q, qd, qdd], [p, v, a],
                                          ["q", "qd", "qdd"], ["p", "v", "a"])
    return cache["tip_motion"]


@dataclass
class SwingPrediction:
    """The model's swing along a plan: ``t`` [s] (K,), ``x`` (K, 4) swing states, ``offset``
    (K, 2) [m] horizontal load offset from under the tip; ``peak_during_m`` the largest
    offset during the move, ``residual_m`` the free swing's amplitude after it (tip at rest),
    ``end_state`` the state at the move's end."""
    t: np.ndarray
    x: np.ndarray
    offset: np.ndarray
    peak_during_m: float
    residual_m: float
    end_state: np.ndarray


def predict_swing(crane: Crane, traj: Trajectory, pendulum: Pendulum,
                  rate: float = 200.0) -> SwingPrediction:
    """Integrate the swing along ``traj`` (from hanging at rest) at ``rate`` [Hz] (plus every
    sample of the plan) with the tip acceleration of the crane's kinematics."""
    f = tip_motion(crane)
    fm = {}

    def acc(times):
        q, qd, qdd, _ = traj.sample(times)
        N = len(q)
        if N not in fm:
            fm[N] = f.map(N)
        return np.array(fm[N](q.T, qd.T, qdd.T)[2]).T

    t = traj.resample(rate)
    x = pendulum.integrate(t, acc)
    off = pendulum.offset(x)
    return SwingPrediction(t=t, x=x, offset=off,
                           peak_during_m=float(np.max(np.linalg.norm(off, axis=1))),
                           residual_m=float(pendulum.amplitude(x[-1])), end_state=x[-1])
