"""The valve model (numpy): valve data per joint, command <-> stroke rate, dead band, and which
functions the pump feeds.

* **pressure-compensated proportional valve**: the flow through the valve depends on the spool
  command only, not on the load; ``flow_gain`` [m³/s] is the flow at full command (|u| = 1).
* **dead band** ``deadband`` (fraction of the command range): |u| ≤ deadband gives no flow;
  beyond it the flow rises linearly, Q = flow_gain·(|u| − deadband)/(1 − deadband). The inverse
  (:func:`stroke_rate_to_command`) compensates it: u = sign(ẋ)·(deadband + (1 − deadband)·
  Q/flow_gain) for Q > 0, and u = 0 at rest (no jump to the dead-band edge while the actuator
  stands still).
* **metered flow and area by direction**: the valve meters the flow of the chamber it feeds,
  Q = A·|ẋ| with A = area_a (piston side) while extending (ẋ > 0) and A = area_b (annulus)
  while retracting. A *single-acting* cylinder has no annulus connection: lowering is gravity
  driven and the valve meters the oil *leaving the piston side* to tank, so A = area_a in both
  directions (only the sign of u changes) — and that flow does not come from the pump
  (:func:`draws_pump`). Rotary drives use the motor displacement (area_a = area_b) and the
  motor angle as "stroke".
* The optional hydraulic transformer is not part of the valve model: with it enabled, part of
  the target cylinder's flow bypasses its valve.

This module imports nothing from the package (the spec parser's effect catalogue uses it), so
it reads the spec's actuators itself; :mod:`planner.model.flows` is the pump side.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["REST_TOL", "ValveParams", "valve_params", "command_to_stroke_rate",
           "stroke_rate_to_command", "metered_flow", "draws_pump"]

REST_TOL = 1e-9  # |Q| ≤ REST_TOL·flow_gain counts as "at rest": u = 0, no dead-band jump


@dataclass(frozen=True)
class ValveParams:
    """Per-actuator arrays (n,): metered areas by direction, flow gain, dead band."""
    area_extend: np.ndarray   # [m² | m³/rad] area metered while ẋ > 0
    area_retract: np.ndarray  # [m² | m³/rad] area metered while ẋ < 0
    flow_gain: np.ndarray     # [m³/s] flow at |u| = 1
    deadband: np.ndarray      # [-] fraction of the command range without flow
    single: np.ndarray        # bool: single-acting (lowering returns to tank, not from the pump)


def valve_params(spec_or_crane) -> ValveParams:
    """Valve data of every actuator of a spec (or crane); raises ValueError naming a joint
    without a finite positive flow gain or with a dead band outside [0, 1)."""
    spec = getattr(spec_or_crane, "spec", spec_or_crane)
    if not hasattr(spec, "joints"):
        raise TypeError(f"expected a CraneSpec or a Crane, got {type(spec_or_crane).__name__}")
    acts = [j.actuator for j in spec.joints]
    for j, a in zip(spec.joints, acts):
        if not (math.isfinite(a.flow_gain) and a.flow_gain > 0):
            raise ValueError(f"crane '{spec.id}': joint '{j.name}' has no finite valve "
                             f"flow_gain ({a.flow_gain}); feed-forward commands need one")
        if not 0.0 <= a.deadband < 1.0:
            raise ValueError(f"crane '{spec.id}': joint '{j.name}' deadband "
                             f"{a.deadband} outside [0, 1)")
    single = np.array([a.acting == "single" for a in acts])
    area_a = np.array([a.area_a for a in acts])
    # single-acting: lowering meters the oil leaving the piston side
    return ValveParams(area_extend=area_a,
                       area_retract=np.where(single, area_a, [a.area_b for a in acts]),
                       flow_gain=np.array([a.flow_gain for a in acts]),
                       deadband=np.array([a.deadband for a in acts]), single=single)


def command_to_stroke_rate(vp: ValveParams, u, flow_scale=1.0) -> np.ndarray:
    """Commands (..., n) -> stroke rates (..., n): saturation at ±1, dead band, area by
    direction; ``flow_scale`` (scalar or per joint) multiplies every valve's flow."""
    u = np.clip(u, -1.0, 1.0)
    mag = np.maximum(np.abs(u) - vp.deadband, 0.0) / (1.0 - vp.deadband)
    Q = np.asarray(flow_scale, float) * vp.flow_gain * mag
    area = np.where(u > 0, vp.area_extend, vp.area_retract)
    return np.sign(u) * Q / area


def metered_flow(vp: ValveParams, xd) -> np.ndarray:
    """Flow through each valve [m³/s] (≥ 0) for stroke rates ``xd`` (..., n)."""
    xd = np.asarray(xd, float)
    return np.where(xd > 0, vp.area_extend, vp.area_retract) * np.abs(xd)


def stroke_rate_to_command(vp: ValveParams, xd):
    """Stroke rates (..., n) -> (unclipped commands, signed valve flows [m³/s]): the inverse of
    :func:`command_to_stroke_rate` for |u| ≤ 1 outside the dead band; a flow of at most
    ``REST_TOL``·flow_gain counts as rest (u = 0, flow 0)."""
    xd = np.asarray(xd, float)
    Q = metered_flow(vp, xd)
    moving = Q > REST_TOL * vp.flow_gain
    u = np.where(moving, np.sign(xd) * (vp.deadband + (1.0 - vp.deadband) * Q / vp.flow_gain),
                 0.0)
    return u, np.where(moving, np.sign(xd) * Q, 0.0)


def draws_pump(vp: ValveParams, direction) -> np.ndarray:
    """Which valves take their flow from the pump (bool, shaped like ``direction`` (..., n)):
    all but a single-acting cylinder lowering (``direction`` ≤ 0; any signed quantity: a
    command, a flow or a stroke rate), whose oil goes to tank."""
    return (np.asarray(direction) > 0) | ~vp.single
