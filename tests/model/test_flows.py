"""The numpy hydraulics (planner.model.flows) and valve model (planner.model.valves) against the
CasADi definition and against analytic facts."""
import copy
import tomllib
from dataclasses import replace

import numpy as np
import pytest

from planner import Crane
from planner.model import flows, valves
from planner.model.hydraulics import OUTPUTS
from planner.model.spec import parse_spec
from planner.problems import crane_path

from tests.conftest import MACHINES, random_configs


def _variant(cid, edit, name):
    data = copy.deepcopy(tomllib.loads(crane_path(cid).read_text()))
    edit(data)
    return Crane(parse_spec(data, name))


def _enable_ht(data):
    data["transformer"]["enabled"] = True


def _constant_pressure(data):
    data["pump"] = dict(kind="constant_pressure", max_flow=0.003, pressure=21e6,
                        efficiency=0.8, tank_pressure=3e5, source="test")


def _no_standby(data):
    """Margin above standby and a tank pressure: the active-flow threshold decides the pump
    pressure of an idle machine (margin, or standby = 0)."""
    data["pump"].update(standby=0.0, tank_pressure=2e5)


VARIANTS = {"s100f+ht": ("s100f", _enable_ht), "s100f+cp": ("s100f", _constant_pressure),
            "cat215b+ls0": ("cat215b", _no_standby)}


@pytest.fixture(scope="module", params=MACHINES + list(VARIANTS))
def model(request):
    if request.param in VARIANTS:
        cid, edit = VARIANTS[request.param]
        return _variant(cid, edit, request.param)
    return Crane.from_id(request.param)


def random_states(crane, N=400, seed=1):
    """Random (q, qd, qdd, payload) with idle joints, rates below the active-flow threshold,
    both force signs, and both directions of every actuator."""
    rng = np.random.default_rng(seed)
    q = random_configs(crane, N, seed=seed)
    L = crane.limit_arrays()
    qd = rng.uniform(L["qd_min"], L["qd_max"], (N, crane.n))
    mode = rng.integers(0, 6, (N, crane.n))
    qd = np.where(mode == 0, 0.0, qd)                 # idle
    qd = np.where(mode == 1, qd * 1e-7, qd)           # numerical crumbs of motion
    qd[:20] *= 1e-7                                   # whole machine idle but for crumbs
    qd[:10:2] = 0.0                                   # whole machine at rest
    qdd = rng.uniform(-1, 1, (N, crane.n)) * L["qdd_max"] * 3
    payload = rng.uniform(0, 2, (N, 1)) * crane.spec.payload.total
    return q, qd, qdd, payload


def test_transformer_variant_is_enabled():
    ht = _variant("s100f", _enable_ht, "ht")
    T = flows.actuator_table(ht.spec)
    assert T.transformer and T.ht_source == ht.spec.joint_index("jib")
    assert T.ht_target == ht.spec.joint_index("boom")
    assert not flows.actuator_table(Crane.from_id("s100f")).transformer


def test_numpy_hydraulics_equal_the_casadi_definition(model):
    q, qd, qdd, m = random_states(model)
    ref = model.hydraulics(q, qd, qdd, m)
    got = flows.hydraulics(model.spec, ref["x"], ref["xd"], ref["force"])
    assert tuple(got) == OUTPUTS
    for k in OUTPUTS:
        a, b = np.asarray(got[k]), np.asarray(ref[k])
        assert a.shape == b.shape, k
        scale = max(float(np.max(np.abs(b))), 1e-300)
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13 * scale, err_msg=k)
    # the states exercised every branch that the comparison is about
    assert np.any(ref["q_act"] == 0) and np.any(ref["q_act"] > 0)
    assert np.any(ref["force"] < 0) and np.any(ref["force"] > 0)
    assert np.any((ref["p_load"] == 0) & (ref["q_act"] > 0))   # crumbs below the threshold
    assert np.any((ref["q_pump"] > 0) & (ref["q_pump"] <= flows.actuator_table(model).active_flow))


def test_batched_over_leading_axes(model):
    q, qd, qdd, m = random_states(model, N=24)
    ref = model.hydraulics(q, qd, qdd, m)
    shaped = {k: ref[k].reshape((2, 3, 4) + ref[k].shape[1:]) for k in ("x", "xd", "force")}
    got = flows.hydraulics(model, shaped["x"], shaped["xd"], shaped["force"])
    for k in OUTPUTS:
        assert got[k].shape == (2, 3, 4) + ref[k].shape[1:], k
        np.testing.assert_allclose(got[k].reshape(ref[k].shape), ref[k], rtol=1e-12,
                                   atol=1e-3, err_msg=k)
    one = flows.hydraulics(model, ref["x"][5], ref["xd"][5], ref["force"][5])
    assert np.shape(one["p_pump"]) == () and one["p_a"].shape == (model.n,)


def test_chamber_pressures_balance_the_force(model):
    q, qd, qdd, m = random_states(model, N=200, seed=4)
    F = model.inverse_dynamics(q, qd, qdd, m) / model.stroke(q)[1]
    p_a, p_b = flows.chamber_pressures(model.spec, F)
    T = flows.actuator_table(model.spec)
    pt = model.spec.pump.tank_pressure
    holds = ~(T.single & (F < 0))        # a single-acting cylinder cannot pull
    if T.transformer:
        holds[:, T.ht_source] &= p_a[:, T.ht_source] > pt   # source clamped at tank otherwise
    # a single-acting cylinder's rod side is vented: A_a·(p_a − p_tank) carries the force
    balance = np.where(T.single, T.area_a * (p_a - pt), T.area_a * p_a - T.area_b * p_b)
    np.testing.assert_allclose(balance[holds], F[holds], rtol=1e-9,
                               atol=1e-6 * np.max(np.abs(F)))
    if not T.transformer:   # the chamber on the unloaded side sits at tank
        np.testing.assert_array_equal(np.where(F >= 0, p_b, p_a), pt)


@pytest.mark.parametrize("cid", ["cranab850", "umea-lab", "s100f", "cat215b"])
def test_swept_volume_is_the_integral_of_the_pump_draw(cid):
    """Stroke maps are monotone over the joint range, so along any joint move the pump delivers
    exactly the swept volume of the net stroke change: compare with the CasADi flow
    integrated over a smooth move."""
    crane = Crane.from_id(cid)
    q0, q1 = random_configs(crane, 2, seed=7)
    t = np.linspace(0.0, 5.0, 20001)
    s = t / t[-1]
    b = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
    bd = (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / t[-1]
    q = q0 + np.outer(b, q1 - q0)
    qd = np.outer(bd, q1 - q0)
    h = crane.hydraulics(q, qd, np.zeros_like(q))
    integral = np.sum(0.5 * (h["q_act"][1:] + h["q_act"][:-1]) * np.diff(t)[:, None], axis=0)
    x0, x1 = crane.stroke(q0)[0], crane.stroke(q1)[0]
    V = flows.swept_volume(crane.spec, x1 - x0)
    np.testing.assert_allclose(integral, V, rtol=1e-6, atol=1e-12)
    np.testing.assert_array_equal(V, flows.pump_draw(crane, x1 - x0))


def test_single_acting_lowering_draws_nothing():
    crane = Crane.from_id("s100f")
    T = flows.actuator_table(crane)
    assert T.single.tolist() == [False, True, False, False]
    xd = np.array([[0.0, -0.05, 0.0, 0.0], [0.0, 0.05, 0.0, 0.0]])
    Q = flows.pump_draw(crane.spec, xd)
    assert Q[0, 1] == 0.0 and Q[1, 1] == pytest.approx(T.area_a[1] * 0.05)


def test_actuator_table_is_cached_per_spec():
    crane = Crane.from_id("umea-lab")
    assert flows.actuator_table(crane.spec) is flows.actuator_table(crane)
    other = replace(crane.spec, joints=crane.spec.joints)
    assert flows.actuator_table(other) is not flows.actuator_table(crane.spec)
    with pytest.raises(ValueError, match="expected 4 values"):
        flows.pump_draw(crane.spec, np.zeros(3))
    with pytest.raises(TypeError, match="CraneSpec"):
        flows.actuator_table("umea-lab")


# ----------------------------------------------------------------------------- valves
@pytest.mark.parametrize("cid", ["cranab850", "umea-lab", "s100f", "cat215b"])
def test_valve_round_trip_and_dead_band(cid):
    crane = Crane.from_id(cid)
    spec = crane.spec
    joints = tuple(replace(j, actuator=replace(j.actuator, deadband=0.12)) for j in spec.joints)
    vp = valves.valve_params(replace(spec, joints=joints))
    rng = np.random.default_rng(2)
    u = rng.uniform(-1, 1, (500, crane.n))
    xd = valves.command_to_stroke_rate(vp, u)
    dead = np.abs(u) <= 0.12
    assert np.all(xd[dead] == 0) and np.all(np.sign(xd[~dead]) == np.sign(u[~dead]))
    u2, flow = valves.stroke_rate_to_command(vp, xd)
    np.testing.assert_allclose(u2[~dead], u[~dead], rtol=1e-12, atol=1e-15)
    assert np.all(u2[dead] == 0)
    # the metered flow is the dead-band-corrected command times the gain (analytic)
    expect = vp.flow_gain * np.maximum(np.abs(u) - 0.12, 0) / 0.88
    np.testing.assert_allclose(np.abs(flow), np.where(dead, 0.0, expect), rtol=1e-12, atol=0)
    # saturation: commands beyond ±1 give the full-gain rate
    np.testing.assert_allclose(valves.command_to_stroke_rate(vp, 3 * np.ones(crane.n)),
                               vp.flow_gain / vp.area_extend, rtol=1e-15)


@pytest.mark.parametrize("cid", ["cranab850", "umea-lab", "s100f", "cat215b"])
def test_valve_flow_from_the_pump_equals_the_pump_draw(cid):
    """Two routes to the pump flow: valve flow of the functions the pump feeds, and the
    hydraulics' pump draw (no transformer: every valve's flow comes from the pump except a
    single-acting cylinder lowering)."""
    crane = Crane.from_id(cid)
    vp = valves.valve_params(crane)
    xd = np.random.default_rng(3).normal(0, 0.05, (300, crane.n))
    from_valves = np.where(valves.draws_pump(vp, xd), valves.metered_flow(vp, xd), 0.0)
    np.testing.assert_allclose(from_valves, flows.pump_draw(crane, xd), rtol=1e-15, atol=0)


def test_single_acting_valve_meters_the_piston_side_both_ways():
    vp = valves.valve_params(Crane.from_id("s100f"))
    assert vp.single.tolist() == [False, True, False, False]
    assert vp.area_retract[1] == vp.area_extend[1]
    assert vp.area_retract[2] < vp.area_extend[2]
    assert valves.draws_pump(vp, np.array([-1.0, -1.0, -1.0, 1.0])).tolist() == \
        [True, False, True, True]


def test_valve_params_name_the_joint():
    spec = Crane.from_id("umea-lab").spec
    bad = tuple(replace(j, actuator=replace(j.actuator, flow_gain=np.inf)) if j.name == "jib"
                else j for j in spec.joints)
    with pytest.raises(ValueError, match="joint 'jib' has no finite valve flow_gain"):
        valves.valve_params(replace(spec, joints=bad))
    bad = tuple(replace(j, actuator=replace(j.actuator, deadband=1.0)) if j.name == "boom"
                else j for j in spec.joints)
    with pytest.raises(ValueError, match=r"joint 'boom' deadband 1.0 outside \[0, 1\)"):
        valves.valve_params(replace(spec, joints=bad))
