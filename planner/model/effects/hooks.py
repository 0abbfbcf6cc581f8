"""How an effect acts in each plant: its hooks, and refusal by name (never silently dropped).

An effect (:class:`~planner.model.effects.base.Effect`) acts through the hooks it overrides.
Each plant (the fast quasi-static replay, the Exudyn plant, the dynamic twin) calls a fixed
set of hooks, listed in its class as ``hooks``; an effect acts in a plant through the hooks
that both share. When it shares none, the plant **refuses** it with :class:`EffectRefused`,
which names the effect, the plant and the plants that do apply it — a judge that drops what it
was asked to simulate would say something untrue.

The hooks (the stage they belong to in brackets):

=============  ===================================================================================
commands       what the valves see of the command signal [commands]
start          the true start pose [start]
valves         valve and pump data: flow gains, dead bands, pump flow [valves]
payload        the load in the grapple [forces]
bodies         the rigid-body data of the machine (a spec with other masses) [forces]
force          an extra actuator force at given states — the quasi-static stand-in of a
               physical force [forces]
drift          an extra stroke rate at given states — the quasi-static stand-in of a
               flow [strokes]
dynamics       the physical data of a dynamic plant (``[dynamics]``: oil, hoses, friction,
               leakage) [dynamics]
grapple        the passive link the grapple hangs on (``[dynamics.grapple]``): only a plant
               with the pendulum in its bodies applies it [dynamics]
sense_q_at     what the position sensors report at given times [sensors]
sense_p_at     what the pressure transducers report at given times [sensors]
=============  ===================================================================================

``sense_q`` / ``sense_p`` (time-independent sensors) count as ``sense_q_at`` / ``sense_p_at``:
the base class's time-aware hooks call them.

**Physical data first.** A dynamic plant integrates forces and flows itself; where an effect
gives its physical data (``dynamics``, ``bodies``), a dynamic plant applies that and not the
quasi-static stand-ins (``force``, ``drift``) — applying both would count the effect twice.
A stand-in alone is applied by a dynamic plant where it has a meaning there (an extra force,
evaluated at the start of each step) and refused where it has none (a stroke drift: a
force-driven plant has no way to impose a stroke rate).
"""
from __future__ import annotations

__all__ = ["HOOKS", "QUASI_STATIC_HOOKS", "DYNAMIC_HOOKS", "PENDULUM_HOOKS", "STAND_INS",
           "PHYSICAL",
           "EffectRefused", "overridden", "hooks_in"]

HOOKS = ("commands", "start", "valves", "payload", "bodies", "force", "drift", "dynamics",
         "grapple", "sense_q_at", "sense_p_at")
#: the hooks the quasi-static plant (and the discrepancy model, the same replay) calls
QUASI_STATIC_HOOKS = ("commands", "start", "valves", "payload", "force", "drift", "sense_q_at",
                      "sense_p_at")
#: the hooks a dynamic plant (Exudyn, the twin) calls; one with the grapple pendulum in its
#: bodies (Exudyn) calls ``grapple`` too
DYNAMIC_HOOKS = ("commands", "start", "valves", "payload", "bodies", "dynamics", "force",
                 "sense_q_at", "sense_p_at")
PENDULUM_HOOKS = DYNAMIC_HOOKS + ("grapple",)
#: quasi-static stand-ins a dynamic plant skips when the effect gives physical data
STAND_INS = ("force", "drift")
PHYSICAL = ("dynamics", "bodies", "grapple")
# a hook counts as overridden when the class (or a class between it and Effect) defines one of
# these methods
_ALIASES = {"sense_q_at": ("sense_q_at", "sense_q"), "sense_p_at": ("sense_p_at", "sense_p")}


class EffectRefused(ValueError):
    """A plant was asked for an effect it cannot apply: ``effect`` (its name), ``plant``."""

    def __init__(self, effect: str, plant: str, message: str):
        super().__init__(message)
        self.effect, self.plant = effect, plant


def overridden(cls, base) -> tuple[str, ...]:
    """The hooks (of :data:`HOOKS`) that the effect class ``cls`` overrides (defines in a
    class between it and ``base``, the Effect base class), in hook order."""
    out = []
    for h in HOOKS:
        for name in _ALIASES.get(h, (h,)):
            if any(name in vars(k) for k in cls.__mro__ if issubclass(k, base)
                   and k is not base):
                out.append(h)
                break
    return tuple(out)


def hooks_in(cls, base, plant_hooks, physical_first: bool = False) -> tuple[str, ...]:
    """The hooks through which effect class ``cls`` acts in a plant that calls
    ``plant_hooks``; with ``physical_first`` (a dynamic plant) the stand-ins are dropped when
    the effect gives physical data. Empty: the plant refuses the effect."""
    own = overridden(cls, base)
    used = [h for h in plant_hooks if h in own]
    if physical_first and any(h in own for h in PHYSICAL):
        used = [h for h in used if h not in STAND_INS]
    return tuple(used)
