"""The pump rows of the move NLP: the pump-flow limit at every check point and, for the energy
objectives, the load-sensing pump pressure per node and the pump energy (trapezoid rule), priced
as the crane prices it (:mod:`planner.model.pricing`: seed or machine)."""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from planner.methods.nlp.limits import pump_draw

__all__ = ["PumpRows"]


@dataclass(frozen=True)
class PumpRows:
    """How one move NLP writes its pump rows: its ``crane``, actuator table ``acts``
    (:func:`~planner.model.flows.actuator_table`), ``N`` intervals, ``objective`` ("time",
    "energy", "blend"), ``path`` ("free", "line", "curve"), whether the ``pump`` limit
    holds, the share of Q_max kept free (``margin``) and whether every row must stay inside
    its own stage (``stagewise``: the FATROP solver)."""
    crane: object
    acts: object
    N: int
    objective: str
    path: str
    pump: bool
    margin: float
    stagewise: bool = False

    def add(self, lay, pts, mids, h, payload, act_mask, lifted: dict | None = None):
        """Pump flow slacks and limit at every check point (``pts``: (q, q̇, q̈) at the nodes,
        ``mids`` at the interval midpoints) into the layout ``lay``; for the energy
        objectives the load-sensing pump pressure per node (``act_mask``: the activity
        parameter, :mod:`planner.methods.nlp.activity`) and the pump energy (trapezoid rule,
        interval ``h``, ``payload`` parameter), returned (0 when not needed). ``lifted`` (a
        dict, minimum time): filled with the pump rows written in free symbols for the nodes'
        stroke Jacobians (:func:`~planner.methods.nlp.hessian.lagrangian_hessian`'s arguments)."""
        crane, spec, n, N = self.crane, self.crane.spec, self.crane.n, self.N
        pump_margin = self.margin
        Aa, Ab, dbl = self.acts.area_a, self.acts.area_b, ~self.acts.single
        n_dbl = int(dbl.sum())
        Qm = spec.pump.max_flow
        need_energy = self.objective in ("energy", "blend")
        if not (self.pump or need_energy):
            return 0
        if not need_energy and self.path != "curve":   # one smooth inequality per check point
            # stroke Jacobians at the nodes; at a midpoint the mean of its nodes' (the
            # Jacobian moves by O(h²) of itself in between, far inside the pump margin, and the
            # Hessian costs half: measured 22 vs 45 ms per solve on umea-lab, N = 40)
            # (FATROP: a row may only use its own stage's variables, so the midpoint's own)
            J = [crane.f_stroke(q)[1] for q, _, _ in pts]
            Jm = ([crane.f_stroke(q)[1] for q, _, _ in mids] if self.stagewise
                  else [(J[k] + J[k + 1]) / 2 for k in range(N)])
            first = lay.ng
            for k, (Jk, (_, v, _)) in enumerate(zip(J + Jm, pts + mids)):
                lay.add_con("pump", pump_draw(Jk, v, self.acts, Qm), -ca.inf, 1 - pump_margin,
                            stage=(k % (N + 1), 1))
            if lifted is not None and not self.stagewise:
                # the same rows in free symbols Y for the nodes' stroke Jacobians: the Hessian
                # differentiates the kinematics once per node (planner.methods.nlp.hessian)
                Y = ca.SX.sym("Jy", n, N + 1)
                Ys = [Y[:, k] for k in range(N + 1)]
                Ym = [(Ys[k] + Ys[k + 1]) / 2 for k in range(N)]
                lifted.update(rows=np.arange(first, lay.ng), Y=Y,
                              Q=ca.horzcat(*(q for q, _, _ in pts)),
                              stroke=lambda q: crane.f_stroke(q)[1],
                              rows_y=ca.vertcat(*(pump_draw(Yk, v, self.acts, Qm) for Yk, (
                                  _, v, _) in zip(Ys + Ym, pts + mids))))
            return 0
        checks = pts + mids if self.pump else pts
        # least energy: stroke Jacobians at the nodes, at a midpoint (only its pump row needs
        # it) the mean of its nodes' as above (its own, a function of the interpolated joints,
        # tripled the flow rows' Hessian: 263k of 1.13M instructions); the curve mode (already
        # at the edge of its iteration limit) keeps the midpoint's own
        J = [crane.f_stroke(q)[1] for q, _, _ in pts]
        if need_energy:
            J += [(J[k] + J[k + 1]) / 2 for k in range(N)]
        else:
            J += [crane.f_stroke(q)[1] for q, _, _ in mids]
        powers = []
        for idx, (q, v, a) in enumerate(checks):
            dxdq = J[idx]
            xd = dxdq * v
            # flows drawn from the pump as fractions of Q_max: extending (piston side) and
            # retracting (annulus; none for a single-acting cylinder lowering)
            sp = lay.add_var(f"sp{idx}", n, 0.0, 10.0)
            lay.add_con("flow_extend", Qm * sp - Aa * xd, 0.0, ca.inf)
            flows = [sp]
            if dbl.any():
                sm = lay.add_var(f"sm{idx}", n_dbl, 0.0, 10.0)
                lay.add_con("flow_retract", Qm * sm + Ab[dbl] * xd[np.flatnonzero(dbl)], 0.0,
                            ca.inf)
                flows.append(sm)
            total = sum(ca.sum1(f_) for f_ in flows)
            if self.pump:
                lay.add_con("pump", total, -ca.inf, 1 - pump_margin)
            if need_energy and idx <= N:
                F = crane.f_id(q, v, a, payload) / dxdq
                if spec.pump.kind == "load_sensing":
                    p = lay.add_var(f"p{idx}", 1, spec.pump.standby / 1e6, 1e3)  # [MPa]
                    mg = spec.pump.margin / 1e6
                    # load sensing: a function raises the pump pressure only while it draws
                    # flow. Which ones do is the activity mask (a parameter, updated from the
                    # solution and re-solved: see solve); inactive ones are relaxed by a big M,
                    # so every constraint is smooth
                    # (machine pricing: the meter-in pressure against the outlet's
                    # counter-pressure, friction included — the model's one definition,
                    # crane.f_pin; the seed pricing keeps its own F/A_a, −F/A_b bit for bit)
                    base = idx * (n + n_dbl)
                    m_pos = act_mask[base:base + n]
                    if crane.pricing == "seed":
                        p_ext, p_ret = F / Aa, -F / Ab
                    else:
                        p_ext, p_ret = crane.f_pin(F, xd)
                    lay.add_con("pressure", p - mg - p_ext / 1e6 + 1e3 * (1 - m_pos), 0.0,
                                ca.inf)
                    if dbl.any():
                        k = np.flatnonzero(dbl)
                        m_neg = act_mask[base + n:base + n + n_dbl]
                        lay.add_con("pressure", p - mg - p_ret[k] / 1e6 + 1e3 * (1 - m_neg),
                                    0.0, ca.inf)
                else:
                    p = lay.add_var(f"p{idx}", 1, spec.pump.pressure / 1e6,
                                    spec.pump.pressure / 1e6)
                powers.append(p * 1e6 * Qm * total / spec.pump.efficiency)
        if not need_energy:
            return 0
        return h * (sum(powers[1:-1]) + 0.5 * (powers[0] + powers[-1]))
