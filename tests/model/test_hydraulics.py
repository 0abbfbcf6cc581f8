"""Hydraulics and energy: flows, pressures, load-sensing pump, single-acting lowering."""
import copy
import tomllib

import numpy as np
import pytest

from planner import Crane
from planner.model.hydraulics import ACTIVE_FLOW
from planner.model.spec import parse_spec
from planner.trajectory import Trajectory, evaluate
from planner.problems import crane_path


def min_jerk(q0, q1, T, rate=50.0):
    t = np.linspace(0, T, int(T * rate) + 1)
    s = t / T
    b = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
    bd = (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T
    bdd = (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2
    d = q1 - q0
    return t, q0 + np.outer(b, d), np.outer(bd, d), np.outer(bdd, d)


def test_slow_lift_costs_at_least_potential_energy_over_efficiency():
    crane = Crane.from_id("s100f")
    q0 = np.array([0.0, -0.1, 0.6, 1.0])
    q1 = q0.copy()
    q1[1] = -0.6  # raise the boom (clockwise positive: negative is up) — boom only
    t, q, qd, qdd = min_jerk(q0, q1, 30.0)
    ev = evaluate(crane, Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names)))
    dV = crane.potential_energy(q1) - crane.potential_energy(q0)
    m = crane.spec.payload.total
    dh = crane.tip(q1)[1] - crane.tip(q0)[1]
    eta = crane.spec.pump.efficiency
    assert dV > m * 9.81 * dh > 0
    assert ev.energy_J >= dV / eta
    assert ev.energy_J >= m * 9.81 * dh / eta
    # not wildly more: LS margin and standby only (one function moving, nothing throttled)
    assert ev.energy_J <= 1.5 * dV / eta
    # pump pressure = the boom's load pressure + the LS margin while it moves
    moving = ev.hyd["q_act"][:, 1] > ACTIVE_FLOW * crane.spec.pump.max_flow
    np.testing.assert_allclose(ev.hyd["p_pump"][moving],
                               ev.hyd["p_load"][moving, 1] + crane.spec.pump.margin, rtol=1e-9)


def test_single_acting_lowering_draws_no_pump_flow():
    crane = Crane.from_id("s100f")
    q0 = np.array([0.0, -0.6, 0.6, 1.0])
    q1 = q0.copy()
    q1[1] = -0.1  # lower the boom
    t, q, qd, qdd = min_jerk(q0, q1, 10.0)
    ev = evaluate(crane, Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names)))
    assert np.all(ev.hyd["xd"][1:-1, 1] < 0)  # the lift cylinder retracts...
    assert np.all(ev.hyd["q_act"][:, 1] == 0)  # ...and draws nothing from the pump
    assert ev.energy_J == 0.0
    assert np.all(ev.hyd["p_b"][:, 1] == crane.spec.pump.tank_pressure)  # rod side vented


def test_direction_dependent_areas():
    crane = Crane.from_id("s100f")
    q = np.array([0.0, -0.3, 0.4, 1.0])
    z = np.zeros(4)
    act = crane.spec.joints[3].actuator
    out = crane.hydraulics(q, np.array([0, 0, 0, 0.4]), z)
    assert out["q_act"][3] == pytest.approx(act.area_a * 0.2)  # telescope: x = q/2, extending
    inn = crane.hydraulics(q, np.array([0, 0, 0, -0.4]), z)
    assert inn["q_act"][3] == pytest.approx(act.area_b * 0.2)
    assert out["q_pump"] == pytest.approx(out["q_act"].sum())


@pytest.mark.parametrize("pricing", ["seed", "machine"])
def test_chamber_pressures_balance_force(pricing):
    """Seed pricing: the chambers carry the required force; machine pricing: that force plus
    the spec's friction, F_c·tanh(ẋ/v_s) + d·ẋ, written out here from the [dynamics] table."""
    crane = Crane.from_id("cat215b", pricing=pricing)
    dyn = crane.spec.dynamics.joints
    rng = np.random.default_rng(0)
    L = crane.limit_arrays()
    for _ in range(20):
        q = L["q_min"] + rng.random(3) * (L["q_max"] - L["q_min"])
        qd = rng.normal(0, 0.2, 3)
        qdd = rng.normal(0, 0.3, 3)
        h = crane.hydraulics(q, qd, qdd)
        Aa = np.array([j.actuator.area_a for j in crane.spec.joints])
        Ab = np.array([j.actuator.area_b for j in crane.spec.joints])
        fric = 0.0 * qd
        if pricing == "machine":
            G = np.array([j.actuator.flow_gain for j in crane.spec.joints])
            v_s = 0.01 * G / np.minimum(Aa, Ab)
            fric = np.array([dyn[j].coulomb * np.tanh(v / s) + dyn[j].viscous * v
                             for j, v, s in zip(crane.names, h["xd"], v_s)])
        np.testing.assert_allclose(Aa * h["p_a"] - Ab * h["p_b"], h["force"] + fric, rtol=1e-9,
                                   atol=1e-6)
        # virtual work: force · stroke rate = joint torque · joint rate
        tau = crane.inverse_dynamics(q, qd, qdd)
        np.testing.assert_allclose(h["force"] * h["xd"], tau * qd, rtol=1e-9, atol=1e-6)


def test_constant_pressure_pump_power():
    data = copy.deepcopy(tomllib.loads(crane_path("s100f").read_text()))
    data["pump"] = dict(kind="constant_pressure", max_flow=0.003, pressure=21e6, efficiency=0.8,
                        source="test")
    crane = Crane(parse_spec(data, "cp"))
    h = crane.hydraulics(np.array([0.0, -0.3, 0.4, 1.0]), np.array([0.1, 0.05, 0.1, 0.2]),
                         np.zeros(4))
    assert h["p_pump"] == 21e6
    assert h["power"] == pytest.approx(21e6 * h["q_pump"] / 0.8)


def test_hydraulic_transformer_credits_jib_rod_flow():
    data = copy.deepcopy(tomllib.loads(crane_path("s100f").read_text()))
    data["transformer"]["enabled"] = True
    ht = Crane(parse_spec(data, "ht"))
    conv = Crane.from_id("s100f")
    q = np.array([0.0, -0.3, 0.4, 1.0])
    # boom up (x1 extends) while the jib opens (its cylinder extends, rod side expels oil)
    qd = np.array([0.0, -0.1, -0.2, 0.0])
    a, b = conv.hydraulics(q, qd, np.zeros(4)), ht.hydraulics(q, qd, np.zeros(4))
    A1 = conv.spec.joints[1].actuator.area_a
    A2b = conv.spec.joints[2].actuator.area_b
    assert b["q_act"][1] == pytest.approx(max(A1 * a["xd"][1] - A2b * a["xd"][2], 0.0))
    assert b["q_pump"] < a["q_pump"]
