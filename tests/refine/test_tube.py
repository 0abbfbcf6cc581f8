"""The landing tube of the calm stage (:class:`planner.refine.cost.CommandCost`, ``tube``).

Oracles: central finite differences of the same cost (its gradient), the tip's distance from
the goal by the forward kinematics of the twin's own run (the term's value: the cost uses the
tip's levers), and the cost without the tube (a tube wider than the run's largest distance
adds nothing).
"""
import numpy as np
import pytest

from planner.model.twin import Twin
from planner.model.twin.shooting import Shooting
from planner.refine import RefineOptions
from planner.refine.cost import CommandCost
from planner.refine.bounds import start_openings

from tests.refine.conftest import RATE


@pytest.fixture(scope="module")
def problem(umea_move):
    crane, move, t_u, u = umea_move
    opts = RefineOptions(settle=1.0, rest_window=0.5)
    twin = Twin(crane)
    sh = Shooting(twin)
    R = int(round(1.0 / (RATE * twin.step)))
    Ku = t_u.size + int(round(opts.tail * RATE))
    K = sh.steps((Ku + 1) * R + int(round(opts.settle / twin.step)))
    lo, hi = -np.ones((Ku, crane.n)), np.ones((Ku, crane.n))
    db = np.asarray(twin.params.per["deadband"], float)
    z = start_openings((t_u, u), move.t[0], Ku, db, lo, hi, RATE).ravel()

    def cost(tube):
        return CommandCost(sh, move, Ku, R, K, opts, crane, None, None, None, tube)
    return crane, move, sh, z, cost


def _errors(crane, sh, cost, z):
    """The joint errors after the plan's end of the run the cost makes of openings ``z``."""
    from planner.model.valves import past_deadband
    us = cost.steps(past_deadband(z.reshape(cost.Ku, crane.n), cost.db))
    run = sh.run(cost.x0, us)
    return (run.x[:, :crane.n] - cost.q_ref)[cost.after]


def _displacements2(crane, goal, ea):
    """Σ_j |fk(goal + e_j·1_j) − fk(goal)|² [mm²] per row: each joint's own tip displacement
    by the forward kinematics."""
    tip0 = crane.fk(goal)
    s = np.zeros(len(ea))
    for j in range(crane.n):
        q = np.repeat(goal[None, :], len(ea), axis=0)
        q[:, j] += ea[:, j]
        s += np.sum((1e3 * (crane.fk(q) - tip0)) ** 2, axis=1)
    return s


def test_the_tube_term_is_the_tips_excess_over_its_radius_squared(problem):
    crane, move, sh, z, cost = problem
    plain = cost((0.0, 0.0))
    ea = _errors(crane, sh, plain, z)
    d2 = _displacements2(crane, move.q[-1], ea)
    assert d2.max() > 1.0    # the nominal commands leave the tip off: the tube acts
    r = 0.3 * np.sqrt(d2.max())       # [mm]
    J0, _ = plain(z)
    J1, _ = cost((1e-3 * r, 100.0))(z)
    expected = 100.0 * sh.h * float(np.sum(np.maximum(d2 - r ** 2, 0.0) ** 2))
    assert J1 - J0 == pytest.approx(expected, rel=1e-2)
    # a tube wider than the largest distance adds nothing
    wide = cost((2e-3 * np.sqrt(d2.max()), 100.0))
    assert wide(z)[0] == pytest.approx(J0, rel=1e-12)


def test_the_tube_terms_gradient_matches_central_differences(problem):
    crane, move, sh, z, cost = problem
    c = cost((1e-3, 100.0))
    rng = np.random.default_rng(3)
    ea = 2e-3 * rng.normal(size=c.L2.shape)
    ea[::2] *= 1e-2                              # rows in and out of a 1 mm tube
    J, g = c.tube(ea)
    assert J > 0 and np.any(g == 0.0) and np.any(g != 0.0)
    for _ in range(4):
        v = rng.normal(size=ea.shape)
        eps = 1e-7
        fd = (c.tube(ea + eps * v)[0] - c.tube(ea - eps * v)[0]) / (2 * eps)
        assert float(np.sum(g * v)) == pytest.approx(fd, rel=1e-5)
