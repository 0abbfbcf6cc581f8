"""The independent dynamic plant: each machine as an Exudyn multibody system with hydraulic
pressure dynamics, driven open loop by valve commands.

* **Multibody**: an Exudyn ``ObjectKinematicTree`` (minimal coordinates, Exudyn's own
  recursive dynamics) built from the spec's DH chain: joint i turns about (slides along) its
  local z, then the constant part of its DH row follows; link masses, centres of mass and
  inertias are the model's (:func:`planner.model.dynamics.lumped_links`, actuator masses
  lumped as the model lumps them) and the payload is a point mass at the tip — or, with a
  grapple link (``[dynamics.grapple]``, the ``grapple_swing`` effect), hangs on two damped pins
  below it (:mod:`planner.simulation.dynamic.grapple`); gravity acts in −z of frame 0. Nothing of the project's inverse dynamics is used to move the plant.
* **Actuators**: each actuator acts on its joint with the generalised force F·dx/dq (virtual
  work), F from the chamber pressures (:class:`~planner.simulation.dynamic.circuit.Circuit`),
  dx/dq from the spec's mounting geometry (the stroke map of :mod:`planner.model.actuators`:
  cylinder pins, deflection levers, the telescope's chain ratio, a motor's gear, a rack's
  pinion radius). The chamber pressures and the pump pressure are Exudyn ``NodeGenericODE1``
  coordinates of an ``ObjectGenericODE1`` whose right-hand side is the circuit, integrated
  implicitly together with the multibody (generalised-α, Newton on the Jacobian of the whole
  residual, so that it sees the coupling both ways). Both user functions read one evaluation
  of the state's physics (:mod:`planner.simulation.dynamic.fastpath`).
* **Valves**: the commands (after the commands-stage effects: delay, spool lag) drive the
  spools through a first-order lag (``spool_time_constant``), updated exactly once per step.

Bounded: the step count is fixed by the span and the step, the wall time is checked every step
(``max_wall_s``), and non-finite or absurd states (pressure above 10× relief, a joint 20 % of
its range beyond a limit) stop the run; the result then says ``status`` "diverged" or
"timeout" and ``t_fail`` (never a hang, never "ok" on a blown-up state).
"""
from __future__ import annotations

import math
import time as _time
from bisect import bisect_right
from dataclasses import dataclass, field, replace

import numpy as np

from planner.model import Crane
from planner.model.commands import held_commands
from planner.model.effects.hooks import PENDULUM_HOOKS
from planner.model.effects.motion import valve_commands
from planner.simulation.dynamic.bodies import StrokeTable, tree_parameters
from planner.simulation.dynamic.circuit import CONTACT_REFINE, Circuit, PressureBulk
from planner.simulation.dynamic.fastpath import state_function
from planner.simulation.dynamic.grapple import extend_tree, hanging_angles
from planner.simulation.dynamic.interrupt import DeferredInterrupt
from planner.simulation.plants import BasePlant, PlantDiverged, PlantRecord
from planner.simulation.replay import stroke_stops, valve_set

__all__ = ["StrokeTable", "tree_parameters", "DynamicRun", "ExudynPlant", "PlantDiverged"]  # noqa: the first two re-exported


def _aslist(a) -> list:
    return a.tolist() if hasattr(a, "tolist") else list(a)


@dataclass
class DynamicRun:
    """What the dynamic plant did, at every integration step: t (K,), q, qd (K, n), strokes
    x, xd, pressures p_a, p_b (K, n) [Pa], pump pressure p_s (K,), spool positions (K, n),
    commands u (K, n) as commanded; ``status`` "ok" | "diverged" | "timeout", ``t_fail``
    (None when ok), ``reason``; ``wall_s`` the wall time; ``circuit``; ``payload`` [kg];
    with a grapple link, its two pin angles and rates ``grapple_q``, ``grapple_qd`` (K, 2)."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    p_a: np.ndarray
    p_b: np.ndarray
    p_s: np.ndarray
    spool: np.ndarray
    u: np.ndarray
    circuit: Circuit
    payload: float
    status: str = "ok"
    t_fail: float | None = None
    reason: str = ""
    wall_s: float = 0.0
    meta: dict = field(default_factory=dict)
    grapple_q: np.ndarray | None = None
    grapple_qd: np.ndarray | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def sample(self, t):
        """(q, p_a, p_b, u) interpolated linearly at times t (M,) (u: the command in effect)."""
        t = np.asarray(t, float)

        def lin(a):
            return np.column_stack([np.interp(t, self.t, a[:, i]) for i in range(a.shape[1])])
        k = np.clip(np.searchsorted(self.t, t + 1e-9, side="right") - 1, 0, len(self.t) - 1)
        return lin(self.q), lin(self.p_a), lin(self.p_b), self.u[k]


class ExudynPlant(BasePlant):
    """One machine as an Exudyn model (see the module doc), with the physical counterparts of
    ``effects`` (a sequence of :class:`planner.model.effects.Effect`, after the spec's own
    calibrated ones), each through the hooks it declares (:mod:`planner.model.effects.hooks`):
    ``payload`` (tip mass), ``bodies`` (e.g. a heavier actuator, lumped as the model lumps
    it), ``dynamics`` (the ``[dynamics]`` data: bulk modulus, hose volumes, friction, leakage,
    the grapple link), ``valves`` (flow gains, dead bands, pump limit), ``commands`` (delay,
    spool lag before the plant's own spool), ``start``, ``force`` (an extra actuator force
    with no physical data, evaluated at the start of each step and held over it) and the
    sensors (``sense_q_at`` / ``sense_p_at``, on the output: :meth:`sense`). An effect with
    none of these (a bare stroke drift) is refused by name. ``dynamics`` overrides the spec's
    ``[dynamics]``; ``step`` is the fixed integration step [s]. ``bulk``: a
    :class:`~planner.simulation.dynamic.circuit.PressureBulk` makes the oil's bulk modulus rise
    with pressure (a physical effect the twin does not model; None, the default: constant β)."""
    name = "exudyn"
    description = ("Exudyn multibody + chamber-pressure dynamics, its own circuit code (the "
                   "independent judge)")
    hooks = PENDULUM_HOOKS
    physical_first = True

    def __init__(self, crane: Crane, effects=(), dynamics=None, step: float = 2e-3,
                 bulk: PressureBulk | None = None):
        spec = crane.spec
        dyn = dynamics if dynamics is not None else spec.dynamics
        if dyn is None:
            raise ValueError(f"crane '{spec.id}' ({spec.path}): field 'dynamics': missing "
                             "section; the Exudyn plant needs [dynamics] (bulk_modulus, hose "
                             "volumes, …; see planner/model/dynamics_spec.py)")
        if not (step > 0 and math.isfinite(step) and step <= 0.01):
            raise ValueError(f"ExudynPlant: step = {step!r} s; allowed: 0 < step <= 0.01")
        if spec.transformer is not None and spec.transformer.enabled:
            raise ValueError(f"crane '{spec.id}': field 'transformer.enabled': true; the "
                             "dynamic plant does not model the hydraulic transformer")
        self.crane, self.step = crane, float(step)
        self._take_effects(crane, effects)
        for e in self.acting("dynamics"):   # the oil, hoses, friction, leakage
            dyn = e.dynamics(crane, dyn)
        for e in self.acting("grapple"):    # the link the grapple swings on
            dyn = e.grapple(crane, dyn)
        self.dyn = dyn
        payload = spec.payload.total
        for e in self.acting("payload"):
            payload = e.payload(crane, payload)
        self.payload = payload
        true_spec = spec
        for e in self.acting("bodies"):
            true_spec = e.bodies(crane, true_spec)
        #: the rigid-body truth's own model (for initial pressures and energies only)
        self.true_crane = crane if true_spec is spec else Crane(true_spec)
        #: effects whose extra force (no physical data) is added at each step
        self.extra_forces = self.acting("force")
        jd = [dyn.joints[j.name] for j in spec.joints]
        vs = valve_set(crane, self.acting("valves"))
        self.stops = stroke_stops(crane)
        self.circuit = replace(Circuit.from_crane(crane, dyn, self.stops, vs.flow_gain_scale,
                                                  vs.deadband, vs.pump_flow_scale,
                                                  np.array([d.leakage for d in jd])),
                               coulomb=np.array([d.coulomb for d in jd]),
                               viscous=np.array([d.viscous for d in jd]))
        if bulk is None and (dyn.bulk_low != 1.0 or dyn.bulk_high != 1.0):
            # the spec's own [dynamics] pressure law (a calibrated machine's), in this plant's
            # own circuit code
            bulk = PressureBulk(p_ref=dyn.bulk_reference_pressure, p_abs=1.0e5,
                                lo=dyn.bulk_low, hi=dyn.bulk_high)
        if bulk is not None:
            if not isinstance(bulk, PressureBulk):
                raise ValueError(f"ExudynPlant: bulk = {bulk!r}; allowed: None or a "
                                 "PressureBulk")
            self.circuit = replace(self.circuit, bulk=bulk)
        self.tree = (tree_parameters(true_spec, payload) if dyn.grapple is None else
                     extend_tree(tree_parameters(true_spec, 0.0), payload, dyn.grapple))
        self.strokes = StrokeTable(crane)

    # ------------------------------------------------------------------ the model
    def _build(self, q0, p0):
        import exudyn as exu
        from exudyn.itemInterface import (NodeGenericODE1, NodeGenericODE2, ObjectGenericODE1,
                                          ObjectKinematicTree)
        n = self.crane.n
        T = self.tree
        m = len(T["types"])             # n, or n + 2 with the grapple's pins
        c_pin = T["grapple"].damping if m > n else 0.0
        jt = {"revolute": exu.JointType.RevoluteZ, "prismatic": exu.JointType.PrismaticZ}
        SC = exu.SystemContainer()
        mbs = SC.AddSystem()
        node = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.0] * m,
                                           initialCoordinates=list(map(float, q0)),
                                           initialCoordinates_t=[0.0] * m,
                                           numberOfODE2Coordinates=m))
        hnode = mbs.AddNode(NodeGenericODE1(referenceCoordinates=[0.0] * (2 * n + 1),
                                            initialCoordinates=list(map(float, p0)),
                                            numberOfODE1Coordinates=2 * n + 1))
        coords = exu.OutputVariableType.Coordinates
        coords_t = exu.OutputVariableType.Coordinates_t
        state = self._state
        evaluate = state_function(self.circuit, self.strokes)
        # both halves of the coupled system at one state in one evaluation: the engine asks
        # for the joint forces and for the pressure rates at the same state (each residual,
        # each Jacobian column), so the second callback finds the first one's result
        last = state["last"] = [None, None, None, None, None]

        def both(q, qd, p):
            # evaluate subtracts an effect's extra force: a load the actuator works against
            # (as in the quasi-static plant, where the actuator must supply it)
            tau, pdot = evaluate(q, qd, p, state["o"], state["extra"])
            if m > n:                   # the grapple's pins: damped
                tau += [-c_pin * w for w in qd[n:]]
            last[:] = q, qd, p, tau, pdot
            return tau, pdot

        def force(mbs_, t, item, q, q_t):
            p = mbs_.GetNodeOutput(hnode, coords).tolist()
            q, q_t = _aslist(q), _aslist(q_t)
            if p == last[2] and q == last[0] and q_t == last[1]:
                return last[3]
            return both(q, q_t, p)[0]

        def rhs(mbs_, t, item, p):
            q = mbs_.GetNodeOutput(node, coords).tolist()
            qd = mbs_.GetNodeOutput(node, coords_t).tolist()
            p = _aslist(p)
            if p == last[2] and q == last[0] and qd == last[1]:
                return last[4]
            return both(q, qd, p)[1]

        tree = mbs.AddObject(ObjectKinematicTree(
            nodeNumber=node, jointTypes=[jt[k] for k in T["types"]],
            linkParents=list(range(-1, m - 1)),
            jointTransformations=exu.Matrix3DList([h[:3, :3] for h in T["hts"]]),
            jointOffsets=exu.Vector3DList([h[:3, 3] for h in T["hts"]]),
            linkInertiasCOM=exu.Matrix3DList(T["inertias"]),
            linkCOMs=exu.Vector3DList(T["coms"]), linkMasses=T["masses"],
            gravity=[0.0, 0.0, -self.crane.spec.gravity], forceUserFunction=force))
        mbs.AddObject(ObjectGenericODE1(nodeNumbers=[hnode], rhsUserFunction=rhs))
        return exu, SC, mbs, node, hnode, tree

    def _extra_force(self, t, q, qd, p, k):
        """The ``force`` hooks of effects without physical data at the state of step k
        (held over the step; qdd from the last two steps' rates)."""
        from planner.simulation.plant import PlantState
        n, crane = self.crane.n, self.crane
        q, qd = np.array(q[:n], float)[None], np.array(qd[:n], float)[None]
        prev = self._state.get("qd_prev")
        qdd = np.zeros_like(qd) if prev is None else (qd - prev) / self._state["h"]
        self._state["qd_prev"] = qd
        x, d = self.strokes.batch(q)
        Fm = np.atleast_2d(self.true_crane.inverse_dynamics(q, qd, qdd, self.payload)) / d
        s = PlantState(crane, np.array([t]), q, qd, qdd, x, d * qd, Fm, self.payload,
                       force=Fm, p_a=np.array(p[:n], float)[None],
                       p_b=np.array(p[n:2 * n], float)[None])
        return sum(np.atleast_2d(e.force(crane, s))[0] for e in self.extra_forces)

    def initial_pressures(self, q0):
        """Load-holding chamber pressures at rest in q0 (the model's inverse dynamics of the
        true masses and payload): the state the plant starts from."""
        tau = self.true_crane.inverse_dynamics(q0, np.zeros(self.crane.n),
                                               np.zeros(self.crane.n), self.payload)
        return self.circuit.initial_pressures(tau / np.array(self.strokes(q0)[1]))

    # ------------------------------------------------------------------ running
    def integrate(self, t_u, u, q0, t_end: float | None = None, max_wall_s: float = 600.0,
                  spectral_radius: float = 0.9, controller=None) -> DynamicRun:
        """Replay commands ``u`` (M, n), each held from ``t_u[k]`` (zero-order hold), from
        rest at ``q0`` (start effects applied) until ``t_end`` (default t_u[-1]). Returns a
        :class:`DynamicRun` (its status says whether it finished).

        ``controller(t, q, qd, p_a, p_b) -> u`` (n,): closed loop instead — called at every
        control instant ``t_u[k]`` with the plant's state (true joints, chamber pressures) and
        its command held until the next instant (``u`` then only gives the shape; the
        commands-stage effects do not apply).

        When the engine's Newton iteration fails (not the plant's own checks), the run is
        repeated with half the step, twice at most: a starving pump or a stop hit at speed is
        stiffer than the default step resolves (``meta["step"]`` says which step ran); a run that
        reaches an end stop, at 1/``CONTACT_REFINE`` of it (``meta["stop_contact"]``)."""
        wall0 = _time.perf_counter()
        # Ctrl-C only asks while the engine runs (it swallows a KeyboardInterrupt raised in a
        # user function): the next step stops the run, KeyboardInterrupt follows it
        with DeferredInterrupt() as stop:
            for halvings in range(3):
                run = self._integrate(self.step / 2 ** halvings, t_u, u, q0, t_end,
                                      max_wall_s - (_time.perf_counter() - wall0),
                                      spectral_radius, controller, stop)
                if run.ok or not run.meta.get("engine_failed") or stop.requested:
                    break
            if not stop.requested and self.circuit.on_a_stop(run.x, run.xd):  # CONTACT_REFINE
                fine = self._integrate(self.step / CONTACT_REFINE, t_u, u, q0, t_end,
                                       max_wall_s - (_time.perf_counter() - wall0),
                                       spectral_radius, controller, stop)
                fine.meta["stop_contact"] = True
                run = fine if fine.ok or not run.ok else run
        run.wall_s = _time.perf_counter() - wall0
        return run

    def _integrate(self, h, t_u, u, q0, t_end, max_wall_s, spectral_radius, controller,
                   stop=None):
        crane, n = self.crane, self.crane.n
        t_u, u, q0, t0, t_end, K = held_commands(t_u, u, q0, n, t_end, h, "ExudynPlant.run")
        # the commands-stage effects, then the machine's own [dynamics] command_delay
        t_u, u, u_valves = valve_commands(crane, self.acting("commands"), t_u, u, t_end,
                                          self.dyn.command_delay)
        L = crane.limit_arrays()
        for e in self.acting("start"):
            q0 = e.start(crane, q0)
        q0 = np.clip(q0, L["q_min"], L["q_max"])
        pa0, pb0 = self.initial_pressures(q0)
        C = self.circuit
        ps0 = float(C.pump_setpoint(np.zeros(n)))
        self._state = state = {"o": [0.0] * n, "extra": [0.0] * n, "h": h}
        m = len(self.tree["types"])     # the crane's joints, then the grapple's pins if any
        q0_tree = np.concatenate([q0, hanging_angles(self.tree, q0) if m > n else []])
        exu, SC, mbs, node, hnode, _ = self._build(q0_tree, np.concatenate([pa0, pb0, [ps0]]))
        rec = {k: np.full((K + 1, n), np.nan) for k in ("p_a", "p_b", "spool", "u")}
        rec["q"], rec["qd"] = np.full((K + 1, m), np.nan), np.full((K + 1, m), np.nan)
        rec["t"] = t0 + h * np.arange(K + 1)
        rec["p_s"] = np.full(K + 1, np.nan)
        spool = [0.0] * n
        decay = math.exp(-h / self.dyn.spool_time_constant)
        span = L["q_max"] - L["q_min"]
        p_cap = 10.0 * min(C.p_relief, 1e8)
        wall0 = _time.perf_counter()
        fail = {}
        coords = exu.OutputVariableType.Coordinates

        def record(k):
            q = mbs.GetNodeOutput(node, coords)
            qd = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates_t)
            p = mbs.GetNodeOutput(hnode, coords)
            rec["q"][k], rec["qd"][k] = q, qd
            rec["p_a"][k], rec["p_b"][k], rec["p_s"][k] = p[:n], p[n:2 * n], p[2 * n]
            return q[:n], qd[:n], p

        # the per-step checks and the spool in plain Python on lists (numpy's per-call
        # overhead on n-vectors would cost more than the step's physics)
        t_list, u_list, u_rows = t_u.tolist(), u_valves.tolist(), u
        q_low = (L["q_min"] - 0.2 * span).tolist()
        q_high = (L["q_max"] + 0.2 * span).tolist()
        deadband = C.deadband.tolist()
        isfinite = math.isfinite
        cache = state["last"]

        def pre_step(mbs_, t):
            if stop is not None and stop.requested:     # Ctrl-C (see integrate)
                return False
            # the engine passes the time at the end of the coming step; the state is the
            # state at its start
            k = int(round((t - t0) / h)) - 1
            if k < 0 or k > K:
                return True
            t = t0 + k * h
            q, qd, p = record(k)
            j = max(bisect_right(t_list, t + 1e-9 * h) - 1, 0)
            if controller is not None and state.get("j") != j:
                state["j"] = j
                state["u"] = np.asarray(controller(t, np.array(q), np.array(qd),
                                                   np.array(p[:n]), np.array(p[n:2 * n])),
                                        float).reshape(n)
            cmd = u_list[j] if controller is None else state["u"].tolist()
            rec["u"][k] = u_rows[j] if controller is None else cmd
            rec["spool"][k] = spool
            ql, pl = q[:n].tolist(), p.tolist()
            bad = None
            if not all(map(isfinite, ql + qd[:n].tolist() + pl + cmd)):
                bad = "non-finite state"
            elif max(map(abs, pl)) > p_cap:
                bad = f"pressure {max(map(abs, pl)):.3g} Pa above 10× relief"
            elif any(a < lo or a > hi for a, lo, hi in zip(ql, q_low, q_high)):
                bad = "a joint left its range by more than 20 %"
            elif _time.perf_counter() - wall0 > max_wall_s:
                fail.update(status="timeout", t=t, reason=f"wall time above {max_wall_s:g} s")
                return False
            if bad:
                fail.update(status="diverged", t=t, reason=bad, checked=True)
                return False
            # spool: first-order lag towards the held (delayed, lagged) command, exact step;
            # the opening without the dead band (Circuit.opening)
            o = []
            for i in range(n):
                c = -1.0 if cmd[i] < -1.0 else (1.0 if cmd[i] > 1.0 else cmd[i])
                spool[i] = c + (spool[i] - c) * decay
                v = -1.0 if spool[i] < -1.0 else (1.0 if spool[i] > 1.0 else spool[i])
                w = abs(v) - deadband[i]
                o.append(0.0 if w <= 0.0 or v == 0.0 else
                         math.copysign(w / (1.0 - deadband[i]), v))
            state["o"] = o
            if self.extra_forces:
                state["extra"] = self._extra_force(t, q, qd, p, k).tolist()
            cache[2] = None         # the inputs changed: no evaluation of the last step holds
            return True

        mbs.SetPreStepUserFunction(pre_step)
        mbs.Assemble()
        s = exu.SimulationSettings()
        ti = s.timeIntegration
        ti.numberOfSteps, ti.startTime, ti.endTime = K, t0, t0 + K * h
        ti.verboseMode = 0
        ti.adaptiveStep = False
        ti.newton.useModifiedNewton = True
        ti.newton.maxIterations = 40
        ti.newton.relativeTolerance = 1e-8
        ti.newton.absoluteTolerance = 1e-6
        ti.newton.numericalDifferentiation.minimumCoordinateSize = 1
        # the Jacobian of the whole residual (joints and pressures together): the engine's
        # per-object Jacobians miss the coupling (pressures -> joint forces, joint motion ->
        # pressure rates), which left Newton converging linearly (6.5 iterations per step on
        # bench_exudyn_speed's recording instead of 3.3); it is kept over steps and renewed
        # when an iteration shrinks the error by less than 5×
        ti.newton.numericalDifferentiation.doSystemWideDifferentiation = True
        ti.newton.modifiedNewtonContractivity = 0.2
        ti.generalizedAlpha.spectralRadius = spectral_radius
        s.solution.file.write = False
        exu.SetWriteToConsole(False)    # the engine's banners would corrupt --json -
        try:
            ok = mbs.SolveDynamic(s, showHints=False)
        except Exception as e:          # the engine's own failure (Newton, singular matrix)
            last = np.flatnonzero(np.isfinite(rec["p_s"]))
            ok, fail = False, fail or dict(status="diverged", t=float(rec["t"][last[-1]])
                                           if last.size else t0, reason=str(e)[:200])
        finally:
            exu.SetWriteToConsole(True)
        if not fail and ok is False:
            last = np.flatnonzero(np.isfinite(rec["p_s"]))
            fail = dict(status="diverged", t=float(rec["t"][last[-1]]) if last.size else t0,
                        reason="the integrator did not converge")
        engine = bool(fail) and fail.get("status") == "diverged" and "reason" in fail and (
            ok is False and not fail.get("checked"))
        if engine:
            fail["reason"] = self._engine_failure(rec, h, fail["reason"])
        if not fail:
            record(K)
            rec["u"][K] = rec["u"][K - 1]
            rec["spool"][K] = spool
        good = np.isfinite(rec["p_s"])
        rec = {k: v[good] for k, v in rec.items()}
        pins = dict(grapple_q=rec["q"][:, n:], grapple_qd=rec["qd"][:, n:]) if m > n else {}
        rec["q"], rec["qd"] = rec["q"][:, :n], rec["qd"][:, :n]
        x, d = self.strokes.batch(rec["q"])
        return DynamicRun(t=rec["t"], q=rec["q"], qd=rec["qd"], x=x, xd=d * rec["qd"], **pins,
                          p_a=rec["p_a"], p_b=rec["p_b"], p_s=rec["p_s"], spool=rec["spool"],
                          u=rec["u"], circuit=C, payload=self.payload,
                          status=fail.get("status", "ok"), t_fail=fail.get("t"),
                          reason=fail.get("reason", ""), wall_s=_time.perf_counter() - wall0,
                          meta=dict(step=h, steps=K, engine_failed=engine))

    def _engine_failure(self, rec, h, what: str) -> str:
        """The reason of an engine failure with what the plant was doing: the joints on or
        near a stroke end and the pump-line pressure at the last recorded step."""
        last = np.flatnonzero(np.isfinite(rec["p_s"]))
        if not last.size:
            return f"{what} (at the first step of {h:g} s)"
        k = last[-1]
        x, _ = self.strokes.batch(rec["q"][k:k + 1, :self.crane.n])
        lo, hi = self.circuit.x_lo, self.circuit.x_hi
        near = [f"{j} ({'lower' if abs(x[0, i] - lo[i]) < abs(x[0, i] - hi[i]) else 'upper'})"
                for i, j in enumerate(self.crane.names)
                if not self.circuit.motor[i]
                and min(abs(x[0, i] - lo[i]), abs(x[0, i] - hi[i])) < 1e-3]
        return (f"{what}: the integrator's Newton iteration failed with a step of {h:g} s; "
                f"joints at a stroke end: {', '.join(near) or 'none'}; pump line "
                f"{rec['p_s'][k] / 1e6:.2f} MPa")

    def run(self, t_u, u, q0, t_end: float | None = None, rate: float | None = None,
            **kw) -> PlantRecord:
        """The plant interface (:class:`planner.simulation.plants.BasePlant`):
        :meth:`integrate`, sampled at ``rate`` [Hz] (default: the command grid) and read
        through the sensors (:meth:`sense`). ``kw``: :meth:`integrate`'s options."""
        run = self.integrate(t_u, u, q0, t_end=t_end, **kw)
        t_u = np.asarray(t_u, float)
        dt = (1.0 / float(rate) if rate is not None else
              float(np.median(np.diff(t_u))) if t_u.size > 1 else 0.02)
        t = t_u[0] + dt * np.arange(int(np.floor((run.t[-1] - t_u[0]) / dt + 1e-9)) + 1)
        q, p_a, p_b, u_s = run.sample(t)
        q_s, pa_s, pb_s = self.sense(q, p_a, p_b, t)
        return PlantRecord(t, u_s, q_s, pa_s, pb_s, q, p_a, p_b, plant=self.name,
                           status=run.status, reason=run.reason, t_fail=run.t_fail,
                           meta=dict(run.meta, run=run, wall_s=run.wall_s))

    def pump_energy(self, rec: PlantRecord) -> float:
        """The pump's energy at the shaft [J] of a :meth:`run` (its energy balance's
        ``pump_shaft_J``: ∫ p_s·ΣQ_in dt plus the pump line's stored energy, over η)."""
        from planner.simulation.dynamic.energy import energy_balance
        return energy_balance(self, rec.meta["run"])["pump_shaft_J"]

    def sense(self, q, p_a, p_b, t=None):
        """What the transducers report at the sample times ``t`` (N,) [s] (the sensor
        effects: offsets, gains, drifts counted from the first sample). Without ``t`` a
        time-dependent sensor effect is refused (it would silently read as constant)."""
        q, p_a, p_b = (np.atleast_2d(np.asarray(a, float)) for a in (q, p_a, p_b))
        sensors = [e for e in self.effects
                   if {"sense_q_at", "sense_p_at"} & set(self.applied[e])]
        if t is None:
            timed = [e.name for e in sensors if {"sense_q_at", "sense_p_at"}
                     & set(vars(type(e)))]
            if timed:
                raise ValueError(f"ExudynPlant.sense: effect {timed[0]} changes with time; "
                                 "give the sample times t")
            t = np.zeros(len(q))
        t = np.asarray(t, float).ravel()
        for e in sensors:
            q = e.sense_q_at(self.crane, t, q)
            p_a, p_b = e.sense_p_at(self.crane, t, p_a, p_b)
        return q, p_a, p_b
