"""The valve physics, written once (CasADi): one proportional spool valve per actuator, its
dead band, its pressure-compensated meter-in edge, its meter-out (load-holding) edge, the
single-acting lowering edge, anti-cavitation make-up and the leakage of the loaded chamber —
and the steady state the quasi-static model plans with (command <-> stroke rate).

Every expression below is written once, as a function of CasADi (or plain float) scalars, and
exposed as a named :class:`casadi.Function` over scalar SX inputs (:data:`FUNCTIONS`, built by
:func:`function`): call it on SX/MX inside an NLP or a dynamic model, map it, differentiate
it. The numeric faces (batched, compiled; :mod:`planner.model.valves`) evaluate these same
functions; the spec's parameters are inputs, not constants, so one compiled copy serves every
machine, every valve-stage effect (a gain error, a dead band) and a calibration that fits them.

Per valve, pressures in Pa, flows in m³/s, p_t the tank pressure:

* **opening** from the spool position s: o = sign(s)·max(|s| − d, 0)/(1 − d) with s clipped
  to [−1, 1] and dead band d ∈ [0, 1) (fraction of the spool range without flow). The inverse
  outside the dead band: s = sign(o)·(d + (1 − d)·|o|).
* **regularised root** r(Δp) = Δp/(Δp² + Δp_r²)^¼ (Δp_r = 0.2 bar, :data:`DP_REG`): √Δp for
  |Δp| ≫ Δp_r, linear through zero (finite slope for Newton's method of a stiff integrator).
* **meter-in edge** (pump line p_s to the meter-in chamber p_in; individual pressure
  compensator): Q_in = G·|o|·c(p_s − p_in), c(Δp) = r(min(max(Δp, 0), Δp_c))/r(Δp_c). The
  compensator holds at most Δp_c across the edge, so with Δp ≥ Δp_c the flow is exactly G·|o|,
  independent of the load; below it the flow falls with √Δp (the pump cannot keep up:
  starvation); the check valve stops reverse flow (c = 0 for Δp ≤ 0). Normalised by r(Δp_c),
  not √Δp_c, so that the regulated flow is exactly G·|o| — the quasi-static steady state.
* **meter-out edge** (outlet chamber p_out to tank; a return-flow compensator, the
  steady-state action of a load-holding valve): Q_out = k·|o|·r(min(p_out − p_t, Δp_o))/r(Δp_o)
  with k = (1 + m)·G·A_out/A_in: at most (1 + m) times the outflow that matches the meter-in
  flow (margin m), reached at Δp_o. A passive load is metered in (a back pressure a little
  under Δp_o), an overrunning load is metered out (it runs at most m faster than commanded
  while anti-cavitation fills the inlet). No check valve: an outlet below tank draws back.
* **single-acting cylinder** (no rod-side connection): raising meters in from the pump;
  lowering meters the oil *leaving the piston side* to tank through the compensated edge,
  Q = G·|o|·c(p_a − p_t) (gravity driven, no pump flow); the rod side is vented.
* **counter-pressure of a metering outlet** (the load-holding valve carrying a passive load
  at the commanded speed): the outflow is the matched one, 1/(1 + m) of the return cap, so the
  outlet sits Δp_b above tank with r(Δp_b) = r(Δp_o)/(1 + m) — solved exactly,
  Δp_b² = (y⁴ + √(y⁸ + 4·y⁴·Δp_r²))/2, y = r(Δp_o)/(1 + m) (≈ Δp_o/(1 + m)² for Δp_o ≫
  Δp_r). What the machine pricing (:mod:`planner.model.pricing`) makes the pump push against.
* **anti-cavitation make-up** from tank into a chamber below tank: Q = G/Δp_f·δ²/(δ + Δp_r),
  δ = max(p_t − p, 0), Δp_f = 10 bar (about the full valve flow at 10 bar under tank; zero at
  and above tank with a continuous slope).
* **leakage** of the loaded chamber (the side with the larger p·A) to tank: λ·max(p − p_t, 0)
  [λ m³/(s·Pa)]; a single-acting cylinder leaks only from its piston side.
* **steady state, quasi-static** (compensator in regulation, chambers at their load-holding
  pressures): the valve delivers Q = G·|o(u)| and the actuator moves at ẋ = sign(o)·Q/A, A the
  *metered* area: A_a extending, A_b retracting, A_a for a single-acting cylinder lowering (its
  piston-side outflow); rotary drives use their displacement. Only functions that draw pump
  flow load the pump: all but a single-acting cylinder lowering. The inverse (feed-forward):
  Q = A·|ẋ| and u = sign(ẋ)·(d + (1 − d)·Q/G); a flow of at most :data:`REST_TOL`·G counts as
  rest, u = 0 (no jump to the dead-band edge while the actuator stands still).

**The judge keeps its own copy.** The Exudyn plant (:mod:`planner.simulation.dynamic.circuit`)
is the independent judge of the model's claims, so it implements the same circuit in its own
numpy (and plain-Python) code and imports nothing of this module. tests/model/
test_valve_physics.py cross-checks the two on random states of every machine: openings,
make-up, leakage and the edge flows agree to round-off (both normalise an edge by r at its
regulating drop; until 2026-11-26 the judge divided by √Δp_c and √Δp_o, a factor 1 − 4·10⁻⁵
and 1 − 4·10⁻⁴ that moved the twin 2.4 mm from the judge at rest on an s100f move).
"""
from __future__ import annotations

from functools import lru_cache

import casadi as ca

__all__ = ["DP_REG", "REST_TOL", "MAKEUP_DP", "OPEN_EPS", "root", "opening", "spool",
           "compensator", "meter_in", "meter_out", "return_gain", "back_pressure", "makeup",
           "leakage", "metered_flow", "draws_pump", "edge_flows", "steady_state", "command",
           "FUNCTIONS", "function"]

DP_REG = 2.0e4      # [Pa] laminar region of the regularised orifice root
REST_TOL = 1e-9     # |Q| ≤ REST_TOL·G counts as "at rest": u = 0, no dead-band jump
MAKEUP_DP = 1.0e6   # [Pa] depression under tank at which make-up passes about the valve flow
OPEN_EPS = 1e-6     # |o| at or below this: the valve draws nothing (no LS signal)


# ----------------------------------------------------------------------------- expressions
def root(dp):
    """Signed, regularised square root r(Δp) = Δp/(Δp² + Δp_r²)^¼ [√Pa]."""
    return dp / ca.sqrt(ca.sqrt(dp * dp + DP_REG ** 2))


def opening(s, deadband):
    """Effective opening o ∈ [−1, 1] from the spool position ``s`` (clipped to [−1, 1])."""
    s = ca.fmin(ca.fmax(s, -1.0), 1.0)
    return ca.sign(s) * ca.fmax(ca.fabs(s) - deadband, 0.0) / (1.0 - deadband)


def spool(o, deadband):
    """The spool position that gives opening ``o`` ≠ 0 (the dead band skipped; 0 at o = 0)."""
    return ca.sign(o) * (deadband + (1.0 - deadband) * ca.fabs(o))


def compensator(dp, dp_c):
    """Fraction c ∈ [0, 1] of the regulated flow an individually compensated edge passes at
    the drop ``dp`` (1 from ``dp_c`` on, √-like below, 0 for dp ≤ 0: the check valve)."""
    return root(ca.fmin(ca.fmax(dp, 0.0), dp_c)) / root(dp_c)


def meter_in(o, dp, gain, dp_c):
    """Meter-in edge flow Q_in ≥ 0 at opening ``o`` and drop ``dp`` = p_s − p_in."""
    return gain * ca.fabs(o) * compensator(dp, dp_c)


def meter_out(o, dp, k_out, dp_out):
    """Meter-out edge flow (to tank; negative when the outlet is below tank) at opening ``o``
    and drop ``dp`` = p_out − p_t; ``k_out`` the return cap at full opening."""
    return k_out * ca.fabs(o) * root(ca.fmin(dp, dp_out)) / root(dp_out)


def return_gain(gain, margin, area_out, area_in):
    """Return cap k = (1 + m)·G·A_out/A_in of the meter-out edge."""
    return (1.0 + margin) * gain * (area_out / area_in)


def back_pressure(dp_out, margin):
    """Drop Δp_b ≥ 0 [Pa] across the meter-out edge at which it passes the matched outflow,
    1/(1 + ``margin``) of its cap (reached at ``dp_out``): the exact inverse of :func:`root`."""
    y4 = (root(dp_out) / (1.0 + margin)) ** 4
    return ca.sqrt((y4 + ca.sqrt(y4 * y4 + 4.0 * y4 * DP_REG ** 2)) / 2.0)


def makeup(p, p_tank, gain):
    """Anti-cavitation flow from tank into a chamber at pressure ``p`` (≥ 0)."""
    d = ca.fmax(p_tank - p, 0.0)
    return gain / MAKEUP_DP * d * d / (d + DP_REG)


def leakage(p_a, p_b, area_a, area_b, leak, p_tank, single):
    """Leakage (l_a, l_b) ≥ 0 of the loaded chamber to tank; ``single`` 1 for a single-acting
    cylinder (rod side vented: no rod-side leak). Which side is loaded blends over ±Δp_r of
    p_a − p_b·A_b/A_a (tanh): a hard switch jumps where the sides balance, where a slew holding
    a swinging load sits, and an implicit integrator's Newton iteration fails there (the
    judge's circuit, planner.simulation.dynamic.circuit.loaded_share, the same form)."""
    x = ca.fmin(ca.fmax((p_a - p_b * area_b / area_a) / DP_REG, -40.0), 40.0)
    w = 1.0 / (1.0 + ca.exp(-2.0 * x))      # (1 + tanh x)/2, exact in relative terms
    l_a = w * leak * ca.fmax(p_a - p_tank, 0.0)
    l_b = ca.if_else(single, 0.0, (1.0 - w) * leak * ca.fmax(p_b - p_tank, 0.0))
    return l_a, l_b


def metered_flow(xd, area_extend, area_retract):
    """Flow through the valve (≥ 0) at stroke rate ``xd``: the metered area by direction
    (also the pump draw, with the area the pump fills while retracting)."""
    return area_extend * ca.fmax(xd, 0.0) + area_retract * ca.fmax(-xd, 0.0)


def draws_pump(direction, single):
    """1 where the valve takes its flow from the pump: all but a single-acting cylinder
    lowering (``direction`` ≤ 0: any signed command, flow or rate)."""
    return ca.logic_or(direction > 0, ca.logic_not(single))


def edge_flows(p_a, p_b, p_s, o, gain, margin, area_a, area_b, single, leak, p_tank, dp_c,
               dp_out):
    """The valve section of one actuator at chamber pressures ``p_a``, ``p_b``, pump
    pressure ``p_s`` and opening ``o``: (q_a, q_b) net valve flow into each chamber, q_in
    drawn from the pump (≥ 0), q_out to tank, p_load (the meter-in chamber's pressure while
    the valve draws, else 0), and net_a, net_b: q_a, q_b plus make-up minus leakage — the
    flow into each chamber but the swept volume's (the pressure equations'
    ṗ = β/V·(net − A·(±ẋ)); net_b = 0 for a single-acting cylinder)."""
    ext = o > 0
    p_in = ca.if_else(ext, p_a, p_b)
    p_out = ca.if_else(ext, p_b, p_a)
    k_out = ca.if_else(ext, return_gain(gain, margin, area_b, area_a),
                       return_gain(gain, margin, area_a, area_b))
    lower = ca.logic_and(single, ca.logic_not(ext))
    q_in = ca.if_else(lower, 0.0, meter_in(o, p_s - p_in, gain, dp_c))
    q_out = ca.if_else(lower, meter_in(o, p_a - p_tank, gain, dp_c),
                       ca.if_else(single, 0.0, meter_out(o, p_out - p_tank, k_out, dp_out)))
    q_a = ca.if_else(ext, q_in, -q_out)
    q_b = ca.if_else(single, 0.0, ca.if_else(ext, -q_out, q_in))
    draws = ca.logic_and(ca.fabs(o) > OPEN_EPS, ca.logic_not(lower))
    p_load = ca.if_else(draws, p_in, 0.0)
    l_a, l_b = leakage(p_a, p_b, area_a, area_b, leak, p_tank, single)
    net_a = q_a - l_a + makeup(p_a, p_tank, gain)
    net_b = ca.if_else(single, 0.0, q_b - l_b + makeup(p_b, p_tank, gain))
    return q_a, q_b, q_in, q_out, p_load, net_a, net_b


def steady_state(u, gain, deadband, area_extend, area_retract, single):
    """Quasi-static forward: command ``u`` -> (stroke rate ẋ, metered flow Q ≥ 0, 1 where the
    pump feeds it): the meter-in (or lowering) edge in regulation, Q = G·|o(u)|."""
    o = opening(u, deadband)
    q = gain * ca.fabs(o)      # = meter_in(o, Δp ≥ Δp_c, gain, Δp_c): the compensator's 1
    area = ca.if_else(o > 0, area_extend, area_retract)
    return ca.sign(o) * q / area, q, draws_pump(u, single)


def command(xd, gain, deadband, area_extend, area_retract):
    """Quasi-static inverse: stroke rate ``xd`` -> (unclipped command u, signed valve flow);
    a flow of at most REST_TOL·G is rest (u = 0, flow 0)."""
    q = metered_flow(xd, area_extend, area_retract)
    moving = q > REST_TOL * gain
    sgn = ca.sign(xd)
    u = ca.if_else(moving, spool(sgn * (q / gain), deadband), 0.0)
    return u, ca.if_else(moving, sgn * q, 0.0)


# ----------------------------------------------------------------------------- named functions
#: name -> (expression builder, input names, output names); every input a scalar
FUNCTIONS = {
    "valve_opening": (opening, ("spool", "deadband"), ("opening",)),
    "valve_meter_in": (meter_in, ("opening", "dp", "gain", "dp_c"), ("q_in",)),
    "valve_meter_out": (meter_out, ("opening", "dp", "k_out", "dp_out"), ("q_out",)),
    "valve_back_pressure": (back_pressure, ("dp_out", "margin"), ("dp_back",)),
    "valve_makeup": (makeup, ("p", "p_tank", "gain"), ("q_makeup",)),
    "valve_leakage": (leakage, ("p_a", "p_b", "area_a", "area_b", "leak", "p_tank", "single"),
                      ("l_a", "l_b")),
    "valve_flows": (edge_flows, ("p_a", "p_b", "p_s", "opening", "gain", "margin", "area_a",
                                 "area_b", "single", "leak", "p_tank", "dp_c", "dp_out"),
                    ("q_a", "q_b", "q_in", "q_out", "p_load", "net_a", "net_b")),
    "valve_steady_state": (steady_state, ("u", "gain", "deadband", "area_extend",
                                          "area_retract", "single"), ("xd", "q", "draws")),
    "valve_command": (command, ("xd", "gain", "deadband", "area_extend", "area_retract"),
                      ("u", "flow")),
    "valve_metered_flow": (metered_flow, ("xd", "area_extend", "area_retract"), ("q",)),
    "valve_draws_pump": (draws_pump, ("direction", "single"), ("draws",)),
}


@lru_cache(maxsize=None)
def function(name: str) -> ca.Function:
    """The named :class:`casadi.Function` of :data:`FUNCTIONS` (scalar SX inputs and outputs,
    built once per process); ValueError naming the allowed names otherwise."""
    if name not in FUNCTIONS:
        raise ValueError(f"valve function {name!r}: allowed {', '.join(FUNCTIONS)}")
    build, ins, outs = FUNCTIONS[name]
    xs = [ca.SX.sym(k) for k in ins]
    ys = build(*xs)
    ys = ys if isinstance(ys, tuple) else (ys,)
    return ca.Function(name, xs, list(ys), list(ins), list(outs))
