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
(d_x, d_y) = (L sin β, −L sin α cos β).

**The body turns with the boom.** The link hangs on two pins carried by the boom's last link:
the first about the boom's pitch axis e₁ (fixed in the last link), the second about e₂, square
to e₁ and to the link. So the body's angular velocity is ω_b = ω_L + ȧ e₁ + ḃ e₂ (ω_L the last
link's, ȧ, ḃ the pin rates): the load spins with the slew, and the pins' damping acts on the
rates relative to the boom. The pin rates follow from the world angles without the pin angles
themselves: u = d/L turns as u̇ = ω_b × u, so r = (ȧ, ḃ) solves
[e₁ × u, e₂ × u]·r = u̇ − ω_L × u (two equations in the plane square to u). The equations of
motion are Newton's and Euler's for the body (the grapple's inertia m k² about every axis
through its centre of mass), the pivot force eliminated, projected on the two pin axes, which
pass no torque but their damping:

    e_i · [ (k² + L² (1 − u uᵀ)) ω̇_b + L² (u·ω_b) u × ω_b + L u × (a_tip − g) ] = −(c/m) r_i,

with ω̇_b = ω̇_L + ṙ₁ e₁ + ṙ₂ e₂ + r₁ ω_L × e₁ + r₂ (ω_L + r₁ e₁) × e₂ (e₁ turns with the
link, e₂ with the cross between the pins): two linear equations for ṙ, then θ̈ (θ = (α, β))
from ü = ω̇_b × u + ω_b × (ω_b × u) = J_u θ̈ + J̇_u θ̇. The **drive** (:data:`DRIVE`, 12
numbers, frame 0) is what the crane hands the link: the pivot's acceleration a_tip, the
first pin's axis e₁ and the last link's ω_L and ω̇_L (:func:`tip_motion` computes it from q,
q̇, q̈). A three-number drive is a pivot that moves without turning, its first pin about
world y. (The tests check these equations against Lagrange's, derived by CasADi's own
differentiation of the kinetic energy, to machine precision; they are a quarter of the
operations.)

Why it matters (``benchmarks/sway_twin_gap.py``, s100f, 880 kg on 1.5 m, k = 0.3 m, the
Exudyn plant's recorded joints driving the model): with the body not turning with the boom the
model's swing was up to 34 mm from the plant's over a forwarder move and its slew (the load's
spin couples into the swing like a gyroscope); with the pins on the boom 0.2 mm.

Small angles: ω₀ = √(g L / (L² + k²)) (1.5 m, k = 0.3 m: 2.51 rad/s, 0.40 Hz), damping ratio
ζ = c / (2 m √(g L (L² + k²))).

The swing's right-hand side is written once in CasADi (:attr:`Pendulum.f_swing`, a named
``casadi.Function`` an NLP calls on symbols); :meth:`Pendulum.rhs` is its numeric face.
:func:`predict_swing` integrates it (RK4 on a fine grid, one CasADi ``mapaccum`` call) along a
planned trajectory's drive (:func:`tip_motion`: the crane's own forward kinematics
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
from planner.model.kinematics import joint_transforms

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.trajectory import Trajectory

__all__ = ["Pendulum", "SwingPrediction", "predict_swing", "tip_motion", "swing_rhs_expr",
           "STATE", "DRIVE", "DRIVE_SIZE", "as_drive", "pin_axis_joint"]

#: the swing state's entries, in order
STATE = ("alpha", "beta", "alpha_dot", "beta_dot")
#: the drive's entries (three numbers each, frame 0): the pivot's acceleration [m/s²], the
#: first pin's axis (unit), the last link's angular velocity [rad/s] and its rate [rad/s²]
DRIVE = ("a_tip", "pin_axis", "omega_link", "omega_link_dot")
DRIVE_SIZE = 12
#: the first pin's axis of a three-number drive (a pivot that moves without turning)
STILL_AXIS = (0.0, 1.0, 0.0)
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
        """``swing_rhs(x[4], drive[12]) -> xdot[4]``: the swing's ODE (x = α, β, α̇, β̇;
        the drive of :data:`DRIVE`)."""
        x, a = ca.SX.sym("x", 4), ca.SX.sym("drive", DRIVE_SIZE)
        xdot = swing_rhs_expr(x, a, self.length, self.mass, self.gyration, self.damping,
                              self.gravity)
        return ca.Function("swing_rhs", [x, a], [xdot], ["x", "drive"], ["xdot"],
                           {"cse": True})

    def values(self) -> np.ndarray:
        """(length, mass, gyration, damping): the link's data in the order
        :func:`swing_rhs_expr` takes them (a compiled twin's parameter inputs)."""
        return np.array([self.length, self.mass, self.gyration, self.damping], float)

    def rhs(self, x, drive) -> np.ndarray:
        """Numeric face of :attr:`f_swing`: (4,) or (N, 4) states, (12,) or (N, 12) drives
        (:data:`DRIVE`; or (3,) / (N, 3) tip accelerations [m/s²]: :func:`as_drive`) ->
        state derivatives of the same leading shape."""
        x, a = np.asarray(x, float), as_drive(drive)
        single = x.ndim == 1 and a.ndim == 1
        X, A = np.atleast_2d(x), np.atleast_2d(a)
        N = max(len(X), len(A))
        out = np.array(self.f_swing.map(N)(np.broadcast_to(X, (N, 4)).T,
                                            np.broadcast_to(A, (N, DRIVE_SIZE)).T)).T
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

    def energy(self, x, pin_axis=STILL_AXIS) -> np.ndarray:
        """(…,) swing energy [J] in the tip's frame with the tip and the boom at rest: kinetic
        ½ m |ḋ|² + ½ m k² |ω_b|² (ω_b the pin rates', module doc) plus m g (L + d_z) (zero
        hanging at rest); ``pin_axis`` the first pin's (frame 0; it changes the energy by
        the k² share of the spin only: fourth order in the swing angles)."""
        x = np.asarray(x, float)
        a, b, ad, bd = (x[..., i] for i in range(4))
        L, m, k = self.length, self.mass, self.gyration
        u = np.stack(_direction(1.0, a, b), -1)
        # u̇ = ∂u/∂α α̇ + ∂u/∂β β̇
        ua = np.stack([np.zeros_like(a), -np.cos(a) * np.cos(b), np.sin(a) * np.cos(b)], -1)
        ub = np.stack([np.cos(b), np.sin(a) * np.sin(b), np.cos(a) * np.sin(b)], -1)
        ud = ua * ad[..., None] + ub * bd[..., None]
        e1 = np.broadcast_to(np.asarray(pin_axis, float), u.shape)
        e2 = np.cross(u, e1)
        e2 = e2 / np.linalg.norm(e2, axis=-1, keepdims=True)
        A = np.stack([np.cross(e1, u), np.cross(e2, u)], -1)            # (…, 3, 2)
        AtA = np.einsum("...ki,...kj->...ij", A, A)
        r = np.linalg.solve(AtA, np.einsum("...ki,...k->...i", A, ud)[..., None])[..., 0]
        wb = r[..., :1] * e1 + r[..., 1:] * e2
        T = 0.5 * m * (L * L * np.sum(ud * ud, -1) + k * k * np.sum(wb * wb, -1))
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
        """``rk4(x, d0, d_half, d1, dt) -> x⁺``: one RK4 step of :attr:`f_swing` (drives at
        the step's start, middle and end)."""
        if "rk4" not in self._cache:
            x, dt = ca.SX.sym("x", 4), ca.SX.sym("dt")
            a0, ah, a1 = (ca.SX.sym(f"d{i}", DRIVE_SIZE) for i in range(3))
            f = self.f_swing
            k1 = f(x, a0)
            k2 = f(x + 0.5 * dt * k1, ah)
            k3 = f(x + 0.5 * dt * k2, ah)
            k4 = f(x + dt * k3, a1)
            self._cache["rk4"] = ca.Function("swing_rk4", [x, a0, ah, a1, dt],
                                             [x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
        return self._cache["rk4"]

    def integrate(self, t, a_of_t, x0=(0.0, 0.0, 0.0, 0.0)) -> np.ndarray:
        """(K, 4) states at the times ``t`` (K,) [s] from ``x0``, driven by
        ``a_of_t(times) -> (…, 12)`` (the drive, :data:`DRIVE`) or ``(…, 3)`` (the tip's
        acceleration [m/s²] alone, :func:`as_drive`) (RK4 on the steps of ``t``)."""
        t = np.asarray(t, float)
        mid = 0.5 * (t[1:] + t[:-1])
        A = as_drive(a_of_t(t))
        Ah = as_drive(a_of_t(mid))
        K = len(t)
        if K < 2:
            return np.asarray(x0, float)[None, :]
        run = self.step_function().mapaccum(K - 1)
        X = np.array(run(np.asarray(x0, float), A[:-1].T, Ah.T, A[1:].T, np.diff(t)[None, :]))
        return np.vstack([np.asarray(x0, float), X.T])


def as_drive(a) -> np.ndarray:
    """(…, 12) drives from (…, 12) drives or (…, 3) tip accelerations [m/s²]: those get the
    drive of a pivot that moves without turning (pin axis :data:`STILL_AXIS`, ω_L = 0)."""
    a = np.asarray(a, float)
    if a.shape[-1] == DRIVE_SIZE:
        return a
    if a.shape[-1] != 3:
        raise ValueError(f"pendulum drive: {a.shape[-1]} numbers per row; allowed 12 "
                         f"({', '.join(DRIVE)}) or 3 (a_tip)")
    rest = np.zeros(a.shape[:-1] + (DRIVE_SIZE - 3,))
    rest[..., :3] = STILL_AXIS
    return np.concatenate([a, rest], -1)


def _solve2(M, b):
    """The 2×2 system M·x = b in closed form (CasADi expressions)."""
    det = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    return ca.vertcat(M[1, 1] * b[0] - M[0, 1] * b[1], M[0, 0] * b[1] - M[1, 0] * b[0]) / det


def swing_rhs_expr(x, drive, length, mass, gyration, damping, gravity):
    """The swing's ODE as a CasADi expression (the module doc's equations, the one
    definition): state ``x`` (α, β, α̇, β̇), ``drive`` (:data:`DRIVE`: 12, or 3 for a tip
    acceleration alone) and the link's data, numbers or symbols (a compiled twin takes them
    as inputs) -> ẋ (4)."""
    if drive.numel() == 3:
        drive = ca.vertcat(drive, ca.DM(STILL_AXIS), ca.DM.zeros(6))
    th, thd = x[:2], x[2:]
    L, m, k, c = length, mass, gyration, damping
    a, e1, wl, wld = drive[0:3], drive[3:6], drive[6:9], drive[9:12]
    sa, cs_a, sb, cs_b = ca.sin(th[0]), ca.cos(th[0]), ca.sin(th[1]), ca.cos(th[1])
    u = ca.vertcat(sb, -sa * cs_b, -cs_a * cs_b)                 # d / L
    Ju = ca.horzcat(ca.vertcat(0, -cs_a * cs_b, sa * cs_b),      # ∂u/∂α, ∂u/∂β
                    ca.vertcat(cs_b, sa * sb, cs_a * sb))
    ud = Ju @ thd
    e2 = ca.cross(u, e1)
    e2 = e2 / ca.norm_2(e2)
    E = (e1, e2)
    # the pin rates r: u̇ − ω_L × u = r₁ e₁ × u + r₂ e₂ × u
    A = ca.horzcat(ca.cross(e1, u), ca.cross(e2, u))
    r = _solve2(A.T @ A, A.T @ (ud - ca.cross(wl, u)))
    wb = wl + r[0] * e1 + r[1] * e2
    # ω̇_b = w0 + ṙ₁ e₁ + ṙ₂ e₂ (e₁ turns with the link, e₂ with the cross)
    w0 = wld + r[0] * ca.cross(wl, e1) + r[1] * ca.cross(wl + r[0] * e1, e2)

    def inertial(w):     # (k² + L² (1 − u uᵀ)) w: the body's inertia about the pivot / m
        return k * k * w + L * L * (w - ca.dot(u, w) * u)
    rest = (inertial(w0) + L * L * ca.dot(u, wb) * ca.cross(u, wb)
            + L * ca.cross(u, a - ca.vertcat(0, 0, -gravity)))
    Mr = ca.vertcat(*[ca.horzcat(*[ca.dot(E[i], inertial(E[j])) for j in range(2)])
                      for i in range(2)])
    rd = _solve2(Mr, ca.vertcat(*[-c / m * r[i] - ca.dot(E[i], rest) for i in range(2)]))
    wbd = w0 + rd[0] * e1 + rd[1] * e2
    # θ̈ from ü = ω̇_b × u + ω_b × (ω_b × u) = J_u θ̈ + J̇_u θ̇
    udd = ca.cross(wbd, u) + ca.cross(wb, ca.cross(wb, u))
    Jd = ca.horzcat(ca.vertcat(0, sa * cs_b * thd[0] + cs_a * sb * thd[1],
                               cs_a * cs_b * thd[0] - sa * sb * thd[1]),
                    ca.vertcat(-sb * thd[1], cs_a * sb * thd[0] + sa * cs_b * thd[1],
                               -sa * sb * thd[0] + cs_a * cs_b * thd[1]))
    return ca.vertcat(thd, _solve2(Ju.T @ Ju, Ju.T @ (udd - Jd @ thd)))


def pin_axis_joint(crane: Crane) -> int:
    """Index of the joint whose axis the grapple's first pin shares: the first revolute joint
    after the slew (the boom's pitch axis), as the plant hangs it."""
    j = next((i for i in range(1, crane.n) if crane.spec.joints[i].revolute), None)
    if j is None:
        raise ValueError(f"grapple link: {crane.spec.id} has no revolute joint after the first "
                         "(no boom pitch axis to hang the grapple's first pin on)")
    return j


def tip_motion(crane: Crane) -> ca.Function:
    """``tip_motion(q, qd, qdd) -> (p, v, a, drive, axis, omega)``: the tip's Cartesian
    position [m], velocity [m/s] and acceleration [m/s²] in frame 0 (the crane's forward
    kinematics, J q̈ + J̇ q̇), the grapple link's drive (:data:`DRIVE`), and of it the first
    pin's axis and the last link's angular velocity [rad/s] (functions of q, q̇ only)."""
    cache = _TIP_MOTION.setdefault(crane, {})
    if "tip_motion" not in cache:
        n = crane.n
        q, qd, qdd = ca.SX.sym("q", n), ca.SX.sym("qd", n), ca.SX.sym("qdd", n)
        T, R, rots = ca.SX.eye(4), None, []
        for A in joint_transforms(crane.spec, q):
            T = T @ A
            rots.append(T[:3, :3])
        p, R = T[:3, 3], rots[-1]
        J = ca.jacobian(p, q)
        v = J @ qd
        a = J @ qdd + ca.jacobian(v, q) @ qd
        try:                             # the pitch axis: z of the frame before that joint
            axis = rots[pin_axis_joint(crane) - 1][:, 2]
        except ValueError:               # no pitch joint: a pin about world y (still axis)
            axis = ca.SX(ca.DM(STILL_AXIS))
        Rd = ca.reshape(ca.jacobian(ca.reshape(R, 9, 1), q) @ qd, 3, 3)
        W = Rd @ R.T                     # skew(ω_L)
        w = ca.vertcat(W[2, 1], W[0, 2], W[1, 0])
        wd = ca.jacobian(w, ca.vertcat(q, qd)) @ ca.vertcat(qd, qdd)
        cache["tip_motion"] = ca.Function(
            "tip_motion", [q, qd, qdd], [p, v, a, ca.vertcat(a, axis, w, wd), axis, w],
            ["q", "qd", "qdd"], ["p", "v", "a", "drive", "axis", "omega"], {"cse": True})
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
    sample of the plan) with the drive of the crane's kinematics."""
    f = tip_motion(crane)
    fm = {}

    def acc(times):
        q, qd, qdd, _ = traj.sample(times)
        N = len(q)
        if N not in fm:
            fm[N] = f.map(N)
        return np.array(fm[N](q.T, qd.T, qdd.T)[3]).T

    t = traj.resample(rate)
    x = pendulum.integrate(t, acc)
    off = pendulum.offset(x)
    return SwingPrediction(t=t, x=x, offset=off,
                           peak_during_m=float(np.max(np.linalg.norm(off, axis=1))),
                           residual_m=float(pendulum.amplitude(x[-1])), end_state=x[-1])
