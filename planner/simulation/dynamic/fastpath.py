"""The Exudyn plant's physics for one state, in plain Python: what the implicit integrator
evaluates several times per step (the residual of each Newton iteration and the columns of
its numerical Jacobian).

One call gives both halves of the coupled system at a state (q, q̇, p) — the stroke map x(q),
dx/dq (the dense tables of :class:`~planner.simulation.dynamic.bodies.StrokeTable`, linear
interpolation, x extrapolated linearly beyond the table and dx/dq held there), the joint
torques τ = dx/dq·(F − F_extra) of the actuator forces, and the pressure rates
(ṗ_a, ṗ_b, ṗ_s) of the circuit — so the stroke lookups are done once per state, not once
per callback (with the opt-in pressure-dependent bulk modulus of
:class:`~planner.simulation.dynamic.circuit.PressureBulk` when the circuit carries one). The
equations are those of
:class:`~planner.simulation.dynamic.circuit.Circuit` (its module doc); the numpy versions
there are the definition, and tests/simulation/test_exudyn.py checks this fast path against
them (plain Python because numpy's per-call overhead on 4-vectors would dominate).
"""
from __future__ import annotations

import math

from planner.simulation.dynamic.circuit import (DP_REG, STOP_DAMPING, STOP_RAMP, STOP_SOFT,
                                                STOP_STIFFNESS)

__all__ = ["state_function"]


def state_function(circuit, strokes):
    """``evaluate(q, qd, p, o, extra) -> (tau, pdot)`` for one state: joint positions and
    rates q, qd (lists, the crane's n joints first), the pressures p = [p_a (n), p_b (n), p_s]
    [Pa], the valve openings o (n) and the extra loads (n) the actuators work against;
    tau (n) the actuators' joint torques / forces, pdot (2n + 1) the pressure rates."""
    C, S = circuit, strokes
    n = C.n
    pt, dpc, beta = float(C.p_tank), float(C.dp_c), float(C.beta)
    dpo = float(C.dp_out)
    reg2 = DP_REG ** 2
    # each edge normalised by the regularised root at its regulating drop (circuit.root)
    sdpc = dpc / math.sqrt(math.sqrt(dpc * dpc + reg2))
    sdpo = dpo / math.sqrt(math.sqrt(dpo * dpo + reg2))
    ls = C.pump_kind == "load_sensing"
    standby, margin, relief = float(C.standby), float(C.margin), float(C.p_relief)
    p_const = float(C.p_set_const)
    qmax, k_pump, inv_tau = float(C.q_max), beta / float(C.v_pump), 1.0 / float(C.tau_pump)
    k_stop, c_stop = STOP_STIFFNESS, STOP_STIFFNESS * STOP_DAMPING
    tables, last = S.columns()
    law = C.bulk                      # None: β constant (the default, bit-identical)
    if law is not None:
        b_pa, b_ref = float(law.p_abs), float(law.p_ref) + float(law.p_abs)
        b_lo, b_hi = float(law.lo), float(law.hi)

        def bulk(pr):
            """β(p) of the pressure-dependent law (circuit.PressureBulk)."""
            r = (pr + b_pa) / b_ref
            return beta * (b_lo if r < b_lo else (b_hi if r > b_hi else r))
    joints = []
    for i in range(n):
        motor, single = bool(C.motor[i]), bool(C.single[i])
        joints.append((
            *tables[i],
            float(C.area_a[i]), float(C.area_b[i]), float(C.x_lo[i]), float(C.x_hi[i]),
            float(C.hose_a[i]), float(C.hose_b[i]), float(C.gain[i]), float(C.k_out_a[i]),
            float(C.k_out_b[i]), float(C.coulomb[i]), float(C.viscous[i]),
            float(C.v_smooth[i]), float(C.leak[i]), single, motor))
    sqrt, tanh = math.sqrt, math.tanh
    # the regularised root (circuit.root) is written out below: e / √√(e² + Δp_reg²)

    def evaluate(q, qd, p, o, extra):
        tau = [0.0] * n
        pdot = [0.0] * (2 * n + 1)
        ps = p[2 * n]
        qsum = pl_max = 0.0
        for i in range(n):
            (q0, h, X, D, Aa, Ab, lo, hi, hose_a, hose_b, gain, koa, kob, coul, visc, vs, leak,
             single, motor) = joints[i]
            # stroke map (the table)
            z = (q[i] - q0) / h
            k = int(z)
            k = 0 if k < 0 else (last if k > last else k)
            w = z - k
            x = X[k] + w * (X[k + 1] - X[k])
            d = D[k] + (0.0 if w < 0.0 else (1.0 if w > 1.0 else w)) * (D[k + 1] - D[k])
            xd = d * qd[i]
            pa, pb = p[i], p[n + i]
            # actuator force
            F = ((pa * Aa - (pt if single else pb) * Ab) - coul * tanh(xd / vs) - visc * xd)
            if not motor:
                over = (x - hi if x > hi else 0.0) - (lo - x if x < lo else 0.0)
                if over != 0.0:
                    a = abs(over)
                    spring = a * a / (2.0 * STOP_SOFT) if a < STOP_SOFT else a - 0.5 * STOP_SOFT
                    F -= k_stop * math.copysign(spring, over) + c_stop * (
                        a / STOP_RAMP if a < STOP_RAMP else 1.0) * xd
            tau[i] = d * (F - extra[i])
            # valve flows
            oi = o[i]
            ext = oi > 0
            mag = abs(oi)
            if ext:
                p_in, p_out = pa, pb
            else:
                p_in, p_out = pb, pa
            if single and not ext:
                q_in = 0.0
                e = pa - pt
                e = 0.0 if e < 0.0 else (dpc if e > dpc else e)
                q_out = gain * mag * (e / sqrt(sqrt(e * e + reg2))) / sdpc
            else:
                e = ps - p_in
                e = 0.0 if e < 0.0 else (dpc if e > dpc else e)
                q_in = gain * mag * (e / sqrt(sqrt(e * e + reg2))) / sdpc
                if single:
                    q_out = 0.0
                else:
                    e = p_out - pt
                    e = e if e < dpo else dpo
                    q_out = (kob if ext else koa) * mag * (e / sqrt(sqrt(e * e + reg2))) / sdpo
                if mag > 1e-6 and p_in > pl_max:
                    pl_max = p_in
            if ext:
                qa, qb = q_in, -q_out
            else:
                qa, qb = -q_out, q_in
            # chamber volumes, leakage, anti-cavitation, pressure build-up
            xc = lo if x < lo else (hi if x > hi else x)
            va = hose_a + (0.0 if motor else Aa * (xc - lo))
            la = lb = 0.0
            if leak:    # the loaded side's share blended over ±0.2 bar (loaded_share)
                w = (pa - pb * Ab / Aa) / DP_REG
                w = 1.0 / (1.0 + math.exp(-2.0 * (-40.0 if w < -40.0 else
                                                  (40.0 if w > 40.0 else w))))
                la = w * leak * (pa - pt if pa > pt else 0.0)
                if not single:
                    lb = (1.0 - w) * leak * (pb - pt if pb > pt else 0.0)
            mk = gain / 1e6
            e = pt - pa if pa < pt else 0.0
            ba = beta if law is None else bulk(pa)
            pdot[i] = ba / va * (qa - Aa * xd - la + mk * e * e / (e + DP_REG))
            if not single:
                vb = hose_b + (0.0 if motor else Ab * (hi - xc))
                e = pt - pb if pb < pt else 0.0
                bb = beta if law is None else bulk(pb)
                pdot[n + i] = bb / vb * (qb + Ab * xd - lb + mk * e * e / (e + DP_REG))
            qsum += q_in
        if ls:
            pset = pl_max + margin if pl_max > 0 else 0.0
            pset = min(max(standby, pset), relief)
        else:
            pset = p_const
        excess = qsum - qmax
        if excess > 0.0 and law is not None:
            excess *= bulk(ps) / beta
        pdot[2 * n] = (pset - ps) * inv_tau - k_pump * (excess if excess > 0.0 else 0.0)
        return tau, pdot

    return evaluate
