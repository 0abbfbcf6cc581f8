"""Effects that change the motion: what the valves see of the commands (time_delay, valve_lag),
where the crane starts (start_offset), the valve and pump data (flow_gain, valve_deadband,
pump_flow_limit) and pressure-driven extra stroke (leakage)."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from planner.model.commands import delayed_held
from planner.model.effects.base import Effect, Parameter, is_slew
from planner.units import CraneLike


__all__ = ["valve_commands", "TimeDelay", "ValveLag", "StartOffset", "FlowGain",
           "ValveDeadband", "PumpFlowLimit", "Leakage"]

# a holding pressure (10 MPa above tank) and a pressure step (1 MPa) to size trial magnitudes
_HOLD_PRESSURE = 10e6


# ===================================================================== commands stage
#: a delayed or lagged command signal is carried this many delays (lag time constants) past
#: the last command (a lag's remainder then e⁻⁵ ≈ 0.7 % of its last step)
PAD_DELAYS = 5.0


def valve_commands(crane: CraneLike, effects, t_u, u, t_end: float, own_delay: float = 0.0):
    """(t_u, u, u_valves): the held commands ``u`` (M, n) from ``t_u`` (M,) and what the
    valves see of them after ``effects`` (the commands-stage effects a plant applies, in
    order) and a machine's own transport delay ``own_delay`` [s], for a plant that holds the
    last row until ``t_end`` [s].

    A delay or lag moves the commands' end later: the valves see the last command ``delay``
    after it was given. The effects act sample by sample on the grid, so without more rows
    the valves would hold, to ``t_end``, a value from one delay before the end (a plan's last
    correction, 3 s long instead of 20 ms; a lag's state, never reaching the last command).
    The grid is therefore extended past ``t_u[-1]``, within ``t_end``, by rows that hold the
    last command (what the plant holds anyway), :data:`PAD_DELAYS` × the summed delays and
    lags long; the commanded signal ``u`` is unchanged by it. The instants where a delayed
    command changes (t_u + each cumulative delay) are added to the grid, so the delayed signal
    is exact there (:func:`planner.model.commands.delayed_held`)."""
    acting = list(effects)
    t_u = np.asarray(t_u, float)
    delays = [float(e.delay) for e in acting if isinstance(e, TimeDelay) and e.delay > 0]
    delays += [float(own_delay)] if own_delay > 0 else []
    d = sum(float(e.command_delay) for e in acting) + max(float(own_delay), 0.0)
    if d > 0 and t_u.size > 1 and t_end > t_u[-1]:
        dt = float(np.median(np.diff(t_u)))
        k = int(math.ceil((min(t_end, t_u[-1] + PAD_DELAYS * d + dt) - t_u[-1]) / dt - 1e-9))
        if k > 0:
            t_u = np.concatenate([t_u, t_u[-1] + dt * np.arange(1, k + 1)])
            u = np.vstack([u, np.repeat(u[-1:], k, axis=0)])
    if delays and t_u.size > 1:
        # the instants where a delayed command changes: the delayed signal is then exact
        # on the grid (held, no interval means across a change)
        shifted = np.concatenate([t_u + c for c in np.cumsum(delays)])
        grid = np.union1d(t_u, shifted[shifted < t_u[-1]])
        keep = np.concatenate([[True], np.diff(grid) > 1e-9 * (grid[-1] - grid[0])])
        grid = grid[keep]
        j = np.clip(np.searchsorted(t_u, grid + 1e-12 * abs(grid).max(), side="right") - 1,
                    0, t_u.size - 1)
        t_u, u = grid, u[j]
    u_valves = u
    for e in acting:
        u_valves = e.commands(crane, t_u, u_valves)
    if own_delay > 0:
        u_valves = TimeDelay(delay=own_delay).commands(crane, t_u, u_valves)
    return t_u, u, u_valves


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
        # u(t − d), 0 before the record (a recording starts at rest): the interval means on
        # t_u, exact where the grid holds t_u + d (valve_commands adds those instants)
        return delayed_held(t_u, u, self.delay)

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
