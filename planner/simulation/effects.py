"""The catalogue of effects a nominal crane model can miss (DESIGN "Core ideas" 3).

Each effect is a small immutable object: a ``name``, a ``description`` of its physical meaning,
the ``signature`` it leaves in the residual (measured − simulated; seed 001's table), its
``parameters`` (unit, plausible range) and, when it belongs to one actuator, the ``joint``. The
same object is injected into the "true" plant (:func:`planner.simulation.plant.respond`) and fitted to data
by :mod:`planner.calibration.discrepancy` — one definition serves injection and identification.

An effect acts at one stage of the plant (the hooks below; the default hooks do nothing):

===========  ==================================================================================
commands     what the valves see of the command signal (time_delay, valve_lag)
valves       valve and pump parameters of the replay (flow_gain, valve_deadband,
             pump_flow_limit)
forces       extra actuator force or load (coulomb_friction, viscous_friction, payload_mass,
             actuator_mass)
strokes      extra stroke motion driven by pressure (leakage)
sensors      what the transducers report (joint_offset, pressure_offset)
===========  ==================================================================================

Parse the CLI form with :func:`parse_effect` (``"flow_gain:joint=boom,scale=1.05"``) and list
the catalogue with :func:`catalogue`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Parameter", "Effect", "CATALOGUE", "catalogue", "make", "parse_effect",
           "effect_from_dict"]


@dataclass(frozen=True)
class Parameter:
    name: str
    unit: str
    low: float          # plausible range (also the bounds when the effect is fitted)
    high: float
    neutral: float      # the value at which the effect vanishes
    description: str = ""


class Effect:
    """Base class: subclasses set the class attributes and override the hooks they need."""
    name = ""
    description = ""
    signature = ""
    parameters: tuple[Parameter, ...] = ()
    per_joint = False
    stage = ""
    acts_on = ""        # "positions", "pressures" or "positions and pressures"

    def __init__(self, joint: str | None = None, **values):
        if self.per_joint and joint is None:
            raise ValueError(f"effect {self.name}: needs joint=<joint name>")
        if not self.per_joint and joint is not None:
            raise ValueError(f"effect {self.name}: acts on the whole machine, takes no joint "
                             f"(got joint={joint!r})")
        known = {p.name for p in self.parameters}
        unknown = set(values) - known
        if unknown:
            raise ValueError(f"effect {self.name}: unknown parameter(s) {sorted(unknown)}; "
                             f"allowed: {', '.join(sorted(known)) or 'none'}"
                             + (", joint" if self.per_joint else ""))
        vals = []
        for p in self.parameters:
            v = float(values.get(p.name, p.neutral))
            if not (math.isfinite(v) and p.low <= v <= p.high):
                raise ValueError(f"effect {self.name}: {p.name} = {v:g} {p.unit} outside the "
                                 f"plausible range [{p.low:g}, {p.high:g}] {p.unit}")
            vals.append(v)
        self.joint = joint
        self._values = tuple(vals)

    # ---------------------------------------------------------------- values
    @property
    def values(self) -> dict:
        return {p.name: v for p, v in zip(self.parameters, self._values)}

    def __getattr__(self, item):
        # parameter values read as attributes (e.g. effect.scale); only called for misses
        for p, v in zip(type(self).parameters, self.__dict__.get("_values", ())):
            if p.name == item:
                return v
        raise AttributeError(item)

    def vector(self) -> np.ndarray:
        return np.array(self._values, float)

    def with_vector(self, v) -> "Effect":
        """The same effect with new parameter values (fitting); values are clipped into the
        plausible range."""
        v = np.clip(np.asarray(v, float), [p.low for p in self.parameters],
                    [p.high for p in self.parameters])
        return type(self)(self.joint, **{p.name: float(x) for p, x in zip(self.parameters, v)})

    def neutral_vector(self, crane) -> np.ndarray:
        """Parameter values at which the effect vanishes on this crane (the fit's start)."""
        return np.array([p.neutral for p in self.parameters], float)

    def bounds(self):
        return ([p.low for p in self.parameters], [p.high for p in self.parameters])

    def _on_own_joint(self, crane, like, column_of) -> np.ndarray:
        """An (N, n) array shaped like ``like``: zero except this effect's joint column,
        ``column_of(i)`` (the per-joint force and drift hooks)."""
        i = self.index(crane)
        out = np.zeros_like(like)
        out[:, i] = column_of(i)
        return out

    def index(self, crane) -> int:
        try:
            return list(crane.names).index(self.joint)
        except ValueError:
            raise ValueError(f"effect {self.name}: unknown joint {self.joint!r}; "
                             f"joints of {crane.spec.id}: {', '.join(crane.names)}") from None

    @property
    def kinematic(self) -> bool:
        """True when the effect changes the motion (so the replay must be re-run)."""
        return self.stage in ("commands", "valves", "strokes")

    # ---------------------------------------------------------------- identity
    def _key(self):
        return (self.name, self.joint, self._values)

    def __eq__(self, other):
        return isinstance(other, Effect) and self._key() == other._key()

    def __hash__(self):
        return hash(self._key())

    def __repr__(self):
        parts = ([f"joint={self.joint}"] if self.joint else []) + \
                [f"{p.name}={v:.6g}" for p, v in zip(self.parameters, self._values)]
        return f"{self.name}({', '.join(parts)})"

    __str__ = __repr__

    def to_dict(self) -> dict:
        return dict(name=self.name, **({"joint": self.joint} if self.joint else {}),
                    **self.values)

    @classmethod
    def describe(cls) -> dict:
        """The catalogue entry (CONTRACT: name, description, parameters name -> [low, high];
        a joint parameter takes a joint name)."""
        params = {p.name: [p.low, p.high] for p in cls.parameters}
        if cls.per_joint:
            params = {"joint": "joint name", **params}
        return dict(name=cls.name, description=cls.description, signature=cls.signature,
                    parameters=params, units={p.name: p.unit for p in cls.parameters},
                    stage=cls.stage, acts_on=cls.acts_on)

    # ---------------------------------------------------------------- hooks
    def commands(self, crane, t_u, u):
        """Commands (M, n) held over [t_u[k], t_u[k+1]) -> what the valves act on (the mean
        over each hold period)."""
        return u

    def plant(self, crane, plant):
        """The replay's :class:`planner.simulation.replay.Plant` with this effect's valve/pump change."""
        return plant

    def payload(self, crane, m: float) -> float:
        """The load in the grapple [kg]."""
        return m

    def force(self, crane, s) -> np.ndarray | None:
        """Extra actuator force (N, n) [N | N·m] at the states ``s`` (a :class:`PlantState`)."""
        return None

    def drift(self, crane, s) -> np.ndarray | None:
        """Extra stroke rate (N, n) [m/s | rad/s] at the states ``s``."""
        return None

    def sense_q(self, crane, q):
        return q

    def sense_p(self, crane, p_a, p_b):
        return p_a, p_b


def _unit_q(crane, i):
    return "rad" if crane.spec.joints[i].revolute else "m"


# ===================================================================== commands stage
class TimeDelay(Effect):
    name = "time_delay"
    description = ("transport delay between the command and the valves (bus, controller cycle, "
                   "pilot stage), the same for every function")
    signature = ("positions lag the simulation in every moving joint at once; error ∝ speed, "
                 "changes sign when the motion reverses; pressures shifted in time")
    parameters = (Parameter("delay", "s", 0.0, 0.3, 0.0, "pure delay of every command"),)
    stage, acts_on = "commands", "positions and pressures"

    def commands(self, crane, t_u, u):
        d = self.delay
        if d <= 0:
            return u
        dt = float(np.median(np.diff(t_u))) if len(t_u) > 1 else 1.0
        m, f = divmod(d / dt, 1.0)
        m = int(m)
        # mean over [t_k, t_k+1) of the delayed hold signal: f·u[k-m-1] + (1-f)·u[k-m]
        idx = np.arange(len(u))
        a = u[np.clip(idx - m, 0, None)]
        b = u[np.clip(idx - m - 1, 0, None)]
        # before the record the valves were closed (a recording starts at rest)
        a = np.where((idx - m < 0)[:, None], 0.0, a)
        b = np.where((idx - m - 1 < 0)[:, None], 0.0, b)
        return (1.0 - f) * a + f * b


class ValveLag(Effect):
    name = "valve_lag"
    description = ("first-order spool dynamics of one valve: the flow follows the command with "
                   "a time constant")
    signature = ("one joint lags after command steps and overshoots the simulation when "
                 "the command falls; the error ∝ command rate; other joints unaffected")
    parameters = (Parameter("tau", "s", 0.0, 0.5, 0.0, "time constant of the valve"),)
    per_joint, stage, acts_on = True, "commands", "positions and pressures"

    def commands(self, crane, t_u, u):
        tau = self.tau
        if tau <= 0:
            return u
        i = self.index(crane)
        dt = np.diff(t_u, append=t_u[-1] + (t_u[-1] - t_u[-2] if len(t_u) > 1 else 1.0))
        out = u.copy()
        y = 0.0                      # closed before the record (it starts at rest)
        for k in range(len(u)):      # exact for held inputs: mean of y over each period
            a = math.exp(-dt[k] / tau)
            uk = u[k, i]
            out[k, i] = uk + (y - uk) * tau / dt[k] * (1.0 - a)
            y = uk + (y - uk) * a
        return out


# ===================================================================== valves stage
class FlowGain(Effect):
    name = "flow_gain"
    description = "the valve of one function passes a different flow than the spec's gain"
    signature = ("one joint moves proportionally too far (scale > 1) or too short; the error "
                 "grows with the distance travelled and returns when the motion reverses; "
                 "nothing at rest")
    parameters = (Parameter("scale", "1", 0.5, 1.5, 1.0, "true flow gain / spec flow gain"),)
    per_joint, stage, acts_on = True, "valves", "positions and pressures"

    def plant(self, crane, plant):
        from dataclasses import replace
        g = np.broadcast_to(np.asarray(plant.flow_gain_scale, float), (crane.n,)).copy()
        g[self.index(crane)] *= self.scale
        return replace(plant, flow_gain_scale=tuple(g))


class ValveDeadband(Effect):
    name = "valve_deadband"
    description = ("the dead band of one valve (spool overlap) differs from the spec's, "
                   "which the feed-forward compensates")
    signature = ("one joint moves too little (wider band) or too much at small commands; the "
                 "relative error is largest at low speed and vanishes at full command")
    parameters = (Parameter("width", "1", 0.0, 0.4, 0.0,
                            "true dead band as a fraction of the command range"),)
    per_joint, stage, acts_on = True, "valves", "positions and pressures"

    def neutral_vector(self, crane):
        return np.array([crane.spec.joints[self.index(crane)].actuator.deadband])

    def plant(self, crane, plant):
        from dataclasses import replace
        from planner.model.valves import valve_params as valve_parameters
        db = (np.asarray(plant.deadband, float) if plant.deadband is not None
              else valve_parameters(crane).deadband.copy())
        db = np.broadcast_to(db, (crane.n,)).copy()
        db[self.index(crane)] = self.width
        return replace(plant, deadband=tuple(db))


class PumpFlowLimit(Effect):
    name = "pump_flow_limit"
    description = "the pump delivers less than the spec's maximum flow (wear, engine speed)"
    signature = ("only while the functions together ask for more than the pump gives: every "
                 "pump-fed joint slows by the same factor; nothing at low demand")
    parameters = (Parameter("scale", "1", 0.1, 1.0, 1.0,
                            "true maximum pump flow / spec maximum flow"),)
    stage, acts_on = "valves", "positions and pressures"

    def plant(self, crane, plant):
        from dataclasses import replace
        return replace(plant, pump_flow_scale=plant.pump_flow_scale * self.scale)


# ===================================================================== forces stage
def _smooth_sign(crane, i, xd):
    """sign(ẋ) smoothed over 1 % of the actuator's full-command stroke speed (no chatter at
    rest, the same in the plant and in the fit)."""
    a = crane.spec.joints[i].actuator
    v = 0.01 * a.flow_gain / min(a.area_a, a.area_b)
    return np.tanh(xd / v)


class CoulombFriction(Effect):
    name = "coulomb_friction"
    description = "seal and guide friction of one actuator, constant in magnitude"
    signature = ("pressure residual of one actuator like a square wave switching with the "
                 "sign of its velocity; zero at rest; positions unaffected (compensated valves)")
    parameters = (Parameter("force", "N (N·m for rotary drives)", 0.0, 3.0e4, 0.0,
                            "friction force at the actuator"),)
    per_joint, stage, acts_on = True, "forces", "pressures"

    def force(self, crane, s):
        return self._on_own_joint(crane, s.force_model, lambda i: self.force_value
                                  * _smooth_sign(crane, i, s.xd[:, i]))

    @property
    def force_value(self):
        """The "force" parameter [N] (the name ``force`` is the hook)."""
        return self._values[0]



class ViscousFriction(Effect):
    name = "viscous_friction"
    description = "viscous damping of one actuator (oil shear, line losses), ∝ stroke speed"
    signature = ("pressure residual of one actuator proportional to its velocity; zero at "
                 "rest; positions unaffected")
    parameters = (Parameter("coefficient", "N·s/m (N·m·s/rad for rotary drives)", 0.0, 5.0e5,
                            0.0, "force per stroke speed"),)
    per_joint, stage, acts_on = True, "forces", "pressures"

    def force(self, crane, s):
        return self._on_own_joint(crane, s.force_model, lambda i: self.coefficient * s.xd[:, i])


class PayloadMass(Effect):
    name = "payload_mass"
    description = "the load in the grapple differs from the spec's"
    signature = ("gravity-like pressure bias on every lifting actuator, growing with reach, "
                 "present at rest; plus inertial terms; positions unaffected")
    parameters = (Parameter("mass", "kg", -3000.0, 5000.0, 0.0,
                            "extra mass in the grapple (negative: lighter than the spec)"),)
    stage, acts_on = "forces", "pressures"

    def payload(self, crane, m):
        return max(m + self.mass, 0.0)


class ActuatorMass(Effect):
    name = "actuator_mass"
    description = ("the mass of one actuator (cylinder and piston, seed 001's minor links) "
                   "differs from the model's, lumped half at each pin")
    signature = ("gravity-like pressure bias of that actuator and the ones below it, "
                 "present at rest, varying with the pose; plus terms in its acceleration")
    parameters = (Parameter("mass", "kg", -500.0, 2000.0, 0.0, "extra actuator mass"),)
    per_joint, stage, acts_on = True, "forces", "pressures"

    def force(self, crane, s):
        return self.mass * s.unit_actuator_force(self.index(crane))


# ===================================================================== strokes stage
class Leakage(Effect):
    name = "leakage"
    description = ("internal leakage of one actuator's load-holding side (piston seal, "
                   "holding valve) to tank, ∝ the holding pressure")
    signature = ("slow drift of the joint in the direction of its load, also while held; "
                 "grows with the holding pressure and with time")
    parameters = (Parameter("coefficient", "m³/(s·Pa)", 0.0, 2.0e-11, 0.0,
                            "leak flow per pressure above tank"),)
    per_joint, stage, acts_on = True, "strokes", "positions and pressures"

    def drift(self, crane, s):
        pt = crane.spec.pump.tank_pressure

        def rate(i):   # out of the loaded chamber: towards the load
            a = crane.spec.joints[i].actuator
            return np.where(s.force[:, i] >= 0,
                            -self.coefficient * (s.p_a[:, i] - pt) / a.area_a,
                            self.coefficient * (s.p_b[:, i] - pt) / a.area_b)
        return self._on_own_joint(crane, s.xd, rate)


# ===================================================================== sensors stage
class JointOffset(Effect):
    name = "joint_offset"
    description = "a constant bias of one joint's position sensor (mounting, zeroing)"
    signature = ("positions alone cannot tell it from the start pose; the pressures are "
                 "computed at the wrong angle: a pose-dependent gravity bias, present at rest")
    parameters = (Parameter("offset", "rad (m for prismatic joints)", -0.1, 0.1, 0.0,
                            "reading − true position"),)
    per_joint, stage, acts_on = True, "sensors", "positions and pressures"

    def sense_q(self, crane, q):
        q = q.copy()
        q[:, self.index(crane)] += self.offset
        return q


class PressureOffset(Effect):
    name = "pressure_offset"
    description = "constant bias of one actuator's two pressure transducers (zero drift)"
    signature = "constant pressure bias of one chamber or both, at rest and in motion"
    parameters = (Parameter("offset_a", "Pa", -2.0e6, 2.0e6, 0.0, "chamber a (piston side)"),
                  Parameter("offset_b", "Pa", -2.0e6, 2.0e6, 0.0, "chamber b (rod side)"))
    per_joint, stage, acts_on = True, "sensors", "pressures"

    def sense_p(self, crane, p_a, p_b):
        i = self.index(crane)
        p_a, p_b = p_a.copy(), p_b.copy()
        p_a[:, i] += self.offset_a
        p_b[:, i] += self.offset_b
        return p_a, p_b


CATALOGUE: dict[str, type[Effect]] = {c.name: c for c in (
    JointOffset, FlowGain, ValveDeadband, ValveLag, TimeDelay, PumpFlowLimit, Leakage,
    CoulombFriction, ViscousFriction, PayloadMass, ActuatorMass, PressureOffset)}

STAGES = ("commands", "valves", "forces", "strokes", "sensors")


def catalogue() -> list[dict]:
    """Every effect's catalogue entry (``effects list --json``)."""
    return [c.describe() for c in CATALOGUE.values()]


def make(name: str, joint: str | None = None, **values) -> Effect:
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(CATALOGUE)}")
    return CATALOGUE[name](joint, **values)


def effect_from_dict(d: dict) -> Effect:
    d = dict(d)
    return make(d.pop("name", None), d.pop("joint", None), **d)


def parse_effect(text: str, crane=None) -> Effect:
    """``NAME:key=value,…`` -> an effect (angles may be written ``1.5deg``). With a crane,
    the joint name is checked against it."""
    from planner.units import parse_angle
    name, _, rest = text.partition(":")
    name = name.strip()
    kw: dict = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        k, eq, v = item.partition("=")
        if not eq:
            raise ValueError(f"effect {text!r}: expected key=value, got {item!r}")
        k, v = k.strip(), v.strip()
        if k == "joint":
            kw[k] = v
            continue
        try:
            kw[k] = parse_angle(v) if v.endswith("deg") else float(v)
        except (TypeError, ValueError):
            raise ValueError(f"effect {text!r}: {k} = {v!r} is not a number") from None
    e = make(name, kw.pop("joint", None), **kw)
    if crane is not None and e.joint is not None:
        e.index(crane)
    return e
