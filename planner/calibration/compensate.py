"""Compensation: feed-forward re-planned on the calibrated model (the nominal model plus the
identified effects), and its open-loop tracking against the plain feed-forward (the calibrated
model's spec text: :func:`planner.calibration.calibrated.calibrated_spec_text`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.feedforward import commands
from planner.methods.nlp import stretch
from planner.model.valves import command_to_stroke_rate, draws_pump, valve_params
from planner.simulation.plant import respond
from planner.simulation.replay import valve_set

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["compensate", "closed_loop"]


def compensate(crane: Crane, plan, effects, rate: float = 50.0, iterations: int = 10):
    """Re-plan the feed-forward of ``plan`` on the calibrated model (the plant *with*
    ``effects``). Returns (plan_used, t, u, q0_reading):

    - a pump that gives less than the plan needs (pump_flow_limit): the plan is slowed
      uniformly until its peak pump demand fits the calibrated pump (+2 % margin) — no command
      can make the true plant follow the original timing;
    - kinematic effects (gain, dead band, lag, delay, leakage): the nominal commands, then
      iterative learning on the calibrated model: per joint, the stroke-rate error ``d``
      samples ahead (d from the effects' command delays: delays, lags) corrected through the nominal valve gain
      (D-type ILC: the plant is an integrator, so rate errors fixed leave no position error);
    - sensor offsets: the crane is positioned before the move until its sensors read the
      plan's start plus the offsets (``q0_reading``);
    - pressure-only effects need no change of the commands."""
    effects = tuple(effects)
    bias = np.zeros((1, crane.n))
    for e in effects:
        bias = e.sense_q(crane, bias)
    pump_scale = valve_set(crane, effects).pump_flow_scale
    vp = valve_params(crane)
    ff = commands(crane, plan, rate)
    if pump_scale < 1.0:
        # pump flow the plan asks for (valve flows of the functions fed by the pump)
        draws = draws_pump(vp, ff.flow)
        need = float(np.max(np.sum(np.where(draws, np.abs(ff.flow), 0.0), axis=1)))
        avail = crane.spec.pump.max_flow * pump_scale
        if need > avail:
            plan = stretch(plan, plan.duration * 1.02 * need / avail)
            ff = commands(crane, plan, rate)
    t, u = ff.t, ff.u.copy()
    q0_reading = plan.q[0] + bias[0]
    kin = tuple(e for e in effects if e.kinematic)
    if not kin:
        return plan, t, u, q0_reading
    x_des = crane.stroke(plan.sample(t)[0])[0]
    g = 0.5 * (command_to_stroke_rate(vp, np.ones((1, crane.n)))[0]
               - command_to_stroke_rate(vp, -np.ones((1, crane.n)))[0])
    dt = 1.0 / rate
    d = int(round(sum(e.command_delay for e in kin) / dt))
    for _ in range(iterations):
        r = respond(crane, t, u, plan.q[0], kin, t_end=t[-1])
        e_x = x_des - crane.stroke(r.state.q)[0]
        e_ahead = np.vstack([e_x[d:], np.repeat(e_x[-1:], d, axis=0)]) if d else e_x
        rate_err = np.vstack([np.diff(e_ahead, axis=0) / dt, np.zeros((1, crane.n))])
        u = np.clip(u + 0.7 * rate_err / g, -1.0, 1.0)
    return plan, t, u, q0_reading


def closed_loop(crane: Crane, plan, calibrated, plant_effects=None, rate: float = 50.0) -> dict:
    """Open-loop tracking of ``plan`` on a plant with ``plant_effects`` (default: the
    calibrated effects themselves — a prediction), with the nominal feed-forward and with the
    feed-forward re-planned on the calibrated model (:func:`compensate`). The crane is
    positioned at the start with its (possibly biased) sensors. Tip error [m] vs the plan:
    max and RMS, before and after."""
    truth = tuple(calibrated if plant_effects is None else plant_effects)
    bias = np.zeros((1, crane.n))
    for e in truth:
        bias = e.sense_q(crane, bias)

    def run(p, t, u, q_read):
        q_true0 = q_read - bias[0]     # positioned until the sensors read q_read
        r = respond(crane, t, u, q_true0, truth, t_end=t[-1])
        e = np.linalg.norm(crane.fk(r.state.q) - crane.fk(p.sample(r.t)[0]), axis=1)
        return dict(max_m=float(e.max()), rms_m=float(np.sqrt(np.mean(e ** 2))),
                    final_m=float(e[-1]), duration_s=float(p.duration))
    ff = commands(crane, plan, rate)
    before = run(plan, ff.t, ff.u, plan.q[0])
    p2, t, u, q_read = compensate(crane, plan, calibrated, rate)
    after = run(p2, t, u, q_read)
    return dict(before=before, after=after, predicted=plant_effects is None,
                reduction=(1.0 - after["rms_m"] / before["rms_m"]) if before["rms_m"] > 0
                else 0.0)
