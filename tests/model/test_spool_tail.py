"""The closing spool's tail of the machine pricing (planner.model.pricing.spool_step /
spool_lag, flows.spool_tail, flows.held_hydraulics): a function that stops while another
moves keeps its valve open past OPEN_EPS for τ·ln(u₀/OPEN_EPS) (hand calculation, dead band 0)
and holds the LS pump at its held meter-in pressure plus the margin all that while; the closed
form of the lag against the CasADi step chained; the seed pricing has none."""
import math

import casadi as ca
import numpy as np
import pytest

from planner import Crane
from planner.model import flows
from planner.model.pricing import spool_lag, spool_step
from planner.model.valve_physics import OPEN_EPS

SLEW, JIB = 0, 2


def test_closed_form_lag_equals_the_step_chained():
    """Random uneven grid over 3 s (75 τ: several closed-form chunks), commands that change
    sign and rest: the closed form against the CasADi step, one step at a time."""
    rng = np.random.default_rng(3)
    tau = 0.04
    t = np.cumsum(np.r_[0.0, rng.uniform(1e-4, 4e-3, 1500)])
    u = np.where(rng.random((len(t), 2)) < 0.3, 0.0, rng.uniform(-1, 1, (len(t), 2)))
    s0, uu, h = ca.SX.sym("s0"), ca.SX.sym("u"), ca.SX.sym("h")
    f = ca.Function("f", [s0, uu, h], [spool_step(s0, uu, h, tau)])
    want = np.empty_like(u)
    want[0] = u[0]
    for k in range(len(t) - 1):
        want[k + 1] = [float(f(want[k, i], u[k, i], t[k + 1] - t[k])) for i in range(2)]
    got = spool_lag(t, u, tau)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def _stop_plan(crane, t_stop=1.0, T=2.0, dt=1e-3):
    """The jib extending at 0.1 m/s stroke rate until ``t_stop`` and then at rest, the slew
    turning throughout; unloaded forces (their pressures come from the pricing)."""
    t = np.arange(0.0, T + dt / 2, dt)
    n = crane.n
    xd = np.zeros((len(t), n))
    xd[:, SLEW] = 0.02
    xd[t < t_stop, JIB] = 0.1
    x = np.tile(np.array([0.0, 0.3, 0.6, 0.5]), (len(t), 1))
    force = np.zeros((len(t), n))
    force[:, JIB] = 2.0e5         # a heavy jib: its holding pressure sets the pump
    force[:, SLEW] = 1.0e3
    return t, flows.hydraulics(crane, x, xd, force)


def test_a_stopped_function_holds_the_pump_for_its_spools_tail():
    """By hand: the jib's command u₀ = A_a·ẋ/G (dead band 0) decays from its stop as
    u₀·e^(−(t − t₁)/τ), t₁ the first sample at rest (held from there, zero-order); the valve
    shows the LS line its pressure until u₀·e^(−Δt/τ) = OPEN_EPS — and the pump sits at the
    jib's held piston-side pressure + margin, then falls to the slew's."""
    crane = Crane.from_id("s100f")
    spec, pr = crane.spec, crane.prices
    act = spec.joints[JIB].actuator
    assert act.deadband == 0.0 and spec.joints[SLEW].actuator.deadband == 0.0
    tau = spec.dynamics.spool_time_constant
    t, hyd = _stop_plan(crane)
    h = flows.held_hydraulics(crane, t, hyd)
    u0 = act.area_a * 0.1 / act.flow_gain
    k1 = int(np.argmax(t >= 1.0))
    t_end = t[k1] + tau * math.log(u0 / OPEN_EPS)
    assert 0.3 < t_end - 1.0 < 0.6                     # ≈ 0.45 s at τ = 40 ms
    margin = spec.pump.margin
    inside = (t > 1.0 + 1e-6) & (t < t_end - 2e-3)
    after = t > t_end + 2e-3
    jib_hold = h["p_a"][:, JIB]
    assert np.all(jib_hold[inside] > h["p_load"][inside, SLEW] + 1e6)   # it would set the pump
    np.testing.assert_allclose(h["p_pump"][inside], jib_hold[inside] + margin, rtol=1e-12)
    want_after = np.maximum(spec.pump.standby, h["p_load"][after, SLEW] + margin)
    np.testing.assert_allclose(h["p_pump"][after], want_after, rtol=1e-12)
    # the pump work of the tail: by hand, (jib's hold − slew's load)·Q over the tail
    w = h["p_pump"] * h["q_pump"]
    w0 = np.maximum(spec.pump.standby, h["p_load"][:, SLEW] + margin) * h["q_pump"]
    extra = np.sum((w - w0)[t > 1.0 + 1e-6]) * 1e-3
    q = h["q_pump"][-1]
    hand = (jib_hold[-1] - h["p_load"][-1, SLEW]) * q * (t_end - 1.0)
    assert extra == pytest.approx(hand, rel=0.01)
    # before the stop nothing changes: the jib moves and draws in the plan anyway
    np.testing.assert_allclose(h["p_pump"][t < 1.0], hyd["p_pump"][t < 1.0], rtol=1e-12)


def test_seed_pricing_has_no_tail():
    crane = Crane.from_id("s100f", pricing="seed")
    assert crane.prices.tau_spool == 0.0
    t, hyd = _stop_plan(crane)
    assert flows.spool_tail(crane.prices, t, hyd["xd"]) is None
    assert flows.held_hydraulics(crane, t, hyd) is hyd
