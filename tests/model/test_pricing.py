"""The pump pricing of the quasi-static model (planner.model.pricing): the machine pricing
against hand-computed cases, the seed pricing against the figures the model gave before the
machine pricing existed, and the CasADi gradients the energy NLP uses against finite
differences."""
import math
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest

from planner import Crane
from planner.model import flows
from planner.model.pricing import pricing_of
from planner.trajectory import Trajectory, evaluate


def _back_pressure_by_bisection(dp_out, margin, reg=2.0e4):
    """Oracle: the drop at which the return edge passes 1/(1 + margin) of its cap, found by
    bisection on the orifice law r(Δp) = Δp/(Δp² + Δp_r²)^¼ (no closed form used)."""
    r = lambda d: d / (d * d + reg * reg) ** 0.25   # noqa: E731
    target = r(dp_out) / (1.0 + margin)
    lo, hi = 0.0, dp_out
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if r(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def _one_moving(crane, i, xd_i, F_i):
    """Stroke rates and forces with only actuator ``i`` moving (the others idle, unloaded)."""
    xd = np.zeros(crane.n)
    F = np.zeros(crane.n)
    xd[i], F[i] = xd_i, F_i
    return xd, F


def _fric(crane, i, v):
    d = crane.spec.dynamics
    j = crane.spec.joints[i]
    jd = d.joints[j.name]
    v_s = 0.01 * j.actuator.flow_gain / min(j.actuator.area_a, j.actuator.area_b)
    return jd.coulomb * math.tanh(v / v_s) + jd.viscous * v


def test_back_pressure_is_the_matched_outflow_drop():
    for cid in ("s100f", "umea-lab"):
        d = Crane.from_id(cid).spec.dynamics
        want = _back_pressure_by_bisection(d.meter_out_dp, d.meter_out_margin)
        got = pricing_of(Crane.from_id(cid).spec).back
        np.testing.assert_allclose(got[got > 0], want, rtol=1e-12)
        # ≈ Δp_o/(1 + m)² far above the orifice's laminar region
        assert want == pytest.approx(d.meter_out_dp / (1 + d.meter_out_margin) ** 2, rel=2e-3)


def test_passive_lift_pays_the_outlet_counter_pressure():
    """The jib of cranab850 extending against a 40 kN load: the rod side sits Δp_b above
    tank, the piston side carries load + friction + that counter-pressure, the pump runs at
    the piston pressure + the LS margin."""
    crane = Crane.from_id("cranab850")
    spec, i = crane.spec, 2
    act, pump = spec.joints[i].actuator, spec.pump
    v, F = 0.05, 4.0e4
    xd, force = _one_moving(crane, i, v, F)
    h = flows.hydraulics(crane, np.zeros(crane.n), xd, force)
    dp_b = _back_pressure_by_bisection(spec.dynamics.meter_out_dp, spec.dynamics.meter_out_margin)
    pt = pump.tank_pressure
    p_a = (F + _fric(crane, i, v) + act.area_b * (pt + dp_b)) / act.area_a
    assert h["p_b"][i] == pytest.approx(pt + dp_b, rel=1e-12)
    assert h["p_a"][i] == pytest.approx(p_a, rel=1e-12)
    p_pump = max(pump.standby, p_a + pump.margin)
    assert h["power"] == pytest.approx(p_pump * act.area_a * v / pump.efficiency, rel=1e-12)
    # the seed pricing: the load alone, rod side at tank
    hs = flows.hydraulics(crane, np.zeros(crane.n), xd, force, mode="seed")
    assert hs["p_a"][i] == pytest.approx((F + act.area_b * pt) / act.area_a, rel=1e-12)
    assert hs["power"] < h["power"]


def test_lowering_a_light_load_costs_counter_pressure_times_flow():
    """Lowering the jib (retracting) with a load smaller than the counter-pressure's force:
    the seed pricing calls it overrunning (rod side at tank: the pump's LS pressure is the
    margin alone); on the machine the piston side sits Δp_b above tank, so the pump pushes the
    rod side to A_a·(p_t + Δp_b) − F − F_f over A_b — the counter-pressure (less the load's
    help) times the flow."""
    crane = Crane.from_id("cranab850")
    spec, i = crane.spec, 2
    act, pump = spec.joints[i].actuator, spec.pump
    dp_b = _back_pressure_by_bisection(spec.dynamics.meter_out_dp, spec.dynamics.meter_out_margin)
    v = -0.05
    F = 0.5 * act.area_a * dp_b        # the load pulls the jib in, less than Δp_b·A_a
    xd, force = _one_moving(crane, i, v, F)
    pt = pump.tank_pressure
    h = flows.hydraulics(crane, np.zeros(crane.n), xd, force)
    p_b = (act.area_a * (pt + dp_b) - F - _fric(crane, i, v)) / act.area_b
    assert p_b > pt
    assert h["p_a"][i] == pytest.approx(pt + dp_b, rel=1e-12)
    assert h["p_b"][i] == pytest.approx(p_b, rel=1e-12)
    assert h["p_load"][i] == pytest.approx(p_b, rel=1e-12)
    Q = act.area_b * abs(v)
    assert h["q_pump"] == pytest.approx(Q, rel=1e-12)
    # with a pump that has no standby floor the hydraulic power is (p_b + margin)·Q
    spec0 = replace(spec, pump=replace(pump, standby=0.0))
    h0 = flows.hydraulics(Crane(spec0), np.zeros(crane.n), xd, force)
    assert h0["power"] * pump.efficiency == pytest.approx((p_b + pump.margin) * Q, rel=1e-12)
    hs = flows.hydraulics(Crane(spec0, pricing="seed"), np.zeros(crane.n), xd, force)
    assert hs["p_load"][i] == pt and hs["power"] * pump.efficiency == pytest.approx(
        (pt + pump.margin) * Q, rel=1e-12)


def test_overrunning_load_is_held_by_the_outlet():
    """Lowering the jib under a heavy load: the inlet (rod side) sits at tank — the anti-
    cavitation valve keeps it there — and the piston side throttles the load to tank; the
    pump delivers the metered flow at its floor."""
    crane = Crane.from_id("cranab850")
    spec, i = crane.spec, 2
    act, pump = spec.joints[i].actuator, spec.pump
    v, F = -0.05, 6.0e4
    xd, force = _one_moving(crane, i, v, F)
    h = flows.hydraulics(crane, np.zeros(crane.n), xd, force)
    pt = pump.tank_pressure
    assert h["p_b"][i] == pt
    assert h["p_a"][i] == pytest.approx((F + _fric(crane, i, v) + act.area_b * pt)
                                        / act.area_a, rel=1e-12)
    assert h["power"] == pytest.approx(max(pump.standby, pt + pump.margin) * act.area_b * -v
                                       / pump.efficiency, rel=1e-12)


def test_single_acting_lowering_stays_free():
    crane = Crane.from_id("s100f")
    xd, force = _one_moving(crane, 1, -0.05, 8.0e4)
    h = flows.hydraulics(crane, np.zeros(crane.n), xd, force)
    assert h["q_pump"] == 0 and h["power"] == 0


@pytest.mark.parametrize("cid,golden", [
    ("s100f", (74627.2588260277, 282644.9611330492)),
    ("cranab850", (107836.80619614881, 253443.29429715913)),
    ("umea-lab", (7607.725284109004, 2495.1418540562818)),
    ("cat215b", (1459398.907429793, 1039702.1328323465))])
def test_seed_pricing_reproduces_the_old_figures(cid, golden):
    """The switch keeps the old pricing: evaluate()'s pump energy of two fixed moves equals
    the figures the model gave before the machine pricing existed (commit 8888bd9, printed to
    full precision); the machine pricing costs more on every one of them."""
    seed = Crane.from_id(cid, pricing="seed")
    machine = Crane.from_id(cid)
    assert machine.pricing == "machine" and seed.pricing == "seed"
    L = seed.limit_arrays()
    q0 = L["q_min"] + 0.3 * (L["q_max"] - L["q_min"])
    q1 = L["q_min"] + 0.7 * (L["q_max"] - L["q_min"])
    for (a, b), want in zip(((q0, q1), (q1, q0)), golden):
        t = np.linspace(0, 6.0, 301)
        s = t / 6.0
        d = b - a
        q = a + np.outer(10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5, d)
        qd = np.outer((30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / 6.0, d)
        qdd = np.outer((60 * s - 180 * s ** 2 + 120 * s ** 3) / 36.0, d)
        tr = Trajectory(t, q, qd, qdd, joint_names=tuple(seed.names))
        assert evaluate(seed, tr).energy_J == pytest.approx(want, rel=1e-12)
        assert evaluate(machine, tr).energy_J > want


def test_spec_without_dynamics_prices_as_the_seed():
    crane = Crane.from_id("cranab850")
    bare = Crane(replace(crane.spec, dynamics=None))
    assert bare.pricing == "seed"
    rng = np.random.default_rng(5)
    L = crane.limit_arrays()
    q = L["q_min"] + rng.random((50, crane.n)) * (L["q_max"] - L["q_min"])
    qd = rng.uniform(L["qd_min"], L["qd_max"], (50, crane.n))
    qdd = rng.normal(0, 0.3, (50, crane.n))
    a = bare.hydraulics(q, qd, qdd)
    b = Crane.from_id("cranab850", pricing="seed").hydraulics(q, qd, qdd)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def test_bad_pricing_names_the_field_and_the_choices():
    with pytest.raises(ValueError, match=r"pricing: 'exudyn' is not a pricing; allowed: seed, "
                                         r"machine"):
        Crane.from_id("umea-lab", pricing="exudyn")
    spec = replace(Crane.from_id("umea-lab").spec, dynamics=None)
    with pytest.raises(ValueError, match=r"pricing: 'machine' needs the \[dynamics\] section"):
        Crane(spec, pricing="machine")


def test_nlp_gradients_match_finite_differences():
    """The energy NLP's load-sensing rows use crane.f_pin and the pump power f_hyd: their
    CasADi Jacobians against central differences at random moving states."""
    crane = Crane.from_id("cranab850")
    n = crane.n
    F, v = ca.SX.sym("F", n), ca.SX.sym("v", n)
    pe, pr = crane.f_pin(F, v)
    jac = ca.Function("j", [F, v], [ca.jacobian(ca.vertcat(pe, pr), ca.vertcat(F, v))])
    val = ca.Function("f", [F, v], [ca.vertcat(pe, pr)])
    rng = np.random.default_rng(9)
    for _ in range(5):
        x0 = np.concatenate([rng.normal(0, 3e4, n), rng.uniform(-0.1, 0.1, n)])
        J = np.array(jac(x0[:n], x0[n:]))
        fd = np.zeros_like(J)
        for k in range(2 * n):
            h = 1e-3 if k < n else 1e-7
            e = np.zeros(2 * n)
            e[k] = h
            fd[:, k] = (np.array(val((x0 + e)[:n], (x0 + e)[n:])).ravel()
                        - np.array(val((x0 - e)[:n], (x0 - e)[n:])).ravel()) / (2 * h)
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-6 * np.abs(J).max())
    # pump power w.r.t. the joint rates, away from the kinks (one function moving, passive)
    q = ca.SX.sym("q", n)
    qd = ca.SX.sym("qd", n)
    m = crane.spec.payload.total
    P = crane.f_hyd(q, qd, ca.DM.zeros(n), m)[9]
    dP = ca.Function("dP", [q, qd], [ca.jacobian(P, qd)])
    fP = ca.Function("P", [q, qd], [P])
    L = crane.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    qd0 = np.zeros(n)
    qd0[2] = -0.1                      # the jib lifts (its cylinder extends) against gravity
    g = float(np.array(dP(q0, qd0))[0, 2])
    h = 1e-6
    e = np.zeros(n)
    e[2] = h
    fd = (float(fP(q0, qd0 + e)) - float(fP(q0, qd0 - e))) / (2 * h)
    assert float(fP(q0, qd0)) > 0
    assert g == pytest.approx(fd, rel=1e-5)
