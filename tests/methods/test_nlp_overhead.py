"""Issue 31, the minimum-time NLP's overhead in process: each cheaper mechanism against the
judge it replaces — the exact move's limit check against evaluate(), the Hessian through the
stroke Jacobians against CasADi's own, the lazy exact-move check against checking up front, and
the lower bound's IK of both ends in one call against one call per end."""
import numpy as np
import pytest

from planner.bounds import _end_configs, _end_grids, _ends_configs, _ends_grids, lower_bound
from planner.methods.nlp import MoveNLP, exact, move
from planner.methods.nlp.exact import exact_move, feasible_exact, limit_violation
from planner.model import Crane, UnreachableError
from planner.trajectory import evaluate
from tests.conftest import random_tip_moves


_moves = random_tip_moves


@pytest.mark.parametrize("cid", ["umea-lab", "s100f"])
def test_the_exact_moves_limit_check_is_evaluates_measure(cid):
    """limit_violation (kinematic limits, the pump's draw from the stroke rates) against
    evaluate()'s max_limit_violation over the same kinds, at the switch times and on the 1 kHz
    resampling, on Ruckig moves of 10 random moves (some within the pump, some not)."""
    crane = Crane.from_id(cid)
    nlp = MoveNLP(crane, "time", N=8, pump=True, solver="ipopt", cache="off")
    seen = []
    for a, b in _moves(crane, 10, 7):
        tr = exact_move(nlp, a, b, nlp.guesses.bound(a, b))
        assert "pump_flow" in tr.limits
        for rate in (1e-9, 1000.0):
            ref = evaluate(crane, tr, rate=rate, kinds=tr.limits).max_limit_violation
            assert limit_violation(crane, tr, rate) == pytest.approx(ref, rel=1e-12, abs=1e-15)
        seen.append(ref > exact.LIMIT_TOL)
    assert any(seen) and not all(seen)


def test_the_hessian_through_the_stroke_jacobians_is_casadis(umea_lab, monkeypatch):
    """The Lagrangian's Hessian written by planner.methods.nlp.hessian against the one CasADi
    derives from the same NLP: the same sparsity, the same values at random points and
    multipliers, fewer instructions."""
    monkeypatch.setattr(move, "LIFTED_HESSIAN", False)
    ref = MoveNLP(umea_lab, "time", N=10, pump=True, solver="ipopt", cache="off")
    monkeypatch.setattr(move, "LIFTED_HESSIAN", True)
    got = MoveNLP(umea_lab, "time", N=10, pump=True, solver="ipopt", cache="off")
    Hr, Hg = (m.solver.get_function("nlp_hess_l") for m in (ref, got))
    assert Hg.sparsity_out(0) == Hr.sparsity_out(0)
    assert Hg.n_instructions() < Hr.n_instructions()
    rng = np.random.default_rng(3)
    lo, hi = ref.lbw, np.minimum(ref.ubw, ref.lbw + 10.0)
    for _ in range(10):
        x = lo + (hi - lo) * rng.random(ref.nw)
        args = (x, rng.random(Hr.size_in(1)), rng.random(), rng.standard_normal(Hr.size_in(3)))
        a, b = Hg(*args).full(), Hr(*args).full()
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10 * np.abs(b).max())


def test_the_exact_move_is_checked_only_where_it_decides(umea_lab, monkeypatch):
    """The NLP always solved: the exact move is checked at most once per solve, and the plan
    is what an up-front check gives — Ruckig's move exactly when it is feasible and faster
    than the NLP's own solution."""
    nlp = MoveNLP(umea_lab, "time", N=40, pump=True, solver="ipopt", cache="off")
    nlp.certify = False
    calls = []
    real = exact.feasible
    monkeypatch.setattr(exact, "feasible", lambda m, tr: calls.append(1) or real(m, tr))
    for a, b in _moves(umea_lab, 20, 31)[:6]:
        calls.clear()
        r = nlp.solve(a, b)
        assert r.ok and len(calls) <= 1
        own = r.stats.get("nlp_duration_s", r.duration_s)
        up_front = feasible_exact(nlp, a, b, nlp.guesses.bound(a, b))
        swap = up_front is not None and up_front.duration < own * (1 - 1e-6)
        assert (r.stats.get("winner") == "ruckig") == swap
        if swap:
            assert r.duration_s == up_front.duration


@pytest.mark.parametrize("cid", ["umea-lab", "s100f"])
def test_both_ends_ik_in_one_call_is_one_call_per_end(cid):
    """The lower bound's IK of both ends in one call against one call per end: the same
    configurations, telescopes and reachable masks; an unreachable end still raises with its
    spelled-out reason."""
    crane = Crane.from_id(cid)
    a, b = _moves(crane, 3, 11)[2]
    grid = np.linspace(*crane.tele_range, 41)
    for (q1, t1), (q2, t2) in zip(_ends_configs(crane, ((a, None), (b, None)), grid),
                                  [_end_configs(crane, a, None, grid),
                                   _end_configs(crane, b, None, grid)]):
        np.testing.assert_array_equal(q1, q2)
        np.testing.assert_array_equal(t1, t2)
    rng = np.random.default_rng(2)
    gs, gg = (np.sort(rng.uniform(*crane.tele_range, (3, 21)), axis=1) for _ in range(2))
    both = _ends_grids(crane, ((a, None, gs), (b, None, gg)))
    for x, y in zip(both, [_end_grids(crane, a, None, gs), _end_grids(crane, b, None, gg)]):
        for u, v in zip(x, y):
            np.testing.assert_array_equal(u, v)
    with pytest.raises(UnreachableError, match="unreachable for every telescope value: out of "
                                               "reach: .* m from the boom pivot"):
        lower_bound(crane, a, (60.0, 0.0, 0.0))


def test_stroke_derivatives_need_one_joint_per_entry():
    """J, J′, J″ per joint of a stroke Jacobian whose entries each depend on their own joint
    (against the derivatives written by hand); None when one depends on another joint (the
    Hessian then stays CasADi's own)."""
    import casadi as ca

    from planner.methods.nlp.hessian import stroke_derivatives
    own = stroke_derivatives(lambda q: ca.vertcat(ca.sin(q[0]), q[1] ** 3), 2)
    J, d1, d2 = (np.asarray(v).ravel() for v in own(np.array([0.3, 2.0])))
    np.testing.assert_allclose(J, [np.sin(0.3), 8.0])
    np.testing.assert_allclose(d1, [np.cos(0.3), 12.0])
    np.testing.assert_allclose(d2, [-np.sin(0.3), 12.0])
    assert stroke_derivatives(lambda q: ca.vertcat(q[0] * q[1], q[1]), 2) is None


def test_the_callers_ipopt_options_win_over_the_minimum_time_ones(umea_lab):
    """MoveNLP adds TIME_IPOPT for minimum time on a free path; an IPOPT option the caller
    gives for the same key replaces it (a duplicate key once raised TypeError), and both
    solve the same move to the same duration."""
    a, b = _moves(umea_lab, 20, 31)[3]
    got = []
    for opts in (None, {k: "no" for k in move.TIME_IPOPT}):
        m = MoveNLP(umea_lab, "time", N=12, pump=True, solver="ipopt", cache="off",
                    ipopt_options=opts)
        m.certify = False
        r = m.solve(a, b)
        assert r.ok
        got.append(r.stats.get("nlp_duration_s", r.duration_s))
    assert got[1] == pytest.approx(got[0], rel=1e-6)
