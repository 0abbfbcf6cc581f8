"""The valves of a machine: their data from the spec, and the numeric faces of the one valve
definition (:mod:`planner.model.valve_physics`, CasADi; its doc has the physics).

* :func:`valve_params` -> :class:`ValveParams`: what the quasi-static model needs per actuator
  (flow gain at full command, dead band, metered area by direction, single-acting or not);
  :func:`valve_circuit` -> :class:`ValveCircuit`: what the dynamic valve section needs on top
  (both areas, the meter-out margin, the compensators' pressure drops, the tank pressure, a
  leakage coefficient), from the spec's ``[dynamics]`` (:mod:`planner.model.dynamics_spec`).
* the quasi-static faces the replay and the feed-forward use: :func:`command_to_stroke_rate`,
  :func:`steady_flows` (rate, metered flow and pump draw in one call),
  :func:`stroke_rate_to_command` (the inverse, dead band compensated), :func:`metered_flow`,
  :func:`draws_pump`;
* the dynamic faces (a twin's pressure equations, the cross-check against the judge):
  :func:`opening`, :func:`valve_flows`, :func:`makeup`, :func:`leak_flows`.

Every face evaluates the named CasADi function of :mod:`planner.model.valve_physics` through
the house's compiled, batched path (:class:`planner.model.numeric.Batched`): inputs broadcast
against each other over any leading axes (the last axis is the actuators, in spec order, and
the per-actuator data broadcast along it), outputs shaped like the broadcast inputs. No numpy
copy of the valve formulas exists any more; the spec's data are inputs of the compiled
functions, so one compiled copy serves every machine and every valve-stage effect.

The optional hydraulic transformer is not part of the valve model: with it enabled, part of
the target cylinder's flow bypasses its valve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.model.numeric import Elementwise
from planner.model.valve_physics import REST_TOL, function

__all__ = ["REST_TOL", "ValveParams", "valve_params", "ValveCircuit", "valve_circuit",
           "command_to_stroke_rate", "steady_flows", "stroke_rate_to_command", "metered_flow",
           "draws_pump", "opening", "valve_flows", "makeup", "leak_flows", "past_deadband",
           "within_deadband"]



@dataclass(frozen=True)
class ValveParams:
    """Per-actuator arrays (n,): metered areas by direction, flow gain, dead band."""
    area_extend: np.ndarray   # [m² | m³/rad] area metered while ẋ > 0
    area_retract: np.ndarray  # [m² | m³/rad] area metered while ẋ < 0
    flow_gain: np.ndarray     # [m³/s] flow at |u| = 1
    deadband: np.ndarray      # [-] fraction of the command range without flow
    single: np.ndarray        # bool: single-acting (lowering returns to tank, not from the pump)


def _spec(spec_or_crane):
    spec = getattr(spec_or_crane, "spec", spec_or_crane)
    if not hasattr(spec, "joints"):
        raise TypeError(f"expected a CraneSpec or a Crane, got {type(spec_or_crane).__name__}")
    return spec


def valve_params(spec_or_crane) -> ValveParams:
    """Valve data of every actuator of a spec (or crane); raises ValueError naming a joint
    without a finite positive flow gain or with a dead band outside [0, 1)."""
    spec = _spec(spec_or_crane)
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


@dataclass(frozen=True)
class ValveCircuit:
    """The dynamic valve section of a machine: per-actuator arrays (n,) ``gain`` [m³/s],
    ``deadband``, ``area_a``, ``area_b`` [m² | m³/rad], ``single`` (bool), ``leak``
    [m³/(s·Pa)]; scalars ``margin`` (meter-out margin), ``dp_c`` and ``dp_out`` [Pa] (the
    meter-in compensator's drop, the drop at the return cap), ``p_tank`` [Pa]."""
    gain: np.ndarray
    deadband: np.ndarray
    area_a: np.ndarray
    area_b: np.ndarray
    single: np.ndarray
    leak: np.ndarray
    margin: float
    dp_c: float
    dp_out: float
    p_tank: float


def valve_circuit(spec_or_crane, dynamics=None, gain_scale=1.0, deadband=None,
                  leak=None) -> ValveCircuit:
    """The :class:`ValveCircuit` of a spec (or crane) with its ``[dynamics]`` (or
    ``dynamics``, a :class:`~planner.model.dynamics_spec.DynamicsSpec`), per-valve gain
    factors ``gain_scale``, dead bands ``deadband`` (None: the spec's) and leakage
    coefficients ``leak`` (None: none). ValueError when the spec has no ``[dynamics]``."""
    spec = _spec(spec_or_crane)
    dyn = dynamics if dynamics is not None else getattr(spec, "dynamics", None)
    if dyn is None:
        raise ValueError(f"crane '{spec.id}': dynamics: the spec has no [dynamics] section "
                         "(the dynamic valve section needs compensator_dp, meter_out_dp, "
                         "meter_out_margin)")
    vp = valve_params(spec)
    n = spec.n

    def per(v, default):
        return np.broadcast_to(np.asarray(default if v is None else v, float), (n,)).copy()

    return ValveCircuit(gain=vp.flow_gain * per(gain_scale, 1.0),
                        deadband=per(deadband, vp.deadband),
                        area_a=np.array([j.actuator.area_a for j in spec.joints]),
                        area_b=np.array([j.actuator.area_b for j in spec.joints]),
                        single=vp.single.copy(), leak=per(leak, 0.0),
                        margin=float(dyn.meter_out_margin), dp_c=float(dyn.compensator_dp),
                        dp_out=float(dyn.meter_out_dp),
                        p_tank=float(spec.pump.tank_pressure))


# ----------------------------------------------------------------------------- the faces
_FACES: dict[str, Elementwise] = {}


def _call(name: str, *args) -> list[np.ndarray]:
    """The compiled, batched face of ``valve_physics.function(name)`` on broadcast arrays."""
    face = _FACES.get(name)
    if face is None:
        face = _FACES[name] = Elementwise(function(name))
    return face(*args)


def steady_flows(vp: ValveParams, u, flow_scale=1.0):
    """Commands (..., n) -> (stroke rates, metered flows ≥ 0 [m³/s], drawn from the pump
    (bool)), each (..., n): saturation at ±1, dead band, area by direction; ``flow_scale``
    (scalar or per joint) multiplies every valve's flow."""
    gain = np.asarray(flow_scale, float) * vp.flow_gain
    xd, q, draws = _call("valve_steady_state", u, gain, vp.deadband, vp.area_extend,
                         vp.area_retract, vp.single)
    return xd, q, draws > 0.5


def command_to_stroke_rate(vp: ValveParams, u, flow_scale=1.0) -> np.ndarray:
    """Commands (..., n) -> stroke rates (..., n) (see :func:`steady_flows`)."""
    return steady_flows(vp, u, flow_scale)[0]


def metered_flow(vp: ValveParams, xd) -> np.ndarray:
    """Flow through each valve [m³/s] (≥ 0) for stroke rates ``xd`` (..., n)."""
    return _call("valve_metered_flow", xd, vp.area_extend, vp.area_retract)[0]


def stroke_rate_to_command(vp: ValveParams, xd):
    """Stroke rates (..., n) -> (unclipped commands, signed valve flows [m³/s]): the inverse of
    :func:`command_to_stroke_rate` for |u| ≤ 1 outside the dead band; a flow of at most
    ``REST_TOL``·flow_gain counts as rest (u = 0, flow 0)."""
    u, flow = _call("valve_command", xd, vp.flow_gain, vp.deadband, vp.area_extend,
                    vp.area_retract)
    return u, flow


def draws_pump(vp: ValveParams, direction) -> np.ndarray:
    """Which valves take their flow from the pump (bool, shaped like ``direction`` (..., n)):
    all but a single-acting cylinder lowering (``direction`` ≤ 0; any signed quantity: a
    command, a flow or a stroke rate), whose oil goes to tank."""
    return _call("valve_draws_pump", direction, vp.single)[0] > 0.5


def opening(valves, spool) -> np.ndarray:
    """Effective openings (..., n) from spool positions (``valves``: anything with a
    per-actuator ``deadband``, a :class:`ValveParams` or a :class:`ValveCircuit`)."""
    return _call("valve_opening", spool, valves.deadband)[0]


def past_deadband(v, db):
    """Commands (..., n) that open the valves by ``v`` beyond their dead bands ``db`` (n,):
    sign(v)·(db + (1 − db)·|v|), 0 where v = 0 — the dead band's inverse, what a valve
    controller's dead-band compensation sends (planner.refine works in openings)."""
    v = np.asarray(v, float)
    return np.sign(v) * (db + (1.0 - db) * np.abs(v))


def within_deadband(u, db):
    """The openings (..., n) that commands ``u`` give past dead bands ``db``:
    sign(u)·max(|u| − db, 0)/(1 − db) (:func:`past_deadband`'s inverse where it opens)."""
    u = np.asarray(u, float)
    return np.sign(u) * np.maximum(np.abs(u) - db, 0.0) / (1.0 - db)


def valve_flows(vc: ValveCircuit, p_a, p_b, p_s, o) -> dict:
    """The valve sections at chamber pressures ``p_a``, ``p_b`` (..., n), pump pressure
    ``p_s`` (...) and openings ``o`` (..., n): dict of arrays (..., n) q_a, q_b (net valve flow
    into each chamber), q_in (from the pump), q_out (to tank), p_load (meter-in pressure of a
    drawing valve, else 0), net_a, net_b (valve + make-up − leakage into each chamber)."""
    p_s = np.asarray(p_s, float)[..., None]
    res = _call("valve_flows", p_a, p_b, p_s, o, vc.gain, vc.margin, vc.area_a, vc.area_b,
                vc.single, vc.leak, vc.p_tank, vc.dp_c, vc.dp_out)
    return dict(zip(("q_a", "q_b", "q_in", "q_out", "p_load", "net_a", "net_b"), res))


def makeup(vc: ValveCircuit, p) -> np.ndarray:
    """Anti-cavitation flow from tank into chambers at pressures ``p`` (..., n) [m³/s]."""
    return _call("valve_makeup", p, vc.p_tank, vc.gain)[0]


def leak_flows(vc: ValveCircuit, p_a, p_b):
    """Leakage (l_a, l_b) ≥ 0 [m³/s] of the loaded chamber to tank, each (..., n)."""
    l_a, l_b = _call("valve_leakage", p_a, p_b, vc.area_a, vc.area_b, vc.leak, vc.p_tank,
                     vc.single)
    return l_a, l_b
