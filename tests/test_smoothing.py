"""Ruckig rest-to-rest moves: optimal duration (analytic oracle), all limits incl. jerk."""
import numpy as np
import pytest

from planner import Crane
from planner.bounds import lower_bound, rest_to_rest_time
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import evaluate

from .conftest import MACHINES, random_configs


@pytest.mark.parametrize("cid", MACHINES)
def test_duration_is_the_slowest_joints_minimum_and_limits_hold(cid):
    crane = Crane.from_id(cid)
    L = crane.limit_arrays()
    qs = random_configs(crane, 6, seed=11)
    for q0, q1 in zip(qs[:3], qs[3:]):
        r = rest_to_rest(crane, q0, q1)
        assert r.ok
        d = q1 - q0
        v = np.where(d >= 0, L["qd_max"], -L["qd_min"])
        expect = np.max(rest_to_rest_time(d, v, L["qdd_max"], L["qddd_max"]))
        assert r.duration_s == pytest.approx(expect, rel=1e-6)
        ev = evaluate(crane, r.trajectory)
        assert ev.max_limit_violation <= 1e-5, ev
        np.testing.assert_allclose(r.trajectory.q[[0, -1]], [q0, q1], atol=1e-9)
        np.testing.assert_allclose(r.trajectory.qd[[0, -1]], 0.0, atol=1e-9)


def test_between_bound_optimal_ends_it_meets_the_bound():
    crane = Crane.from_id("s100f")
    a, b = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)
    lb = lower_bound(crane, a, b)
    r = rest_to_rest(crane, crane.ik(a, lb.tele_start), crane.ik(b, lb.tele_goal))
    assert r.duration_s == pytest.approx(lb.rest_to_rest_s, rel=1e-6)


def test_out_of_limit_configuration_is_refused():
    crane = Crane.from_id("umea-lab")
    q = np.array([0.0, 0.5, -1.0, 0.5])
    bad = q.copy()
    bad[1] = 2.0
    r = rest_to_rest(crane, q, bad)
    assert r.status == "invalid" and "boom" in r.reason
