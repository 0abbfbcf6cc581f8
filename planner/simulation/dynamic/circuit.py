"""The hydraulic circuit of the dynamic plant (numpy, batched over leading axes; last axis =
actuators in spec order): chamber pressure build-up, valves, load-holding valves, the
load-sensing pump, friction, and the power flows for the energy balance.

Per actuator (piston side a, rod side b; a rotary drive's two motor ports):

* chamber volumes V_a = V_hose,a + A_a·(x − x_lo), V_b = V_hose,b + A_b·(x_hi − x) (cylinders
  and rack cylinders; a motor keeps its hose volumes); pressure build-up
  ṗ = β/V · (Q_into − A·(±ẋ) − Q_leak + Q_makeup);
* **proportional valve** (spool opening ``o`` in [−1, 1] after its first-order lag and dead
  band): the meter-in edge passes G·|o|·r(min(Δp, Δp_c))/r(Δp_c) from the pump line, r the
  regularised root below (an individual pressure compensator holds at most Δp_c across it, so
  a regulated edge passes exactly G·|o|; below that the flow falls with √Δp — pump
  saturation; a check valve stops reverse flow); the meter-out edge has its
  own compensator (return-flow control, the steady-state action of a load-holding valve): it
  passes at most (1 + ``meter_out_margin``) times the outflow that matches the meter-in flow,
  reached at ``meter_out_dp`` — so a passive load is metered in (a back pressure a little
  under ``meter_out_dp`` on the outlet) and an overrunning load is metered out, running at
  most ``meter_out_margin`` faster than commanded while the inlet fills by anti-cavitation;
* **single-acting cylinder**: the rod side is vented (tank pressure); lowering meters the oil
  leaving the piston side through the compensated edge (gravity driven, from no pump flow);
* anti-cavitation valves feed a chamber from tank below tank pressure;
* **pump** (state p_s): load sensing towards max(standby, highest meter-in pressure of the
  drawing functions + margin), capped at ``max_pressure`` (relief), with the regulator lag
  ``pump_time_constant``; when the valves draw more than Q_max the pump line (volume V_p) loses
  pressure at β/V_p per unit excess flow. Constant-pressure pumps hold their set pressure.
* actuator force F = p_a·A_a − p_b·A_b − F_c·tanh(ẋ/v_s) − d·ẋ (Coulomb smoothed over 1 % of
  the full-command speed), plus stiff end stops at the strokes of the joint limits (their
  damping ramped in over the first millimetre, so the force is continuous at contact).

**Pressure-dependent bulk modulus** (opt-in, :class:`PressureBulk`, or a spec's ``[dynamics]``
bulk_low / bulk_high / bulk_reference_pressure; off by default; the twin has its own version):
β(p) = β₀·clip((p + p_a)/(p_ref + p_a), lo, hi) in every chamber and the pump line —
oil with entrained air is softer at low pressure (the air is compressed) and stiffer at high. In
a closed chamber (Q = 0) compressed from V₀ to V, within the unclipped range,
(p + p_a) = (p₀ + p_a)·(V₀/V)^(β₀/(p_ref + p_a)). The energy balance
(:mod:`planner.simulation.dynamic.energy`) keeps β₀ for the oil's stored energy, so with the
law on its residual is only approximate.

Orifice roots are regularised below 0.2 bar (linear through zero) so that Newton's method of
the implicit integrator sees finite slopes; each edge is normalised by the regularised root at
its regulating drop (Δp_c, Δp_o), so the gains mean what they say: G·|o| through a regulated
meter-in edge, the return cap at Δp_o. (Until 2026-11-26 the edges divided by √Δp_c and √Δp_o
and passed 1 − 4·10⁻⁵ and 1 − 4·10⁻⁴ of those flows: on an overrunning, metered-out
deceleration the meter-out edge sets the speed, and that 4·10⁻⁴ alone left the s100f slew
0.6 mrad — 2.4 mm at the tip — from where the same commands put the model's twin.)
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass

import numpy as np

from planner.model.valves import valve_params

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Circuit", "PressureBulk", "root", "loaded_share", "DP_REG", "STOP_STIFFNESS",
           "CONTACT_REFINE", "STOP_HIT_SPEED", "STOP_BAND",
           "STOP_DAMPING",
           "STOP_RAMP", "STOP_SOFT"]

DP_REG = 2.0e4          # [Pa] orifice laminar region
STOP_STIFFNESS = 2.0e8  # [N/m] end stops (per m of stroke; N·m/rad-equivalent for drives)
#: a run whose cylinder or rack reaches its end stop is repeated at this fraction of the plant's
#: step (ExudynPlant.integrate): the stop's spring rings at kHz against the actuator's mass; at
#: 2 ms a umea-lab telescope meeting its stop at 0.16 m/s rebounded at 2.9 m/s, its rod side at
#: 703 bar, and rested 48 mm off the goal (library entry r35, refined); at 0.5 ms it rests on it
CONTACT_REFINE = 4
#: [m/s] a stroke at its stop faster than this counts as a hit (ExudynPlant.integrate); the
#: s100f library's retracted telescopes rest on their stops (0.0 m/s) and are judged at 2 ms
#: as at 0.5 ms within 0.05 mm
STOP_HIT_SPEED = 0.01
#: [m] how near its stop a stroke counts as running into it (at 2 ms a stroke meeting its stop
#: at 0.5 m/s may be sampled only on its way back out)
STOP_BAND = 1e-3
STOP_DAMPING = 0.05     # [s] end-stop damping = this × stiffness, ...
STOP_RAMP = 1.0e-3      # [m] ... reached linearly over this penetration (continuous at contact:
#                          a damping force that jumps on at contact stalls the Newton iteration
#                          of a start on a stop)
STOP_SOFT = 1.0e-4      # [m] the stiffness, too, ramps in over this penetration (the force is
#                          k·o²/(2·δ) below δ, k·(o − δ/2) beyond: its slope is continuous at
#                          contact; a slope that jumps from 0 to k made the implicit integrator's
#                          Newton iteration fail on a joint that starts exactly on its stop)


def _stop_spring(over):
    """Penetration -> spring part of the end-stop force / stiffness (C¹ at contact)."""
    o = np.abs(over)
    return np.sign(over) * np.where(o < STOP_SOFT, o * o / (2.0 * STOP_SOFT),
                                    o - 0.5 * STOP_SOFT)


def root(dp):
    """Signed, regularised square root √|Δp|·sign(Δp) [√Pa] (linear within ±0.2 bar)."""
    dp = np.asarray(dp, float)
    return dp / np.sqrt(np.sqrt(dp * dp + DP_REG ** 2))


def loaded_share(dp):
    """The share w ∈ [0, 1] of the leakage taken from side a at the load's pressure difference
    dp = p_a − p_b·A_b/A_a [Pa]: 1 where side a carries the load, 0 where side b does, blended
    over ±0.2 bar ((1 + tanh)/2). A hard switch made the right-hand side jump where the two sides
    balance — a slew holding a swinging load (equal trapped pressures, the load turning it to
    and fro) slides along that surface, and the implicit integrator's Newton iteration failed
    there at every step size (s100f, a 1.5 m grapple, 4.7 s into a hold; 2026-11-27)."""
    x = np.clip(np.asarray(dp, float) / DP_REG, -40.0, 40.0)
    return 1.0 / (1.0 + np.exp(-2.0 * x))     # (1 + tanh x)/2, exact in relative terms


@dataclass(frozen=True)
class PressureBulk:
    """A bulk modulus that rises with pressure (see the module doc): the factor on β₀ is
    (p + ``p_abs``)/(``p_ref`` + ``p_abs``) clipped to [``lo``, ``hi``]; ``p_ref`` [Pa] the
    pressure at which the spec's β₀ holds, ``p_abs`` [Pa] the atmosphere (gauge pressures)."""
    p_ref: float = 8.0e6
    p_abs: float = 1.0e5
    lo: float = 0.5
    hi: float = 1.25

    def __post_init__(self):
        for name, v, lo, hi in (("p_ref", self.p_ref, 1e5, 1e8), ("p_abs", self.p_abs, 0.0, 1e6),
                                ("lo", self.lo, 0.01, 1.0), ("hi", self.hi, 1.0, 10.0)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"PressureBulk: field '{name}' = {v!r}; allowed: "
                                 f"{lo:g} .. {hi:g}")

    def factor(self, p):
        """β(p)/β₀ for pressures p [Pa] (any shape)."""
        r = (np.asarray(p, float) + self.p_abs) / (self.p_ref + self.p_abs)
        return np.clip(r, self.lo, self.hi)


@dataclass
class Circuit:
    """Constants of one machine's circuit (arrays (n,)); see the module doc. Build with
    :meth:`from_crane`."""
    n: int
    area_a: np.ndarray
    area_b: np.ndarray
    single: np.ndarray
    motor: np.ndarray          # rotary drive: no chamber volume change
    x_lo: np.ndarray
    x_hi: np.ndarray
    hose_a: np.ndarray
    hose_b: np.ndarray
    gain: np.ndarray           # [m³/s] meter-in flow at full opening (compensated)
    deadband: np.ndarray
    k_out_a: np.ndarray        # [m³/(s·√Pa)] meter-out orifice of side a at full opening
    k_out_b: np.ndarray
    coulomb: np.ndarray
    viscous: np.ndarray
    v_smooth: np.ndarray       # [m/s] Coulomb smoothing speed
    leak: np.ndarray           # [m³/(s·Pa)] leakage of the loaded chamber to tank
    beta: float
    dp_c: float
    dp_out: float
    pump_kind: str
    q_max: float
    margin: float
    standby: float
    p_set_const: float
    p_relief: float
    p_tank: float
    tau_pump: float
    v_pump: float
    efficiency: float
    bulk: PressureBulk | None = None    # None: β constant (the spec's)

    @classmethod
    def from_crane(cls, crane: Crane, dyn, stops, gain_scale=1.0, deadband=None, pump_scale=1.0,
                   leak=None) -> "Circuit":
        """The circuit of ``crane`` with dynamics ``dyn`` (:class:`DynamicsSpec`), stroke end
        stops ``stops`` = (lo, hi) (n,) and the valves-stage deviations of a plant: per-valve
        gain factors, dead bands, the pump-flow factor; ``leak`` per-actuator leakage."""
        spec = crane.spec
        n = spec.n
        vp = valve_params(crane)
        acts = [j.actuator for j in spec.joints]
        area_a = np.array([a.area_a for a in acts])
        area_b = np.array([a.area_b for a in acts])
        jd = [dyn.joints[j.name] for j in spec.joints]
        lo, hi = (np.asarray(s, float) for s in stops)
        cyl = np.array([a.kind in ("triangle", "lever", "telescope") for a in acts])
        x_lo = np.where(cyl, 0.0, lo)
        x_hi = np.where(cyl, [a.stroke for a in acts], hi)
        gain = vp.flow_gain * np.broadcast_to(np.asarray(gain_scale, float), (n,))
        pump = spec.pump
        c_out = 1.0 + dyn.meter_out_margin
        return cls(
            n=n, area_a=area_a, area_b=area_b, single=vp.single.copy(),
            motor=np.array([a.kind == "rotary" for a in acts]), x_lo=x_lo, x_hi=x_hi,
            hose_a=np.array([d.hose_volume[0] for d in jd]),
            hose_b=np.array([d.hose_volume[1] for d in jd]),
            gain=gain, deadband=vp.deadband.copy() if deadband is None else
            np.broadcast_to(np.asarray(deadband, float), (n,)).copy(),
            k_out_a=c_out * gain * (area_a / area_b),
            k_out_b=c_out * gain * (area_b / area_a),
            coulomb=np.array([d.coulomb for d in jd]), viscous=np.array([d.viscous for d in jd]),
            v_smooth=0.01 * vp.flow_gain / np.minimum(area_a, area_b),
            leak=np.zeros(n) if leak is None else np.asarray(leak, float),
            beta=dyn.bulk_modulus, dp_c=dyn.compensator_dp, dp_out=dyn.meter_out_dp,
            pump_kind=pump.kind, q_max=pump.max_flow * pump_scale,
            margin=pump.margin, standby=pump.standby, p_set_const=pump.pressure,
            p_relief=min(pump.max_pressure, 1e9), p_tank=pump.tank_pressure,
            tau_pump=dyn.pump_time_constant, v_pump=dyn.pump_line_volume,
            efficiency=pump.efficiency)

    # ------------------------------------------------------------------ pieces
    def beta_at(self, p):
        """Effective bulk modulus [Pa] at pressures p (β when the law is off)."""
        return self.beta if self.bulk is None else self.beta * self.bulk.factor(p)

    def opening(self, spool):
        """Effective valve opening (..., n) from spool positions: dead band removed."""
        s = np.clip(spool, -1.0, 1.0)
        return np.sign(s) * np.maximum(np.abs(s) - self.deadband, 0.0) / (1.0 - self.deadband)

    def volumes(self, x):
        """Chamber volumes (V_a, V_b) [m³] at strokes x (..., n)."""
        x = np.clip(x, self.x_lo, self.x_hi)
        va = self.hose_a + np.where(self.motor, 0.0, self.area_a * (x - self.x_lo))
        vb = self.hose_b + np.where(self.motor, 0.0, self.area_b * (self.x_hi - x))
        return va, vb

    def friction(self, xd):
        """Friction force [N | N·m] opposing the stroke rate (..., n)."""
        return self.coulomb * np.tanh(xd / self.v_smooth) + self.viscous * xd

    def on_a_stop(self, x, xd) -> bool:
        """Whether a cylinder or rack of the strokes ``x`` (K, n), rates ``xd``, runs into its
        end stop: within :data:`STOP_BAND` of it, moving towards it faster than
        :data:`STOP_HIT_SPEED` (one resting on it, or leaving it, is resolved at any step)."""
        if x is None or not len(x):
            return False
        live = ~np.asarray(self.motor, bool)
        x, xd = np.asarray(x, float)[:, live], np.asarray(xd, float)[:, live]
        hit_hi = (x >= self.x_hi[live] - STOP_BAND) & (xd > STOP_HIT_SPEED)
        hit_lo = (x <= self.x_lo[live] + STOP_BAND) & (xd < -STOP_HIT_SPEED)
        return bool(np.any(hit_hi | hit_lo))

    def stop_force(self, x, xd):
        """End-stop force (..., n) pushing back into [x_lo, x_hi] (cylinders and racks)."""
        over = np.maximum(x - self.x_hi, 0.0) - np.maximum(self.x_lo - x, 0.0)
        k = STOP_STIFFNESS * np.where(self.motor, 0.0, 1.0)
        ramp = np.minimum(np.abs(over) / STOP_RAMP, 1.0)
        return -k * _stop_spring(over) - STOP_DAMPING * k * ramp * xd

    def force(self, p_a, p_b, x, xd):
        """Net actuator force [N | N·m] along +x."""
        p_b = np.where(self.single, self.p_tank, p_b)
        return (p_a * self.area_a - p_b * self.area_b - self.friction(xd)
                + self.stop_force(x, xd))

    def flows(self, p_a, p_b, p_s, o):
        """Valve flows for pressures p_a, p_b (..., n), pump pressure p_s (...) and openings
        o (..., n): dict q_a, q_b (net into each chamber through the valve), q_in (drawn
        from the pump, ≥ 0), q_out (to tank, ≥ 0 mostly), dp_in, dp_out (drops across the
        edges), p_load (meter-in chamber pressure of drawing functions, else 0)."""
        pt = self.p_tank
        p_s = np.asarray(p_s, float)[..., None]
        ext = o > 0
        mag = np.abs(o)
        p_in = np.where(ext, p_a, p_b)
        p_out = np.where(ext, p_b, p_a)
        dp_in = p_s - p_in
        comp = root(np.clip(dp_in, 0.0, self.dp_c)) / root(self.dp_c)
        q_in = self.gain * mag * comp
        k_out = np.where(ext, self.k_out_b, self.k_out_a)
        dp_out = p_out - pt
        q_out = k_out * mag * root(np.minimum(dp_out, self.dp_out)) / root(self.dp_out)
        # single-acting: raising draws from the pump; lowering meters the piston-side
        # outflow through the compensated edge, the rod side is vented
        lower = self.single & ~ext
        q_low = self.gain * mag * root(np.clip(p_a - pt, 0.0, self.dp_c)) / root(self.dp_c)
        q_in = np.where(lower, 0.0, q_in)
        q_out = np.where(lower, q_low, np.where(self.single, 0.0, q_out))
        dp_out = np.where(lower, p_a - pt, dp_out)
        q_a = np.where(ext, q_in, -q_out)
        q_b = np.where(ext, -q_out, q_in)
        q_b = np.where(self.single, 0.0, q_b)
        draws = (mag > 1e-6) & ~lower
        return dict(q_a=q_a, q_b=q_b, q_in=q_in, q_out=q_out, dp_in=dp_in, dp_out=dp_out,
                    p_load=np.where(draws, p_in, 0.0))

    def pump_setpoint(self, p_load):
        """LS set pressure (...) from the load pressures (..., n)."""
        if self.pump_kind != "load_sensing":
            return np.full(np.shape(p_load)[:-1], float(self.p_set_const))
        pl = np.max(p_load, axis=-1)
        return np.minimum(np.maximum(self.standby, np.where(pl > 0, pl + self.margin, 0.0)),
                          self.p_relief)

    def leak_flows(self, p_a, p_b):
        """Leakage out of the loaded chamber to tank (l_a, l_b) ≥ 0 [m³/s]: which chamber is
        loaded blends over ±0.2 bar of p_a − p_b·A_b/A_a (:func:`loaded_share`)."""
        pt = self.p_tank
        w = loaded_share(p_a - p_b * self.area_b / self.area_a)
        la = w * self.leak * np.maximum(p_a - pt, 0.0)
        lb = np.where(self.single, 0.0, (1.0 - w) * self.leak * np.maximum(p_b - pt, 0.0))
        return la, lb

    def makeup(self, p):
        """Anti-cavitation flow from tank into a chamber below tank pressure [m³/s] (full valve
        flow at 10 bar under tank; zero at and above tank, with a continuous slope: d²/(d + 0.2
        bar) for d = tank − p > 0)."""
        d = np.maximum(self.p_tank - np.asarray(p, float), 0.0)
        return self.gain / 1e6 * d * d / (d + DP_REG)

    # ------------------------------------------------------------------ the ODE
    def rhs(self, p_a, p_b, p_s, o, x, xd):
        """Time derivatives (ṗ_a, ṗ_b, ṗ_s) of the pressure states."""
        f = self.flows(p_a, p_b, p_s, o)
        va, vb = self.volumes(x)
        la, lb = self.leak_flows(p_a, p_b)
        dpa = self.beta_at(p_a) / va * (f["q_a"] - self.area_a * xd - la + self.makeup(p_a))
        dpb = self.beta_at(p_b) / vb * (f["q_b"] + self.area_b * xd - lb + self.makeup(p_b))
        dpb = np.where(self.single, 0.0, dpb)
        excess = np.maximum(np.sum(f["q_in"], axis=-1) - self.q_max, 0.0)
        dps = ((self.pump_setpoint(f["p_load"]) - p_s) / self.tau_pump
               - self.beta_at(p_s) / self.v_pump * excess)
        return dpa, dpb, dps

    def initial_pressures(self, force):
        """Load-holding pressures (p_a, p_b) for actuator forces (n,) (the loaded side
        carries the force, the other sits at tank; a motor/cylinder with F < 0 on side b)."""
        pt = self.p_tank
        F = np.asarray(force, float)
        p_a = np.where(F >= 0, (F + self.area_b * pt) / self.area_a, pt)
        p_b = np.where(F >= 0, pt, (self.area_a * pt - F) / self.area_b)
        p_a = np.where(self.single, pt + np.maximum(F, 0) / self.area_a, p_a)
        return p_a, np.where(self.single, pt, p_b)
