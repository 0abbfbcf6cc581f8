"""The move NLP's limits between its check points, written once for
:class:`~planner.methods.nlp.move.MoveNLP` (a change here changes the compiled-cache key:
:mod:`planner.methods.nlp.cache` hashes this module's source).

- :func:`step`: the exact triple-integrator step under constant jerk;
- :func:`add_velocity_limits`: the velocity limit checked with each interval's own jerk;
- :func:`pump_draw`: the direction-dependent pump draw as one smooth, conservative
  expression (no slack variables).

Velocity. In an interval of length h under constant jerk j the velocity is a quadratic with
second derivative j: between two check points h/2 apart it exceeds the larger of them by at most
|j|·(h/2)²/8 = |j|·h²/32. Each interval's three check points (its ends and its midpoint) are
tightened by that interval's own bound, with |j|
over-estimated smoothly by √(j² + ε²) (ε = 10⁻²·j_max): the limit holds everywhere, and a
cruise at the limit (j = 0) is checked ε·h²/32 inside it (umea-lab, N = 40: ~1e-5 of the
velocity limit). The earlier uniform tightening j_max·h²/32 held a long move's cruise that far
below the limit (up to +9.7 % duration against the Ruckig optimum on joint-space ends). Both
limits of a check point are one row: with c and r the middle and half-width of [q̇_min, q̇_max]
and x = 1 − gap/r, ((q̇ − c)/r)² ≤ x·|x| holds exactly when |q̇ − c| + gap ≤ r, i.e. q̇ + gap ≤
q̇_max and q̇ − gap ≥ q̇_min (x·|x| < 0 when the gap alone exceeds r: no q̇ passes). Measured
(issue 31): on 20 random umea-lab moves with the pump the two-row form with ε = 10⁻³ took 656
IPOPT iterations in all, this one 438 (480 instead of 960 velocity rows at N = 40; 1.9× → 1.55×
a plain Opti, the NLP always solved); on 40 random moves per machine 1459 → 908 (umea-lab) and
1475 → 1259 (s100f), every solve ok, the NLP's own durations +4·10⁻⁶ and +7·10⁻⁶ (median
relative). A smooth |q̇ − c| ≈ √((q̇ − c)² + δ²), δ = 10⁻³·r, was as fast on umea-lab but
stalled IPOPT on long s100f moves (219–1000 iterations: its curvature 1/δ at q̇ = c).

Pump. An actuator draws A_a·ẋ extending and A_b·|ẋ| retracting (a single-acting one nothing
retracting): c₁·ẋ + c₂·|ẋ| with c₁ = (A_a − A_b)/2, c₂ = (A_a + A_b)/2 (single-acting: A_b = 0).
|ẋ| is over-estimated by √(ẋ² + ε²) ≤ |ẋ| + ε, ε chosen per actuator so that the whole draw is
over-estimated by at most :data:`PUMP_SMOOTH` (1 %) of Q_max, only with every actuator at rest
(ε²/2|ẋ| for a moving one): one inequality per check point, never below the exact draw. A smaller
ε (0.1 %) curved the rows so sharply near ẋ = 0 that IPOPT hit max_iter on a umea-lab move
(0.3 % took 211 iterations, 1 % 49). The slack form it replaces (per check point and actuator
s ≥ A_a·ẋ, s ≥ −A_b·ẋ, Σ s ≤ Q_max) doubled the variables (1301 vs 653 at N = 40 on umea-lab).

Relief. A joint whose acceleration limit was set for a light pose can ask, at full reach with the
payload, for more force than its actuator makes at the relief pressure (cat215b's swing: 48 of 48
random time-optimal moves asked its motor for up to 2.2 × the relief pressure, 8 % in the median
once its friction was corrected; cranab850's boom 4 of 48, up to 1.44 ×). The machine then lags
the plan by metres, and no feed-forward can make it follow. :func:`add_relief_rows` bounds, at
every node, the chamber pressure each actuator needs to carry the inverse-dynamics force (the
crane's pricing: friction and the outlet's counter-pressure under the machine pricing, F/A_a and
−F/A_b under the seed's), extending and retracting alike, by :func:`relief_limit`: the relief
pressure less the load-sensing margin (the compensated meter-in edge still passes its flow).
Both directions, because a chamber holding an over-running load is capped by the same relief.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["step", "add_velocity_limits", "pump_draw", "add_relief_rows", "relief_limit",
           "PUMP_SMOOTH", "JERK_SMOOTH"]

PUMP_SMOOTH = 1e-2   # largest over-estimate of the smooth pump draw, a fraction of Q_max
JERK_SMOOTH = 1e-2   # ε of the smooth |j| in the velocity check, a fraction of j_max


def step(q, v, a, j, h):
    """The exact triple-integrator step: (q, q̇, q̈) after time h under constant jerk j."""
    return (q + h * v + h ** 2 / 2 * a + h ** 3 / 6 * j, v + h * a + h ** 2 / 2 * j, a + h * j)


def add_velocity_limits(layout, L, jmax, pts, mids, ends, U, h, uniform: bool = False) -> None:
    """Velocity rows ("velocity") into ``layout``: every interval k's start ``pts[k]``,
    midpoint ``mids[k]`` and end ``ends[k]`` (each a (q, q̇, q̈) triple; the end written in the
    interval's own variables) within the limits of ``L`` (qd_min, qd_max) tightened by
    √(U_k² + ε²)·h_k²/32, ε = JERK_SMOOTH·``jmax``, both limits in one row per check point
    and joint — every row inside stage k. ``h`` the
    interval lengths (N + 1 equal expressions: the duration's copies). ``uniform``: every node
    and midpoint tightened by ``jmax``·h²/32 instead (the earlier form, kept for the curve
    mode: its jerk-coupled rows left IPOPT at max_iter on seed 003's circle, where the uniform
    rows solve in 365 iterations)."""
    N = len(mids)
    if uniform:
        for k, (_, v, _) in enumerate(pts + mids):
            gap = np.asarray(jmax, float) * h[k % (N + 1)] ** 2 / 32
            layout.add_con("velocity", v + gap, -ca.inf, L["qd_max"])
            layout.add_con("velocity", v - gap, L["qd_min"], ca.inf)
        return
    eps2 = (JERK_SMOOTH * np.asarray(jmax, float)) ** 2
    c, r = (L["qd_max"] + L["qd_min"]) / 2, (L["qd_max"] - L["qd_min"]) / 2
    for k in range(N):
        x = 1 - ca.sqrt(U[:, k] ** 2 + eps2) * h[k] ** 2 / (32 * r)   # 1 - gap/r
        for _, v, _ in (pts[k], mids[k], ends[k]):   # |v - c| + gap <= r
            layout.add_con("velocity", ((v - c) / r) ** 2 - x * ca.fabs(x), -ca.inf, 0.0,
                           stage=(k, 1))


def pump_draw(dxdq, v, acts, max_flow: float):
    """The pump draw at joint rates ``v`` with stroke Jacobian (diagonal) ``dxdq`` as a fraction
    of ``max_flow``: smooth, never below the exact draw, at most PUMP_SMOOTH above it. ``acts``
    the actuator table (:func:`planner.model.flows.actuator_table`: area_a, area_b, single)."""
    Aa = np.asarray(acts.area_a, float)
    Ab = np.where(acts.single, 0.0, np.asarray(acts.area_b, float))
    c1, c2 = (Aa - Ab) / 2, (Aa + Ab) / 2
    eps = PUMP_SMOOTH * max_flow / (len(Aa) * c2)
    xd = dxdq * v
    return ca.sum1(c1 * xd + c2 * ca.sqrt(xd ** 2 + eps ** 2)) / max_flow


def relief_limit(spec) -> float:
    """The highest chamber pressure [Pa] a plan may ask for: the pump's ``max_pressure`` less the
    load-sensing ``margin`` (a constant-pressure pump: its set pressure, when lower); inf when
    the spec gives no relief pressure."""
    pu = spec.pump
    p = float(pu.max_pressure)
    if pu.kind == "load_sensing":
        return p - float(pu.margin)
    return min(p, float(pu.pressure))


def add_relief_rows(layout, crane: Crane, acts, pts, payload) -> None:
    """Relief rows ("relief") into ``layout``: at every node of ``pts`` ((q, q̇, q̈) triples)
    the chamber pressure each actuator needs to carry its inverse-dynamics force with
    ``payload`` (a parameter) — extending and, for a double-acting one, retracting — at most
    :func:`relief_limit` (rows scaled by it: ≤ 1). Each row inside its node's stage."""
    p_lim = relief_limit(crane.spec)
    Aa = np.asarray(acts.area_a, float)
    Ab = np.asarray(acts.area_b, float)
    dbl = np.flatnonzero(~np.asarray(acts.single, bool))
    for k, (q, v, a) in enumerate(pts):
        dxdq = crane.f_stroke(q)[1]
        F = crane.f_id(q, v, a, payload) / dxdq
        if crane.pricing == "seed":
            p_ext, p_ret = F / Aa, -F / np.where(Ab > 0, Ab, 1.0)
        else:
            p_ext, p_ret = crane.f_pin(F, dxdq * v)
        rows = ca.vertcat(p_ext, p_ret[dbl.tolist()]) if dbl.size else p_ext
        layout.add_con("relief", rows / p_lim, -ca.inf, 1.0, stage=(k, 1))
