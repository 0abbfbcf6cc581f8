"""Issue 31: the minimum-time move NLP's cheaper forms, each against an independent judge — the
one-row velocity check against the two limits it stands for, the certified exact move against
the lower bound, Ruckig and the NLP itself, and the exact move's quick rejection against
evaluate() on a 1 kHz resampling."""
import casadi as ca
import numpy as np
import pytest

from planner.bounds import lower_bound
from planner.methods.nlp import Layout, MoveNLP
from planner.methods.nlp.exact import feasible_exact
from planner.methods.nlp.limits import JERK_SMOOTH, add_velocity_limits
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import Trajectory, evaluate
from tests.conftest import random_tip_moves


_moves = random_tip_moves


@pytest.fixture(scope="module")
def nlp(umea_lab):
    return MoveNLP(umea_lab, "time", N=40, pump=True, solver="ipopt", cache="off")


def test_one_velocity_row_is_both_limits_with_the_jerk_gap(umea_lab):
    """The row of every check point against the two inequalities it replaces, written here in
    numpy: q̇ + gap ≤ q̇_max and q̇ − gap ≥ q̇_min, gap = √(j² + ε²)·h²/32 — on random
    velocities, jerks and interval lengths, long ones included (gap > half the range: nothing
    passes)."""
    L = umea_lab.limit_arrays()
    n = umea_lab.n
    jmax = L["qddd_max"]
    lay = Layout()
    v = [lay.add_var(f"v{i}", n, -10, 10) for i in range(3)]
    U = lay.add_var("U", (n, 1), -jmax[:, None], jmax[:, None])
    h = lay.add_var("h", 1, 0.0, 10.0)
    add_velocity_limits(lay, L, jmax, [(None, v[0], None)], [(None, v[1], None)],
                        [(None, v[2], None)], U, [h, h])
    _, _, lbg, ubg = lay.bounds()
    assert len(ubg) == 3 * n and np.all(ubg == 0) and np.all(np.isinf(lbg))
    g = ca.Function("g", [lay.w], [lay.g])
    rng = np.random.default_rng(5)
    for _ in range(400):
        vs = rng.uniform(1.3 * L["qd_min"], 1.3 * L["qd_max"], (3, n))
        j = rng.uniform(-jmax, jmax)
        hh = rng.choice([0.02, 0.05, 0.3, 1.5, 3.0])
        w = np.concatenate([vs.ravel(), j, [hh]])
        row_ok = np.asarray(g(w)).ravel() <= 0
        gap = np.sqrt(j ** 2 + (JERK_SMOOTH * jmax) ** 2) * hh ** 2 / 32
        two = (vs + gap <= L["qd_max"]) & (vs - gap >= L["qd_min"])
        margin = np.minimum(L["qd_max"] - vs - gap, vs - gap - L["qd_min"])
        clear = np.abs(margin) > 1e-9          # not on the boundary itself
        assert np.array_equal(row_ok[clear.ravel()], two.ravel()[clear.ravel()])


def test_a_certified_move_is_ruckigs_at_the_bound_without_the_nlp(umea_lab, nlp):
    """The first random umea-lab move of the overhead bench: the pump does not bind, so the
    jerk-limited Ruckig move at the bound's telescopes is feasible and lasts the lower bound.
    It is returned without solving the NLP; the NLP solved anyway is not faster, and the move
    keeps every limit (the pump too) on a 1 kHz resampling."""
    a, b = _moves(umea_lab, 20, 31)[0]
    r = nlp.solve(a, b)
    assert r.ok and r.stats.get("certified") and r.iterations == 0
    lb = nlp.guesses.bound(a, b)
    rk = rest_to_rest(umea_lab, umea_lab.ik(a, lb.tele_start), umea_lab.ik(b, lb.tele_goal))
    assert r.duration_s == pytest.approx(rk.duration_s, rel=1e-12)
    assert r.duration_s == pytest.approx(lb.combined_s, rel=1e-6)
    assert r.duration_s >= lower_bound(umea_lab, a, b).combined_s * (1 - 1e-4)
    ev = evaluate(umea_lab, r.trajectory)
    assert "pump_flow" in ev.checked and ev.max_limit_violation <= 1e-4
    nlp.certify = False
    try:
        own = nlp.solve(a, b)
    finally:
        nlp.certify = True
    assert own.ok and own.iterations > 0 and not own.stats.get("certified")
    assert own.stats["nlp_duration_s"] >= r.duration_s * (1 - 1e-6)
    assert own.duration_s == pytest.approx(r.duration_s, rel=1e-12)   # the swap, as before


def test_a_move_the_pump_limits_is_solved_by_the_nlp(umea_lab, nlp):
    """The fourth move of the bench: Ruckig's move needs more oil than the pump gives
    (evaluate() at 1 kHz), so nothing is certified and the NLP's own solution is returned,
    within every limit."""
    a, b = _moves(umea_lab, 20, 31)[3]
    lb = nlp.guesses.bound(a, b)
    rk = rest_to_rest(umea_lab, umea_lab.ik(a, lb.tele_start), umea_lab.ik(b, lb.tele_goal))
    assert evaluate(umea_lab, rk.trajectory, kinds=("pump_flow",)).max_limit_violation > 1e-3
    r = nlp.solve(a, b)
    assert r.ok and r.iterations > 0 and "winner" not in r.stats
    assert r.duration_s > rk.duration_s
    assert evaluate(umea_lab, r.trajectory).max_limit_violation <= 1e-6


def test_the_exact_moves_quick_rejection_agrees_with_the_full_check(umea_lab, nlp):
    """feasible_exact (its switch times first, then 1 kHz) against evaluate() on the 1 kHz
    resampling alone, on 12 random moves (both verdicts occur)."""
    verdicts = []
    for a, b in _moves(umea_lab, 20, 31)[:12]:
        lb = nlp.guesses.bound(a, b)
        got = feasible_exact(nlp, a, b, lb)
        rk = rest_to_rest(umea_lab, umea_lab.ik(a, lb.tele_start),
                          umea_lab.ik(b, lb.tele_goal)).trajectory
        ts = np.asarray(rk.meta["switch_times"])
        q, qd, qdd, _ = rk.sample(ts)
        tr = Trajectory(ts, q, qd, qdd, joint_names=tuple(umea_lab.names))
        full = evaluate(umea_lab, tr, kinds=("position", "velocity", "acceleration", "jerk",
                                             "pump_flow")).max_limit_violation <= 1e-4
        assert (got is not None) == full
        verdicts.append(full)
    assert any(verdicts) and not all(verdicts)
