"""The refinement's solver (planner.refine.solve) and its calm stage.

Oracles: the known minimum of a convex quadratic, a cost whose gradient lies until a point
(L-BFGS-B's line search then fails: an early stop that a restart must get past), and the
twin's own prediction of the first stage (what the calm stage may only improve on)."""
import numpy as np
import pytest

from planner.feedforward import stored_commands
from planner.model.twin import Twin
from planner.refine import RefineOptions, refine_commands
from planner.refine.solve import minimize_commands

A = np.diag([1.0, 10.0, 100.0, 3.0])
B = np.array([0.3, -0.2, 0.1, 0.4])


def quadratic(z):
    r = z - B
    return float(r @ A @ r), 2.0 * A @ r


class Lying:
    """The quadratic, but for its first ``n`` evaluations the gradient points the wrong way
    (the line search finds no decrease along it and L-BFGS-B stops ABNORMAL)."""

    def __init__(self, n):
        self.n, self.calls = n, 0

    def __call__(self, z):
        self.calls += 1
        J, g = quadratic(z)
        return (J, -g) if self.calls <= self.n else (J, g)


def test_the_solver_reaches_a_quadratics_minimum_without_restarting():
    r = minimize_commands(quadratic, np.zeros(4), 200)
    assert np.allclose(r.x, B, atol=1e-6)
    assert r.restarts == 0 and r.fun == pytest.approx(0.0, abs=1e-10)


def test_a_run_that_stops_early_is_restarted_from_its_best_point():
    plain = minimize_commands(Lying(15), np.zeros(4), 200, restarts=False)
    assert plain.message.startswith("ABNORMAL")
    assert plain.fun > 1e-2                        # stuck where the lie left it
    again = minimize_commands(Lying(15), np.zeros(4), 200)
    assert again.restarts >= 1
    assert np.allclose(again.x, B, atol=1e-6)


def test_the_solver_keeps_its_budget_and_the_bounds():
    cost = Lying(10 ** 9)                          # never tells the truth: restarts gain nothing
    r = minimize_commands(cost, np.zeros(4), 30)
    assert cost.calls <= 2 * 30 + 1
    far = minimize_commands(lambda z: (float(np.sum((z - 5.0) ** 2)), 2.0 * (z - 5.0)),
                            np.zeros(3), 50, shut=np.array([False, True, False]))
    assert np.allclose(far.x, [1.0, 0.0, 1.0])     # |u| ≤ 1, a shut command stays 0
    assert r.nit <= 30


@pytest.fixture(scope="module")
def case(umea_move):
    crane, move, _, _ = umea_move
    return crane, Twin(crane), move


def _score(m):
    return max(m["rest_offset_m"], m["residual_oscillation_m"])


def test_the_calm_stage_runs_where_the_first_leaves_the_move_off_and_never_worsens_it(case):
    crane, twin, move = case
    t_u, u = stored_commands(move)
    base = dict(iterations=6, settle=1.0, rest_window=0.5)
    off = refine_commands(crane, move, t_u, u, twin=twin,
                          options=RefineOptions(calm=0.0, **base))
    assert off.predicted["calm"] is None
    on = refine_commands(crane, move, t_u, u, twin=twin,
                         options=RefineOptions(calm=1.0, calm_below=0.0, **base))
    calm = on.predicted["calm"]
    assert calm is not None and calm["end_weight"] == pytest.approx(5.0 * 30.0)
    # the first stage is the same run with or without the calm stage after it
    assert calm["first"] == pytest.approx(off.predicted["refined"], rel=1e-9)
    kept = on.predicted["refined"]
    assert _score(kept) <= _score(calm["first"]) + 1e-12
    if calm["taken"]:
        assert _score(kept) < _score(calm["first"])
        assert on.iterations > off.iterations
    else:
        assert kept == pytest.approx(calm["first"], rel=1e-12)
    # above its threshold it does not run
    high = refine_commands(crane, move, t_u, u, twin=twin,
                           options=RefineOptions(calm=1.0, calm_below=1.0, **base))
    assert high.predicted["calm"] is None
