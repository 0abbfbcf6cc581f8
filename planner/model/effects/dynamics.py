"""Effects only a dynamic plant has (stage ``dynamics``): the oil's stiffness and the hoses'
oil volume. They change how fast pressure builds up, so the lag, ringing and hydraulic natural
frequency of every move; the quasi-static plant and the discrepancy model have no compressible
oil at all, so they refuse these effects (:func:`~planner.model.effects.base.quasi_static`), the
trials never draw them and the discrepancy search never fits them. The Exudyn plant
(:mod:`planner.simulation.dynamic`) applies them to its ``[dynamics]`` data.

The lowest hydraulic natural frequency of an actuator moving a mass m goes as
ω² = β·(A_a²/V_a + A_b²/V_b)/m: × sqrt(s) for a bulk modulus scaled by s, × 1/sqrt(s) for all
oil volumes scaled by s (the chambers' own oil unchanged, the hose share of V scaled).
"""
from __future__ import annotations

from dataclasses import replace

from planner.model.effects.base import Effect, Parameter

__all__ = ["BulkModulus", "HoseVolume"]


class BulkModulus(Effect):
    name = "bulk_modulus"
    description = ("effective oil stiffness (oil, hose walls, entrained air) scaled: aerated or "
                   "warm oil and soft hoses lower it")
    signature = ("pressures build up and settle slower after every command step, more ringing "
                 "at a lower hydraulic frequency; positions lag under load; no static offset")
    parameters = (Parameter("scale", "×", 0.1, 3.0, 1.0,
                            "factor on the spec's [dynamics] bulk_modulus"),)
    stage, acts_on = "dynamics", "positions and pressures"

    def dynamics(self, crane, dyn):
        return replace(dyn, bulk_modulus=dyn.bulk_modulus * self.scale)


class HoseVolume(Effect):
    name = "hose_volume"
    description = ("oil volume of one actuator's hoses scaled (longer or wider hoses, an "
                   "accumulator-like dead volume)")
    signature = ("that actuator's pressures build up slower and it rings at a lower frequency; "
                 "no static offset")
    parameters = (Parameter("scale", "×", 0.2, 10.0, 1.0,
                            "factor on the actuator's [dynamics] hose volumes (both ports)"),)
    per_joint = True
    stage, acts_on = "dynamics", "positions and pressures"

    def dynamics(self, crane, dyn):
        self.index(crane)   # an unknown joint is refused with the known ones named
        j = dyn.joints[self.joint]
        hv = tuple(v * self.scale for v in j.hose_volume)
        return replace(dyn, joints={**dyn.joints, self.joint: replace(j, hose_volume=hv)})
