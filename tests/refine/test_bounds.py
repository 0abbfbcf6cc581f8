"""The refined openings' ranges (planner.refine.command_bounds) and the solver keeping them.

Oracles: the rules read off the nominal commands by hand (which rows keep their sign, which
joint moves one way only, where the landing window frees them), and the bound-constrained
minimum of a separable quadratic (each coordinate clipped to its box)."""
import numpy as np
import pytest

from planner.model.twin import Twin
from planner.refine import (ENERGY_ENTRY_WEIGHT, TIME_ENTRY_WEIGHT, RefineOptions,
                            command_bounds, for_objective, refine_commands)
from planner.refine.solve import minimize_commands

RATE = 50.0


def nominal():
    """Four joints over 2 s at 50 Hz: 0 raises then idles, 1 lowers only, 2 reverses, 3 is
    held (all zero)."""
    u = np.zeros((100, 4))
    u[10:40, 0] = 0.5
    u[20:90, 1] = -0.3
    u[10:30, 2], u[50:70, 2] = 0.4, -0.4
    return u


def test_default_bounds_are_the_valves_range_and_keep_closed_shuts_only_the_held_joint():
    u = nominal()
    lo, hi = command_bounds(u, 125, RefineOptions())
    assert lo.shape == hi.shape == (125, 4)
    assert np.all(lo == -1.0) and np.all(hi == 1.0)
    lo, hi = command_bounds(u, 125, RefineOptions(keep_closed=True, lead=0.3))
    end = 100 - 15
    assert np.all(lo[:end, 3] == 0.0) and np.all(hi[:end, 3] == 0.0)
    assert np.all(lo[end:, 3] == -1.0) and np.all(hi[end:, 3] == 1.0)
    assert np.all(lo[:, :3] == -1.0) and np.all(hi[:, :3] == 1.0)


def test_keep_direction_keeps_each_joints_sign_until_the_landing_window():
    u = nominal()
    lo, hi = command_bounds(u, 125, RefineOptions(keep_direction=True, lead=0.3,
                                                  idle_reverse=0.0))
    end = 100 - 15
    # joint 0 raises only: never lowered before the window, idle rows included
    assert np.all(lo[:end, 0] == 0.0) and np.all(hi[:end, 0] == 1.0)
    # joint 1 lowers only: never raised before the window
    assert np.all(hi[:end, 1] == 0.0) and np.all(lo[:end, 1] == -1.0)
    # joint 2 goes both ways: its moving rows keep their sign, its idle rows are free
    assert np.all(lo[10:30, 2] == 0.0) and np.all(hi[50:70, 2] == 0.0)
    assert np.all(lo[:10, 2] == -1.0) and np.all(hi[:10, 2] == 1.0)
    assert np.all(lo[35:45, 2] == -1.0) and np.all(hi[35:45, 2] == 1.0)
    # joint 3 never moves: no direction to keep (keep_closed is the option for it)
    assert np.all(lo[:, 3] == -1.0) and np.all(hi[:, 3] == 1.0)
    # the landing window and the tail: every joint free both ways
    assert np.all(lo[end:] == -1.0) and np.all(hi[end:] == 1.0)
    # the nominal commands lie inside their bounds (the refinement starts feasible)
    assert np.all(u[:end] >= lo[:end]) and np.all(u[:end] <= hi[:end])


def test_idle_reverse_lets_a_one_way_joint_correct_a_droop_a_little_while_it_is_held():
    # s100f d00-p00:energy: the jib, held while the boom and slew move, droops 0.04 rad on
    # its oil; putting it right takes a 1 % opening against the way the plan later moves it
    u = nominal()
    opts = RefineOptions(keep_direction=True, lead=0.3, idle_reverse=0.05)
    lo, hi = command_bounds(u, 125, opts)
    end = 100 - 15
    idle0 = np.abs(u[:end, 0]) <= opts.idle
    assert np.all(lo[:end, 0][idle0] == -0.05) and np.all(lo[:end, 0][~idle0] == 0.0)
    idle1 = np.abs(u[:end, 1]) <= opts.idle
    assert np.all(hi[:end, 1][idle1] == 0.05) and np.all(hi[:end, 1][~idle1] == 0.0)
    assert np.all(hi[:end, 0] == 1.0) and np.all(lo[:end, 1] == -1.0)
    # a joint that goes both ways is as before: moving rows keep their sign, idle rows free
    lo0, hi0 = command_bounds(u, 125, RefineOptions(keep_direction=True, lead=0.3,
                                                    idle_reverse=0.0))
    assert np.array_equal(lo[:, 2:], lo0[:, 2:]) and np.array_equal(hi[:, 2:], hi0[:, 2:])
    with pytest.raises(ValueError, match="idle_reverse"):
        RefineOptions(idle_reverse=1.5)


def test_the_solver_stops_on_its_bounds_at_the_clipped_minimum():
    A = np.array([1.0, 4.0, 2.0, 8.0])
    B = np.array([0.6, -0.7, 0.2, -0.1])

    def cost(z):
        r = z - B
        return float(r @ (A * r)), 2.0 * A * r

    lo = np.array([-1.0, 0.0, -1.0, 0.0])
    hi = np.array([0.0, 1.0, 1.0, 1.0])
    r = minimize_commands(cost, np.zeros(4), 200, bounds=(lo, hi))
    assert np.allclose(r.x, np.clip(B, lo, hi), atol=1e-6)
    shut = np.array([False, False, True, False])
    r = minimize_commands(cost, np.zeros(4), 200, shut=shut, bounds=(lo, hi))
    assert r.x[2] == 0.0 and np.allclose(r.x, np.clip(B, lo, hi) * ~shut, atol=1e-6)


def test_keep_direction_must_be_a_bool():
    with pytest.raises(ValueError, match="keep_direction"):
        RefineOptions(keep_direction=1)


def test_refined_commands_keep_the_nominal_direction_on_the_twin(umea_move):
    crane, move, t_u, u = umea_move
    # the constrained refinement alone (its plain fallback is tested below)
    opts = RefineOptions(iterations=6, settle=1.0, rest_window=0.5, calm=0.0,
                         keep_direction=True, idle_reverse=0.0, fallback_above=0.0)
    r = refine_commands(crane, move, t_u, u, twin=Twin(crane), options=opts)
    end = u.shape[0] - int(round(opts.lead * RATE))
    lo, hi = command_bounds(u, r.u.shape[0], opts)
    assert r.u.shape[0] > end and np.any(r.u[:end] != u[:end])   # it did refine
    assert np.all(r.u[:end] >= lo[:end] - 1e-12) and np.all(r.u[:end] <= hi[:end] + 1e-12)
    # each joint that moved one way in the plan was never commanded the other way
    one_way = 0
    for j in range(crane.n):
        up, down = np.any(u[:end, j] > opts.idle), np.any(u[:end, j] < -opts.idle)
        if up and not down:
            assert np.all(r.u[:end, j] >= 0.0)
        if down and not up:
            assert np.all(r.u[:end, j] <= 0.0)
        one_way += up != down
    assert one_way == crane.n      # a rest-to-rest move: every joint one way


def test_an_energy_move_is_refined_priced_and_a_time_move_priced_lighter():
    o = RefineOptions(iterations=7)
    assert for_objective(o, None) is o
    t = for_objective(o, "time")
    assert t.energy_weight == TIME_ENTRY_WEIGHT < ENERGY_ENTRY_WEIGHT
    assert not t.keep_direction and t.iterations == 7
    assert for_objective(RefineOptions(energy_weight=5.0), "time").energy_weight == 5.0
    plain_t = RefineOptions(time_entries="plain")
    assert for_objective(plain_t, "time") is plain_t
    e = for_objective(o, "energy")
    assert e.keep_direction and e.energy_weight == ENERGY_ENTRY_WEIGHT and e.iterations == 7
    assert for_objective(RefineOptions(energy_weight=5.0), "energy").energy_weight == 5.0
    plain = RefineOptions(energy_entries="plain")
    assert for_objective(plain, "energy") is plain


def test_a_constrained_refinement_that_does_not_land_on_the_twin_is_refined_plain_too(umea_move):
    crane, move, t_u, u = umea_move
    twin = Twin(crane)
    base = dict(iterations=4, settle=1.0, rest_window=0.5, calm=0.0)
    # a threshold no refinement of 4 iterations meets: the plain one runs too
    opts = for_objective(RefineOptions(fallback_above=1e-9, **base), "energy")
    r = refine_commands(crane, move, t_u, u, twin=twin, options=opts)
    fb = r.predicted["fallback"]
    score = lambda m: max(m["rest_offset_m"], m["residual_oscillation_m"])  # noqa: E731
    assert fb["taken"] == (score(fb["plain"]) < score(fb["first"]))
    assert r.predicted["refined"] == (fb["plain"] if fb["taken"] else fb["first"])
    assert r.options["keep_direction"] and r.options["energy_weight"] == ENERGY_ENTRY_WEIGHT
    plain = refine_commands(crane, move, t_u, u, twin=twin,
                            options=RefineOptions(**base))
    assert fb["plain"] == plain.predicted["refined"]          # the same plain refinement
    if fb["taken"]:
        assert np.array_equal(r.u, plain.u)
    # a time move (nothing kept, nothing priced) and a threshold of 0: no second refinement
    assert "fallback" not in plain.predicted
    off = refine_commands(crane, move, t_u, u, twin=twin,
                          options=for_objective(RefineOptions(fallback_above=0.0, **base),
                                                "energy"))
    assert "fallback" not in off.predicted
