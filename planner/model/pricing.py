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

* **held (trapped) chamber pressure** — the one effect with memory, carried by
  :func:`held_pressures` (a per-function state, the chamber pair (p_a, p_b), stepped along a
  plan's time grid; :func:`planner.model.flows.held_hydraulics` applies it in ``evaluate()``).
  A double-acting function that braked or held a load keeps both chambers pressurised when
  its load lightens or it stops and starts again: the load-holding (return-flow) edge passes
  at most (1 + m) times the matched outflow, the LS pump feeds the inlet at its commanded
  flow, so the pair loses its excess only through the margin m. Per time step h, with the
  chamber stiffnesses K_a = β·A_a²/V_a, K_b = β·A_b²/V_b (V: hose volume plus the swept
  volume at the stroke, as the judge's chambers):

  - a change ΔF of the carried force F (friction in) compresses one chamber and relieves the
    other in the ratio of their stiffnesses: Δp_a = K_a·ΔF/((K_a + K_b)·A_a),
    Δp_b = −K_b·ΔF/((K_a + K_b)·A_b) (at rest and moving alike; a chamber driven below tank
    is refilled by make-up: the pair falls back to the load-holding pressures of F);
  - moving with its valve open, the outlet bleeds at most at
    ṗ_out = −m·β·A_out·|ẋ|/V_out · K_in/(K_a + K_b) (the margin's extra outflow, shared
    between the chambers by their stiffnesses), never below its quasi-static pressure above;
    the inlet balances F against it, p_in = (F + A_out·p_out)/A_in ≥ p_t — the pressure the
    LS pump must reach;
  - at rest (valve closed) the pair is trapped (only the load change above moves it).

  The pair starts at the plan's first sample (the quasi-static pressures). Where no excess
  builds up the step returns the quasi-static pressures exactly. β is ``bulk_modulus``, m
  ``meter_out_margin``, the hose volumes ``hose_volume`` of ``[dynamics]``; the swept volume
  from the actuator's stroke (x from 0 to ``stroke`` for a cylinder, the joint limits'
  strokes for a rack, none for a motor). The pressure-dependent bulk law (``bulk_low`` …) is
  not carried (β at its reference). Single-acting cylinders and the transformer's coupled
  pair keep their quasi-static pressures. **The NLP, the DP and the laws price per node**
  (no state): the energy NLP's moves compete under ``evaluate()``, which carries it, with the
  stretched and the time-optimal moves (:mod:`planner.methods.nlp.energy`).

* **the closing spool's tail** — the other effect with memory, carried by
  :func:`spool_lag` along a plan's time grid (:func:`planner.model.flows.held_hydraulics`
  applies it in ``evaluate()``). A proportional valve's spool follows its command u with a
  first-order lag τ (``spool_time_constant``), and a valve open past ``OPEN_EPS`` shows the LS
  line its meter-in pressure (the judge's rule, :mod:`planner.model.valve_physics`). When a
  function stops while others move, its command falls to 0 but its spool decays as
  s·e^(−Δt/τ): from an opening s₀ the valve stays open for τ·ln(s₀/(d + (1 − d)·OPEN_EPS))
  (d the dead band; ≈ 0.3–0.5 s at τ = 40 ms, d = 0), and all that while the pump is held at
  the stopped function's holding pressure (its held pair, meter-in side of the lagged
  spool) plus the margin, while the plan's own pump pressure drops to the moving functions'.
  On the s100f energy entries (which stop and start functions mid-move) this is the larger
  half of the excess where a stopped telescope or jib sets the plant's pump
  (benchmarks/results/energy_tail_judgefix.md). The step, exact for a command held over it:
  s₁ = u + (s₀ − u)·e^(−h/τ) (:func:`spool_step`); the plan's command is the quasi-static
  inverse of its stroke rate (:func:`planner.model.valve_physics.command`, clipped to ±1).
  The spool starts at the plan's first command. The tail adds no flow (the plant's stopped
  function creeps on a few 10⁻⁵ of its stroke). τ from the spec's ``[dynamics]``; the seed
  pricing has none.

Every parameter comes from the spec's ``[dynamics]`` (see its provenance there); the only
constant here, :data:`SMOOTH_SPEED`, is assumed as the judge assumes it. The expressions are
written once (CasADi, :func:`friction`, :func:`meter_in_pressures`, :func:`moving_pressures`,
:func:`held_step`, :func:`spool_step`);
:mod:`planner.model.flows` is their numpy copy (checked against these on random states).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np

from planner.model.actuators import stroke_expr
from planner.model.numeric import jit_function
from planner.model.spec import CraneSpec
from planner.model.valve_physics import OPEN_EPS, back_pressure

__all__ = ["ACTIVE_FLOW", "PRICINGS", "SMOOTH_SPEED", "Pricing", "pricing_of", "friction",
           "meter_in_pressures", "moving_pressures", "held_step", "held_pressures",
           "spool_step", "spool_lag"]

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
    the flow above which a function draws (shows the LS line its pressure). The held pressure
    (:func:`held_pressures`): ``held`` which functions carry it (none in the seed pricing),
    ``area_a``, ``area_b`` [m² | m³/rad], ``hose_a``, ``hose_b`` [m³], ``x_lo``, ``x_hi``
    [m | rad] the stroke range of the swept volume, ``swept`` 1 where the chambers' volume
    changes with the stroke, ``beta`` [Pa], ``margin`` [-], ``p_tank`` [Pa]. The closing
    spool's tail (:func:`spool_lag`): ``tau_spool`` [s] (0: none, the seed pricing),
    ``deadband`` [-], ``gain`` [m³/s] the valves' flow gains, ``area_extend``,
    ``area_retract`` [m² | m³/rad] the metered areas (:mod:`planner.model.valves`)."""
    mode: str
    back: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray
    v_smooth: np.ndarray
    active: np.ndarray
    held: np.ndarray = field(default=None)
    area_a: np.ndarray = field(default=None)
    area_b: np.ndarray = field(default=None)
    hose_a: np.ndarray = field(default=None)
    hose_b: np.ndarray = field(default=None)
    x_lo: np.ndarray = field(default=None)
    x_hi: np.ndarray = field(default=None)
    swept: np.ndarray = field(default=None)
    beta: float = 1.0
    margin: float = 0.0
    p_tank: float = 0.0
    tau_spool: float = 0.0
    deadband: np.ndarray = field(default=None)
    gain: np.ndarray = field(default=None)
    area_extend: np.ndarray = field(default=None)
    area_retract: np.ndarray = field(default=None)

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
    acts = [j.actuator for j in spec.joints]
    geo = dict(area_a=np.array([a.area_a for a in acts], float),
               area_b=np.array([a.area_b for a in acts], float), p_tank=spec.pump.tank_pressure)
    if mode == "seed":
        return Pricing(mode, zero, zero, zero, zero + 1.0,
                       zero + ACTIVE_FLOW * spec.pump.max_flow, held=np.zeros(n, bool),
                       hose_a=zero + 1.0, hose_b=zero + 1.0, x_lo=zero, x_hi=zero, swept=zero,
                       **geo)
    dyn = spec.dynamics
    if dyn is None:
        raise ValueError(f"pricing: 'machine' needs the [dynamics] section of crane "
                         f"'{spec.id}' ({spec.path}), which it lacks; allowed there: 'seed'")
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
    x_lo, x_hi, swept = _stroke_ranges(spec)
    tail = dict(tau_spool=float(dyn.spool_time_constant) if np.all(valve) else 0.0,
                deadband=np.array([a.deadband for a in acts], float), gain=np.where(valve, G, 1.0),
                area_extend=geo["area_a"].copy(),
                area_retract=np.where(single, geo["area_a"], geo["area_b"]))
    out = Pricing(mode, back, np.array([d.coulomb for d in jd], float),
                  np.array([d.viscous for d in jd], float), v_s, active,
                  held=~(single | coupled),
                  hose_a=np.array([d.hose_volume[0] for d in jd], float),
                  hose_b=np.array([d.hose_volume[1] for d in jd], float),
                  x_lo=x_lo, x_hi=x_hi, swept=swept, beta=float(dyn.bulk_modulus),
                  margin=float(dyn.meter_out_margin), **geo, **tail)
    for a in (out.back, out.coulomb, out.viscous, out.v_smooth, out.active, out.held,
              out.area_a, out.area_b, out.hose_a, out.hose_b, out.x_lo, out.x_hi, out.swept,
              out.deadband, out.gain, out.area_extend, out.area_retract):
        a.setflags(write=False)
    return out


def _stroke_ranges(spec: CraneSpec):
    """(x_lo, x_hi, swept) per actuator: a cylinder's stroke 0 … ``stroke``, a rack's strokes
    at its joint limits (swept where both are finite), a motor none (its hoses only)."""
    lo, hi, swept = [], [], []
    for j in spec.joints:
        a = j.actuator
        if a.kind in ("triangle", "lever", "telescope"):
            ends = (0.0, float(a.stroke))
        elif a.kind == "rack":
            ends = tuple(sorted(float(stroke_expr(j, q)) for q in j.limits.q))
        else:
            ends = (0.0, 0.0)
        ok = bool(np.all(np.isfinite(ends))) and a.kind != "rotary"
        lo.append(ends[0] if ok else 0.0)
        hi.append(ends[1] if ok else 0.0)
        swept.append(1.0 if ok else 0.0)
    return np.array(lo), np.array(hi), np.array(swept)


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


def held_step(pa0, pb0, force, xd, x, moving, pa_q, pb_q, h, area_a, area_b, hose_a, hose_b,
              x_lo, x_hi, swept, beta, margin, p_tank):
    """One step h [s] of the held chamber pair of one double-acting function (module doc):
    from the previous pair (``pa0``, ``pb0``) to the pair at the new sample, where it carries
    ``force`` (friction in) at stroke rate ``xd`` and stroke ``x`` with its valve open
    (``moving`` > 0.5) or closed; ``pa_q``, ``pb_q`` its quasi-static pressures there (the
    floor of a moving outlet). CasADi or float scalars; returns (p_a, p_b)."""
    xc = ca.fmin(ca.fmax(x, x_lo), x_hi)
    va = hose_a + swept * area_a * (xc - x_lo)
    vb = hose_b + swept * area_b * (x_hi - xc)
    ka, kb = beta * area_a ** 2 / va, beta * area_b ** 2 / vb
    ks = ka + kb
    dF = force - (pa0 * area_a - pb0 * area_b)
    na = pa0 + ka * dF / (ks * area_a)
    nb = pb0 - kb * dF / (ks * area_b)
    cav = ca.logic_or(na < p_tank, nb < p_tank)   # make-up: back to the load-holding pair
    pos = force >= 0
    na = ca.if_else(cav, ca.if_else(pos, (force + area_b * p_tank) / area_a, p_tank), na)
    nb = ca.if_else(cav, ca.if_else(pos, p_tank, (area_a * p_tank - force) / area_b), nb)
    open_ = moving > 0.5
    ext = ca.logic_and(open_, xd > 0)
    ret = ca.logic_and(open_, xd < 0)
    bleed = margin * beta * ca.fabs(xd) * h / ks
    pb_e = ca.fmax(pb_q, nb - bleed * area_b * ka / vb)
    pa_e = ca.fmax((force + area_b * pb_e) / area_a, p_tank)
    pa_r = ca.fmax(pa_q, na - bleed * area_a * kb / va)
    pb_r = ca.fmax((area_a * pa_r - force) / area_b, p_tank)
    pa = ca.if_else(ext, pa_e, ca.if_else(ret, pa_r, na))
    pb = ca.if_else(ext, pb_e, ca.if_else(ret, pb_r, nb))
    return pa, pb


def spool_step(s0, u, h, tau):
    """One step h [s] of a valve spool's first-order lag (time constant ``tau`` [s]) from
    ``s0`` toward the command ``u`` held over the step — exact: u + (s0 − u)·e^(−h/τ)
    (module doc, the closing spool's tail). CasADi or float scalars."""
    return u + (s0 - u) * ca.exp(-h / tau)


def spool_lag(t, u, tau: float, s0=None):
    """The spools (N, n) of commands ``u`` (N, n), each held from its sample time ``t`` (N,)
    to the next, lagged by ``tau`` [s] from ``s0`` (default u[0]): :func:`spool_step` chained,
    written in closed form — s_k·E_k = s_c + Σ_{j<k} u_j·(E_{j+1} − E_j), E_k = e^((t_k −
    t_c)/τ) — over chunks of at most 50·τ (so E stays below e^50)."""
    t = np.asarray(t, float)
    u = np.asarray(u, float)
    out = np.empty_like(u)
    out[0] = u[0] if s0 is None else s0
    c = 0
    while c < len(t) - 1:
        e = int(np.searchsorted(t, t[c] + 50.0 * tau, side="right"))
        e = min(max(e, c + 2), len(t))          # samples c .. e-1, at least one step
        E = np.exp((t[c:e] - t[c]) / tau)[:, None]
        acc = np.cumsum(u[c:e - 1] * np.diff(E, axis=0), axis=0)
        out[c + 1:e] = (out[c] + acc) / E[1:]
        c = e - 1
    return out


#: the inputs of :func:`held_step` after the state: per-step, then per-function constants
_STEP_IN = ("force", "xd", "x", "moving", "pa_q", "pb_q", "h")
_CONST_IN = ("area_a", "area_b", "hose_a", "hose_b", "x_lo", "x_hi", "swept", "beta", "margin",
             "p_tank", "held")
CHUNK = 512   # samples per call of the mapped step (the last chunk is padded)


@lru_cache(maxsize=None)
def _held_map(n: int):
    """:func:`held_step` of n functions mapped over :data:`CHUNK` steps, compiled
    (:func:`planner.model.numeric.jit_function`; the interpreter without a compiler), its
    call buffer bound to numpy arrays: (evaluate, state (2n,) = [p_a; p_b], inputs
    (CHUNK, 18·n): per step the n values of each name of ``_STEP_IN + _CONST_IN`` (held 0:
    the quasi-static pair passes through), outputs (CHUNK, 2n): the state after each step)."""
    z = ca.SX.sym("p", 2 * n)
    u = ca.SX.sym("u", len(_STEP_IN + _CONST_IN) * n)
    names = _STEP_IN + _CONST_IN
    pa, pb = [], []
    for i in range(n):
        a = [u[names.index(k) * n + i] for k in names]
        ya, yb = held_step(z[i], z[n + i], *a[:-1])
        on = a[-1] > 0.5
        pa.append(ca.if_else(on, ya, a[names.index("pa_q")]))
        pb.append(ca.if_else(on, yb, a[names.index("pb_q")]))
    f = ca.Function("held_step", [z, u], [ca.vertcat(*pa, *pb)])
    fm = jit_function(f.mapaccum("held_pressures", CHUNK))
    buf, ev = fm.buffer()
    z0, ins, outs = np.zeros(2 * n), np.zeros((CHUNK, u.numel())), np.zeros((CHUNK, 2 * n))
    buf.set_arg(0, memoryview(z0))
    buf.set_arg(1, memoryview(ins))
    buf.set_res(0, memoryview(outs))
    return buf, ev, z0, ins, outs


def held_pressures(pr: Pricing, t, x, xd, force, moving, p_a, p_b):
    """Chamber pressures (p_a, p_b), each (N, n), of a plan sampled at the times ``t`` (N,)
    with the held pair carried along (module doc): ``x``, ``xd`` strokes and rates,
    ``force`` the carried force (friction in), ``moving`` bool, the valve open, ``p_a``,
    ``p_b`` the quasi-static pressures (each (N, n)). Functions without it (``pr.held``
    False: the seed pricing, single-acting, coupled) keep ``p_a``, ``p_b``."""
    p_a, p_b = np.asarray(p_a, float), np.asarray(p_b, float)
    if not np.any(pr.held) or len(t) < 2:
        return p_a, p_b
    N, n = p_a.shape
    h = np.diff(np.asarray(t, float))
    cols = [np.asarray(force, float)[1:], np.asarray(xd, float)[1:], np.asarray(x, float)[1:],
            np.asarray(moving, float)[1:], p_a[1:], p_b[1:], np.repeat(h[:, None], n, 1)]
    cols += [np.broadcast_to(np.asarray(getattr(pr, k), float), (N - 1, n)) for k in _CONST_IN]
    U = np.hstack(cols)
    _, ev, z, ins, outs = _held_map(n)
    out = np.empty((N - 1, 2 * n))
    z[:n], z[n:] = p_a[0], p_b[0]
    for s in range(0, N - 1, CHUNK):
        m = min(CHUNK, N - 1 - s)
        ins[:m] = U[s:s + m]
        ins[m:] = U[s + m - 1]          # padding: any valid step
        ev()
        out[s:s + m] = outs[:m]
        z[:] = outs[m - 1]
    pa = np.vstack([p_a[:1], out[:, :n]])
    pb = np.vstack([p_b[:1], out[:, n:]])
    keep = ~np.asarray(pr.held, bool)
    return np.where(keep, p_a, pa), np.where(keep, p_b, pb)
