"""Contract tests over the plant and effect registries (issue 26), the way pysindy and
python-control run every implementation through the same checks:

* every registered effect x every plant: applied with a visible change of the right sign in
  the channel it acts on (against the same plant without it), or refused at construction with
  :class:`EffectRefused` naming it — never built and silently ignored; a force effect and a
  drift effect registered here, as a plug-in would, go through the same checks;
* every machine x every plant on a move that starts on joint limits, drives into the end stops
  and away and back onto them: the plant runs it and stays inside the stops.

The oracles are the effects' own definitions (an offset reads as the offset, a drift as rate x
elapsed time, a friction raises the extending pressure), the sign a physical argument gives,
and the nominal run of the same plant.
"""
import numpy as np
import pytest

from planner.model import Crane
from planner.problems import crane_ids
from planner.model.effects import (CATALOGUE, Effect, EffectRefused, Parameter, make, register,
                                   unregister)
from planner.simulation.plants import PLANTS, applying, make_plant

# phases: A boom out at half command (0-0.5 s), B hold (0.5-1.0), C every joint at full command
# (1.0-1.4: the pump saturates), D boom in at half command (1.4-1.9), E hold (1.9-2.4)
T_U = np.array([0.0, 0.5, 1.0, 1.4, 1.9, 2.4])
T_END = 2.4
RATE = 100.0
BOOM = 1


def commands(n):
    u = np.zeros((len(T_U), n))
    u[0, BOOM] = 0.5
    u[2, :] = 1.0
    u[3, BOOM] = -0.5
    return u


def at(rec, t):
    return int(np.argmin(np.abs(rec.t - t)))


class Push(Effect):
    """A plug-in force effect with no physical data: a constant load on one actuator."""
    name = "test_push"
    description = "a constant extra load the actuator works against (test plug-in)"
    parameters = (Parameter("load", "N", 0.0, 1e5, 0.0, "extra load"),)
    per_joint, stage, acts_on = True, "forces", "pressures"

    def force(self, crane, s):
        return self.on_own_joint(crane, s.force_model, lambda i: np.full(len(s.t), self.load))


class Creep(Effect):
    """A plug-in drift effect with no physical data: a constant stroke rate."""
    name = "test_creep"
    description = "a constant stroke creep (test plug-in)"
    parameters = (Parameter("rate", "m/s", -0.01, 0.01, 0.0, "stroke rate"),)
    per_joint, stage, acts_on = True, "strokes", "positions"

    def drift(self, crane, s):
        return self.on_own_joint(crane, s.xd, lambda i: np.full(len(s.t), self.rate))


@pytest.fixture(scope="module")
def plugins():
    for c in (Push, Creep):
        register(c)
    yield
    for c in (Push, Creep):
        unregister(c.name)


@pytest.fixture(scope="module")
def machine():
    crane = Crane.from_id("umea-lab")
    L = crane.limit_arrays()
    return crane, 0.5 * (L["q_min"] + L["q_max"])


_NOMINAL = {}


def nominal(plant, crane, q0):
    if plant not in _NOMINAL:
        _NOMINAL[plant] = make_plant(plant, crane).run(T_U, commands(crane.n), q0, t_end=T_END,
                                                       rate=RATE)
    return _NOMINAL[plant]


def instance(name, crane):
    """A realistic instance of each effect (the trials' own magnitude where it has one)."""
    special = {"bulk_modulus": dict(scale=0.5), "hose_volume": dict(joint="boom", scale=3.0),
               "grapple_swing": dict(length=1.2, damping=500.0),
               "test_push": dict(joint="boom", load=3000.0),
               "test_creep": dict(joint="boom", rate=2e-3)}
    if name in special:
        kw = dict(special[name])
        return make(name, kw.pop("joint", None), **kw)
    cls = CATALOGUE[name]
    return cls.trial(crane, np.random.default_rng(1), joint="boom" if cls.per_joint else None)


def travel(rec, t0, t1, i=BOOM):
    return rec.q_true[at(rec, t1), i] - rec.q_true[at(rec, t0), i]


def check_change(name, e, crane, nom, rec):
    """Assert the effect's change is visible and of the right sign (see the module doc)."""
    dq, dpa = rec.q - nom.q, rec.p_a - nom.p_a
    area_a = crane.spec.joints[BOOM].actuator.area_a
    elapsed = rec.t - rec.t[0]
    if name == "joint_offset":
        np.testing.assert_allclose(dq[:, BOOM], e.offset, atol=1e-9)
    elif name == "sensor_gain":
        np.testing.assert_allclose(dq[:, BOOM], (e.scale - 1.0) * rec.q_true[:, BOOM],
                                   atol=1e-9)
    elif name == "sensor_drift":
        np.testing.assert_allclose(dq[:, BOOM], e.rate * elapsed, atol=1e-9)
    elif name == "pressure_offset":
        np.testing.assert_allclose(dpa[:, BOOM], e.offset_a, atol=1e-3)
        np.testing.assert_allclose((rec.p_b - nom.p_b)[:, BOOM], e.offset_b, atol=1e-3)
    elif name == "pressure_drift":
        np.testing.assert_allclose(dpa[:, BOOM], e.rate_a * elapsed, atol=1e-3)
    elif name in ("flow_gain", "valve_deadband", "valve_lag", "time_delay"):
        # the boom's travel in phase A: the flow gain scales it; a wider band shortens it; a
        # lag or a delay holds it back early in the phase
        t1 = 0.5 if name in ("flow_gain", "valve_deadband") else 0.15
        ratio = travel(rec, 0.0, t1) / travel(nom, 0.0, t1)
        want = e.scale if name == "flow_gain" else None
        if want is not None:
            assert (ratio - 1.0) * (want - 1.0) > 0 and abs(ratio - 1) > 0.3 * abs(want - 1)
        else:
            assert ratio < 0.97, ratio
    elif name == "pump_flow_limit":
        # phase C: every joint at full command; a weaker pump moves them less in total
        moved = sum(abs(travel(rec, 1.0, 1.4, i)) for i in range(crane.n))
        assert moved < 0.97 * sum(abs(travel(nom, 1.0, 1.4, i)) for i in range(crane.n))
    elif name in ("leakage", "test_creep"):
        # phase B (hold): the stroke moves towards the load (the boom's piston side holds it)
        # or at the plug-in's rate
        x = crane.stroke(rec.q_true)[0][:, BOOM]
        x0 = crane.stroke(nom.q_true)[0][:, BOOM]
        drift = (x[at(rec, 1.0)] - x[at(rec, 0.6)]) - (x0[at(nom, 1.0)] - x0[at(nom, 0.6)])
        assert nom.p_a_true[at(nom, 0.8), BOOM] > nom.p_b_true[at(nom, 0.8), BOOM]
        if name == "leakage":
            assert drift < -1e-5, drift
        else:
            assert drift == pytest.approx(e.rate * 0.4, rel=0.05)
    elif name in ("coulomb_friction", "viscous_friction"):
        # extending (phase A, second half) takes more piston pressure, retracting less
        a = slice(at(rec, 0.3), at(rec, 0.5))
        d = slice(at(rec, 1.7), at(rec, 1.9))
        assert dpa[a, BOOM].mean() > 0.2e5 and dpa[d, BOOM].mean() < -0.2e5
    elif name in ("payload_mass", "actuator_mass", "test_push"):
        # at rest (end of phase B) the boom holds more (less) load
        k = at(rec, 0.95)
        sign = np.sign(e.mass) if name != "test_push" else 1.0
        assert sign * dpa[k, BOOM] > 0.2e5
        if name == "test_push":
            assert dpa[k, BOOM] == pytest.approx(e.load / area_a, rel=0.25)
    elif name in ("bulk_modulus", "hose_volume", "grapple_swing"):
        # their signed physics (frequencies, the pendulum) is checked in
        # test_exudyn_dynamic_effects.py; here: they change the run visibly
        assert np.abs(dpa).max() > 0.5e6 or np.abs(rec.q_true - nom.q_true).max() > 1e-3
    else:
        raise AssertionError(f"effect {name}: no contract check written for it; add one")


EFFECTS = sorted(CATALOGUE) + ["test_push", "test_creep"]
#: (plant, effect) refused by name at construction although the two share a hook: the twin
#: carries the grapple as a point mass at the tip (no pendulum), so a swinging one is refused


@pytest.mark.parametrize("plant", sorted(PLANTS))
@pytest.mark.parametrize("name", EFFECTS)
def test_every_effect_is_applied_visibly_or_refused_by_name(plugins, machine, plant, name):
    crane, q0 = machine
    e = instance(name, crane)
    if plant not in applying(e):
        with pytest.raises(EffectRefused, match=f"effect {name}: the {plant} plant cannot"):
            make_plant(plant, crane, [e])
        return
    p = make_plant(plant, crane, [e])
    row = [r for r in p.report() if r["name"] == name]
    assert len(row) == 1 and row[0]["hooks"], "the report says which hooks it acted through"
    rec = p.run(T_U, commands(crane.n), q0, t_end=T_END, rate=RATE)
    assert rec.ok, rec.reason
    check_change(name, e, crane, nominal(plant, crane, q0), rec)


def test_every_effect_has_a_plant_and_the_dynamic_only_ones_are_named(plugins):
    assert {n for n in CATALOGUE if not applying(CATALOGUE[n])} == set()
    assert {n for n in CATALOGUE if "fast" not in applying(CATALOGUE[n])} == {
        "bulk_modulus", "hose_volume", "grapple_swing"}
    assert applying(Creep) == ["fast"]      # a bare stroke drift has no dynamic meaning


# ----------------------------------------------------------------------------- joint limits
MACHINES = crane_ids()      # every shipped machine: a new TOML joins the contract


def through_limits(crane):
    """Feed-forward commands (t_u, u) at 50 Hz of two planned rest-to-rest moves (Ruckig,
    within every limit) from a pose with every joint exactly on a limit (alternately lower
    and upper) a quarter of each range inwards and back: the moves start, pass (at rest) and
    end on joint limits; and that start pose."""
    from planner.feedforward import commands
    from planner.methods.ruckig import rest_to_rest
    L = crane.limit_arrays()
    side = np.arange(crane.n) % 2 == 1
    qa = np.where(side, L["q_max"], L["q_min"])
    qb = qa + np.where(side, -0.25, 0.25) * (L["q_max"] - L["q_min"])
    ts, us = [], []
    t0 = 0.0
    for q0, q1 in ((qa, qb), (qb, qa)):
        res = rest_to_rest(crane, q0, q1)
        assert res.ok, res.reason
        ff = commands(crane, res.trajectory, 50.0)
        ts.append(t0 + ff.t - ff.t[0])
        us.append(ff.u)
        t0 = ts[-1][-1] + 0.02
    t_u, u = np.concatenate(ts), np.vstack(us)
    t_u = np.append(t_u, t_u[-1] + 0.02)
    return t_u, np.vstack([u, np.zeros((1, crane.n))]), qa


@pytest.mark.parametrize("plant", sorted(PLANTS))
@pytest.mark.parametrize("crane_id", MACHINES)
def test_moves_that_start_pass_and_end_on_joint_limits_run(crane_id, plant):
    """A legitimate plan on the limits is one the judge must be able to run: the plant runs
    it to the end (no divergence) and stays inside the joint range — within 5 % of it for
    the Exudyn plant, whose open-loop replay may arrive off the plan and press on a stop
    (the stops' compliance), exactly for the fast one (it stops every joint at its limit)."""
    crane = Crane.from_id(crane_id)
    L = crane.limit_arrays()
    t_u, u, q0 = through_limits(crane)
    rec = make_plant(plant, crane).run(t_u, u, q0, t_end=t_u[-1] + 0.5, rate=50.0)
    assert rec.ok, f"{crane_id} {plant}: {rec.reason}"
    assert rec.t[-1] >= t_u[-1]
    tol = (0.05 if plant != "fast" else 1e-9) * (L["q_max"] - L["q_min"])
    assert np.all(rec.q_true >= L["q_min"] - tol) and np.all(rec.q_true <= L["q_max"] + tol)


def test_the_umea_lab_plan_with_the_telescope_on_its_end_runs_on_exudyn(tmp_path, capsys):
    """The reported case (issue 26, defect 1): the NLP puts the telescope exactly on its
    1.55 m end; the Exudyn plant diverged at t = 0 (its end stop's stiffness jumped from 0 to
    2e8 N/m at contact, which stalled the integrator's Newton iteration)."""
    from planner.cli import main
    plan = tmp_path / "fast.csv"
    assert main(["plan", "umea-lab", "--start", "3.5,0.5,-0.8", "--goal", "2.0,2.5,0.3",
                 "--method", "nlp", "--out", str(plan)]) == 0
    first = np.loadtxt(plan, delimiter=",", skiprows=1, max_rows=1)
    header = plan.read_text().splitlines()[0].split(",")
    assert first[header.index("q_tele")] == pytest.approx(1.55, abs=1e-6)
    capsys.readouterr()
    rc = main(["simulate", "umea-lab", "--trajectory", str(plan), "--plant", "exudyn",
               "--out", str(tmp_path / "m.csv")])
    assert rc == 0, capsys.readouterr()
    assert (tmp_path / "m.csv").exists()
