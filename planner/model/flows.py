"""The one numpy copy of the hydraulics: pump draw, swept volume, chamber, load and pump
pressures, pump power — equal to :mod:`planner.model.hydraulics` (the CasADi definition, see
its docstring for the physics), which tests/test_flows.py checks on random states of every
machine.

Use it where a CasADi call does not fit: on stroke changes instead of rates (lower bounds, DP
edges), on huge edge arrays, or on forces that come from somewhere else (a plant with effects).
Every function is batched over leading axes; the last axis is the actuators (joints), in spec
order. ``spec`` may be a :class:`~planner.model.spec.CraneSpec` or anything with a ``.spec``
(a :class:`~planner.model.Crane`). :func:`hydraulics` prices like the CasADi definition: the
crane's pricing, or the spec's default (:mod:`planner.model.pricing`; the numpy copy of its
friction and moving pressures is :func:`friction` and :func:`moving_pressures` here).
:func:`held_hydraulics` carries the priced effects with memory along a plan's time grid
(the held chamber pressures, :func:`planner.model.pricing.held_pressures`; the closing
spools' tails, :func:`spool_tail`).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from planner.model.hydraulics import ACTIVE_FLOW, OUTPUTS
from planner.model.pricing import Pricing, held_pressures, pricing_of, spool_lag
from planner.model.spec import CraneSpec, Pump
from planner.model.valve_physics import OPEN_EPS, REST_TOL

__all__ = ["ActuatorTable", "actuator_table", "pump_draw", "swept_volume", "chamber_pressures",
           "load_pressures", "pump_pressure", "pump_power", "throttle_loss", "hydraulics",
           "pricing", "friction", "moving_pressures", "priced_pressures", "held_hydraulics",
           "spool_tail"]


@dataclass(frozen=True)
class ActuatorTable:
    """Hydraulic constants of one spec as arrays (n,) in joint order.

    ``area_a`` / ``area_b``: piston and annulus areas [m²] (motor displacement [m³/rad] for a
    rotary drive); ``single``: single-acting cylinder (no annulus connection: lowering returns
    oil to tank and draws nothing); ``draw_b``: area the pump fills while retracting (``area_b``,
    0 for a single-acting cylinder and for the transformer's source, whose rod side the
    transformer fills). ``pump``: the spec's pump; ``active_flow`` [m³/s]: the flow above
    which a function counts as drawing (``ACTIVE_FLOW`` · Q_max). Transformer: ``ht_source`` /
    ``ht_target`` joint indices (−1 without an enabled transformer), ``ht_ratio`` and
    ``ht_k`` = ratio · A_b,source / A_a,target (the target's stroke-rate credit per unit of the
    source's rate)."""
    n: int
    area_a: np.ndarray
    area_b: np.ndarray
    single: np.ndarray
    draw_b: np.ndarray
    pump: Pump
    active_flow: float
    ht_source: int = -1
    ht_target: int = -1
    ht_ratio: float = 1.0
    ht_k: float = 0.0

    @property
    def transformer(self) -> bool:
        """True when an enabled hydraulic transformer couples two actuators."""
        return self.ht_source >= 0

    @property
    def tank_pressure(self) -> float:
        return self.pump.tank_pressure


_TABLES: OrderedDict[int, tuple[CraneSpec, ActuatorTable]] = OrderedDict()
_TABLES_MAX = 64


def spec_of(spec_or_crane) -> CraneSpec:
    """The :class:`CraneSpec` of a spec or of a model object carrying one (``.spec``)."""
    spec = getattr(spec_or_crane, "spec", spec_or_crane)
    if not isinstance(spec, CraneSpec):
        raise TypeError(f"expected a CraneSpec or a Crane, got {type(spec_or_crane).__name__}")
    return spec


def _build_table(spec: CraneSpec) -> ActuatorTable:
    acts = [j.actuator for j in spec.joints]
    area_a = np.array([a.area_a for a in acts])
    area_b = np.array([a.area_b for a in acts])
    single = np.array([a.acting == "single" for a in acts])
    draw_b = np.where(single, 0.0, area_b)
    ht = spec.transformer
    kw = {}
    if ht is not None and ht.enabled:
        s, t = spec.joint_index(ht.source_joint), spec.joint_index(ht.target_joint)
        draw_b[s] = 0.0
        kw = dict(ht_source=s, ht_target=t, ht_ratio=ht.ratio,
                  ht_k=ht.ratio * area_b[s] / area_a[t])
    for a in (area_a, area_b, single, draw_b):
        a.setflags(write=False)
    return ActuatorTable(n=spec.n, area_a=area_a, area_b=area_b, single=single, draw_b=draw_b,
                         pump=spec.pump, active_flow=ACTIVE_FLOW * spec.pump.max_flow, **kw)


def actuator_table(spec) -> ActuatorTable:
    """The :class:`ActuatorTable` of a spec (or crane), built once per spec object (specs hold
    dicts, so they are not hashable: the cache is keyed by identity and keeps the spec alive,
    so an id cannot be reused while its entry exists; the 64 most recent specs are kept)."""
    spec = spec_of(spec)
    hit = _TABLES.get(id(spec))
    if hit is not None and hit[0] is spec:
        _TABLES.move_to_end(id(spec))
        return hit[1]
    table = _build_table(spec)
    _TABLES[id(spec)] = (spec, table)
    while len(_TABLES) > _TABLES_MAX:
        _TABLES.popitem(last=False)
    return table


def _last(a, n: int, name: str) -> np.ndarray:
    a = np.asarray(a, float)
    if a.ndim == 0 or a.shape[-1] != n:
        raise ValueError(f"{name}: expected {n} values per sample on the last axis, got shape "
                         f"{a.shape}")
    return a


# ----------------------------------------------------------------------------- flows
def pump_draw(spec, xd) -> np.ndarray:
    """Pump flow drawn per actuator [m³/s] for stroke rates ``xd`` (..., n): piston area
    extending, annulus retracting, nothing for single-acting lowering; with an enabled
    transformer the target draws A_a,t·(ẋ_t − k·ẋ_s)⁺ and the source only A_a,s·ẋ_s⁺."""
    T = actuator_table(spec)
    xd = _last(xd, T.n, "pump_draw: xd")
    Q = np.where(xd > 0, T.area_a * xd, -T.draw_b * xd)
    if T.transformer:
        s, t = T.ht_source, T.ht_target
        Q[..., t] = T.area_a[t] * np.maximum(xd[..., t] - T.ht_k * xd[..., s], 0)
        Q[..., s] = T.area_a[s] * np.maximum(xd[..., s], 0)
    return Q


def swept_volume(spec, dx) -> np.ndarray:
    """Oil volume [m³] the pump must deliver per actuator for stroke changes ``dx`` (..., n):
    :func:`pump_draw` applied to a displacement (it is positively homogeneous). A lower bound
    on ∫Q dt for any motion with that net stroke change."""
    return pump_draw(spec, dx)


# ----------------------------------------------------------------------------- pressures
def chamber_pressures(spec, force):
    """Load-holding chamber pressures (p_a, p_b) [Pa], each shaped like ``force`` (..., n)
    [N | N·m]: F ≥ 0 the piston side carries the load and the rod side sits at tank, F < 0 the
    other way round; a single-acting cylinder has only its piston side (p_a ≥ tank). With an
    enabled transformer the source's rod side sits at ratio · (the target's piston pressure)."""
    T = actuator_table(spec)
    F = _last(force, T.n, "chamber_pressures: force")
    pt = T.tank_pressure
    pos = F >= 0
    p_a = np.where(pos, (F + T.area_b * pt) / T.area_a, pt)
    p_b = np.where(pos, pt, (T.area_a * pt - F) / T.area_b)
    p_a = np.where(T.single, pt + np.maximum(F, 0) / T.area_a, p_a)
    p_b = np.where(T.single, pt, p_b)
    if T.transformer:
        s, t = T.ht_source, T.ht_target
        pbs = T.ht_ratio * p_a[..., t]
        p_b[..., s] = pbs
        p_a[..., s] = np.maximum((F[..., s] + T.area_b[s] * pbs) / T.area_a[s], pt)
    return p_a, p_b


def pricing(spec_or_crane, mode: str | None = None) -> Pricing:
    """The :class:`~planner.model.pricing.Pricing` in force: ``mode``'s, else a crane's own
    (``.prices``), else the spec's default."""
    if mode is None and getattr(spec_or_crane, "prices", None) is not None:
        return spec_or_crane.prices
    return pricing_of(spec_of(spec_or_crane), mode)


def friction(pr: Pricing, xd) -> np.ndarray:
    """Friction force (..., n) [N | N·m] opposing the stroke rates ``xd`` (0: seed pricing)."""
    xd = np.asarray(xd, float)
    if not pr.machine:
        return np.zeros_like(xd)
    return pr.coulomb * np.tanh(xd / pr.v_smooth) + pr.viscous * xd


def moving_pressures(spec, pr: Pricing, force, xd, p_a, p_b):
    """Machine pricing: chamber pressures (p_a, p_b) of the double-acting, uncoupled actuators
    while they move (the passive load against the outlet's counter-pressure, the inlet floored
    at tank, the outlet balancing ``force`` + friction); others and rest keep ``p_a``,
    ``p_b``. ``force`` already carries the friction."""
    T = actuator_table(spec)
    pt = T.tank_pressure
    Aa, Ab = T.area_a, T.area_b
    p_out = pt + pr.back
    pa_ext = np.maximum((force + Ab * p_out) / Aa, pt)
    pb_ret = np.maximum((Aa * p_out - force) / Ab, pt)
    pa = np.where(xd > 0, pa_ext, np.where(xd < 0, (force + Ab * pb_ret) / Aa, p_a))
    pb = np.where(xd > 0, (Aa * pa_ext - force) / Ab, np.where(xd < 0, pb_ret, p_b))
    keep = T.single.copy()
    if T.transformer:
        keep[[T.ht_source, T.ht_target]] = True
    return np.where(keep, p_a, pa), np.where(keep, p_b, pb)


def priced_pressures(spec, force, xd, pr: Pricing | None = None):
    """Chamber pressures (p_a, p_b) for required forces ``force`` at stroke rates ``xd``
    (each (..., n)) under the pricing ``pr`` (default :func:`pricing`): the load-holding
    :func:`chamber_pressures` (seed), or with friction and the moving pressures (machine)."""
    pr = pricing(spec) if pr is None else pr
    if not pr.machine:
        return chamber_pressures(spec, force)
    xd = np.asarray(xd, float)
    force_f = np.asarray(force, float) + friction(pr, xd)
    p_a, p_b = chamber_pressures(spec, force_f)
    return moving_pressures(spec, pr, force_f, xd, p_a, p_b)


def load_pressures(spec, p_a, p_b, xd, q_act, active=None) -> np.ndarray:
    """Load pressure each actuator shows the LS line (..., n) [Pa]: the meter-in chamber's
    (p_a extending, p_b retracting) while it draws more than ``active`` (the pricing's
    threshold, default ``active_flow``), else 0 (the transformer's source: its piston side)."""
    T = actuator_table(spec)
    active = T.active_flow if active is None else active
    xd = np.asarray(xd, float)
    pL = np.where(xd > 0, p_a, np.where(xd < 0, p_b, 0.0))
    if T.transformer:
        pL = np.array(pL, float)
        pL[..., T.ht_source] = np.asarray(p_a)[..., T.ht_source]
    return np.where(np.asarray(q_act) > active, pL, 0.0)


def _total(a) -> np.ndarray:
    """Sum over the last axis, left to right (the CasADi definition's order, to the bit)."""
    a = np.asarray(a, float)
    s = a[..., 0]
    for i in range(1, a.shape[-1]):
        s = s + a[..., i]
    return s


def pump_pressure(spec, p_load, q_pump, drawing=None) -> np.ndarray:
    """Pump pressure [Pa] (shaped like ``q_pump``): load sensing max(standby, max p_load +
    margin while a function draws: ``drawing`` (...) bool, default the pump delivering more
    than ``active_flow``); constant pressure: the set pressure."""
    T = actuator_table(spec)
    pump = T.pump
    q_pump = np.asarray(q_pump, float)
    if pump.kind == "load_sensing":
        pmax = np.max(p_load, axis=-1)
        drawing = q_pump > T.active_flow if drawing is None else drawing
        return np.maximum(pump.standby, np.where(drawing, pmax + pump.margin, 0.0))
    return np.full(q_pump.shape, float(pump.pressure))


def pump_power(spec, p_pump, q_pump) -> np.ndarray:
    """Hydraulic input power of the pump [W]: p_pump · Q / η."""
    return np.asarray(p_pump) * np.asarray(q_pump) / actuator_table(spec).pump.efficiency


def throttle_loss(p_pump, p_load, q_act) -> np.ndarray:
    """Power throttled across the meter-in valves [W]: Σ (p_pump − p_load,i) · Q_i."""
    return _total((np.asarray(p_pump)[..., None] - p_load) * q_act)


def hydraulics(spec, x, xd, force, mode: str | None = None) -> dict:
    """Every quantity of :data:`planner.model.hydraulics.OUTPUTS` from strokes ``x``, stroke
    rates ``xd`` and actuator forces ``force`` (each (..., n)): per-actuator arrays (..., n)
    and pump scalars (...); numerically the CasADi :func:`planner.model.hydraulics.hydraulics`
    priced by :func:`pricing` (``mode``, else a crane's own, else the spec's)."""
    T = actuator_table(spec)
    pr = pricing(spec, mode)
    x = _last(x, T.n, "hydraulics: x")
    xd = _last(xd, T.n, "hydraulics: xd")
    force = _last(force, T.n, "hydraulics: force")
    q_act = pump_draw(spec, xd)
    p_a, p_b = priced_pressures(spec, force, xd, pr)
    p_load = load_pressures(spec, p_a, p_b, xd, q_act, pr.active)
    q_pump = _total(q_act)
    p_pump = pump_pressure(spec, p_load, q_pump,
                           np.any(q_act > pr.active, axis=-1) if pr.machine else None)
    values = dict(x=x, xd=xd, force=force, p_a=p_a, p_b=p_b, p_load=p_load, q_act=q_act,
                  p_pump=p_pump, q_pump=q_pump, power=pump_power(spec, p_pump, q_pump),
                  throttle_loss=throttle_loss(p_pump, p_load, q_act))
    return {k: values[k] for k in OUTPUTS}


def spool_tail(pr: Pricing, t, xd):
    """The closing spool's tail (:mod:`planner.model.pricing`): (open (N, n) bool, the valve
    lagged open past ``OPEN_EPS``; s (N, n) the lagged spools) of a plan's stroke rates ``xd``
    at the times ``t`` (N,): the quasi-static command of each rate (clipped to ±1) through
    :func:`planner.model.pricing.spool_lag`. None without a tail (``pr.tau_spool`` 0)."""
    if not pr.tau_spool > 0 or len(t) < 2:
        return None
    xd = np.asarray(xd, float)
    q = np.where(xd > 0, pr.area_extend * xd, -pr.area_retract * xd)
    o = np.where(q > REST_TOL * pr.gain, np.sign(xd) * q / pr.gain, 0.0)
    u = np.clip(np.sign(o) * (pr.deadband + (1.0 - pr.deadband) * np.abs(o)), -1.0, 1.0)
    s = spool_lag(t, u, pr.tau_spool)
    o_lag = np.maximum(np.abs(s) - pr.deadband, 0.0) / (1.0 - pr.deadband)
    return o_lag > OPEN_EPS, s


def held_hydraulics(spec_or_crane, t, hyd: dict, mode: str | None = None) -> dict:
    """``hyd`` (the :data:`~planner.model.hydraulics.OUTPUTS` of samples at the times ``t``
    (N,), in time order) with the held chamber pressures of the pricing carried along
    (:func:`planner.model.pricing.held_pressures`), the closing spools' tails
    (:func:`spool_tail`: a stopped function whose spool is still open shows the LS line the
    meter-in side of its held pair) and the load, pump pressure, power and throttle loss that
    follow; the seed pricing returns ``hyd`` itself."""
    pr = pricing(spec_or_crane, mode)
    if not np.any(pr.held) and not pr.tau_spool > 0:
        return hyd
    spec = spec_of(spec_or_crane)
    xd, q_act = np.asarray(hyd["xd"], float), np.asarray(hyd["q_act"], float)
    moving = q_act > pr.active
    force_f = np.asarray(hyd["force"], float) + friction(pr, xd)
    p_a, p_b = held_pressures(pr, t, hyd["x"], xd, force_f, moving, hyd["p_a"], hyd["p_b"])
    p_load = load_pressures(spec, p_a, p_b, xd, q_act, pr.active)
    drawing = moving
    tail = spool_tail(pr, t, xd)
    if tail is not None:
        lowering = actuator_table(spec).single & (tail[1] < 0)    # draws nothing
        lagged = tail[0] & ~moving & ~lowering
        p_load = np.where(lagged, np.where(tail[1] > 0, p_a, p_b), p_load)
        drawing = moving | lagged
    q_pump = np.asarray(hyd["q_pump"], float)
    p_pump = pump_pressure(spec, p_load, q_pump, np.any(drawing, axis=-1))
    return dict(hyd, p_a=p_a, p_b=p_b, p_load=p_load, p_pump=p_pump,
                power=pump_power(spec, p_pump, q_pump),
                throttle_loss=throttle_loss(p_pump, p_load, q_act))
