"""Energy balance of a dynamic-plant run: where the pump's work went.

pump work (hydraulic, ∫ p_s·Q_pump dt) = Δ(pump-line oil energy) + meter-in throttling
+ meter-out throttling + return to tank + leakage + anti-cavitation make-up + actuator friction
+ Δ(chamber oil energy, Σ V·p²/2β) + Δ(kinetic + potential energy) + residual.

Every term except the mechanical one comes from the run's own states through the circuit's
flow definitions; the kinetic and potential energies come from the project's model of the same
masses (``plant.true_crane``): E_kin = ½ q̇ᵀ M(q) q̇ with M q̇ = ID(q, 0, q̇) − ID(q, 0, 0) —
so a closed balance also says the Exudyn multibody and the model agree on the mechanics (with a
grapple link, plus what the swinging load adds: :func:`~planner.simulation.dynamic.grapple.
swing_energy`, term ``grapple_swing_J``, and the pins' damping, ``grapple_damping_J``). The
residual (integration error, the second-order oil-energy terms) is reported relative to the
pump work. Pump energy at the shaft = pump work / η (what :func:`planner.trajectory.evaluate`
reports as ``energy_J`` for the quasi-static model).
"""
from __future__ import annotations

import numpy as np

from planner.simulation.dynamic.grapple import swing_energy

__all__ = ["energy_balance"]


def _integral(t, p):
    return float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(t)))


def energy_balance(plant, run) -> dict:
    """The balance of ``run`` (a :class:`DynamicRun` of ``plant``) in J (see the module doc):
    pump_work_J, pump_shaft_J, the terms, residual_J and residual_rel."""
    C = run.circuit
    t = run.t
    # the opening in force over [t_k, t_k+1] is the spool set at the start of that step
    spool = np.vstack([run.spool[1:], run.spool[-1:]])
    o = C.opening(spool)
    f = C.flows(run.p_a, run.p_b, run.p_s, o)
    pt = C.p_tank
    p_in = np.where(o > 0, run.p_a, run.p_b)
    q_in_sum = np.sum(f["q_in"], axis=1)
    la, lb = C.leak_flows(run.p_a, run.p_b)
    mk_a, mk_b = C.makeup(run.p_a), C.makeup(run.p_b)
    mk_b = np.where(C.single, 0.0, mk_b)
    terms = dict(
        meter_in_J=_integral(t, np.sum(f["q_in"] * (run.p_s[:, None] - p_in), axis=1)),
        meter_out_J=_integral(t, np.sum(f["q_out"] * f["dp_out"], axis=1)),
        tank_return_J=_integral(t, np.sum(f["q_out"] * pt, axis=1)),
        leakage_J=_integral(t, np.sum(la * (run.p_a - pt)
                                      + lb * (np.where(C.single, pt, run.p_b) - pt), axis=1)),
        makeup_J=_integral(t, np.sum(mk_a * (pt - run.p_a) + mk_b * (pt - run.p_b), axis=1)),
        friction_J=_integral(t, np.sum(C.friction(run.xd) * run.xd, axis=1)),
        end_stops_J=-_integral(t, np.sum(C.stop_force(run.x, run.xd) * run.xd, axis=1)))
    va, vb = C.volumes(run.x)
    pb = np.where(C.single, pt, run.p_b)
    e_oil = np.sum(va * run.p_a ** 2 + np.where(C.single, 0.0, vb * pb ** 2), axis=1) / (2 * C.beta)
    e_line = C.v_pump * run.p_s ** 2 / (2 * C.beta)
    crane = plant.true_crane
    z = np.zeros_like(run.q)
    m_qd = (crane.inverse_dynamics(run.q, z, run.qd, run.payload)
            - crane.inverse_dynamics(run.q, z, z, run.payload))
    e_kin = 0.5 * np.sum(run.qd * m_qd, axis=1)
    e_pot = crane.potential_energy(run.q, run.payload)
    if run.grapple_q is not None:   # the load swinging on its link, beyond the point mass
        ends = [0, -1]
        e_sw = swing_energy(plant.tree, np.hstack([run.q[ends], run.grapple_q[ends]]),
                            np.hstack([run.qd[ends], run.grapple_qd[ends]]),
                            crane.spec.gravity)
        terms["grapple_swing_J"] = float(e_sw[1] - e_sw[0])
        terms["grapple_damping_J"] = _integral(t, plant.tree["grapple"].damping
                                               * np.sum(run.grapple_qd ** 2, axis=1))
    terms.update(oil_J=float(e_oil[-1] - e_oil[0]), pump_line_J=float(e_line[-1] - e_line[0]),
                 kinetic_J=float(e_kin[-1] - e_kin[0]),
                 potential_J=float(e_pot[-1] - e_pot[0]))
    work = _integral(t, run.p_s * q_in_sum) + terms["pump_line_J"]
    resid = work - sum(terms.values())
    return dict(pump_work_J=work, pump_shaft_J=work / C.efficiency, **terms,
                residual_J=resid, residual_rel=resid / max(abs(work), 1e-9))
