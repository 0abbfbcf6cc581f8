"""How the quasi-static model prices pump work: the seed's ideal circuit, or the machine's.

Two pricings of the same motion (:data:`PRICINGS`), chosen per :class:`~planner.model.Crane`
(``Crane(spec, pricing=…)``; default ``"machine"`` where the spec has a ``[dynamics]``
section, ``"seed"`` otherwise):

* ``"seed"`` — the seeds' ideal load-holding circuit (seed 002's pricing, kept bit for bit for
  the seed comparisons): the chamber that carries the actuator force F = τ/(dx/dq) holds it,
  the other sits at tank; no friction. Lowering and braking an overrunning load cost the pump
  only its flow at the LS floor, and the energy the load gives back vanishes for free.
* ``"machine"`` — what the circuit of the machine makes the pump pay (the circuit the Exudyn
  plant integrates, written here as its steady state):

  - **friction** at the actuator: the chambers must produce F + F_f with
    F_f(ẋ) = F_c·tanh(ẋ/v_s) + d·ẋ (Coulomb ``coulomb`` and viscous ``viscous`` of
    ``[dynamics.joint.<name>]``; v_s = :data:`SMOOTH_SPEED` of the full-command speed
    G/min(A_a, A_b): the Coulomb step rounded off so that the NLP sees a smooth function).
  - **the load-holding (return-flow) valve's counter-pressure**: the meter-out edge passes at
    most (1 + m) times the outflow that matches the meter-in flow, reached at Δp_o
    (``meter_out_margin`` m, ``meter_out_dp`` Δp_o of ``[dynamics]``). Carrying a *passive*
    load at the commanded speed, the outflow is the matched one, 1/(1 + m) of the cap: the
    outlet chamber sits Δp_b above tank, r(Δp_b) = r(Δp_o)/(1 + m)
    (:func:`planner.model.valve_physics.back_pressure`; ≈ Δp_o/(1 + m)²), and the meter-in
    chamber must push against it: p_in = (F + F_f + A_out·(p_t + Δp_b))/A_in.
  - **overrunning loads and anti-cavitation make-up**: when that p_in would fall below tank
    (the load pulls: lowering, braking), the meter-in chamber is held at tank by the
    anti-cavitation valve and the outlet chamber takes the load,
    p_out = (A_in·p_t − F − F_f)/A_out ≥ p_t + Δp_b, throttling the load's energy to tank.
    The pump still delivers the metered flow A_in·|ẋ| into the inlet at its LS floor — that is
    what lowering and braking cost it; the energy the load gives back is burnt at the outlet,
    not returned.
  - the LS pump as before (:mod:`planner.model.hydraulics`): max(standby, highest meter-in
    pressure of the drawing functions + margin) — but a function *draws* (shows the LS line its
    pressure) as soon as its valve opens, Q > ``OPEN_EPS``·G (:mod:`planner.model.
    valve_physics`: the judge's rule), not only above the seed pricing's 10⁻⁴ of Q_max: a
    function crept along at a few 10⁻⁵ of its flow (a plan's "idle" joint) raises the pump to
    its holding pressure on the machine, and so it does here. No standby *flow*: the judge's pump delivers
    what the valves draw and nothing else (a bleed would price idle time, which the plant
    does not).

  A single-acting cylinder has no return line to throttle (its rod side is vented): raising
  pays its friction, lowering stays free. The hydraulic transformer (seed 002's option, which
  the Exudyn plant does not model) keeps its coupled pressures and only adds friction. At rest
  (ẋ = 0) the load-holding pressures of the seed pricing hold either way.

Every parameter comes from the spec's ``[dynamics]`` (see its provenance there); the only
constant here, :data:`SMOOTH_SPEED`, is assumed as the judge assumes it. The expressions are
written once (CasADi, :func:`friction`, :func:`meter_in_pressures`, :func:`moving_pressures`);
:mod:`planner.model.flows` is their numpy copy (checked against these on random states).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from planner.model.spec import CraneSpec
from planner.model.valve_physics import OPEN_EPS, back_pressure

__all__ = ["ACTIVE_FLOW", "PRICINGS", "SMOOTH_SPEED", "Pricing", "pricing_of", "friction",
           "meter_in_pressures", "moving_pressures"]

ACTIVE_FLOW = 1e-4  # seed pricing: fraction of the pump's max flow below which a function idles
PRICINGS = ("seed", "machine")
#: assumed: the Coulomb friction is rounded off over this fraction of the full-command stroke
#: speed G/min(A_a, A_b) (as the Exudyn plant rounds it: a seal's stick-slip band is far below
#: the speeds a crane plans with, so the figure only keeps the NLP's gradient finite)
SMOOTH_SPEED = 0.01


@dataclass(frozen=True)
class Pricing:
    """Constants of one pricing of one spec, arrays (n,) in joint order: ``back`` [Pa] the
    load-holding valve's counter-pressure above tank on a metering outlet (0: seed pricing, or
    a single-acting cylinder, or a transformer joint), ``coulomb`` [N | N·m], ``viscous``
    [N·s/m | N·m·s/rad], ``v_smooth`` [m/s | rad/s] (see the module doc), ``active`` [m³/s]
    the flow above which a function draws (shows the LS line its pressure)."""
    mode: str
    back: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray
    v_smooth: np.ndarray
    active: np.ndarray

    @property
    def machine(self) -> bool:
        return self.mode == "machine"


def pricing_of(spec: CraneSpec, mode: str | None = None) -> Pricing:
    """The :class:`Pricing` ``mode`` ("seed" | "machine"; None: machine where the spec has a
    ``[dynamics]`` section, else seed) of ``spec``; ValueError naming the field, the value and
    what is allowed."""
    if mode is None:
        mode = "machine" if spec.dynamics is not None else "seed"
    if mode not in PRICINGS:
        raise ValueError(f"pricing: {mode!r} is not a pricing; allowed: {', '.join(PRICINGS)}")
    n = spec.n
    zero = np.zeros(n)
    if mode == "seed":
        return Pricing(mode, zero, zero, zero, zero + 1.0,
                       zero + ACTIVE_FLOW * spec.pump.max_flow)
    dyn = spec.dynamics
    if dyn is None:
        raise ValueError(f"pricing: 'machine' needs the [dynamics] section of crane "
                         f"'{spec.id}' ({spec.path}), which it lacks; allowed there: 'seed'")
    acts = [j.actuator for j in spec.joints]
    jd = [dyn.joints[j.name] for j in spec.joints]
    single = np.array([a.acting == "single" for a in acts])
    ht = spec.transformer if (spec.transformer and spec.transformer.enabled) else None
    coupled = np.zeros(n, bool)
    if ht is not None:
        coupled[[spec.joint_index(ht.source_joint), spec.joint_index(ht.target_joint)]] = True
    dp_b = float(back_pressure(dyn.meter_out_dp, dyn.meter_out_margin))
    back = np.where(single | coupled, 0.0, dp_b)
    G = np.array([a.flow_gain for a in acts], float)
    valve = np.isfinite(G) & (G > 0)
    full = np.where(valve, G, 0.0) / np.array([min(a.area_a, a.area_b) for a in acts])
    v_s = np.where(valve, SMOOTH_SPEED * full, 1.0)
    active = np.where(valve, OPEN_EPS * np.where(valve, G, 0.0),
                      ACTIVE_FLOW * spec.pump.max_flow)
    out = Pricing(mode, back, np.array([d.coulomb for d in jd], float),
                  np.array([d.viscous for d in jd], float), v_s, active)
    for a in (out.back, out.coulomb, out.viscous, out.v_smooth, out.active):
        a.setflags(write=False)
    return out


# ----------------------------------------------------------------------------- expressions
def friction(pr: Pricing, i: int, xd):
    """Friction force [N | N·m] of actuator ``i`` opposing the stroke rate ``xd`` (CasADi)."""
    if not pr.machine or (pr.coulomb[i] == 0 and pr.viscous[i] == 0):
        return 0 * xd
    return pr.coulomb[i] * ca.tanh(xd / pr.v_smooth[i]) + pr.viscous[i] * xd


def meter_in_pressures(pr: Pricing, area_a, area_b, p_tank, i: int, force, xd):
    """(p_ext, p_ret): the meter-in chamber pressure actuator ``i`` needs to carry ``force``
    (the required F, friction added here) at stroke rate ``xd`` extending (piston side) and
    retracting (rod side) against the outlet's counter-pressure — the passive-load formula,
    not floored at tank (below tank the load overruns and the chamber sits at tank). The
    energy NLP's load-sensing rows use these; the seed pricing gives its F/A_a, −F/A_b (with
    the tank pressure on the outlet)."""
    Fa = force + friction(pr, i, xd)
    p_out = p_tank + pr.back[i]
    return (Fa + area_b * p_out) / area_a, (area_a * p_out - Fa) / area_b


def moving_pressures(pr: Pricing, area_a, area_b, p_tank, i: int, force, xd, p_a, p_b):
    """Chamber pressures (p_a, p_b) of a double-acting actuator ``i`` under the machine
    pricing while it moves (``p_a``, ``p_b``: the load-holding pressures, kept at rest): the
    passive formula of :func:`meter_in_pressures` floored at tank on the meter-in side, the
    outlet balancing the force (≥ p_t + Δp_b)."""
    Fa = force + friction(pr, i, xd)
    pe, pr_ = meter_in_pressures(pr, area_a, area_b, p_tank, i, force, xd)
    pa_ext = ca.fmax(pe, p_tank)
    pb_ret = ca.fmax(pr_, p_tank)
    pa = ca.if_else(xd > 0, pa_ext, ca.if_else(xd < 0, (Fa + area_b * pb_ret) / area_a, p_a))
    pb = ca.if_else(xd > 0, (area_a * pa_ext - Fa) / area_b, ca.if_else(xd < 0, pb_ret, p_b))
    return pa, pb
