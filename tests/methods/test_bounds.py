"""Analytic lower bounds against Ruckig (an independent time-optimal solver) and feasible moves."""
import numpy as np
import pytest
import ruckig
from hypothesis import given
from hypothesis import strategies as st

from planner import Crane, UnreachableError
from planner.bounds import lower_bound, rest_to_rest_time
from planner.trajectory import Trajectory, evaluate


def ruckig_duration(d, v, a, j):
    inp = ruckig.InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [d]
    inp.current_velocity = inp.current_acceleration = [0.0]
    inp.target_velocity = inp.target_acceleration = [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
    tr = ruckig.Trajectory(1)
    assert ruckig.Ruckig(1).calculate(inp, tr) in (ruckig.Result.Working, ruckig.Result.Finished)
    return tr.duration


def test_anchor_values():
    assert rest_to_rest_time(2.0, 0.5, 0.5) == pytest.approx(5.0)
    assert rest_to_rest_time(2.0, 0.5, 0.5, 2.0) == pytest.approx(5.25)


@given(d=st.floats(1e-3, 10), v=st.floats(0.05, 2), a=st.floats(0.05, 3), j=st.floats(0.1, 30))
def test_rest_to_rest_matches_ruckig(d, v, a, j):
    assert rest_to_rest_time(d, v, a, j) == pytest.approx(ruckig_duration(d, v, a, j), rel=1e-6)


def ruckig_move(crane, qs, qg, samples: int = 4000):
    """The synchronised time-optimal Ruckig move between two configurations, sampled."""
    L = crane.limit_arrays()
    n = crane.n
    inp = ruckig.InputParameter(n)
    inp.current_position, inp.target_position = list(qs), list(qg)
    inp.current_velocity = inp.current_acceleration = [0.0] * n
    inp.target_velocity = inp.target_acceleration = [0.0] * n
    inp.max_velocity = list(L["qd_max"])
    inp.min_velocity = list(L["qd_min"])
    inp.max_acceleration = list(L["qdd_max"])
    inp.max_jerk = list(L["qddd_max"])
    tr = ruckig.Trajectory(n)
    ruckig.Ruckig(n).calculate(inp, tr)
    t = np.linspace(0, tr.duration, samples)
    s = [tr.at_time(x) for x in t]
    return Trajectory(t, [p[0] for p in s], [p[1] for p in s], [p[2] for p in s],
                      joint_names=tuple(crane.names))


@pytest.mark.parametrize("cid,start,goal", [
    ("s100f", (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)),
    ("umea-lab", (3.0, 1.8, 0.0), (2.5, 3.0, -0.5)),
    ("cranab850", (1.5, 1.0, 0.0), (5.5, -3.0, 0.0)),
])
def test_feasible_moves_never_beat_the_bound(cid, start, goal):
    """A limit-respecting Ruckig move between any reachable end configurations takes at least the
    rest-to-rest bound, and swept oil volume at least the pump bound's volume."""
    crane = Crane.from_id(cid)
    lb = lower_bound(crane, start, goal)
    assert lb.velocity_s <= lb.rest_to_rest_s <= lb.combined_s
    assert lb.pump_s <= lb.combined_s
    rng = np.random.default_rng(0)
    lo, hi = crane.tele_range
    for _ in range(5):
        try:
            qs = crane.ik(start, rng.uniform(lo, hi))
            qg = crane.ik(goal, rng.uniform(lo, hi))
        except UnreachableError:
            continue
        tr = ruckig_move(crane, qs, qg)
        # (jerk is piecewise constant in Ruckig: between samples the quintic interpolant of a
        # piecewise cubic is not exact in jerk, so judge up to acceleration here)
        ev = evaluate(crane, tr, kinds=("position", "velocity", "acceleration"))
        assert ev.ok(1e-3)
        assert tr.duration >= lb.rest_to_rest_s - 1e-9
        pumped = np.trapezoid(ev.hyd["q_pump"], ev.t)
        assert pumped >= lb.pump_s * crane.spec.pump.max_flow * (1 - 1e-3)


def test_bound_is_minimised_over_the_telescope():
    crane = Crane.from_id("s100f")
    start, goal = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)
    lb = lower_bound(crane, start, goal)
    fixed = lower_bound(crane, q_start=crane.ik(start, 1.0), q_goal=crane.ik(goal, 1.0))
    assert lb.combined_s <= fixed.combined_s
    at_arg = lower_bound(crane, q_start=crane.ik(start, lb.tele_start),
                         q_goal=crane.ik(goal, lb.tele_goal))
    assert at_arg.combined_s == pytest.approx(lb.combined_s, rel=1e-9)


def test_energy_bound_is_potential_energy_gain():
    crane = Crane.from_id("cat215b")
    lb = lower_bound(crane, (5.0, 1.0, 0.0), (4.0, 3.0, 1.0))
    qs, qg = crane.ik((5.0, 1.0, 0.0)), crane.ik((4.0, 3.0, 1.0))
    dV = crane.potential_energy(qg) - crane.potential_energy(qs)
    assert lb.energy_J == pytest.approx(dV / crane.spec.pump.efficiency)
    assert lb.tele_start is None
    down = lower_bound(crane, (4.0, 3.0, 1.0), (5.0, 1.0, 0.0))
    assert down.energy_J == 0.0


def test_unreachable_end_is_reported():
    crane = Crane.from_id("s100f")
    with pytest.raises(UnreachableError, match="every telescope value"):
        lower_bound(crane, (30.0, 0.0, 0.0), (5.0, 1.0, 0.0))


def test_batched_refinement_equals_pair_by_pair():
    """The refinement evaluates all its grids in one batch; every grid pair must give what the
    single-pair evaluation gives on the reachable configurations (unreachable ones: +inf)."""
    from planner.bounds import _end_configs, _end_grids, _pair_bounds, _pair_bounds_batch
    crane = Crane.from_id("s100f")
    start, goal = (8.5, -1.0, 0.0), (3.0, 2.5, 1.5)   # far reach: some telescopes fail
    lo, hi = crane.tele_range
    rng = np.random.default_rng(3)
    gs = np.sort(rng.uniform(lo, hi, (4, 9)), axis=1)
    gg = np.sort(rng.uniform(lo, hi, (4, 7)), axis=1)
    A, B = _end_grids(crane, start, None, gs), _end_grids(crane, goal, None, gg)
    assert not A[2].all()                              # the case with holes is exercised
    batch = _pair_bounds_batch(crane, A, B)
    for s in range(4):
        qs, _ = _end_configs(crane, start, None, gs[s])
        qg, _ = _end_configs(crane, goal, None, gg[s])
        for m_b, m_1 in zip(batch, _pair_bounds(crane, qs, qg)):
            assert np.all(np.isinf(m_b[s][~A[2][s]])) and np.all(np.isinf(m_b[s][:, ~B[2][s]]))
            np.testing.assert_array_equal(m_b[s][np.ix_(A[2][s], B[2][s])], m_1)


def test_combined_only_refines_the_combined_bound_and_leaves_the_rest_at_the_grid():
    """The NLP guess's cheaper bound: the combined bound refined like the full search (never
    above the unrefined grid's), the other fields exactly the unrefined grid's values."""
    c = Crane.from_id("s100f")
    a, b = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)
    grid = lower_bound(c, a, b, n_grid=41, refine=0)
    full = lower_bound(c, a, b, n_grid=41, refine=2, starts=4)
    only = lower_bound(c, a, b, n_grid=41, refine=2, starts=4, combined_only=True)
    assert only.combined_s <= grid.combined_s
    assert only.combined_s == pytest.approx(full.combined_s, rel=1e-9)
    assert (only.tele_start, only.tele_goal) == pytest.approx((full.tele_start, full.tele_goal))
    for f in ("velocity_s", "rest_to_rest_s", "pump_s", "energy_J"):
        assert getattr(only, f) == getattr(grid, f)
        assert getattr(full, f) <= getattr(grid, f)
