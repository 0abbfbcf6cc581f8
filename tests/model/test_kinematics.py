"""Forward / inverse kinematics against independent oracles."""
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from planner import Crane, UnreachableError

from tests.conftest import MACHINES, random_configs


def _elbow_side(crane, q):
    """+1 when the jib joint lies left of (above) the shoulder->tip chord, from frame origins."""
    o = crane.frame_origins(q)
    sl = q[crane.chain.slew] + crane.chain.psi_h
    h = np.array([math.cos(sl), math.sin(sl), 0.0])

    def pl(p):
        return np.array([p @ h, p[2]])
    S, E, T = pl(o[1]), pl(o[2]), pl(o[-1])
    a, b = T - S, E - S
    side = np.sign(a[0] * b[1] - a[1] * b[0])
    return side if T[0] >= 0 else -side  # seen from behind the slew axis the sides swap


@pytest.mark.parametrize("cid", MACHINES)
@given(u=st.lists(st.floats(0.01, 0.99), min_size=4, max_size=4))
def test_fk_ik_round_trip(cid, u):
    crane = Crane.from_id(cid)
    L = crane.limit_arrays()
    q = L["q_min"] + np.array(u[: crane.n]) * (L["q_max"] - L["q_min"])
    tip = crane.tip(q)
    tele = q[crane.chain.tele] if crane.chain.tele is not None else None
    side = _elbow_side(crane, q)
    try:
        q2 = crane.ik(tip, tele)
    except UnreachableError as e:
        # only a configuration on the other elbow branch may fail, and the message says so
        assert side != crane.chain.elbow and "other elbow branch" in str(e)
        return
    np.testing.assert_allclose(crane.tip(q2), tip, atol=1e-9)
    if side == crane.chain.elbow:
        np.testing.assert_allclose(q2, q, atol=1e-8)


def test_umea_fk_matches_table_I():
    """Direct DH product written from seed 003 Table I (independent of the TOML)."""
    def A(th, d, a, al):
        ct, st_, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        return np.array([[ct, -st_ * ca, st_ * sa, a * ct], [st_, ct * ca, -ct * sa, a * st_],
                         [0, sa, ca, d], [0, 0, 0, 1]])
    th20, d40 = 0.1192, 1.813
    crane = Crane.from_id("umea-lab")
    for q in ([0, 0, -1.0, 0], [0.3, 0.8, -2.0, 1.2], [-0.7, -0.2, -0.5, 0.4],
              [0.1, 1.3, -2.6, 1.5]):
        q1, q2, q3, q4 = q
        T = (A(q1, 2.202, 0, math.pi / 2) @ A(q2 + th20, 0, 1.4, 0)
             @ A(math.pi / 2 + q3 - th20, 0, 0.104, math.pi / 2) @ A(0, d40 + q4, 0, -math.pi / 2))
        np.testing.assert_allclose(crane.fk(np.array(q)), T[:3, 3], atol=1e-12)
        r, z, s = crane.tip(np.array(q))
        assert r == pytest.approx(math.hypot(T[0, 3], T[1, 3]))
        assert s == pytest.approx(math.atan2(T[1, 3], T[0, 3]))


def test_cranab850_fk_matches_seed_000_formula():
    crane = Crane.from_id("cranab850")
    J = crane.spec.joints
    d0, d1, d2 = J[0].dh.d, J[1].dh.a, J[3].dh.d  # the fitted lengths, in the seed's formula
    for q in random_configs(crane, 50, seed=3):
        _, t1, t2, d3 = q
        r = d1 * math.sin(t1) + (d2 + d3) * math.sin(t1 + t2)
        z = d0 + d1 * math.cos(t1) + (d2 + d3) * math.cos(t1 + t2)
        tip = crane.tip(q)
        assert abs(tip[0]) == pytest.approx(abs(r), abs=1e-12)
        assert tip[1] == pytest.approx(z, abs=1e-12)


def test_jacobian_matches_finite_differences(crane):
    qs = random_configs(crane, 20, seed=1)
    qs[:, 0] = np.clip(qs[:, 0], -1.0, 0.4)  # keep atan2 away from its ±π cut
    h = 1e-6
    for q in qs:
        J = crane.jacobian(q)
        Jx = crane.jacobian(q, coords="xyz")
        for i in range(crane.n):
            e = np.zeros(crane.n)
            e[i] = h
            fd = (crane.tip(q + e) - crane.tip(q - e)) / (2 * h)
            fdx = (crane.fk(q + e) - crane.fk(q - e)) / (2 * h)
            np.testing.assert_allclose(J[:, i], fd, atol=1e-6)
            np.testing.assert_allclose(Jx[:, i], fdx, atol=1e-6)


def test_batched_equals_single(crane):
    qs = random_configs(crane, 7, seed=2)
    tips = crane.tip(qs)
    for k in range(7):
        np.testing.assert_allclose(tips[k], crane.tip(qs[k]), atol=0)
    J = crane.jacobian(qs)
    np.testing.assert_allclose(J[3], crane.jacobian(qs[3]), atol=0)


def test_unreachable_messages_name_point_and_reason():
    crane = Crane.from_id("cranab850")
    with pytest.raises(UnreachableError, match=r"r=30\.000 m.*out of reach.*at most"):
        crane.ik((30.0, 0.0, 0.0), tele=0.5)
    with pytest.raises(UnreachableError, match=r"out of reach.*at least"):
        crane.ik((1.5, 1.0, 0.0), tele=0.0)  # needs the telescope out (seed point A)
    with pytest.raises(UnreachableError, match=r"joint limit: slew would be"):
        crane2 = Crane.from_id("umea-lab")
        crane2.ik((3.0, 2.5, 1.2), tele=0.5)  # slew limit is [-1, 0.5] rad


def test_ik_batch_reports_per_point():
    crane = Crane.from_id("s100f")
    tips = np.array([[6.0, -1.0, 0.0], [40.0, 0.0, 0.0], [5.0, 2.0, 0.3]])
    q, reason = crane.ik_batch(tips, 1.0)
    assert reason[0] == "" and reason[2] == ""
    assert "out of reach" in reason[1] and np.all(np.isnan(q[1]))
    np.testing.assert_allclose(crane.tip(q[[0, 2]]), tips[[0, 2]], atol=1e-9)


def test_lateral_offset_machine_round_trip():
    """cat215b has a 0.11 m lateral boom offset: slew of the tip differs from the joint."""
    crane = Crane.from_id("cat215b")
    assert abs(crane.chain.lateral) == pytest.approx(0.11)
    q = np.array([0.5, 0.3, -1.5])
    tip = crane.tip(q)
    assert abs(tip[2] - 0.5) > 1e-3
    np.testing.assert_allclose(crane.ik(tip), q, atol=1e-9)
