"""Local laws: tracking, saturation logic, telescope law, limits."""
import math

import numpy as np
import pytest
from scipy.optimize import minimize

from planner.methods.laws import (LeastNorm, MaxLift, MaxVelocity, follow, rate_box,
                                  weighted_pinv_saturated)
from planner.geometry.paths import Line
from planner.trajectory import evaluate

B, C = (5.5, 1.0, 0.0), (5.5, -3.0, 0.0)


@pytest.mark.parametrize("law,v", [(LeastNorm(), 0.5), (MaxVelocity(), 0.5), (MaxLift(), 0.2)])
def test_unsaturated_laws_track_the_path_at_the_commanded_speed(cranab850, law, v):
    r = follow(cranab850, Line(B, C), law, v, tele0=None if law.name == "max_lift" else 0.6)
    assert r.ok, r.reason
    assert r.min_beta == 1.0
    assert r.duration_s == pytest.approx(4.0 / v, rel=1e-9)
    assert r.max_path_error_m < 2e-3
    tips = cranab850.tip(r.trajectory.q)
    np.testing.assert_allclose(tips[-1], C, atol=2e-3)


def test_saturation_keeps_the_path_and_lowers_the_speed(cranab850):
    r = follow(cranab850, Line(B, C), MaxVelocity(), 10.0, tele0=0.6)
    assert r.ok
    assert r.min_beta < 0.8                    # the command had to be scaled ...
    assert r.duration_s > 4.0 / 10.0 * 1.05    # ... so the move takes longer ...
    assert r.max_path_error_m < 0.02           # ... but the tip stays on the line
    ev = evaluate(cranab850, r.trajectory)
    assert ev.violations["velocity"] <= 1e-9 and ev.violations["position"] == 0.0


def test_weighted_pinv_minimises_the_weighted_norm():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(2, 3))
    v = rng.normal(size=2)
    w = np.array([1.5, 1.0, 8.0])
    big = np.full(3, 1e9)
    qd, beta = weighted_pinv_saturated(J, v, -big, big, w)
    assert beta == 1.0
    np.testing.assert_allclose(J @ qd, v, atol=1e-12)
    cons = {"type": "eq", "fun": lambda x: J @ x - v}
    ref = minimize(lambda x: x @ (w * x), np.zeros(3), constraints=[cons], tol=1e-14)
    np.testing.assert_allclose(qd, ref.x, atol=1e-6)


def test_pinning_solves_exactly_then_scales():
    J = np.array([[1.0, 0.5, 0.2], [0.3, 1.0, -0.4]])
    v = np.array([3.0, 2.0])
    lo, hi = -np.ones(3), np.ones(3)
    qd, beta = weighted_pinv_saturated(J, v, lo, hi, np.ones(3))
    assert np.all(qd <= hi + 1e-12) and np.all(qd >= lo - 1e-12)
    np.testing.assert_allclose(J @ qd, beta * v, atol=1e-12)  # the path direction is kept
    assert beta < 1.0
    assert np.sum(np.isclose(np.abs(qd), 1.0)) >= 2            # two joints pinned at limits


def test_max_lift_telescope_follows_the_cubic(cranab850):
    law = MaxLift()
    p = cranab850.spec.laws.max_lift
    d3, f, g = law.tele_of(cranab850, p["rc"] + 4.2, p["zc"])   # ρ = 4.2, mid-band
    u = 4.2 - 0.5 * (p["rho_min"] + p["rho_max"])
    qh = 0.5 * (p["rho_max"] - p["rho_min"])
    assert d3 == pytest.approx(0.7 * (1 + 1.5 * u / qh - 0.5 * u ** 3 / qh ** 3))
    h = 1e-6
    fd = (law.tele_of(cranab850, p["rc"] + 4.2 + h, p["zc"])[0]
          - law.tele_of(cranab850, p["rc"] + 4.2 - h, p["zc"])[0]) / (2 * h)
    assert f == pytest.approx(fd, rel=1e-6) and g == pytest.approx(0.0, abs=1e-12)
    r = follow(cranab850, Line(B, C), law, 1.0)
    assert r.ok
    tips = cranab850.tip(r.trajectory.q)
    want = np.array([law.tele_of(cranab850, t[0], t[1])[0] for t in tips])
    np.testing.assert_allclose(r.trajectory.q[:, 3], want, atol=5e-3)


def test_rate_box_stops_at_position_limits(cranab850):
    L = cranab850.limit_arrays()
    q = 0.5 * (L["q_min"] + L["q_max"])
    q[1] = L["q_max"][1]
    lo, hi = rate_box(cranab850, q)
    assert hi[1] == 0.0 and lo[1] == L["qd_min"][1]
    q[1] = L["q_max"][1] - 0.01
    lo, hi = rate_box(cranab850, q)
    assert hi[1] == pytest.approx(math.sqrt(2 * L["qdd_max"][1] * 0.01))


def test_unreachable_start_is_reported(cranab850):
    r = follow(cranab850, Line((30.0, 1.0, 0.0), B), MaxVelocity(), 1.0)
    assert r.status == "unreachable" and "r=30.000" in r.reason
