"""The effect base class, the valve set it changes, and the registry (the catalogue).

An effect is one class (see :mod:`planner.model.effects` for the stages and the catalogue).
The class carries everything about the effect, so that the plant, the trials and the
discrepancy search need no branch on its name:

* its **parameters** (:class:`Parameter`: unit, plausible range, neutral value) and whether it
  belongs to one actuator (``per_joint``);
* its **injection**: the hook of its ``stage`` (:meth:`Effect.commands`, :meth:`Effect.start`,
  :meth:`Effect.valves`, :meth:`Effect.payload` / :meth:`Effect.force`, :meth:`Effect.drift`,
  :meth:`Effect.sense_q` / :meth:`Effect.sense_p`; the default hooks change nothing);
* its **trial magnitude** (``trial_range`` and :meth:`Effect.trial_values`: the hidden effect
  drawn in a calibration trial);
* its **command delay** (:attr:`Effect.command_delay`: how far it shifts the valves' response
  behind the command, used by the re-planned feed-forward);
* its **observability rule** (:meth:`Effect.observable`: joints on which it leaves no trace in
  positions and pressures, which trials do not draw);
* its catalogue entry (:meth:`Effect.describe`).

:func:`register` adds a class to :data:`CATALOGUE`; from then on it is listed by
``crane-planner effects list``, drawn by the trials and fitted by the discrepancy search.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.model.effects.hooks import QUASI_STATIC_HOOKS, EffectRefused, hooks_in, overridden
from planner.units import CraneLike, parse_angle


__all__ = ["Parameter", "ValveSet", "Effect", "STAGES", "CATALOGUE", "register", "unregister",
           "catalogue", "make", "effect_from_dict", "parse_effect", "as_effects",
           "quasi_static", "fittable", "refuse", "EffectRefused"]

# the stages of the plant, in the order the plant applies them, then "dynamics": the oil's and
# the hoses' physical data, which only the dynamic (Exudyn) plant has (set before it runs)
STAGES = ("commands", "start", "valves", "forces", "strokes", "sensors", "dynamics")
# the stages the open-loop replay itself applies (the rest are applied on its result)
REPLAY_STAGES = ("commands", "start", "valves")


@dataclass(frozen=True)
class Parameter:
    """One parameter of an effect: ``low``..``high`` is the plausible range (the catalogue's
    range and the bounds of a fit), ``neutral`` the value at which the effect vanishes."""
    name: str
    unit: str
    low: float
    high: float
    neutral: float
    description: str = ""


@dataclass(frozen=True)
class ValveSet:
    """What the valves-stage effects change, as factors on and replacements of the spec's
    valve data: ``flow_gain_scale`` (n,) factor on each valve's flow gain, ``deadband`` (n,)
    each valve's dead band (fraction of the command range), ``pump_flow_scale`` factor on the
    pump's maximum flow. A hook returns a new set (``dataclasses.replace``) with new arrays."""
    flow_gain_scale: np.ndarray
    deadband: np.ndarray
    pump_flow_scale: float = 1.0


class Effect:
    """Base class: a subclass sets the class attributes and overrides the hooks it needs.

    Class attributes: ``name`` (catalogue name), ``description`` (physical meaning),
    ``signature`` (the trace it leaves in the residual measured − simulated), ``parameters``
    (a tuple of :class:`Parameter`), ``per_joint`` (it belongs to one actuator: constructed
    with ``joint=<name>``), ``stage`` (one of :data:`STAGES`), ``acts_on`` ("positions",
    "pressures" or "positions and pressures"), ``trial_range`` ((low, high) of the magnitude a
    trial draws, see :meth:`trial_values`; None: trials never draw it).

    An instance holds the parameter values (read as attributes, e.g. ``effect.scale``); it is
    immutable, hashable and compares by (name, joint, values)."""
    name = ""
    description = ""
    signature = ""
    parameters: tuple[Parameter, ...] = ()
    per_joint = False
    stage = ""
    acts_on = ""
    trial_range: tuple[float, float] | None = None

    def __init__(self, joint: str | None = None, **values):
        self._set(joint, values, check_range=True)

    @classmethod
    def unbounded(cls, joint: str | None = None, **values) -> "Effect":
        """The effect without the plausible-range check (finite values only): perturbation
        studies may go beyond what a fit would consider (e.g. a bigger pump, ``scale`` > 1)."""
        e = cls.__new__(cls)
        e._set(joint, values, check_range=False)
        return e

    def _set(self, joint, values, check_range: bool):
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
            if not math.isfinite(v) or (check_range and not p.low <= v <= p.high):
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

    def neutral_vector(self, crane: CraneLike) -> np.ndarray:
        """Parameter values at which the effect vanishes on this crane (the fit's start)."""
        return np.array([p.neutral for p in self.parameters], float)

    def bounds(self):
        return ([p.low for p in self.parameters], [p.high for p in self.parameters])

    def index(self, crane: CraneLike) -> int:
        """Index of this effect's joint in ``crane`` (ValueError naming the known joints)."""
        try:
            return list(crane.names).index(self.joint)
        except ValueError:
            raise ValueError(f"effect {self.name}: unknown joint {self.joint!r}; "
                             f"joints of {crane.spec.id}: {', '.join(crane.names)}") from None

    def on_own_joint(self, crane: CraneLike, like, column_of) -> np.ndarray:
        """An (N, n) array shaped like ``like``: zero except this effect's joint column,
        ``column_of(i)`` (for the per-joint force and drift hooks)."""
        i = self.index(crane)
        out = np.zeros_like(like)
        out[:, i] = column_of(i)
        return out

    def dynamics(self, crane: CraneLike, dyn):
        """A dynamic plant's ``[dynamics]`` data (a
        :class:`~planner.model.dynamics_spec.DynamicsSpec`) with this effect applied."""
        return dyn

    def grapple(self, crane: CraneLike, dyn):
        """A dynamic plant's ``[dynamics]`` data with this effect's grapple link (its
        ``grapple``: a :class:`~planner.model.dynamics_spec.GrappleLink` or None)."""
        return dyn

    def bodies(self, crane: CraneLike, spec):
        """The machine's rigid-body data as a dynamic plant integrates it (a spec with other
        masses) with this effect applied."""
        return spec

    # ---------------------------------------------------------------- plants
    @classmethod
    def own_hooks(cls) -> tuple:
        """The hooks this effect class overrides (:mod:`planner.model.effects.hooks`)."""
        return overridden(cls, Effect)

    @classmethod
    def hooks_in(cls, plant_hooks, physical_first: bool = False) -> tuple:
        """The hooks through which it acts in a plant that calls ``plant_hooks`` (empty: that
        plant refuses it; see :func:`planner.model.effects.hooks.hooks_in`)."""
        return hooks_in(cls, Effect, plant_hooks, physical_first)

    @property
    def kinematic(self) -> bool:
        """True when the effect changes the motion (so the replay must be re-run)."""
        return self.stage in ("commands", "start", "valves", "strokes")

    @property
    def replayed(self) -> bool:
        """True when the open-loop replay applies it (commands, start and valves stages)."""
        return self.stage in REPLAY_STAGES

    @property
    def command_delay(self) -> float:
        """How far [s] the effect shifts the valves' response behind the command (a delay, a
        lag's time constant); 0 for every other effect."""
        return 0.0

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
    def commands(self, crane: CraneLike, t_u, u):
        """Commands (M, n) held over [t_u[k], t_u[k+1]) -> what the valves act on (the mean
        over each hold period)."""
        return u

    def start(self, crane: CraneLike, q0):
        """The true initial configuration (n,) given the nominal one."""
        return q0

    def valves(self, crane: CraneLike, v: ValveSet) -> ValveSet:
        """The valve and pump data of the replay with this effect's change."""
        return v

    def payload(self, crane: CraneLike, m: float) -> float:
        """The load in the grapple [kg]."""
        return m

    def force(self, crane: CraneLike, s) -> np.ndarray | None:
        """Extra actuator force (N, n) [N | N·m] at the states ``s``
        (a :class:`planner.simulation.plant.PlantState`)."""
        return None

    def drift(self, crane: CraneLike, s) -> np.ndarray | None:
        """Extra stroke rate (N, n) [m/s | rad/s] at the states ``s``."""
        return None

    def sense_q(self, crane: CraneLike, q):
        """What the position sensors report for the true positions ``q`` (N, n)."""
        return q

    def sense_p(self, crane: CraneLike, p_a, p_b):
        """What the pressure transducers report for the true chamber pressures."""
        return p_a, p_b

    def sense_q_at(self, crane: CraneLike, t, q):
        """:meth:`sense_q` at the sample times ``t`` (N,) [s] (the plant calls this one): a
        sensor effect that changes with time (a drift) overrides it; the default ignores
        ``t``."""
        return self.sense_q(crane, q)

    def sense_p_at(self, crane: CraneLike, t, p_a, p_b):
        """:meth:`sense_p` at the sample times ``t`` (N,) [s] (see :meth:`sense_q_at`)."""
        return self.sense_p(crane, p_a, p_b)

    def plant(self, crane: CraneLike, plant=()) -> tuple:
        """``plant`` (a sequence of effects, or a :class:`planner.simulation.replay.Plant`)
        with this effect added: the effect set that the replay, ``stroke_rates`` and the
        plant's ``respond`` take."""
        return as_effects(crane, plant) + (self,)

    # ---------------------------------------------------------------- trials
    @classmethod
    def observable(cls, crane: CraneLike, i: int) -> bool:
        """False when the effect on joint ``i`` leaves no trace in joint positions and
        actuator pressures (no data of that kind can name it; trials do not draw it)."""
        return True

    @classmethod
    def observable_joints(cls, crane: CraneLike) -> list[str]:
        return [j for i, j in enumerate(crane.names) if cls.observable(crane, i)]

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude: float, sign: float, rng,
                     sequence) -> dict:
        """Parameter values of the hidden effect of a trial: ``magnitude`` drawn uniformly in
        ``trial_range``, ``sign`` ±1 (use it where both signs are physical), joint index ``i``
        (None for a machine-wide effect), ``rng`` for any further draw, ``sequence`` the
        trial's test sequence (``peak_demand``: its peak pump demand / the pump's maximum)."""
        raise NotImplementedError(f"effect {cls.name}: no trial magnitude (trial_range is "
                                  f"{cls.trial_range})")

    @classmethod
    def trial(cls, crane: CraneLike, rng, joint: str | None = None, sequence=None) -> "Effect":
        """A hidden effect of realistic magnitude: magnitude, sign, then (per-joint effects
        without ``joint``) an observable joint, each drawn from ``rng`` in that order."""
        if cls.trial_range is None:
            raise ValueError(f"effect {cls.name}: trials do not draw it (no trial_range)")
        lo, hi = cls.trial_range
        mag = float(rng.uniform(lo, hi))
        sign = 1.0 if rng.uniform() < 0.5 else -1.0
        if cls.per_joint and joint is None:
            js = cls.observable_joints(crane)
            joint = js[int(rng.integers(len(js)))]
        i = list(crane.names).index(joint) if joint else None
        return cls(joint, **cls.trial_values(crane, i, mag, sign, rng, sequence))


def is_slew(crane: CraneLike, i: int) -> bool:
    """True for the slew: the first joint of every crane spec turns the crane about the
    vertical axis of frame 0 (docs/design.md, "CONTRACT: tip coordinates"), so gravity does not
    depend on it."""
    return i == 0


# ===================================================================== the registry
CATALOGUE: dict[str, type[Effect]] = {}


def register(cls: type[Effect]) -> type[Effect]:
    """Add an effect class to the catalogue (usable as a class decorator). Re-registering the
    same class is a no-op; another class under a taken name is refused."""
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise TypeError(f"register: expected a subclass of Effect, got {cls!r}")
    if not cls.name or not cls.name.isidentifier():
        raise ValueError(f"effect class {cls.__name__}: name = {cls.name!r}; expected a "
                         "non-empty identifier (letters, digits, underscores)")
    if cls.stage not in STAGES:
        raise ValueError(f"effect {cls.name}: stage = {cls.stage!r}; allowed: "
                         f"{', '.join(STAGES)}")
    if not cls.description:
        raise ValueError(f"effect {cls.name}: description is empty; say what it means "
                         "physically")
    for p in cls.parameters:
        if not (p.low < p.high and p.low <= p.neutral <= p.high):
            raise ValueError(f"effect {cls.name}: parameter {p.name} has range [{p.low:g}, "
                             f"{p.high:g}] and neutral {p.neutral:g}; expected low < high and "
                             "the neutral value inside")
    if cls.trial_range is not None and not 0 <= cls.trial_range[0] <= cls.trial_range[1]:
        raise ValueError(f"effect {cls.name}: trial_range = {cls.trial_range}; expected "
                         "(low, high) with 0 <= low <= high")
    old = CATALOGUE.get(cls.name)
    if old is not None and old is not cls:
        raise ValueError(f"effect {cls.name}: the name is taken by {old.__module__}."
                         f"{old.__qualname__}")
    CATALOGUE[cls.name] = cls
    return cls


def unregister(name: str) -> None:
    """Remove an effect from the catalogue (a plug-in's or a test's)."""
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(CATALOGUE)}")
    del CATALOGUE[name]


def catalogue() -> list[dict]:
    """Every effect's catalogue entry (``effects list --json``)."""
    return [c.describe() for c in CATALOGUE.values()]


def make(name: str, joint: str | None = None, **values) -> Effect:
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(CATALOGUE)}")
    return CATALOGUE[name](joint, **values)


def _given(name, values: dict) -> None:
    """Refuse user input that names an effect but none of its parameters: it would silently
    be the neutral (no) effect, e.g. ``coulomb_friction:joint=boom`` meaning zero friction."""
    cls = CATALOGUE.get(name)
    if cls is None or not cls.parameters or values:   # unknown names: make() says which
        return
    ps = cls.parameters
    what = (f"its parameter {ps[0].name} [{ps[0].unit}] (plausible range [{ps[0].low:g}, "
            f"{ps[0].high:g}])" if len(ps) == 1
            else f"at least one of {', '.join(p.name for p in ps)}")
    raise ValueError(f"effect {name}: give {what}; without it the effect is neutral "
                     f"({', '.join(f'{p.name} = {p.neutral:g}' for p in ps)})")


def effect_from_dict(d: dict) -> Effect:
    """An effect from a table (``name``, ``joint``, parameter values), e.g. a spec's
    ``[[effects]]``; at least one parameter value must be given."""
    d = dict(d)
    name, joint = d.pop("name", None), d.pop("joint", None)
    _given(name, d)
    return make(name, joint, **d)


def parse_effect(text: str, crane: CraneLike | None = None) -> Effect:
    """``NAME:key=value,…`` -> an effect (angles may be written ``1.5deg``). With a crane,
    the joint name is checked against it. At least one parameter value must be given."""
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
    joint = kw.pop("joint", None)
    _given(name, kw)
    e = make(name, joint, **kw)
    if crane is not None and e.joint is not None:
        e.index(crane)
    return e


def fittable() -> list:
    """The catalogue names the quasi-static model can show, so fit (every effect with a
    quasi-static hook): the discrepancy search's default candidates."""
    return [k for k, c in CATALOGUE.items() if c.hooks_in(QUASI_STATIC_HOOKS)]


def refuse(effect, plant: str, plant_hooks, physical_first: bool = False,
           elsewhere: str = "") -> tuple:
    """The hooks through which ``effect`` (an instance or a class) acts in plant ``plant``
    (a plant calling ``plant_hooks``); :class:`EffectRefused` naming the effect, what it acts
    through and ``elsewhere`` (the plants that do apply it) when it shares none."""
    cls = effect if isinstance(effect, type) else type(effect)
    used = cls.hooks_in(plant_hooks, physical_first)
    if not used:
        own = cls.own_hooks()
        raise EffectRefused(cls.name, plant, (
            f"effect {cls.name}: the {plant} plant cannot apply it (it acts through "
            f"{', '.join(own) or 'no hook'}, which the {plant} plant does not have)"
            + (f"; {elsewhere}" if elsewhere else "")))
    return used


def quasi_static(effects) -> tuple:
    """``effects`` (a tuple), refused with :class:`EffectRefused` (a ValueError) when one of
    them has no quasi-static hook (the oil's dynamics, hose volumes, a swinging grapple),
    which the quasi-static plant and model do not have."""
    effects = tuple(effects)
    for e in effects:
        refuse(e, "fast", QUASI_STATIC_HOOKS, elsewhere=(
            "it changes what only a dynamic plant has; simulate it with the exudyn plant "
            "(the quasi-static plant cannot show it, so the quasi-static model cannot fit "
            f"it; fittable: {', '.join(fittable())})"))
    return effects


def as_effects(crane: CraneLike, plant) -> tuple:
    """The effect set of ``plant``: an :class:`Effect`, a sequence of effects, or anything
    with an ``effects(crane)`` method (a :class:`planner.simulation.replay.Plant`)."""
    if isinstance(plant, Effect):
        return (plant,)
    effects = getattr(plant, "effects", None)
    if callable(effects):
        return tuple(effects(crane))
    out = tuple(plant)
    bad = [e for e in out if not isinstance(e, Effect)]
    if bad:
        raise TypeError(f"expected effects (planner.model.effects), got {bad[0]!r}")
    return out
