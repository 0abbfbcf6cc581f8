"""Effects that change the motion: what the valves see of the commands (time_delay, valve_lag),
where the crane starts (start_offset), the valve and pump data (flow_gain, valve_deadband,
pump_flow_limit) and pressure-driven extra stroke (leakage)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from planner.model.effects.base import Effect, Parameter, is_slew
from planner.units import CraneLike


__all__ = ["TimeDelay", "ValveLag", "StartOffset", "FlowGain", "ValveDeadband", "PumpFlowLimit",
           "Leakage"]

# a holding pressure (10 MPa above tank) and a pressure step (1 MPa) to size trial magnitudes
_HOLD_PRESSURE = 10e6


# ===================================================================== commands stage
class TimeDelay(Effect):
    name = "time_delay"
    description = ("transport delay between the command and the valves (bus, controller cycle, "
                   "pilot stage), the same for every function")
    signature = ("positions lag the simulation in every moving joint at once; error ∝ speed, "
                 "changes sign when the motion reverses; pressures shifted in time")
    parameters = (Parameter("delay", "s", 0.0, 0.3, 0.0, "pure delay of every command"),)
    stage, acts_on = "commands", "positions and pressures"
    trial_range = (0.06, 0.20)          # s

    @property
    def command_delay(self) -> float:
        return self.delay

    def commands(self, crane: CraneLike, t_u, u):
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

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(delay=magnitude)


class ValveLag(Effect):
    name = "valve_lag"
    description = ("first-order spool dynamics of one valve: the flow follows the command with "
                   "a time constant")
    signature = ("one joint lags after command steps and overshoots the simulation when "
                 "the command falls; the error ∝ command rate; other joints unaffected")
    parameters = (Parameter("tau", "s", 0.0, 0.5, 0.0, "time constant of the valve"),)
    per_joint, stage, acts_on = True, "commands", "positions and pressures"
    trial_range = (0.08, 0.25)          # s

    @property
    def command_delay(self) -> float:
        return self.tau

    def commands(self, crane: CraneLike, t_u, u):
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

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(tau=magnitude)


# ===================================================================== start stage
class StartOffset(Effect):
    """Not in the catalogue: a start-pose mismatch is a nuisance parameter that every fit
    removes (the start is fitted to the measured positions), so no recording can name it. The
    robustness study perturbs the plant with it (:class:`planner.simulation.replay.Plant`)."""
    name = "start_offset"
    description = "the crane starts away from the nominal initial configuration"
    signature = "every replayed position shifted from the start on; removed by a fitted start"
    parameters = (Parameter("offset", "rad (m for prismatic joints)", -0.1, 0.1, 0.0,
                            "true start − nominal start"),)
    per_joint, stage, acts_on = True, "start", "positions and pressures"

    def start(self, crane: CraneLike, q0):
        q0 = np.array(q0, float)
        q0[self.index(crane)] += self.offset
        return q0


# ===================================================================== valves stage
class FlowGain(Effect):
    name = "flow_gain"
    description = "the valve of one function passes a different flow than the spec's gain"
    signature = ("one joint moves proportionally too far (scale > 1) or too short; the error "
                 "grows with the distance travelled and returns when the motion reverses; "
                 "nothing at rest")
    parameters = (Parameter("scale", "1", 0.5, 1.5, 1.0, "true flow gain / spec flow gain"),)
    per_joint, stage, acts_on = True, "valves", "positions and pressures"
    trial_range = (0.05, 0.20)          # relative gain error

    def valves(self, crane: CraneLike, v):
        g = np.array(v.flow_gain_scale, float)
        g[self.index(crane)] *= self.scale
        return replace(v, flow_gain_scale=g)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(scale=1.0 + sign * magnitude)


class ValveDeadband(Effect):
    name = "valve_deadband"
    description = ("the dead band of one valve (spool overlap) differs from the spec's, "
                   "which the feed-forward compensates")
    signature = ("one joint moves too little (wider band) or too much at small commands; the "
                 "relative error is largest at low speed and vanishes at full command")
    parameters = (Parameter("width", "1", 0.0, 0.4, 0.0,
                            "true dead band as a fraction of the command range"),)
    per_joint, stage, acts_on = True, "valves", "positions and pressures"
    trial_range = (0.08, 0.20)          # widening of the spec's band (absolute)

    def neutral_vector(self, crane: CraneLike):
        return np.array([crane.spec.joints[self.index(crane)].actuator.deadband])

    def valves(self, crane: CraneLike, v):
        db = np.array(v.deadband, float)
        db[self.index(crane)] = self.width
        return replace(v, deadband=db)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        return dict(width=min(crane.spec.joints[i].actuator.deadband + magnitude, 0.4))


class PumpFlowLimit(Effect):
    name = "pump_flow_limit"
    description = "the pump delivers less than the spec's maximum flow (wear, engine speed)"
    signature = ("only while the functions together ask for more than the pump gives: every "
                 "pump-fed joint slows by the same factor; nothing at low demand")
    parameters = (Parameter("scale", "1", 0.1, 1.0, 1.0,
                            "true maximum pump flow / spec maximum flow"),)
    stage, acts_on = "valves", "positions and pressures"
    trial_range = (0.15, 0.40)          # shortfall relative to the sequence's peak demand

    def valves(self, crane: CraneLike, v):
        return replace(v, pump_flow_scale=v.pump_flow_scale * self.scale)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        # a pump short of what the test sequence asks at its peak (else it never shows)
        peak = 1.0 if sequence is None else sequence.peak_demand
        return dict(scale=max(peak * (1.0 - magnitude), 0.1))


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
    trial_range = (0.5e-3, 2e-3)        # m/s: drift speed of the held cylinder at 10 MPa

    def drift(self, crane: CraneLike, s):
        pt = crane.spec.pump.tank_pressure

        def rate(i):   # out of the loaded chamber: towards the load
            a = crane.spec.joints[i].actuator
            return np.where(s.force[:, i] >= 0,
                            -self.coefficient * (s.p_a[:, i] - pt) / a.area_a,
                            self.coefficient * (s.p_b[:, i] - pt) / a.area_b)
        return self.on_own_joint(crane, s.xd, rate)

    def dynamics(self, crane: CraneLike, dyn):
        # a dynamic plant: a flow from the loaded chamber to tank, ∝ its pressure
        self.index(crane)
        j = dyn.joints[self.joint]
        j2 = replace(j, leakage=j.leakage + self.coefficient)
        return replace(dyn, joints={**dyn.joints, self.joint: j2})

    @classmethod
    def observable(cls, crane: CraneLike, i):
        # the slew drive holds no gravity load, so nothing drives a leak
        return not is_slew(crane, i)

    @classmethod
    def trial_values(cls, crane: CraneLike, i, magnitude, sign, rng, sequence):
        # C = v·A / p: the drift speed at the holding pressure
        return dict(coefficient=magnitude * crane.spec.joints[i].actuator.area_a
                    / _HOLD_PRESSURE)
