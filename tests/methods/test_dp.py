"""Bellman DP: optimality against a loop implementation, bounds, convergence, limits."""
import numpy as np
import pytest

from planner import Crane
from planner.bounds import lower_bound
from planner.methods.dp import dp, dp_time_reference
from planner.methods.laws import MaxVelocity, follow
from planner.geometry.paths import Line, Waypoints, circle
from planner.trajectory import evaluate

B, C = (5.5, 1.0, 0.0), (5.5, -3.0, 0.0)


def test_vectorised_dp_equals_loop_reference(cranab850):
    path = Line(B, C)
    kw = dict(step=0.1, tele_step=0.05, window=2)
    fast = dp(cranab850, path, pump=False, **kw)
    assert fast.ok
    assert fast.duration_s == pytest.approx(dp_time_reference(cranab850, path, **kw), rel=1e-12)


@pytest.mark.parametrize("cid,a,b", [("cranab850", B, C), ("cranab850", (2.5, 2.0, 0.0), B),
                                     ("s100f", (6.0, -1.0, 0.0), (4.0, 2.5, 0.0)),
                                     ("umea-lab", (2.6, 1.8, 0.0), (3.4, 3.0, -0.4))])
def test_dp_respects_limits_and_the_velocity_bound(cid, a, b):
    crane = Crane.from_id(cid)
    res = dp(crane, Line(a, b), step=0.02, tele_step=0.02, window=3)
    assert res.ok, res.reason
    ev = evaluate(crane, res.trajectory)
    assert ev.max_limit_violation <= 1e-3, ev
    lb = lower_bound(crane, a, b)
    assert res.duration_s >= lb.velocity_s - 1e-9
    assert res.duration_s >= lb.pump_s - 1e-9
    # the tip stays on the path
    s_tip = crane.tip(res.path_q)
    np.testing.assert_allclose(s_tip, Line(a, b).tip(res.s), atol=1e-8)


def test_dp_converges_as_the_grid_is_refined(cranab850):
    path = Line(B, C)
    T = [dp(cranab850, path, step=d, tele_step=d, window=5).duration_s for d in (0.04, 0.02, 0.01)]
    assert abs(T[2] - T[1]) < abs(T[1] - T[0]) + 1e-3
    assert abs(T[2] - T[1]) / T[2] < 0.02


def test_energy_objective_beats_a_local_law_at_the_same_speed():
    crane = Crane.from_id("s100f")
    a, b = (7.0, 0.0, 0.0), (4.0, 0.0, 0.0)
    v = 0.5
    res = dp(crane, Line(a, b), objective="energy", tip_speed=v, step=0.05, tele_step=0.05,
             window=3)
    assert res.ok, res.reason
    assert res.duration_s == pytest.approx(3.0 / v)
    law = follow(crane, Line(a, b), MaxVelocity(), v, tele0=1.0)
    assert law.ok
    e_dp = evaluate(crane, res.trajectory).energy_J
    e_law = evaluate(crane, law.trajectory).energy_J
    assert e_dp <= 1.01 * e_law


def test_blend_trades_time_for_energy():
    crane = Crane.from_id("s100f")
    path = Line((7.0, -1.0, 0.0), (4.0, 1.5, 0.0))
    kw = dict(step=0.05, tele_step=0.05, window=3)
    fast = dp(crane, path, "blend", lam=0.0, **kw)
    frugal = dp(crane, path, "blend", lam=1e-3, **kw)
    assert frugal.duration_s >= fast.duration_s - 1e-9
    assert frugal.energy_J <= fast.energy_J + 1e-6


def test_any_path_kind(cranab850):
    wp = Waypoints([B, (4.0, 0.0, 0.0), C])
    assert dp(cranab850, wp, step=0.05, tele_step=0.05, window=3).ok
    umea = Crane.from_id("umea-lab")
    circ = circle((3.0, 0.0, 2.5), 0.7, -np.pi / 2, np.pi / 2)
    r = dp(umea, circ, step=0.05, tele_step=0.02, window=3)
    assert r.ok, r.reason
    assert evaluate(umea, r.trajectory).ok()


def test_unreachable_path_names_the_point(cranab850):
    r = dp(cranab850, Line(B, (25.0, 1.0, 0.0)), step=0.05)
    assert r.status == "unreachable"
    assert "leaves the workspace at s =" in r.reason and "out of reach" in r.reason
    r = dp(cranab850, Line((30.0, 1.0, 0.0), B), step=0.05)
    assert r.status == "unreachable" and "at the start" in r.reason


def test_bad_arguments(cranab850):
    with pytest.raises(ValueError, match="tip_speed"):
        dp(cranab850, Line(B, C), objective="energy")
    with pytest.raises(ValueError, match="objective"):
        dp(cranab850, Line(B, C), objective="fastest")
