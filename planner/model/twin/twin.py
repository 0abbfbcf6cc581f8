"""The dynamic twin of one machine: build once, simulate many command sequences.

>>> twin = Twin(Crane.from_id("s100f"))
>>> run = twin.simulate(t_u, u, q0)          # commands held from t_u, from rest at q0
>>> run.q, run.p_a, run.p_b, run.p_s         # on the integrator's step grid

The right-hand side is :mod:`planner.model.twin.ode` (CasADi, the model's RNEA and valve
physics), the integrator :mod:`planner.model.twin.integrator` (BDF2, Newton on the compiled
Jacobian). The machine's hydraulic data are inputs of the compiled step
(:mod:`planner.model.twin.params`), so the twin of the same rigid bodies with other oil, hoses,
friction, leakage, valve or pump data reuses the same compiled code (built once per process
and rigid-body data, compiled once per user: :func:`planner.model.numeric.jit_function`).

A run starts at rest: the chamber pressures hold the load (the model's load-holding pressures
of :meth:`planner.model.Crane.hydraulics` at zero speed — an equilibrium of the twin), the pump
line at its no-load set pressure, the spools closed. It is bounded like the judge: a
non-finite state, a pressure above 10× relief or a joint 20 % of its range beyond a limit
stops it with ``status`` "diverged" and ``t_fail``.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import hashlib
import math
import time
from dataclasses import dataclass, field

import numpy as np

from planner.model.commands import delayed_steps, held_commands
from planner.model.twin.integrator import Stepper
from planner.model.twin.ode import build_rhs, state_size, unpack
from planner.model.twin.coupled import coupled_stepper
from planner.model.twin.oil import oil_stiffness
from planner.model.twin.params import param_index, twin_params
from planner.model.twin.pendulum import grapple_of

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Twin", "TwinRun"]

_STEPPERS: dict = {}


@dataclass
class TwinRun:
    """A twin run on its step grid ``t`` (K + 1,): joints ``q``, ``qd`` (K + 1, n), chamber
    pressures ``p_a``, ``p_b`` [Pa], pump line ``p_s`` (K + 1,), ``spool`` and the command
    ``u`` in effect at each step (K + 1, n); ``newton`` the scaled size of each step's last
    Newton update; ``status`` "ok" | "diverged" with ``reason`` and ``t_fail``; ``swing``
    (K + 1, 4) the grapple's swing states (α, β, α̇, β̇) when the twin carries the load on
    its link (:mod:`planner.model.twin.coupled`), else None."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    p_a: np.ndarray
    p_b: np.ndarray
    p_s: np.ndarray
    spool: np.ndarray
    u: np.ndarray
    newton: np.ndarray
    status: str = "ok"
    reason: str = ""
    t_fail: float | None = None
    wall_s: float = 0.0
    meta: dict = field(default_factory=dict)
    swing: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def sample(self, t):
        """(q, p_a, p_b, u) at times ``t`` (M,): linear interpolation (u: the command in
        effect)."""
        t = np.asarray(t, float)

        def lin(a):
            return np.column_stack([np.interp(t, self.t, a[:, i]) for i in range(a.shape[1])])
        k = np.clip(np.searchsorted(self.t, t + 1e-9, side="right") - 1, 0, len(self.t) - 1)
        return lin(self.q), lin(self.p_a), lin(self.p_b), self.u[k]


def _stepper(crane: Crane, spec, step, newton, chunk):
    """The compiled step of the rigid bodies of ``spec``: the right-hand side depends on
    nothing else of the machine (its joints and gravity; the hydraulic data are inputs), so
    every crane object with the same bodies — a calibrated spec, a library's copy of the
    spec — shares one."""
    key = (repr(spec.joints), repr(spec.gravity), step, newton, chunk)
    st = _STEPPERS.get(key)
    if st is None:
        fs = build_rhs(crane, spec)
        st = _STEPPERS[key] = (Stepper(fs["rhs"], crane.n, step, newton, chunk,
                                       tau_index=param_index(crane.n, "tau_spool")), fs)
    return st


_POWER: dict = {}   # per process: the compiled pump power of each twin's outputs


class Twin:
    """The dynamic twin of ``crane`` (see the module doc) with ``dynamics`` (default the
    spec's ``[dynamics]``), tip ``payload`` [kg] (default the spec's load + tool), the
    valves-stage data ``gain_scale`` (per-valve factors), ``deadband`` (None: the spec's),
    ``pump_scale`` (factor on the pump's maximum flow), the rigid bodies of ``bodies`` (a
    spec with other masses; default the crane's), integrated with ``step`` [s] and ``newton``
    Newton iterations per step; ``grapple`` (True: the spec's ``[dynamics.grapple]``, a link
    length [m] or a :class:`~planner.model.pendulum.Pendulum`; default none: the payload a
    point mass at the tip) hangs the payload on the grapple link, its swing and the boom's
    motion coupled both ways (:mod:`planner.model.twin.coupled`; four more states)."""

    def __init__(self, crane: Crane, dynamics=None, payload=None, gain_scale=1.0, deadband=None,
                 pump_scale: float = 1.0, bodies=None, step: float = 2e-3, newton: int = 3,
                 chunk: int = 50, grapple=None):
        spec = crane.spec
        dyn = spec.dynamics if dynamics is None else dynamics
        if dyn is None:
            raise ValueError(f"crane '{spec.id}' ({spec.path}): field 'dynamics': missing "
                             "section; the twin needs [dynamics] (bulk_modulus, hose volumes, "
                             "…; see planner/model/dynamics_spec.py)")
        if not (math.isfinite(step) and 0 < step <= 0.01):
            raise ValueError(f"Twin: step = {step!r} s; allowed: 0 < step <= 0.01")
        if not (1 <= int(newton) <= 10):
            raise ValueError(f"Twin: newton = {newton!r}; allowed: 1 .. 10 iterations")
        if spec.transformer is not None and spec.transformer.enabled:
            raise ValueError(f"crane '{spec.id}': field 'transformer.enabled': true; the twin "
                             "does not model the hydraulic transformer")
        self.crane, self.dynamics, self.step = crane, dyn, float(step)
        #: [s] the transport delay from the command to the valves (``[dynamics]
        #: command_delay``): the commands are shifted before the compiled steps see them
        self.delay = float(getattr(dyn, "command_delay", 0.0))
        self.payload = spec.payload.total if payload is None else float(payload)
        self.bodies = spec if bodies is None else bodies
        self.params = twin_params(crane, dyn, self.payload, gain_scale, deadband, pump_scale)
        self.P = self.params.vector()
        self.stepper, fs = _stepper(crane, self.bodies, self.step, int(newton), int(chunk))
        self.f_rhs, self.f_outputs = fs["rhs"], fs["outputs"]
        self._rest_model = None
        self.pendulum = grapple_of(crane, grapple, self.payload)
        if self.pendulum is not None:     # the load on its link: the coupled twin
            self.stepper, self.f_rhs = coupled_stepper(crane, self.bodies, self.step,
                                                       int(newton), int(chunk))
            self.P = np.concatenate([self.P, self.pendulum.values()])

    def at_step(self, step: float) -> "Twin":
        """This twin (the same machine, parameters, payload and grapple) integrated with
        another ``step`` [s]; itself when the step is its own."""
        import copy
        if not (math.isfinite(step) and 0 < step <= 0.01):
            raise ValueError(f"Twin: step = {step!r} s; allowed: 0 < step <= 0.01")
        if float(step) == self.step:
            return self
        tw = copy.copy(self)
        tw.step = float(step)
        newton, chunk = self.stepper.newton, self.stepper.chunk
        tw.stepper, fs = _stepper(self.crane, self.bodies, tw.step, newton, chunk)
        tw.f_rhs = fs["rhs"]
        if self.pendulum is not None:
            tw.stepper, tw.f_rhs = coupled_stepper(self.crane, self.bodies, tw.step, newton,
                                                   chunk)
        return tw

    def with_ls_ramp(self, ramp: float) -> "Twin":
        """This twin with the load-sensing signal ramped over openings up to ``ramp`` (the
        optimisation twin of :mod:`planner.refine`; :mod:`planner.model.twin.ode`); itself for
        0. The compiled functions are shared: the ramp is a parameter."""
        import copy
        from dataclasses import replace
        from planner.model.twin.params import param_index
        if not (math.isfinite(ramp) and 0.0 <= ramp <= 0.1):
            raise ValueError(f"Twin: ls_ramp = {ramp!r}; allowed: 0 .. 0.1 (an opening)")
        if ramp == 0.0:
            return self
        tw = copy.copy(self)
        tw.params = replace(self.params, scalar=dict(self.params.scalar, ls_ramp=float(ramp)))
        tw.P = np.array(self.P, float)
        tw.P[param_index(self.crane.n, "ls_ramp")] = float(ramp)
        return tw

    def pump_power(self):
        """The pump's hydraulic power p_s·Σ q_in [W] and its gradient with respect to the
        state, as a batched compiled function of (x (nx,), P) (:class:`planner.model.numeric.
        Batched`: arrays (K, nx) in, [(K, 1), (K, nx)] out). The meter-in flows depend on the
        pressures and the spools only (states), so a cost on the pump's work has an adjoint."""
        import casadi as ca

        from planner.model.numeric import Batched
        key = (id(self.f_outputs), self.stepper.nx, len(self.P))
        f = _POWER.get(key)
        if f is None:
            n, nx = self.crane.n, self.stepper.nx
            X = ca.SX.sym("x", nx)
            P = ca.SX.sym("P", len(self.P))      # the coupled twin's grapple data follow
            out = self.f_outputs(X[:state_size(n)], ca.DM.zeros(n), ca.DM.zeros(n),
                                 P[:self.f_outputs.size1_in(3)])
            w = X[4 * n] * ca.sum1(out[3])
            f = _POWER[key] = Batched(ca.Function("twin_pump_power", [X, P],
                                                  [w, ca.gradient(w, X)]))
        return f

    def pump_energy(self, run: TwinRun) -> float:
        """The pump's work at the shaft [J] over ``run`` (one of this twin's runs): ∫ p_s·Σ q_in
        dt by the trapezoid on the run's steps, the meter-in flows those of this twin's
        valves (:meth:`pump_power`, what a refinement's price integrates), divided by the
        pump efficiency as ``evaluate().energy_J`` is."""
        X = np.column_stack([run.q, run.qd, run.p_a, run.p_b, run.p_s, run.spool])
        if X.shape[1] < self.stepper.nx:      # the grapple's swing: not in the pump's power
            X = np.hstack([X, np.zeros((X.shape[0], self.stepper.nx - X.shape[1]))])
        w = np.asarray(self.pump_power()(X, np.asarray(self.P, float)[None, :])[0]).ravel()
        work = float(np.sum(0.5 * (w[1:] + w[:-1]) * np.diff(run.t))) if w.size > 1 else 0.0
        return work / self.crane.spec.pump.efficiency

    def provenance(self) -> dict:
        """Which twin this is: the machine, its spec file, a fingerprint (sha256, 16 hex) of
        everything that decides a run (the parameter vector, the rigid bodies, the payload,
        the step and Newton iterations), the step, the bulk modulus and the payload."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.P, float).tobytes())
        h.update(repr(self.bodies.joints).encode())
        h.update(f"{self.payload!r} {self.step!r} {self.stepper.newton}".encode())
        if self.delay > 0:
            h.update(f"delay {self.delay!r}".encode())
        spec = self.crane.spec
        out = dict(model="twin", crane_id=spec.id, spec=str(spec.path or ""),
                   fingerprint=h.hexdigest()[:16], step_s=self.step,
                   bulk_modulus_Pa=float(self.params.scalar["beta"]), payload_kg=self.payload)
        if self.delay > 0:
            out["command_delay_s"] = self.delay
        if self.pendulum is not None:
            pend = self.pendulum
            out["grapple"] = dict(length_m=pend.length, mass_kg=pend.mass,
                                  damping=pend.damping, gyration_m=pend.gyration)
        return out

    # ------------------------------------------------------------------ states
    def bodies_model(self):
        """The quasi-static model of this twin's rigid bodies (the crane, or one built from
        ``bodies``): its load-holding pressures and inverse dynamics."""
        if self._rest_model is None:
            from planner.model import Crane
            self._rest_model = (self.crane if self.bodies is self.crane.spec
                                else Crane(self.bodies))
        return self._rest_model

    def holding_pressures(self, q):
        """Load-holding chamber pressures (p_a, p_b) at rest in ``q`` (n,): the model's
        quasi-static pressures at zero speed, with this twin's bodies and payload."""
        n = self.crane.n
        hy = self.bodies_model().hydraulics(np.asarray(q, float), np.zeros(n), np.zeros(n),
                                      self.payload)
        return np.asarray(hy["p_a"], float), np.asarray(hy["p_b"], float)

    def oil_spring_frequencies(self, q) -> np.ndarray:
        """Each joint's oil-spring frequency [Hz] at rest in ``q`` (n,), its valve closed and
        the other joints held: √(k/M)/2π with k = β·(A_a²/V_a + A_b²/V_b)·(dx/dq)² (the
        chambers' volumes at that stroke, hoses included; the rod side left out for a
        single-acting actuator) and M the mass matrix's diagonal entry (this twin's bodies and
        payload). The slowest one sets how long a move rings: cat215b's swing 0.24 Hz, the
        forwarders' slews 0.84 Hz at mid-range."""
        crane, per, n = self.bodies_model(), self.params.per, self.crane.n
        q = np.asarray(q, float).ravel()
        x, dxdq = (np.asarray(a, float).ravel() for a in crane.stroke(q[None]))
        zero = np.zeros(n)
        g = np.asarray(crane.f_id(q, zero, zero, self.payload), float).ravel()
        M = np.array([float(np.asarray(crane.f_id(q, zero, np.eye(n)[j], self.payload)
                                       ).ravel()[j]) - g[j] for j in range(n)])
        sc = self.params.scalar
        p = sc["beta_pref"]     # the bulk law's reference pressure: β(p) = β
        kab = np.array([np.concatenate(oil_stiffness(per, sc, i, x[i], p, p)) for i in range(n)])
        k = per["area_a"] ** 2 * kab[:, 0] + (1.0 - per["single"]) * per["area_b"] ** 2 * kab[:, 1]
        return np.sqrt(k * dxdq ** 2 / M) / (2.0 * np.pi)

    def rest_pump_pressure(self) -> float:
        """The pump line at rest: the regulator's set pressure with no valve open."""
        s = self.params.scalar
        if s["load_sensing"] > 0.5:
            return float(min(s["standby"], s["p_relief"]))
        return float(s["p_const"])

    def rest_state(self, q0) -> np.ndarray:
        """The state (5n + 1,) at rest in ``q0``: holding pressures, pump at rest, spools
        closed."""
        n = self.crane.n
        q0 = np.asarray(q0, float).ravel()
        p_a, p_b = self.holding_pressures(q0)
        return np.concatenate([q0, np.zeros(n), p_a, p_b, [self.rest_pump_pressure()],
                               np.zeros(n), np.zeros(self.stepper.nx - state_size(n))])

    def rhs(self, x, u, f_x=None) -> np.ndarray:
        """ẋ at state ``x`` (5n + 1,) under commands ``u`` (n,) and extra forces ``f_x``."""
        n = self.crane.n
        fx = np.zeros(n) if f_x is None else f_x
        return np.asarray(self.f_rhs(x, u, fx, self.P), float).ravel()

    # ------------------------------------------------------------------ running
    def simulate(self, t_u, u, q0, t_end: float | None = None, force=None,
                 x0=None, t_start: float | None = None) -> TwinRun:
        """Commands ``u`` (M, n) held from ``t_u`` (M,), from rest at ``q0`` (or from the
        state ``x0``) from ``t_start`` (default t_u[0]; the commands before it are only the
        history the command delay reads) until ``t_end`` (default t_u[-1]).
        ``force(t, q, qd, p_a, p_b) -> (n,)``: an extra actuator force (a load the actuators
        work against) evaluated at the start of every chunk of steps (0.1 s at the defaults)
        and held over it. ``run.u`` holds what the valves saw (after the delay)."""
        wall0 = time.perf_counter()
        n, h = self.crane.n, self.step
        t_u, u, q0, t0, t_end, K = held_commands(t_u, u, q0, n, t_end, h, "Twin.simulate",
                                                 t_start=t_start)
        tk = t0 + h * np.arange(K + 1)
        if self.delay > 0:
            uk = delayed_steps(t_u, u, tk, h, self.delay)
        else:
            j = np.clip(np.searchsorted(t_u, tk + 1e-9 * h, side="right") - 1, 0,
                        t_u.size - 1)
            uk = u[j]
        x_start = self.rest_state(q0) if x0 is None else np.asarray(x0, float)
        fx = np.zeros((K, n))
        if force is None:
            X, err = self.stepper.run(x_start, uk[:K], fx, self.P)
        else:
            C = self.stepper.chunk
            X = np.empty((K + 1, self.stepper.nx))
            err = np.empty(K)
            X[0] = x_start
            prev = None
            for s in range(0, K, C):
                e = min(s + C, K)
                st = unpack(X[s], n)
                fx[s:e] = np.asarray(force(tk[s], st["q"], st["qd"], st["p_a"], st["p_b"]),
                                     float).reshape(n)
                Xc, ec = self.stepper.run(X[s], uk[s:e], fx[s:e], self.P, x_prev=prev)
                X[s + 1:e + 1], err[s:e] = Xc[1:], ec
                prev = X[e - 1]
        run = self._checked(tk, X, uk, err)
        if self.pendulum is not None:
            run.swing = X[:len(run.t), state_size(n):]
        run.wall_s = time.perf_counter() - wall0
        run.meta.update(step=h, steps=K, newton_max=float(np.max(err)) if err.size else 0.0)
        return run

    def _checked(self, tk, X, uk, err) -> TwinRun:
        n = self.crane.n
        L = self.crane.limit_arrays()
        span = L["q_max"] - L["q_min"]
        p_cap = 10.0 * min(self.params.scalar["p_relief"], 1e8)
        q, p = X[:, :n], X[:, 2 * n:4 * n + 1]
        bad = ~np.all(np.isfinite(X), axis=1)
        bad |= np.max(np.abs(np.where(np.isfinite(p), p, 0.0)), axis=1) > p_cap
        bad |= np.any((q < L["q_min"] - 0.2 * span) | (q > L["q_max"] + 0.2 * span), axis=1)
        status, reason, t_fail, K = "ok", "", None, len(tk)
        if np.any(bad):
            k = int(np.argmax(bad))
            xs = X[k]
            why = ("non-finite state" if not np.all(np.isfinite(xs)) else
                   "pressure above 10× relief" if np.max(np.abs(xs[2 * n:4 * n + 1])) > p_cap
                   else "a joint left its range by more than 20 %")
            status, reason, t_fail, K = "diverged", why, float(tk[k]), max(k, 1)
        s = unpack(X[:K].T, n)
        return TwinRun(t=tk[:K], q=s["q"].T, qd=s["qd"].T, p_a=s["p_a"].T, p_b=s["p_b"].T,
                       p_s=np.asarray(s["p_s"]).ravel(), spool=s["spool"].T, u=uk[:K],
                       newton=err[:max(K - 1, 0)], status=status, reason=reason,
                       t_fail=t_fail)
