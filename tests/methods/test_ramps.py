"""The pump-aware ramp bound (planner.bounds.ramps) against known optima and feasible moves: a
true lower bound (never above a closed-form optimum, a feasible move or the NLP's plan) that is
tight where one joint is pump-limited."""
import dataclasses

import numpy as np
import pytest

from tests.methods.test_bounds import ruckig_duration as ruckig_1dof  # the oracles
from tests.methods.test_bounds import ruckig_move
from planner import Crane
from planner.bounds import lower_bound, rest_to_rest_time
from planner.bounds.profiles import from_rest_distance
from planner.bounds.ramps import ramp_bound
from planner.methods.nlp import MoveNLP
from planner.trajectory import Trajectory, evaluate


def with_pump(crane, max_flow, **changes):
    """The crane with another pump flow (and other spec fields changed)."""
    s = crane.spec
    return Crane(dataclasses.replace(s, pump=dataclasses.replace(s.pump, max_flow=max_flow),
                                     **changes))


@pytest.fixture(scope="module")
def small_pump():
    """umea-lab with a 9 L/min pump: the telescope alone is pump-limited (0.31 m/s extending,
    its limit is 0.5 m/s)."""
    return with_pump(Crane.from_id("umea-lab"), 1.5e-4)


def test_from_rest_distance_integrates_the_full_effort_speed():
    v, a, j = 0.5, 1.0, 8.0
    t = np.linspace(0, 3, 30001)
    w = np.minimum(np.where(t <= a / j, j * t ** 2 / 2, a * t - a * a / (2 * j)), v)
    d = np.concatenate([[0], np.cumsum((w[1:] + w[:-1]) / 2 * np.diff(t))])
    np.testing.assert_allclose(from_rest_distance(t, v, a, j), d, atol=1e-7)
    assert from_rest_distance(2.0, 0.5, 1.0) == pytest.approx(0.5 * 0.5 * 0.5 + 0.5 * 1.5)


@pytest.mark.parametrize("jerk", [True, False])
def test_one_pump_limited_joint_gets_its_exact_optimum(small_pump, jerk):
    """Only the telescope moves (constant stroke slope): the pump caps its speed at
    v_p = Q / (A·x'), and the optimum is the 1-DOF rest-to-rest move at v_p (Ruckig). The bound
    never exceeds it and is within 0.2 % of it (its τ grid approaches the ramp loss from
    below)."""
    c = small_pump
    L = c.limit_arrays()
    qs = np.array([-0.3, 0.4, -1.2, 0.1])
    qg = qs + np.array([0, 0, 0, 1.2])
    xp = c.stroke(qs)[1][3]
    v_p = c.spec.pump.max_flow / (c.spec.joints[3].actuator.area_a * xp)
    assert v_p < L["qd_max"][3]
    j = L["qddd_max"][3] if jerk else 1e9
    exact = ruckig_1dof(1.2, v_p, L["qdd_max"][3], j)
    rb = ramp_bound(c, q_start=qs, q_goal=qg, jerk=jerk)
    assert rb.binding == "pump: tele"
    assert exact * (1 - 2e-3) <= rb.bound_s <= exact * (1 + 1e-9)
    # the analytic bounds miss the ramps: volume / flow alone is below
    lb = lower_bound(c, q_start=qs, q_goal=qg, jerk=jerk)
    assert lb.combined_s < exact * 0.95


def test_without_the_pump_a_single_joint_is_its_rest_to_rest_optimum():
    """umea-lab's own pump does not limit the slew alone: bang-bang with jerk limits exactly."""
    c = Crane.from_id("umea-lab")
    L = c.limit_arrays()
    qs = np.array([-0.8, 0.4, -1.2, 0.5])
    qg = qs + np.array([1.1, 0, 0, 0])
    rb = ramp_bound(c, q_start=qs, q_goal=qg)
    exact = ruckig_1dof(1.1, L["qd_max"][0], L["qdd_max"][0], L["qddd_max"][0])
    assert rb.binding == "rest-to-rest"
    assert rb.bound_s == pytest.approx(exact, rel=1e-9)
    assert rb.bound_s == pytest.approx(rest_to_rest_time(1.1, L["qd_max"][0], L["qdd_max"][0],
                                                         L["qddd_max"][0]), rel=1e-12)


def _feasible_move(crane, qs, qg):
    """A move that respects every limit the bound assumes: the synchronised Ruckig move
    between the configurations, slowed uniformly until its pump draw (evaluate(), 1 kHz) is
    within Q_max."""
    traj = ruckig_move(crane, qs, qg, samples=3000)
    peak = evaluate(crane, traj, kinds=("pump_flow",)).peak_pump_flow
    return traj.duration * max(1.0, peak / crane.spec.pump.max_flow)


def test_never_above_a_feasible_move(small_pump):
    """Random configuration pairs of the pump-limited crane: a feasible move (Ruckig slowed to
    the pump) is never faster than the bound, and the bound is at least the analytic one."""
    c = small_pump
    L = c.limit_arrays()
    rng = np.random.default_rng(5)
    lo, hi = L["q_min"] + 0.05 * (L["q_max"] - L["q_min"]), L["q_max"] - 0.05 * (L["q_max"]
                                                                                  - L["q_min"])
    tighter = 0
    for _ in range(12):
        qs, qg = lo + rng.random(4) * (hi - lo), lo + rng.random(4) * (hi - lo)
        rb = ramp_bound(c, q_start=qs, q_goal=qg)
        lb = lower_bound(c, q_start=qs, q_goal=qg)
        assert rb.bound_s >= lb.combined_s * (1 - 1e-12)
        assert _feasible_move(c, qs, qg) >= rb.bound_s * (1 - 1e-12)   # equal: r2r binds
        tighter += rb.bound_s > lb.combined_s * 1.01
    assert tighter >= 3        # the ramps matter on this pump


@pytest.mark.parametrize("a,b", [((2.6, 2.2, 0.3), (3.4, 2.6, -0.6)),
                                 ((3.2, 1.6, 0.0), (2.2, 3.1, 0.4)),
                                 pytest.param((2.8, 3.0, -0.5), (3.5, 1.6, 0.2),
                                              marks=pytest.mark.slow)])
def test_the_nlp_plan_is_never_faster_and_close(small_pump, a, b):
    """The minimum-time NLP (free telescopes at both ends) against the bound minimised over
    the telescopes: never below, and within 3 % (the certificate a plan reports)."""
    nlp = _nlp(small_pump)
    r = nlp.solve(a, b)
    assert r.ok, r.reason
    lb = lower_bound(small_pump, a, b, ramps=True)
    assert lb.ramps_s is not None and lb.ramps_s >= lb.combined_s * (1 - 1e-3)
    assert lb.ramps_s <= r.duration_s <= 1.03 * lb.ramps_s


_NLPS = {}


def _nlp(crane):
    if id(crane) not in _NLPS:
        _NLPS[id(crane)] = MoveNLP(crane, "time", "free", N=40, cache="off")
    return _NLPS[id(crane)]


def test_a_transformer_leaves_the_analytic_bound():
    """An enabled hydraulic transformer couples two joints' draws: no ramp bound (None), and
    lower_bound's certificate is the combined bound."""
    base = Crane.from_id("s100f")
    ht = dataclasses.replace(base.spec.transformer, enabled=True)
    c = Crane(dataclasses.replace(base.spec, transformer=ht))
    a, b = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)
    assert ramp_bound(c, a, b) is None
    lb = lower_bound(c, a, b, ramps=True)
    assert lb.ramps_s is None and lb.certified_s == lb.combined_s


def test_joint_ends_are_checked():
    c = Crane.from_id("umea-lab")
    with pytest.raises(ValueError, match="needs 4 values"):
        ramp_bound(c, q_start=[0.0, 0.1], q_goal=[0.0, 0.1, -1.0, 0.2])
    with pytest.raises(ValueError, match="either as a tip"):
        ramp_bound(c, (3.0, 2.0, 0.0), (3.0, 2.5, 0.0), q_start=[0, 0.1, -1.0, 0.2])
