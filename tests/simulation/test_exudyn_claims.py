"""The open-loop replay measures of the claims study (planner/simulation/dynamic/claims.py):
settling time and residual oscillation against analytic decaying sines, the stored-command and
piece-joining helpers against the plans they come from (the fast plant replays feed-forward
exactly), and one short replay on the Exudyn plant (its energy balance closes)."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from planner import Crane
from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.simulation.dynamic.simulate import simulate_trajectory
from planner.simulation.dynamic.claims import (pieces_commands, replay_move,
                                               residual_oscillation, settling_time,
                                               stored_commands)
from planner.simulation.replay import replay
from planner.trajectory import Trajectory

A, TAU, W = 0.04, 0.6, 2 * math.pi * 1.3     # 40 mm, 0.6 s decay, 1.3 Hz


def _decay(t):
    return A * np.exp(-t / TAU) * np.cos(W * t)


def _last_crossing(tol):
    """The analytic settling time: the last root of |A e^(-t/τ) cos ωt| = tol, found by brentq
    between the last extremum of |cos| above the band and the next zero of cos."""
    k = max(k for k in range(200) if A * math.exp(-k * math.pi / W / TAU) > tol)
    a, b = k * math.pi / W, (k + 0.5) * math.pi / W
    return brentq(lambda t: abs(_decay(t)) - tol, a, b)


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


@pytest.mark.parametrize("tol", [0.005, 0.002, 0.0123])
def test_settling_time_matches_the_analytic_decaying_cosine(tol):
    t = np.linspace(0.0, 6.0, 6001)
    ts = settling_time(t, _decay(t), tol)
    assert ts == pytest.approx(_last_crossing(tol), abs=2e-4)


def test_settling_time_never_outside_is_zero_and_never_inside_is_infinite():
    t = np.linspace(0.0, 2.0, 201)
    assert settling_time(t, 0.001 * np.sin(t), 0.005) == 0.0
    assert settling_time(t, 0.01 + 0 * t, 0.005) == math.inf
    # measured from t_from: a decay that starts 1 s into the record
    tt = np.linspace(0.0, 7.0, 7001)
    dd = np.where(tt < 1.0, 0.0, _decay(np.maximum(tt - 1.0, 0.0)))
    assert settling_time(tt, dd, 0.005, t_from=1.0) == pytest.approx(_last_crossing(0.005),
                                                                     abs=2e-4)


def test_residual_oscillation_separates_the_offset_from_the_oscillation():
    t = np.linspace(0.0, 10.0, 10001)
    goal = np.array([3.0, -1.0, 2.0])
    offset = np.array([0.0, 0.03, 0.0])          # comes to rest 30 mm beside the goal
    tip = goal + offset + np.outer(_decay(np.maximum(t - 2.0, 0.0)) * (t >= 2.0),
                                   [1.0, 0.0, 0.0])
    r = residual_oscillation(t, tip, goal, t_arrive=2.0, tol=0.005)
    assert r.offset_m == pytest.approx(0.03, abs=1e-6)
    assert r.peak_osc_m == pytest.approx(A, rel=1e-5)                  # at the arrival
    assert r.peak_to_goal_m == pytest.approx(math.hypot(A, 0.03), rel=1e-5)
    assert r.settle_rest_s == pytest.approx(_last_crossing(0.005), abs=2e-4)
    assert r.settle_goal_s == math.inf                                 # 30 mm > 5 mm for good
    with pytest.raises(ValueError, match="fewer than 2 samples"):
        residual_oscillation(t, tip, goal, t_arrive=11.0)


def test_stored_commands_pick_the_control_grid(s100f):
    q0, q1 = np.array([0.2, -0.3, 0.4, 1.0]), np.array([0.6, -0.1, 0.2, 1.4])
    traj = rest_to_rest(s100f, q0, q1, scale=0.5).trajectory
    ff = commands(s100f, traj, 50.0)
    stored = ff.attach(traj, knots=True)             # what a library entry keeps
    t_u, u = stored_commands(stored, 50.0)
    n = len(t_u)
    assert np.allclose(t_u, traj.t[0] + np.arange(n) / 50.0)
    assert np.allclose(u, ff.u[:n], atol=1e-12)
    bare = Trajectory(stored.t, stored.q, stored.qd, stored.qdd,
                      joint_names=stored.joint_names)
    assert stored_commands(bare) is None                      # no commands stored


def test_pieces_commands_replay_each_piece_on_the_fast_plant(s100f):
    """Two rest-to-rest pieces with a 0.7 s pause: the fast plant's replay of the joined
    commands ends each piece where the plan does (it replays feed-forward exactly)."""
    qa, qb, qc = (np.array(v) for v in ([0.2, -0.3, 0.4, 1.0], [0.5, -0.2, 0.3, 1.3],
                                        [0.1, -0.25, 0.45, 1.1]))
    p1 = rest_to_rest(s100f, qa, qb, scale=0.5).trajectory
    p2 = rest_to_rest(s100f, qb, qc, scale=0.5).trajectory
    t2 = p1.duration + 0.7
    t_u, u = pieces_commands(s100f, [(t2, p2), (0.0, p1)], 50.0)
    assert np.all(np.diff(t_u) > 0)
    sim = replay(s100f, t_u, u, qa, dt=0.02, t_end=t2 + p2.duration + 0.5)
    for t_end, q_end in ((p1.duration + 0.3, qb), (sim.t[-1], qc)):
        k = int(np.argmin(np.abs(sim.t - t_end)))
        assert np.abs(sim.q[k] - q_end).max() < 1e-3


@pytest.mark.slow
def test_short_replay_on_exudyn_runs_and_its_energy_balance_closes(s100f):
    q0, q1 = np.array([0.2, -0.3, 0.4, 1.0]), np.array([0.5, -0.2, 0.3, 1.3])
    traj = rest_to_rest(s100f, q0, q1, scale=0.3).trajectory
    m = replay_move(s100f, traj, settle=1.0)
    assert m.status == "ok"
    assert m.fast["max_track_m"] < 1e-3                 # the quasi-static plant: exact
    assert abs(m.exudyn["balance_residual"]) < 0.02
    assert 0 < m.exudyn["max_track_m"] < 0.5
    assert m.exudyn["pump_J"] > 0


def test_a_move_starting_on_an_end_stop_runs(s100f):
    """The telescope fully out (on its stroke's end stop) while the jib moves: the end-stop
    force is continuous at contact, so the implicit integrator converges (with the damping
    switched on at contact this run stopped at t ≈ 0.03 s)."""
    q0 = np.array([-1.745, -0.3546, 0.183, 2.3 - 1e-7])
    q1 = q0 + np.array([0.0, 0.0, -0.3, 0.0])
    traj = rest_to_rest(s100f, q0, q1, scale=0.5).trajectory
    run, *_ = simulate_trajectory(s100f, traj, 50.0, settle=0.2)
    assert run.ok, (run.status, run.t_fail, run.reason)
    assert abs(run.q[-1, 2] - q1[2]) < 0.05


def test_a_move_planned_onto_a_stroke_end_is_replayed_not_lost():
    """A telescope planned onto its stroke end at full speed (umea-lab, a random library
    move whose goal IK put the telescope at 1.55 m): at the plant's 2 ms step the stiff end
    stop threw a chamber pressure past 10 × relief; the plant now repeats a run that reaches
    a stop at a quarter step itself (``CONTACT_REFINE``), so even a replay without retries
    judges the move instead of reporting it lost."""
    from planner.simulation.dynamic.circuit import CONTACT_REFINE
    from planner.feedforward import commands
    from planner.methods.ruckig import rest_to_rest
    c = Crane.from_id("umea-lab")
    q0 = np.array([-0.086, 0.37234198, -2.46713545, 0.38807043])
    q1 = np.array([-0.222, 0.50044548, -1.21227937, 1.55])
    tr = rest_to_rest(c, q0, q1, scale=1.0).trajectory
    ff = commands(c, tr, 50.0)
    first = replay_move(c, tr, t_u=ff.t, u=ff.u, retries=0)
    assert first.status == "ok" and first.step_s == 2e-3 / CONTACT_REFINE, first.reason
    m = replay_move(c, tr, t_u=ff.t, u=ff.u)
    assert m.status == "ok", m.reason
    assert m.step_s < 2e-3
    assert 0.0 <= m.exudyn["offset_m"] < 0.5      # judged: the nominal commands land off
