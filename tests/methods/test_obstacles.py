"""Obstacles (planner.geometry.obstacles): exact distances, the forwarder headboard kept clear by the NLP,
suite parsing, and library entries that store the plan exactly."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner import Crane
from planner.tasks.suites import load_suite
from planner.methods.nlp import MoveNLP
from planner.geometry.obstacles import Plate, Wall, from_dict
from planner.geometry.paths import tip_to_xyz
from planner.model.spec import SpecError
from planner.trajectory import evaluate

PLATE = Plate(x=-1.2, y_min=-1.5, y_max=1.5, z_bottom=-1.2, z_top=1.3, clearance=0.3)


@settings(max_examples=60, deadline=None)
@given(st.tuples(*[st.floats(-4, 4, allow_nan=False)] * 3))
def test_plate_distance_is_the_distance_to_the_rectangle(p):
    """Against a brute-force minimum over a fine grid of the rectangle's points."""
    ys = np.linspace(PLATE.y_min, PLATE.y_max, 301)
    zs = np.linspace(PLATE.z_bottom, PLATE.z_top, 251)
    Y, Z = np.meshgrid(ys, zs)
    brute = np.sqrt((p[0] - PLATE.x) ** 2 + (p[1] - Y) ** 2 + (p[2] - Z) ** 2).min()
    d = PLATE.distance(np.array([p]), None)[0]
    assert d <= brute + 1e-12 and d >= brute - 0.011      # grid spacing 10 mm


def test_wall_distance_and_bad_obstacles_are_refused():
    w = Wall(r=2.0, z_top=1.0, z_bottom=0.0)
    d = w.distance(None, np.array([[2.5, 0.5, 0.0], [2.0, 1.4, 1.0], [1.0, -1.0, 0.0]]))
    np.testing.assert_allclose(d, [0.5, 0.4, np.sqrt(2)])
    with pytest.raises(ValueError, match="clearance"):
        Plate(x=0, y_min=-1, y_max=1, z_bottom=0, z_top=1, clearance=0)
    with pytest.raises(ValueError, match="y"):
        Plate(x=0, y_min=1, y_max=-1, z_bottom=0, z_top=1)
    with pytest.raises(ValueError, match="unknown keys.*height"):
        from_dict(dict(kind="plate", x=0, y_min=-1, y_max=1, z_bottom=0, height=1))
    with pytest.raises(ValueError, match="kind"):
        from_dict(dict(kind="sphere"))


def test_suite_obstacles_are_parsed_and_errors_name_the_table(tmp_path):
    meta, _ = load_suite("forwarder-cycle")
    assert meta["obstacles"] == (PLATE,)
    bad = tmp_path / "bad.toml"
    bad.write_text('[suite]\nid = "bad"\ncrane = "s100f"\n'
                   '[pickups]\nr = [5.0]\nslew = [0.0]\nz = -1.0\n'
                   '[drops]\nr = [2.0]\nslew = ["170deg"]\nz = 1.5\n'
                   '[obstacles.gate]\nkind = "plate"\nx = -1.0\n')
    with pytest.raises(SpecError, match="obstacles.gate"):
        load_suite(str(bad))


def test_the_headboard_is_cleared_at_little_cost():
    """p05-d00 of the forwarder suite: the unconstrained minimum-time NLP solution brushes the
    headboard (measured 0.095 m from it); with the plate it keeps the clearance on a 1 kHz
    resampling and is hardly slower."""
    crane = Crane.from_id("s100f")
    _, moves = load_suite("forwarder-cycle")
    m = next(m for m in moves if m.id == "p05-d00")

    def dist(r):
        tip = evaluate(crane, r.trajectory).tip
        return PLATE.distance(tip_to_xyz(tip), tip).min()
    nlp = MoveNLP(crane, "time", "free", N=40)
    # the NLP's own solution (an explicit guess: no Ruckig alternative, which clears it here)
    free = nlp.solve(m.start, m.goal, w0=nlp.default_guess(m.start, m.goal)[0])
    hb = MoveNLP(crane, "time", "free", N=40, obstacles=(PLATE,)).solve(m.start, m.goal)
    assert free.ok and hb.ok, (free.reason, hb.reason)
    assert dist(free) < 0.2
    assert dist(hb) >= 0.96 * PLATE.clearance
    assert hb.duration_s <= 1.05 * free.duration_s
    assert evaluate(crane, hb.trajectory).max_limit_violation <= 1e-3


def test_stored_samples_reproduce_the_plan_and_hold_the_commands():
    """FeedForward.attach(knots=True): the plan's nodes are kept, so the quintic through the
    stored rows is the plan itself (the jerk limit holds on the reconstruction), and a
    zero-order hold of the rows gives the control grid's commands."""
    from planner.feedforward import commands
    crane = Crane.from_id("s100f")
    r = MoveNLP(crane, "time", "free", N=30).solve((7.0, 0.0, 0.0), (3.0, 1.0, 2.5))
    assert r.ok
    ff = commands(crane, r.trajectory, 50.0)
    tr = ff.attach(r.trajectory, knots=True)
    t = np.linspace(0, r.duration_s, 4001)
    np.testing.assert_allclose(tr.sample(t)[0], r.trajectory.sample(t)[0], atol=1e-9)
    assert evaluate(crane, tr).violations["jerk"] <= 1e-6
    k = np.clip(np.searchsorted(tr.t, ff.t, side="right") - 1, 0, len(tr.t) - 1)
    np.testing.assert_array_equal(tr.u[k], ff.u)
    assert set(ff.t) <= set(tr.t)


def test_jerk_on_a_tiny_interval_is_not_round_off():
    """A cubic piece (constant jerk 3) sampled with one interval of 50 µs: the reported jerk
    stays 3 (the quintic's third derivative there would be round-off ∝ ε·|q|/h³)."""
    from planner.trajectory import Trajectory
    t = np.array([0.0, 0.02, 0.04, 0.04005, 0.06, 0.08])
    j = 3.0
    q = 3.0 + j * t ** 3 / 6
    tr = Trajectory(t, q[:, None], (j * t ** 2 / 2)[:, None], (j * t)[:, None],
                    joint_names=("a",))
    jerk = tr.sample(np.linspace(0, 0.08, 801))[3][:, 0]
    np.testing.assert_allclose(jerk, j, rtol=1e-6)
