"""Hydraulics: actuator flows, chamber pressures, load-sensing pump (symbolic).

Per actuator i with stroke rate ẋ and required force F = τ / (dx/dq) (virtual work):
* pump flow drawn (direction-dependent areas): Q = A_a·ẋ⁺ + A_b·ẋ⁻ for double-acting,
  Q = A_a·ẋ⁺ for single-acting (lowering returns oil to tank under gravity, draws nothing) —
  the metered flow of the one valve definition (:func:`planner.model.valve_physics.
  metered_flow`) with the area the pump fills while retracting;
* chamber pressures from the force, assuming ideal load-holding valves on the loaded side:
  F ≥ 0: p_a = (F + A_b·p_t)/A_a, p_b = p_t;  F < 0: p_b = (A_a·p_t − F)/A_b, p_a = p_t;
* load pressure seen by the LS line: the meter-in chamber's pressure (p_a extending, p_b
  retracting), only while the actuator draws flow — more than ACTIVE_FLOW·Q_max (10⁻⁴ of the
  pump's maximum: a valve in its dead band passes nothing, and numerical crumbs of motion must
  not switch the pump to another function's load pressure) — the seed pricing; the machine
  pricing's threshold is the valve's own, OPEN_EPS·G (see :mod:`planner.model.pricing`);
* pump: load sensing p_pump = max(standby, max_active p_load + margin); constant pressure
  p_pump = set pressure; pump power = p_pump·ΣQ / η (seed 002), energy = ∫ power dt.
* hydraulic transformer (seed 002, optional): the rod side of the source cylinder is coupled to
  the piston side of the target: the target moves by pump flow plus ratio·A_b,s·ẋ_s, so the pump
  supplies Q_t = A_a,t·(ẋ_t − k·ẋ_s)⁺ with k = ratio·A_b,s/A_a,t; the source's rod side then
  needs no pump flow; ideal units give p_b,s = ratio·p_a,t.
* pricing (:mod:`planner.model.pricing`): the above is the seed pricing; the machine pricing
  adds the actuators' friction to the force and, while an actuator moves, the load-holding
  valve's counter-pressure on its outlet (an overrunning load held by the outlet, the inlet
  at tank) — so lowering and braking cost pump work as on the machine.
"""
from __future__ import annotations

import casadi as ca

from planner.model.pricing import ACTIVE_FLOW, Pricing, friction, moving_pressures, pricing_of
from planner.model.spec import CraneSpec
from planner.model.valve_physics import metered_flow

OUTPUTS = ("x", "xd", "force", "p_a", "p_b", "p_load", "q_act", "p_pump", "q_pump", "power",
           "throttle_loss")


def hydraulics(spec: CraneSpec, x, xd, force, pricing: Pricing | None = None):
    """Symbolic hydraulic quantities. x, xd, force: n-vectors (stroke [m|rad], rate, force
    [N|N·m], the force the motion requires: friction is the pricing's). ``pricing``: a
    :class:`~planner.model.pricing.Pricing` (default: the spec's, :func:`pricing_of`).
    Returns a dict with the names of :data:`OUTPUTS` (vectors per actuator, scalars for the
    pump)."""
    pr = pricing_of(spec) if pricing is None else pricing
    pump = spec.pump
    pt = pump.tank_pressure
    eps = ACTIVE_FLOW * pump.max_flow
    n = spec.n
    ht = spec.transformer if (spec.transformer and spec.transformer.enabled) else None
    hs = spec.joint_index(ht.source_joint) if ht else -1
    htg = spec.joint_index(ht.target_joint) if ht else -1
    p_a, p_b, p_load, q_act = [], [], [], []
    for i, j in enumerate(spec.joints):
        act = j.actuator
        Aa, Ab = act.area_a, act.area_b
        F = force[i]
        v = xd[i]
        single = act.acting == "single"
        coupled = i in (hs, htg)
        if pr.machine and (single or coupled):
            F = F + friction(pr, i, v)
        if single:
            pa = pt + ca.fmax(F, 0) / Aa
            pb = ca.DM(pt)
        else:
            pa = ca.if_else(F >= 0, (F + Ab * pt) / Aa, pt)
            pb = ca.if_else(F >= 0, pt, (Aa * pt - F) / Ab)
            if pr.machine and not coupled:
                pa, pb = moving_pressures(pr, Aa, Ab, pt, i, F, v, pa, pb)
        if i == htg:
            k = ht.ratio * spec.joints[hs].actuator.area_b / Aa
            Q = metered_flow(v - k * xd[hs], Aa, 0.0)
        elif i == hs or single:
            Q = metered_flow(v, Aa, 0.0)
        else:
            Q = metered_flow(v, Aa, Ab)
        pL = ca.if_else(v > 0, pa, ca.if_else(v < 0, pb, 0))
        p_a.append(pa)
        p_b.append(pb)
        p_load.append(ca.if_else(Q > pr.active[i], pL, 0))
        q_act.append(Q)
    if ht is not None:
        # coupled units: the source's rod side sits at ratio·(target piston pressure)
        pbs = ht.ratio * p_a[htg]
        Aa, Ab = spec.joints[hs].actuator.area_a, spec.joints[hs].actuator.area_b
        p_b[hs] = pbs
        p_a[hs] = ca.fmax((force[hs] + friction(pr, hs, xd[hs]) + Ab * pbs) / Aa, pt)
        p_load[hs] = ca.if_else(q_act[hs] > pr.active[hs], p_a[hs], 0)
    Qp = sum(q_act[1:], q_act[0])
    if pump.kind == "load_sensing":
        pmax = p_load[0]
        for pl in p_load[1:]:
            pmax = ca.fmax(pmax, pl)
        if pr.machine:   # the pump answers any drawing function (machine: any open valve)
            drawing = q_act[0] > pr.active[0]
            for i in range(1, n):
                drawing = ca.logic_or(drawing, q_act[i] > pr.active[i])
        else:
            drawing = Qp > eps
        p_pump = ca.fmax(pump.standby, ca.if_else(drawing, pmax + pump.margin, 0))
    else:
        p_pump = ca.DM(pump.pressure) + 0 * Qp
    power = p_pump * Qp / pump.efficiency
    loss = sum(((p_pump - p_load[i]) * q_act[i] for i in range(1, n)),
               (p_pump - p_load[0]) * q_act[0])
    return dict(x=x, xd=xd, force=force, p_a=ca.vertcat(*p_a), p_b=ca.vertcat(*p_b),
                p_load=ca.vertcat(*p_load), q_act=ca.vertcat(*q_act), p_pump=p_pump,
                q_pump=Qp, power=power, throttle_loss=loss)
