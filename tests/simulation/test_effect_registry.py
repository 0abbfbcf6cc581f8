"""Adding an effect is one class: a class defined here (quadratic drag of one actuator, which
nothing in the package knows) is registered and then listed by the CLI, drawn by the trials and
named by the discrepancy search — with no edit elsewhere. And the robustness study's Plant is
a constructor of the same effects the catalogue offers."""
import json

import numpy as np
import pytest

from planner import Crane
from planner.calibration.discrepancy import Discrepancy, candidates
from planner.calibration.trials import TRIAL_MAGNITUDES, draw, hidden_trial
from planner.cli import main
from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.model.effects import (CATALOGUE, Effect, Parameter, StartOffset, make,
                                        parse_effect, register, unregister)
from planner.simulation.plant import respond
from planner.simulation.replay import Plant, replay, stroke_rates

NAME = "test_quadratic_drag"


class QuadraticDrag(Effect):
    """Drag ∝ ẋ·|ẋ| of one actuator (turbulent flow through a restriction)."""
    name = NAME
    description = "turbulent drag of one actuator, ∝ the square of its stroke speed"
    signature = "pressure residual of one actuator ∝ ẋ·|ẋ|; zero at rest"
    parameters = (Parameter("coefficient", "N·s²/m²", 0.0, 1.0e7, 0.0,
                            "force per squared stroke speed"),)
    per_joint, stage, acts_on = True, "forces", "pressures"
    trial_range = (0.5, 1.0)            # × the coefficient giving 1 MPa at full speed

    def force(self, crane, s):
        return self.on_own_joint(crane, s.force_model,
                                 lambda i: self.coefficient * s.xd[:, i] * np.abs(s.xd[:, i]))

    @classmethod
    def observable(cls, crane, i):
        return i != 0

    @classmethod
    def trial_values(cls, crane, i, magnitude, sign, rng, sequence):
        a = crane.spec.joints[i].actuator
        vmax = a.flow_gain / a.area_a
        return dict(coefficient=magnitude * 1e6 * a.area_a / vmax ** 2)


@pytest.fixture
def registered():
    register(QuadraticDrag)
    try:
        yield QuadraticDrag
    finally:
        unregister(NAME)


def test_a_registered_effect_is_listed_and_parsed(registered, cat215b, capsys):
    assert main(["effects", "list", "--json", "-"]) == 0
    by = {e["name"]: e for e in json.loads(capsys.readouterr().out)}
    assert by[NAME]["parameters"] == {"joint": "joint name", "coefficient": [0.0, 1.0e7]}
    assert by[NAME]["stage"] == "forces" and by[NAME]["description"]
    e = parse_effect(f"{NAME}:joint=boom,coefficient=2e6", cat215b)
    assert isinstance(e, QuadraticDrag) and e.coefficient == 2e6
    assert TRIAL_MAGNITUDES[NAME] == (0.5, 1.0)
    unregister(NAME)
    try:
        assert main(["effects", "list", "--json", "-"]) == 0
        assert NAME not in {e["name"] for e in json.loads(capsys.readouterr().out)}
    finally:
        register(QuadraticDrag)


def test_registration_refuses_a_taken_name_or_a_bad_class():
    class Clash(QuadraticDrag):
        name = "flow_gain"
    with pytest.raises(ValueError, match="flow_gain: the name is taken"):
        register(Clash)

    class NoStage(QuadraticDrag):
        name = "test_no_stage"
        stage = "valve"
    with pytest.raises(ValueError, match="stage = 'valve'; allowed: commands"):
        register(NoStage)
    assert "test_no_stage" not in CATALOGUE


def test_its_force_reaches_the_plant(registered, cat215b):
    """Oracle: the analytic drag c·ẋ|ẋ| at the nominal states' stroke speeds."""
    L = cat215b.limit_arrays()
    a = L["q_min"] + 0.3 * (L["q_max"] - L["q_min"])
    b = L["q_min"] + 0.7 * (L["q_max"] - L["q_min"])
    ff = commands(cat215b, rest_to_rest(cat215b, a, b, scale=0.6).trajectory, 50.0)
    nom = respond(cat215b, ff.t, ff.u, a)
    dr = respond(cat215b, ff.t, ff.u, a, [make(NAME, "boom", coefficient=2e6)])
    np.testing.assert_allclose(dr.q, nom.q)                    # positions unaffected
    xd = nom.state.xd[:, 1]
    np.testing.assert_allclose(dr.state.force[:, 1] - nom.state.force[:, 1],
                               2e6 * xd * np.abs(xd), rtol=1e-9, atol=1e-6)
    np.testing.assert_array_equal(dr.state.force[:, [0, 2]], nom.state.force[:, [0, 2]])


def test_trials_draw_it_and_the_search_names_it(registered, cat215b):
    # the random draw: its own magnitude, only on joints its observability rule allows
    for seed in range(20):
        e = draw(cat215b, NAME, np.random.default_rng(seed))
        assert isinstance(e, QuadraticDrag) and e.joint != "swing"
        a = cat215b.spec.joints[e.index(cat215b)].actuator
        full = 1e6 * a.area_a / (a.flow_gain / a.area_a) ** 2
        assert 0.5 * full <= e.coefficient <= 1.0 * full
    # the search's candidates: the new effect on every joint
    cands = candidates(cat215b)
    assert [c.joint for c in cands if c.name == NAME] == list(cat215b.names)
    # a hidden trial with it, and the search names it among its look-alikes
    rec, _, _, truth = hidden_trial(cat215b, NAME, 41, 25.0, joint="boom")
    assert isinstance(truth, QuadraticDrag) and truth.joint == "boom"
    res = Discrepancy(cat215b, candidates=[NAME, "viscous_friction", "coulomb_friction"],
                      second=False).fit(rec)
    assert (res.effect, res.joint) == (NAME, "boom"), (res.message, res.ranking[:3])
    sd = res.uncertainty["coefficient"]
    assert abs(res.parameters["coefficient"] - truth.coefficient) <= 5 * sd + 1e-3 * truth.coefficient


def test_plant_is_a_constructor_of_catalogue_effects():
    """Oracle: the same deviations written as catalogue effects by hand (a start offset is
    not in the catalogue: the fit removes it)."""
    crane = Crane.from_id("s100f")
    L = crane.limit_arrays()
    a = L["q_min"] + 0.3 * (L["q_max"] - L["q_min"])
    b = L["q_min"] + 0.7 * (L["q_max"] - L["q_min"])
    ff = commands(crane, rest_to_rest(crane, a, b, scale=1.0).trajectory, 50.0)
    off = [0.01, -0.02, 0.0, 0.015]
    plant = Plant(q0_offset=off, flow_gain_scale=1.02, pump_flow_scale=0.3, deadband=0.05)
    by_hand = ([StartOffset(j, offset=o) for j, o in zip(crane.names, off)]
               + [make("flow_gain", j, scale=1.02) for j in crane.names]
               + [make("valve_deadband", j, width=0.05) for j in crane.names]
               + [make("pump_flow_limit", scale=0.3)])
    assert set(plant.effects(crane)) == set(by_hand)
    s1 = replay(crane, ff.t, ff.u, a, plant)
    s2 = replay(crane, ff.t, ff.u, a, by_hand)
    np.testing.assert_array_equal(s1.q, s2.q)
    assert s1.meta["pump"] == s2.meta["pump"] and s1.meta["pump"]["short_s"] > 0
    np.testing.assert_array_equal(stroke_rates(crane, ff.u, plant)[0],
                                  stroke_rates(crane, ff.u, by_hand)[0])
    # the plant with effects applies the same deviations (and its start)
    r = respond(crane, ff.t, ff.u, a, plant=plant)
    np.testing.assert_allclose(r.q, s1.q, atol=1e-9)
    np.testing.assert_allclose(r.q[0], np.clip(a + off, L["q_min"], L["q_max"]), atol=1e-9)
    # beyond the catalogue's plausible range (a bigger pump) the Plant still works
    big = replay(crane, ff.t, ff.u, a, Plant(pump_flow_scale=2.0))
    assert big.meta["pump"]["max_flow_m3s"] == 2.0 * crane.spec.pump.max_flow
    with pytest.raises(ValueError, match="scale = 2 .*outside"):
        make("pump_flow_limit", scale=2.0)
