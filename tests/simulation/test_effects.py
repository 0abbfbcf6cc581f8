"""The effects catalogue: contract names, parsing errors, and each injected effect against an
independent oracle (what the effect means physically)."""
import json
import math

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.model.effects import CATALOGUE, catalogue, make, parse_effect
from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.simulation.plant import respond

CONTRACT = ["joint_offset", "flow_gain", "valve_deadband", "valve_lag", "time_delay",
            "pump_flow_limit", "leakage", "coulomb_friction", "viscous_friction",
            "payload_mass", "actuator_mass", "pressure_offset"]


@pytest.fixture(scope="module")
def move(cat215b):
    """A 50 Hz feed-forward of one rest-to-rest move at 60 % speed, then 2 s of rest."""
    L = cat215b.limit_arrays()
    a = L["q_min"] + 0.3 * (L["q_max"] - L["q_min"])
    b = L["q_min"] + 0.7 * (L["q_max"] - L["q_min"])
    tr = rest_to_rest(cat215b, a, b, scale=0.6).trajectory
    ff = commands(cat215b, tr, 50.0)
    t = np.concatenate([ff.t, ff.t[-1] + 0.02 * np.arange(1, 101)])
    u = np.vstack([ff.u, np.zeros((100, cat215b.n))])
    return a, t, u


def test_catalogue_has_the_contract_names_and_json(capsys):
    assert set(CONTRACT) <= set(CATALOGUE)
    assert main(["effects", "list", "--json", "-"]) == 0
    cat_json = json.loads(capsys.readouterr().out)
    by = {e["name"]: e for e in cat_json}
    assert set(CONTRACT) <= set(by)
    for e in cat_json:
        assert e["description"] and isinstance(e["parameters"], dict)
        for k, v in e["parameters"].items():
            if k == "joint":
                assert isinstance(v, str)
            else:
                assert len(v) == 2 and v[0] < v[1]
    assert by["flow_gain"]["parameters"]["joint"] and "joint" not in by["time_delay"]["parameters"]
    # the catalogue, plus the plants that apply each effect (every effect has one)
    assert catalogue() == [{k: v for k, v in e.items() if k != "plants"} for e in cat_json]
    assert all(e["plants"] for e in cat_json)
    assert "fast" not in by["bulk_modulus"]["plants"] and "exudyn" in by["bulk_modulus"]["plants"]
    assert "fast" in by["flow_gain"]["plants"]


@pytest.mark.parametrize("text,match", [
    ("friction:joint=boom,force=1", "unknown effect 'friction'"),
    ("coulomb_friction:force=100", "needs joint"),
    ("time_delay:joint=boom,delay=0.1", "takes no joint"),
    ("flow_gain:joint=boom,gain=1.1", "unknown parameter.*allowed: scale"),
    ("flow_gain:joint=boom,scale=3", "scale = 3 .*outside.*0.5, 1.5"),
    ("flow_gain:joint=arm,scale=1.1", "unknown joint 'arm'.*swing, boom, stick"),
    ("flow_gain:joint=boom,scale=abc", "scale = 'abc' is not a number"),
    ("flow_gain:joint=boom,scale", "expected key=value"),
])
def test_bad_effects_are_refused_with_the_reason(cat215b, text, match):
    with pytest.raises(ValueError, match=match):
        parse_effect(text, cat215b)


def test_parse_accepts_degrees_and_prints_back(cat215b):
    e = parse_effect("joint_offset:joint=boom,offset=2deg", cat215b)
    assert e.offset == pytest.approx(math.radians(2))
    back = parse_effect(str(e).replace("(", ":").replace(")", "").replace(" ", ""), cat215b)
    assert back.name == e.name and back.joint == e.joint
    assert back.offset == pytest.approx(e.offset, rel=1e-5)


def test_no_effect_reproduces_the_nominal_replay(cat215b, move):
    from planner.simulation.replay import replay
    q0, t, u = move
    r = respond(cat215b, t, u, q0)
    sim = replay(cat215b, t, u, q0)
    np.testing.assert_allclose(r.q, sim.q, atol=1e-9)
    h = cat215b.hydraulics(r.state.q, r.state.qd, r.state.qdd)
    np.testing.assert_allclose(r.p_a, h["p_a"], rtol=1e-9, atol=1.0)
    np.testing.assert_allclose(r.p_b, h["p_b"], rtol=1e-9, atol=1.0)


def test_flow_gain_scales_that_joints_travel(cat215b, move):
    q0, t, u = move
    x0 = cat215b.stroke(respond(cat215b, t, u, q0).state.q)[0]
    x1 = cat215b.stroke(respond(cat215b, t, u, q0, [make("flow_gain", "stick", scale=1.1)]).state.q)[0]
    d0, d1 = x0[-1] - x0[0], x1[-1] - x1[0]
    assert d1[2] == pytest.approx(1.1 * d0[2], rel=1e-6)
    np.testing.assert_allclose(d1[:2], d0[:2], rtol=1e-9)


def test_time_delay_shifts_every_joint(cat215b, move):
    q0, t, u = move
    nom = respond(cat215b, t, u, q0).state.q
    dl = respond(cat215b, t, u, q0, [make("time_delay", delay=0.1)]).state.q
    # five samples of delay: the delayed motion is the nominal one five samples later
    np.testing.assert_allclose(dl[5:], nom[:-5], atol=1e-9)


def test_valve_lag_is_a_first_order_response(cat215b):
    """A command step of 0.5 on the boom through a 0.2 s lag: the stroke rate approaches its
    final value as 1 − exp(−t/τ) (per-period means; compared with the analytic integral)."""
    t = np.arange(0, 2.0, 0.02)
    u = np.zeros((len(t), cat215b.n))
    u[5:, 1] = 0.5
    q0 = np.array([0.0, 0.0, -1.5])
    nom = cat215b.stroke(respond(cat215b, t, u, q0).state.q)[0][:, 1]
    lag = cat215b.stroke(respond(cat215b, t, u, q0, [make("valve_lag", "boom", tau=0.2)]).state.q)[0][:, 1]
    rate = (nom[-1] - nom[-2]) / 0.02
    s = np.clip(t - t[5], 0, None)
    expected = nom[0] + rate * (s - 0.2 * (1 - np.exp(-s / 0.2)))
    np.testing.assert_allclose(lag, expected, atol=1e-9 + 1e-6 * abs(rate))


def test_pump_flow_limit_shares_the_flow(cat215b, move):
    from planner.simulation.replay import stroke_rates
    _, t, u = move
    _, demand, _ = stroke_rates(cat215b, u)
    e = make("pump_flow_limit", scale=0.2)
    from planner.simulation.replay import Plant
    plant = e.plant(cat215b, Plant())
    xd, drawn, share = stroke_rates(cat215b, u, plant)
    Q = 0.2 * cat215b.spec.pump.max_flow
    short = demand > Q
    assert short.any()
    np.testing.assert_allclose(share[short], Q / demand[short])
    np.testing.assert_allclose(drawn[short], Q)


def test_joint_offset_biases_the_reading_only(cat215b, move):
    q0, t, u = move
    nom = respond(cat215b, t, u, q0)
    off = respond(cat215b, t, u, q0, [make("joint_offset", "boom", offset=0.02)])
    np.testing.assert_allclose(off.q[:, 1] - nom.q[:, 1], 0.02, atol=1e-12)
    np.testing.assert_allclose(off.p_a, nom.p_a)


def test_pressure_offset_and_friction_act_on_pressures_only(cat215b, move):
    q0, t, u = move
    nom = respond(cat215b, t, u, q0)
    po = respond(cat215b, t, u, q0, [make("pressure_offset", "stick", offset_a=3e5)])
    np.testing.assert_allclose(po.p_a[:, 2] - nom.p_a[:, 2], 3e5)
    fr = respond(cat215b, t, u, q0, [make("coulomb_friction", "boom", force=4000.0)])
    np.testing.assert_allclose(fr.q, nom.q)
    dF = fr.state.force[:, 1] - nom.state.force[:, 1]
    xd = nom.state.xd[:, 1]
    a = cat215b.spec.joints[1].actuator
    v_s = 0.01 * a.flow_gain / min(a.area_a, a.area_b)   # the documented smoothing speed
    fast = np.abs(xd) > 10 * v_s
    np.testing.assert_allclose(dF[fast], 4000.0 * np.sign(xd[fast]), rtol=1e-6)
    assert np.all(dF[-50:] == 0.0)                       # at rest: no friction force


def test_payload_and_actuator_mass_against_the_model_itself(cat215b, move):
    """Payload: the model's own hydraulics with the heavier payload. Actuator mass: a model
    built from the spec with the heavier cylinder (independent of the linear regressor)."""
    from dataclasses import replace
    q0, t, u = move
    nom = respond(cat215b, t, u, q0)
    s = nom.state
    pl = respond(cat215b, t, u, q0, [make("payload_mass", mass=500.0)])
    h = cat215b.hydraulics(s.q, s.qd, s.qdd, cat215b.spec.payload.total + 500.0)
    np.testing.assert_allclose(pl.p_a, h["p_a"], rtol=1e-6, atol=10.0)
    am = respond(cat215b, t, u, q0, [make("actuator_mass", "boom", mass=300.0)])
    j = cat215b.spec.joints[1]
    heavy = Crane(replace(cat215b.spec, joints=(cat215b.spec.joints[0], replace(
        j, actuator=replace(j.actuator, mass=j.actuator.mass + 300.0)), cat215b.spec.joints[2])))
    h2 = heavy.hydraulics(s.q, s.qd, s.qdd)
    np.testing.assert_allclose(am.p_a, h2["p_a"], rtol=1e-6, atol=10.0)


def test_leakage_drifts_a_held_load_at_the_leak_rate(cat215b):
    """Boom held (no command) under gravity: it sinks at C·(p_a − p_t)/A_a."""
    t = np.arange(0, 3.0, 0.02)
    u = np.zeros((len(t), cat215b.n))
    q0 = np.array([0.0, 0.3, -1.5])
    C = 5e-12
    r = respond(cat215b, t, u, q0, [make("leakage", "boom", coefficient=C)])
    x = cat215b.stroke(r.state.q)[0][:, 1]
    a = cat215b.spec.joints[1].actuator
    p = r.state.p_a[:, 1]
    rate = (x[-1] - x[0]) / (t[-1] - t[0])
    assert rate < 0                                   # sinks
    assert rate == pytest.approx(-C * np.mean(p) / a.area_a, rel=1e-3)
