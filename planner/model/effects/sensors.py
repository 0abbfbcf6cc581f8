"""Sensor effects beyond a constant offset: a scale error of a position sensor (sensor_gain),
a position sensor that drifts with time (sensor_drift) and pressure transducers that drift
with time (pressure_drift). They change only what the sensors report (stage "sensors"); the
plant fits the start pose through them (reading = bias + gain · true position), so a fit sees
them as they are and not as a different start.

A drift is counted from the first sample of the recording (the sensors were zeroed when the
logger started): reading = true + rate · (t − t₀).
"""
from __future__ import annotations

import math

import numpy as np

from planner.model.effects.base import Effect, Parameter, is_slew
from planner.units import CraneLike


__all__ = ["SensorGain", "SensorDrift", "PressureDrift"]


def _elapsed(t, like) -> np.ndarray:
    """(N, 1) time since the first sample, broadcast against ``like`` (N, n)."""
    t = np.asarray(t, float).reshape(-1, 1)
    if len(t) != len(like):
        raise ValueError(f"sensor effect: {len(t)} sample times for {len(like)} readings")
    return t - t[0]


class SensorGain(Effect):
    name = "sensor_gain"
    description = ("a scale error of one joint's position sensor (resolver or encoder "
                   "gearing, a wrong counts-per-unit): reading = scale × true position")
    signature = ("position error ∝ the distance from the sensor's zero, as if the flow gain "
                 "were off, but the pressures are computed at the true pose: a pose-dependent "
                 "gravity bias that grows with the joint's angle")
    parameters = (Parameter("scale", "1", 0.9, 1.1, 1.0, "reading / true position"),)
    per_joint, stage, acts_on = True, "sensors", "positions and pressures"
    trial_range = (0.02, 0.05)          # relative scale error

    def sense_q(self, crane: CraneLike, q):
        q = q.copy()
        q[:, self.index(crane)] *= self.scale
        return q

    @classmethod
    def observable(cls, crane: CraneLike, i):
        # on the slew the pressures do not depend on the angle: only flow_gain-like motion
        return not is_slew(crane, i)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(scale=1.0 + sign * magnitude)


class SensorDrift(Effect):
    name = "sensor_drift"
    description = ("one joint's position reading drifts at a constant rate from the start "
                   "of the recording (temperature, a slipping coupling, an integrating "
                   "sensor): reading = true + rate × (t − t₀)")
    signature = ("a position residual growing linearly in time, at rest and in motion, "
                 "independent of the commands; pressures follow the true pose")
    parameters = (Parameter("rate", "rad/s (m/s for prismatic joints)", -0.01, 0.01, 0.0,
                            "drift of the reading"),)
    per_joint, stage, acts_on = True, "sensors", "positions"
    trial_range = (math.radians(0.03), math.radians(0.1))   # rad/s; prismatic: the same in m/s

    def sense_q_at(self, crane: CraneLike, t, q):
        q = q.copy()
        q[:, self.index(crane)] += self.rate * _elapsed(t, q)[:, 0]
        return q

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(rate=sign * magnitude)


class PressureDrift(Effect):
    name = "pressure_drift"
    description = ("one actuator's pressure transducers drift at a constant rate from the "
                   "start of the recording (temperature): reading = true + rate × (t − t₀)")
    signature = "a pressure residual of one chamber or both growing linearly in time"
    parameters = (Parameter("rate_a", "Pa/s", -5.0e4, 5.0e4, 0.0, "chamber a (piston side)"),
                  Parameter("rate_b", "Pa/s", -5.0e4, 5.0e4, 0.0, "chamber b (rod side)"))
    per_joint, stage, acts_on = True, "sensors", "pressures"
    trial_range = (5.0e3, 2.0e4)        # Pa/s on one chamber drawn at random

    def sense_p_at(self, crane: CraneLike, t, p_a, p_b):
        i = self.index(crane)
        p_a, p_b = p_a.copy(), p_b.copy()
        dt = _elapsed(t, p_a)[:, 0]
        p_a[:, i] += self.rate_a * dt
        p_b[:, i] += self.rate_b * dt
        return p_a, p_b

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return (dict(rate_a=sign * magnitude) if rng.uniform() < 0.5
                else dict(rate_b=sign * magnitude))
