"""The ``twin`` plant: the model's dynamic twin (:mod:`planner.model.twin`) behind the plant
interface (:class:`planner.simulation.plants.BasePlant`).

Effects act through the hooks of a dynamic plant (:data:`~planner.model.effects.hooks.
DYNAMIC_HOOKS`), physical data first, exactly as the Exudyn plant applies them:
``dynamics`` (bulk modulus, hose volumes, friction, leakage), ``bodies`` (other masses: the
twin's rigid bodies are rebuilt from that spec), ``payload``, ``valves`` (flow gains, dead
bands, pump limit: inputs of the compiled step), ``commands`` (what the valves see), ``start``,
``force`` (an extra actuator force with no physical data, evaluated at the start of every
0.1 s chunk of steps and held over it) and the sensors on the output. The grapple pendulum
is not in the twin: it carries the grapple as a point mass at the tip, so it does not call
the ``grapple`` hook (the ``grapple_swing`` effect is refused by name, like every effect a
plant has no hook for) and refuses a spec with its own ``[dynamics.grapple]``.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.model.effects.hooks import DYNAMIC_HOOKS
from planner.model.effects.motion import valve_commands
from planner.model.twin import Twin
from planner.simulation.plants import BasePlant, PlantRecord
from planner.simulation.replay import valve_set

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["TwinPlant", "twin_of", "CARRIED"]

#: the hooks a bare :class:`~planner.model.twin.Twin` carries (its data); the others act in
#: :meth:`TwinPlant.run` around it
CARRIED = ("valves", "payload", "bodies", "dynamics", "sense_q_at", "sense_p_at")


class TwinPlant(BasePlant):
    """The dynamic twin of ``crane`` with ``effects`` (see the module doc); ``dynamics``
    overrides the spec's ``[dynamics]``, ``step`` is the integrator's fixed step [s]."""
    name = "twin"
    description = ("the model's dynamic twin: RNEA + chamber pressures, valves and pump in "
                   "CasADi, compiled BDF2")
    hooks = DYNAMIC_HOOKS
    physical_first = True

    def __init__(self, crane: Crane, effects=(), dynamics=None, step: float = 2e-3):
        spec = crane.spec
        self.crane = crane
        self._take_effects(crane, effects)
        dyn = dynamics if dynamics is not None else spec.dynamics
        if dyn is None:
            raise ValueError(f"crane '{spec.id}' ({spec.path}): field 'dynamics': missing "
                             "section; the twin plant needs [dynamics] (bulk_modulus, hose "
                             "volumes, …; see planner/model/dynamics_spec.py)")
        for e in self.acting("dynamics"):
            dyn = e.dynamics(crane, dyn)
        if dyn.grapple is not None:   # the spec's own [dynamics.grapple]
            raise ValueError(f"crane '{spec.id}': field 'dynamics.grapple': the twin plant "
                             "carries the grapple as a point mass at the tip (its pendulum is "
                             "not modelled); simulate a hanging grapple with the exudyn plant")
        payload = spec.payload.total
        for e in self.acting("payload"):
            payload = e.payload(crane, payload)
        bodies = spec
        for e in self.acting("bodies"):
            bodies = e.bodies(crane, bodies)
        vs = valve_set(crane, self.acting("valves"))
        self.extra_forces = self.acting("force")
        self.twin = Twin(crane, dynamics=dyn, payload=payload, gain_scale=vs.flow_gain_scale,
                         deadband=vs.deadband, pump_scale=vs.pump_flow_scale, bodies=bodies,
                         step=step)

    def _force(self, t, q, qd, p_a, p_b):
        """The ``force`` hooks of effects without physical data at one state."""
        from planner.simulation.plant import PlantState
        crane = self.crane
        q, qd = q[None], qd[None]
        x, d = crane.stroke(q)
        Fm = np.atleast_2d(self.twin.bodies_model().inverse_dynamics(q, qd, np.zeros_like(qd),
                                                               self.twin.payload)) / d
        s = PlantState(crane, np.array([t]), q, qd, np.zeros_like(qd), x, d * qd, Fm,
                       self.twin.payload, force=Fm, p_a=p_a[None], p_b=p_b[None])
        return sum(np.atleast_2d(e.force(crane, s))[0] for e in self.extra_forces)

    def run(self, t_u, u, q0, t_end=None, rate=None) -> PlantRecord:
        crane = self.crane
        t_u = np.asarray(t_u, float).ravel()
        u = np.atleast_2d(np.asarray(u, float))
        dt = (1.0 / float(rate) if rate is not None else
              float(np.median(np.diff(t_u))) if t_u.size > 1 else 0.02)
        t0 = float(t_u[0])
        t_u, u, u_valves = valve_commands(crane, self.acting("commands"), t_u, u,
                                          t_u[-1] if t_end is None else float(t_end))
        q0 = np.asarray(q0, float).ravel()
        for e in self.acting("start"):
            q0 = e.start(crane, q0)
        L = crane.limit_arrays()
        q0 = np.clip(q0, L["q_min"], L["q_max"])
        run = self.twin.simulate(t_u, u_valves, q0, t_end=t_end,
                                 force=self._force if self.extra_forces else None)
        t = t0 + dt * np.arange(int(np.floor((run.t[-1] - t_u[0]) / dt + 1e-9)) + 1)
        q, p_a, p_b, _ = run.sample(t)
        k = np.clip(np.searchsorted(t_u, t + 1e-9, side="right") - 1, 0, len(t_u) - 1)
        q_s, pa_s, pb_s = self.sense(q, p_a, p_b, t)
        return PlantRecord(t, u[k], q_s, pa_s, pb_s, q, p_a, p_b, plant=self.name,
                           status=run.status, reason=run.reason, t_fail=run.t_fail,
                           meta=dict(run.meta, run=run, wall_s=run.wall_s))

    def sense(self, q, p_a, p_b, t):
        """What the transducers report at the sample times ``t`` (the sensor effects)."""
        for e in self.effects:
            if {"sense_q_at", "sense_p_at"} & set(self.applied[e]):
                q = e.sense_q_at(self.crane, t, q)
                p_a, p_b = e.sense_p_at(self.crane, t, p_a, p_b)
        return q, p_a, p_b


def twin_of(crane: Crane, step: float = 2e-3) -> Twin:
    """The twin of ``crane`` with the spec's own ``[[effects]]`` (a model written by
    ``discrepancy --save-model``) applied, for work on the bare twin (the feed-forward
    refinement): effects on the machine's data (valves, payload, bodies, dynamics) are carried;
    sensor effects change only what is measured, not the motion the commands are refined
    for; an effect acting on the command signal, the start or as an extra force is refused by
    name (ValueError), never dropped."""
    if not crane.spec.effects:
        return Twin(crane, step=step)
    plant = TwinPlant(crane, step=step)
    for e in plant.effects:
        extra = [h for h in plant.applied[e] if h not in CARRIED]
        if extra:
            raise ValueError(f"crane '{crane.spec.id}': effects: '{e.name}' acts through "
                             f"{', '.join(extra)}, which the refinement's bare twin does not "
                             f"carry; allowed: effects on {', '.join(CARRIED[:4])}")
    return plant.twin
