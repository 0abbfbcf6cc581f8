"""Effects on the loads and on the sensors: extra actuator force or load (coulomb_friction,
viscous_friction, payload_mass, grapple_load, actuator_mass) and what the transducers report
(joint_offset, pressure_offset)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from planner.model.effects.base import Effect, Parameter, is_slew
from planner.units import CraneLike


__all__ = ["CoulombFriction", "ViscousFriction", "PayloadMass", "GrappleLoad", "ActuatorMass",
           "JointOffset", "PressureOffset", "smooth_sign"]


def smooth_sign(crane: CraneLike, i, xd):
    """sign(ẋ) smoothed over 1 % of the actuator's full-command stroke speed (no chatter at
    rest, the same in the plant and in the fit)."""
    a = crane.spec.joints[i].actuator
    v = 0.01 * a.flow_gain / min(a.area_a, a.area_b)
    return np.tanh(xd / v)


def _joint_dynamics(effect, crane: CraneLike, dyn, **change):
    """``dyn`` with the effect's joint's :class:`JointDynamics` fields changed: each keyword
    maps a field to a function of the old joint data."""
    effect.index(crane)   # an unknown joint is refused with the known ones named
    j = dyn.joints[effect.joint]
    j2 = replace(j, **{k: f(j) for k, f in change.items()})
    return replace(dyn, joints={**dyn.joints, effect.joint: j2})


# ===================================================================== forces stage
class CoulombFriction(Effect):
    name = "coulomb_friction"
    description = "seal and guide friction of one actuator, constant in magnitude"
    signature = ("pressure residual of one actuator like a square wave switching with the "
                 "sign of its velocity; zero at rest; positions unaffected (compensated valves)")
    parameters = (Parameter("force", "N (N·m for rotary drives)", 0.0, 3.0e4, 0.0,
                            "friction force at the actuator"),)
    per_joint, stage, acts_on = True, "forces", "pressures"
    trial_range = (0.3, 1.0)            # × 5 % of the actuator's force at 10 MPa

    def force(self, crane: CraneLike, s):
        return self.on_own_joint(crane, s.force_model, lambda i: self.force_value
                                 * smooth_sign(crane, i, s.xd[:, i]))

    def dynamics(self, crane: CraneLike, dyn):
        # a dynamic plant: the actuator's own (smoothed) Coulomb friction, raised
        return _joint_dynamics(self, crane, dyn, coulomb=lambda j: j.coulomb
                               + self.force_value)

    @property
    def force_value(self):
        """The "force" parameter [N] (the name ``force`` is the hook)."""
        return self._values[0]

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        act = crane.spec.joints[i].actuator
        return dict(force=min(magnitude * 0.05 * 10e6 * act.area_a, 3.0e4))


class ViscousFriction(Effect):
    name = "viscous_friction"
    description = "viscous damping of one actuator (oil shear, line losses), ∝ stroke speed"
    signature = ("pressure residual of one actuator proportional to its velocity; zero at "
                 "rest; positions unaffected")
    parameters = (Parameter("coefficient", "N·s/m (N·m·s/rad for rotary drives)", 0.0, 5.0e5,
                            0.0, "force per stroke speed"),)
    per_joint, stage, acts_on = True, "forces", "pressures"
    trial_range = (0.3, 1.0)            # × the coefficient giving 1 MPa at full speed

    def force(self, crane: CraneLike, s):
        return self.on_own_joint(crane, s.force_model, lambda i: self.coefficient * s.xd[:, i])

    def dynamics(self, crane: CraneLike, dyn):
        return _joint_dynamics(self, crane, dyn, viscous=lambda j: j.viscous + self.coefficient)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        act = crane.spec.joints[i].actuator
        vmax = act.flow_gain / act.area_a
        return dict(coefficient=min(magnitude * 1e6 * act.area_a / vmax, 5.0e5))


class PayloadMass(Effect):
    name = "payload_mass"
    description = "the load in the grapple differs from the spec's"
    signature = ("gravity-like pressure bias on every lifting actuator, growing with reach, "
                 "present at rest; plus inertial terms; positions unaffected")
    parameters = (Parameter("mass", "kg", -3000.0, 5000.0, 0.0,
                            "extra mass in the grapple (negative: lighter than the spec)"),)
    stage, acts_on = "forces", "pressures"
    trial_range = (0.3, 1.0)            # × the spec's payload + tool (lighter: ≤ the load)

    def payload(self, crane: CraneLike, m):
        return max(m + self.mass, 0.0)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        m = magnitude * crane.spec.payload.total
        return dict(mass=m if sign > 0 else -min(m, crane.spec.payload.mass))


class GrappleLoad(Effect):
    """Not in the catalogue: :class:`PayloadMass` said in absolute terms (the robustness
    study's ``Plant(payload=…)``)."""
    name = "grapple_load"
    description = "the load in the grapple (absolute), instead of the spec's load + tool"
    signature = "as payload_mass"
    parameters = (Parameter("mass", "kg", 0.0, 1.0e5, 0.0, "load in the grapple"),)
    stage, acts_on = "forces", "pressures"

    def payload(self, crane: CraneLike, m):
        return self.mass


class ActuatorMass(Effect):
    name = "actuator_mass"
    description = ("the mass of one actuator (cylinder and piston, seed 001's minor links) "
                   "differs from the model's, lumped half at each pin")
    signature = ("gravity-like pressure bias of that actuator and the ones below it, "
                 "present at rest, varying with the pose; plus terms in its acceleration")
    parameters = (Parameter("mass", "kg", -500.0, 2000.0, 0.0, "extra actuator mass"),)
    per_joint, stage, acts_on = True, "forces", "pressures"
    trial_range = (0.1, 0.4)            # × the mass of the link the actuator drives

    def force(self, crane: CraneLike, s):
        return self.mass * s.unit_actuator_force(self.index(crane))

    def bodies(self, crane: CraneLike, spec):
        # a dynamic plant integrates the heavier actuator itself (lumped as the model lumps it)
        i = self.index(crane)
        j = spec.joints[i]
        j2 = replace(j, actuator=replace(j.actuator, mass=j.actuator.mass + self.mass))
        return replace(spec, joints=spec.joints[:i] + (j2,) + spec.joints[i + 1:])

    @classmethod
    def observable(cls, crane: CraneLike, i):
        # the slew drive's own mass, lumped near the axis, adds almost nothing to its inertia
        return not is_slew(crane, i)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(mass=magnitude * crane.spec.joints[i].mass)


# ===================================================================== sensors stage
class JointOffset(Effect):
    name = "joint_offset"
    description = "a constant bias of one joint's position sensor (mounting, zeroing)"
    signature = ("positions alone cannot tell it from the start pose; the pressures are "
                 "computed at the wrong angle: a pose-dependent gravity bias, present at rest")
    parameters = (Parameter("offset", "rad (m for prismatic joints)", -0.1, 0.1, 0.0,
                            "reading − true position"),)
    per_joint, stage, acts_on = True, "sensors", "positions and pressures"
    trial_range = (math.radians(1.0), math.radians(3.0))   # rad; prismatic: the same in m

    def sense_q(self, crane: CraneLike, q):
        q = q.copy()
        q[:, self.index(crane)] += self.offset
        return q

    @classmethod
    def observable(cls, crane: CraneLike, i):
        # gravity does not depend on the slew angle (seed 001 needed an external calibrator)
        return not is_slew(crane, i)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(offset=sign * magnitude)


class PressureOffset(Effect):
    name = "pressure_offset"
    description = "constant bias of one actuator's two pressure transducers (zero drift)"
    signature = "constant pressure bias of one chamber or both, at rest and in motion"
    parameters = (Parameter("offset_a", "Pa", -2.0e6, 2.0e6, 0.0, "chamber a (piston side)"),
                  Parameter("offset_b", "Pa", -2.0e6, 2.0e6, 0.0, "chamber b (rod side)"))
    per_joint, stage, acts_on = True, "sensors", "pressures"
    trial_range = (0.3e6, 1.0e6)        # Pa, on one chamber drawn at random

    def sense_p(self, crane: CraneLike, p_a, p_b):
        i = self.index(crane)
        p_a, p_b = p_a.copy(), p_b.copy()
        p_a[:, i] += self.offset_a
        p_b[:, i] += self.offset_b
        return p_a, p_b

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return (dict(offset_a=sign * magnitude) if rng.uniform() < 0.5
                else dict(offset_b=sign * magnitude))
