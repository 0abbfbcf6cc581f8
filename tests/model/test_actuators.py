"""Joint <-> stroke maps: derivatives, inverse, and the hand geometry of each kind."""
import math

import numpy as np
import pytest

from planner import Crane

from tests.conftest import random_configs


def test_stroke_derivative_matches_finite_differences(crane):
    h = 1e-6
    for q in random_configs(crane, 25, seed=4):
        x, d = crane.stroke(q)
        fd = (crane.stroke(q + h)[0] - crane.stroke(q - h)[0]) / (2 * h)
        np.testing.assert_allclose(d, fd, rtol=1e-6, atol=1e-8)


def test_stroke_inverse_round_trip(crane):
    qs = random_configs(crane, 200, seed=5, margin=0.0)
    x, _ = crane.stroke(qs)
    np.testing.assert_allclose(crane.joint_from_stroke(x), qs, atol=1e-10)


def test_strokes_inside_cylinder_range(crane):
    qs = random_configs(crane, 500, seed=6, margin=0.0)
    x, _ = crane.stroke(qs)
    for i, j in enumerate(crane.spec.joints):
        if j.actuator.kind in ("triangle", "lever", "telescope"):
            assert x[:, i].min() >= -1e-3 and x[:, i].max() <= j.actuator.stroke + 1e-3


def test_triangle_is_law_of_cosines():
    """cat215b boom: seed 001's l_p = sqrt(l_l² + l_u² − 2 l_l l_u cos φ) − l_c."""
    crane = Crane.from_id("cat215b")
    act = crane.spec.joints[1].actuator
    ll, lu = math.hypot(*act.base), math.hypot(*act.rod)
    assert ll == pytest.approx(0.625, abs=1e-3) and lu == pytest.approx(2.0, abs=1e-9)
    for qb in (-0.5, 0.0, 0.7):
        q = np.array([0.0, qb, -1.5])
        phi = math.atan2(act.base[1], act.base[0]) - (qb + math.atan2(act.rod[1], act.rod[0]))
        lp = math.sqrt(ll ** 2 + lu ** 2 - 2 * ll * lu * math.cos(phi)) - 1.447
        assert crane.stroke(q)[0][1] == pytest.approx(lp, abs=1e-12)


def test_chain_telescope_moves_tip_twice_the_stroke():
    crane = Crane.from_id("s100f")  # seed 002: d4 = L3 + 2·q3
    q = np.array([0.0, -0.3, 0.2, 0.0])
    x0 = crane.stroke(q)[0][3]
    q[3] = 1.0
    assert crane.stroke(q)[0][3] - x0 == pytest.approx(0.5)
    assert crane.stroke(q)[1][3] == pytest.approx(0.5)


def test_rotary_and_rack_drives():
    cat = Crane.from_id("cat215b")  # 307:1 swing gear (seed 001)
    assert cat.stroke(np.array([0.2, 0.0, -1.5]))[0][0] == pytest.approx(307 * 0.2)
    cr = Crane.from_id("cranab850")  # rack and pinion: x = r·q
    r = cr.spec.joints[0].actuator.radius
    assert cr.stroke(np.array([0.5, 1.0, 1.0, 0.5]))[0][0] == pytest.approx(0.5 * r)


def test_lever_linkage_is_monotone_over_the_jib_range():
    crane = Crane.from_id("s100f")
    L = crane.limit_arrays()
    qs = np.zeros((300, 4))
    qs[:, 2] = np.linspace(L["q_min"][2], L["q_max"][2], 300)
    x, d = crane.stroke(qs)
    assert np.all(d[:, 2] < 0)  # seed 002: extending the jib cylinder gives negative speed
    assert np.all(np.diff(x[:, 2]) < 0)
