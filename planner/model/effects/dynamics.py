"""Effects only a dynamic plant has (stage ``dynamics``): the oil's stiffness, the hoses'
oil volume and a grapple that swings on its link. The first two change how fast pressure builds up, so the lag, ringing and hydraulic natural
frequency of every move; the quasi-static plant and the discrepancy model have no compressible
oil at all, so they refuse these effects (:func:`~planner.model.effects.base.quasi_static`), the
trials never draw them and the discrepancy search never fits them. The Exudyn plant
(:mod:`planner.simulation.dynamic`) applies them to its ``[dynamics]`` data.

The lowest hydraulic natural frequency of an actuator moving a mass m goes as
ω² = β·(A_a²/V_a + A_b²/V_b)/m: × sqrt(s) for a bulk modulus scaled by s, × 1/sqrt(s) for all
oil volumes scaled by s (the chambers' own oil unchanged, the hose share of V scaled).

A grapple of radius of gyration k on a link of length L swings like a compound pendulum,
ω² = g·L/(L² + k²) about a pin that stays still, and loads the boom tip with its swing.
"""
from __future__ import annotations

from dataclasses import replace

from planner.model.dynamics_spec import GYRATION, GrappleLink
from planner.model.effects.base import Effect, Parameter
from planner.units import CraneLike


__all__ = ["BulkModulus", "HoseVolume", "GrappleSwing"]


class BulkModulus(Effect):
    name = "bulk_modulus"
    description = ("effective oil stiffness (oil, hose walls, entrained air) scaled: aerated or "
                   "warm oil and soft hoses lower it")
    signature = ("pressures build up and settle slower after every command step, more ringing "
                 "at a lower hydraulic frequency; positions lag under load; no static offset")
    parameters = (Parameter("scale", "×", 0.1, 3.0, 1.0,
                            "factor on the spec's [dynamics] bulk_modulus"),)
    stage, acts_on = "dynamics", "positions and pressures"

    def dynamics(self, crane: CraneLike, dyn):
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

    def dynamics(self, crane: CraneLike, dyn):
        self.index(crane)   # an unknown joint is refused with the known ones named
        j = dyn.joints[self.joint]
        hv = tuple(v * self.scale for v in j.hose_volume)
        return replace(dyn, joints={**dyn.joints, self.joint: replace(j, hose_volume=hv)})


class GrappleSwing(Effect):
    name = "grapple_swing"
    description = ("grapple and load hang on a passive two-axis link at the boom tip instead "
                   "of being fixed to it (a rotator link that swings in and out of the boom "
                   "plane)")
    signature = ("after every acceleration the tip load swings at the pendulum frequency "
                 "sqrt(g·L/(L²+k²))/2π, seen in the pressures of every actuator that holds "
                 "the load (slew for swing out of the boom plane); no static offset at rest")
    parameters = (Parameter("length", "m", 0.0, 3.0, 0.0,
                            "pivot to the centre of mass of grapple + load; 0: as the spec "
                            "says (fixed at the tip unless it has [dynamics.grapple])"),
                  Parameter("damping", "N·m·s/rad", 0.0, 5.0e4, 0.0,
                            "viscous damping about each of the two pins"))
    stage, acts_on = "dynamics", "pressures"

    def grapple(self, crane: CraneLike, dyn):
        if self.length <= 0:
            return dyn
        k = dyn.grapple.gyration if dyn.grapple is not None else GYRATION
        return replace(dyn, grapple=GrappleLink(self.length, self.damping, k,
                                                "effect grapple_swing"))
