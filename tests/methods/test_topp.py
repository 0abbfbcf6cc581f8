"""TOPP-RA retiming: reproduces the DP time, respects limits, the pump bound binds."""
import numpy as np
import pytest

from planner import Crane
from planner.methods.dp import dp
from planner.methods.topp import retime
from planner.geometry.paths import Line
from planner.trajectory import evaluate


def test_velocity_only_retiming_reproduces_the_dp_time(cranab850):
    r = dp(cranab850, Line((5.5, 1.0, 0.0), (5.5, -3.0, 0.0)), stages=400)
    t = retime(cranab850, r.path_q, limits=("velocity",), gridpoints=400)
    assert t.ok
    assert t.duration_s == pytest.approx(r.duration_s, rel=0.01)
    assert t.duration_s >= r.duration_s * (1 - 1e-3)  # the DP is optimal on its own grid


def test_full_limits_pass_the_judge(cranab850):
    r = dp(cranab850, Line((1.5, 1.0, 0.0), (5.5, -3.0, 0.0)), step=0.02, tele_step=0.02, window=3)
    t = retime(cranab850, r.path_q)
    assert t.ok
    ev = evaluate(cranab850, t.trajectory)
    assert set(ev.checked) == {"position", "velocity", "acceleration", "pump_flow"}
    assert ev.max_limit_violation <= 1e-3
    np.testing.assert_allclose(t.trajectory.qd[[0, -1]], 0.0, atol=1e-9)  # rest to rest


def test_pump_limit_binds_on_a_hydraulically_limited_machine():
    crane = Crane.from_id("s100f")
    r = dp(crane, Line((7.0, -1.0, 0.0), (3.0, 2.0, 0.5)), step=0.02, tele_step=0.02, window=3)
    free = retime(crane, r.path_q, limits=("velocity", "acceleration"))
    pumped = retime(crane, r.path_q)
    assert free.ok and pumped.ok
    ev_free = evaluate(crane, free.trajectory)
    ev = evaluate(crane, pumped.trajectory)
    assert ev_free.violations["pump_flow"] > 0.01   # without it the pump would be overdrawn
    assert ev.violations["pump_flow"] <= 1e-3
    assert ev.peak_pump_flow >= 0.97 * crane.spec.pump.max_flow  # and it is active
    assert pumped.duration_s > free.duration_s


def test_fixed_duration_and_infeasible_duration(cranab850):
    r = dp(cranab850, Line((5.5, 1.0, 0.0), (5.5, -3.0, 0.0)), step=0.05, tele_step=0.05, window=2)
    slow = retime(cranab850, r.path_q, duration=5.0)
    assert slow.ok and slow.duration_s == pytest.approx(5.0, rel=1e-3)
    short = retime(cranab850, r.path_q, duration=0.1)
    assert short.status == "infeasible" and "duration" in short.reason
    with pytest.raises(ValueError, match="unsupported"):
        retime(cranab850, r.path_q, limits=("jerk",))
