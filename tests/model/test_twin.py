"""The dynamic twin (planner/model/twin): rest is an equilibrium at the load-holding pressures,
its right-hand side's Jacobian (what the integrator's Newton iteration uses) matches finite
differences, and on one short move per machine it agrees with the independent Exudyn plant.

Oracles: the model's inverse dynamics (the force each actuator must hold at rest), central
finite differences of the right-hand side, and the Exudyn plant (its own circuit code). The
twin's speed is a benchmark number (benchmarks/bench_twin.py), not asserted here.
"""
import numpy as np
import pytest

from planner.model import Crane
from planner.problems import crane_ids
from planner.model.twin import Twin, state_size, unpack

MACHINES = crane_ids()      # every shipped machine: a new TOML joins the contract


def _pose(crane, f=0.4):
    L = crane.limit_arrays()
    return L["q_min"] + f * (L["q_max"] - L["q_min"])


@pytest.fixture(scope="module", params=MACHINES)
def twin(request):
    return Twin(Crane.from_id(request.param))


def test_rest_is_an_equilibrium_at_the_load_holding_pressures(twin):
    crane = twin.crane
    n = crane.n
    q = _pose(crane)
    x0 = twin.rest_state(q)
    s = unpack(x0, n)
    tau = crane.inverse_dynamics(q, np.zeros(n), np.zeros(n))
    _, d = crane.stroke(q)
    A = np.array([[j.actuator.area_a, j.actuator.area_b] for j in crane.spec.joints])
    pt = crane.spec.pump.tank_pressure
    single = np.array([j.actuator.acting == "single" for j in crane.spec.joints])
    p_b = np.where(single, pt, s["p_b"])
    # the chambers hold exactly the force the rigid bodies need, one side at tank
    np.testing.assert_allclose(s["p_a"] * A[:, 0] - p_b * A[:, 1], tau / d, rtol=1e-9,
                               atol=1e-6 * np.abs(tau / d).max())
    assert np.all(np.isclose(s["p_a"], pt) | np.isclose(s["p_b"], pt))
    xdot = twin.rhs(x0, np.zeros(n))
    sd = unpack(xdot, n)
    assert np.abs(sd["qd"]).max() < 1e-7            # no acceleration
    assert np.abs(np.concatenate([sd["p_a"], sd["p_b"], [sd["p_s"]]])).max() < 1e-3  # Pa/s
    # and it stays there: 1 s with the valves closed moves nothing
    run = twin.simulate(np.array([0.0, 1.0]), np.zeros((2, n)), q)
    assert run.ok
    assert np.abs(run.q[-1] - q).max() < 1e-9
    assert np.abs(run.p_a[-1] - s["p_a"]).max() < 1.0


def test_the_jacobian_matches_finite_differences(twin):
    """The analytic Jacobian the Newton iteration solves with, on a moving state with the
    valves partly open and the pump in regulation (central differences, relative steps)."""
    crane = twin.crane
    n = crane.n
    rng = np.random.default_rng(3)
    x = twin.rest_state(_pose(crane, 0.5))
    s = unpack(x, n)
    x[n:2 * n] = 0.02 * rng.uniform(-1, 1, n)                 # joint rates
    x[2 * n:4 * n] += rng.uniform(0.5e6, 1.5e6, 2 * n)         # both chambers above tank
    x[4 * n] = max(s["p_a"].max(), s["p_b"].max()) + 4e6       # pump above every load
    x[4 * n + 1:] = 0.6 * rng.choice([-1, 1], n)               # spools out of the dead band
    u = 0.3 * rng.choice([-1, 1], n)
    import casadi as ca
    X = ca.SX.sym("x", state_size(n))
    J = ca.Function("J", [X], [ca.jacobian(twin.f_rhs(X, u, np.zeros(n), twin.P), X)])
    Ja = np.array(J(x))
    scale = np.concatenate([np.full(2 * n, 1e-6), np.full(2 * n + 1, 1.0), np.full(n, 1e-6)])
    Jf = np.empty_like(Ja)
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = scale[k]
        Jf[:, k] = (twin.rhs(x + e, u) - twin.rhs(x - e, u)) / (2 * scale[k])
    err = np.abs(Ja - Jf)
    tol = 1e-5 * np.abs(Ja).max(axis=1, keepdims=True) + 1e-4 * np.abs(Ja)
    assert np.all(err <= tol), np.unravel_index(np.argmax(err - tol), err.shape)


@pytest.mark.parametrize("crane_id", MACHINES)
def test_agrees_with_the_exudyn_plant_on_a_short_move(crane_id):
    """The boom out at 40 % command for 0.6 s, then 0.8 s ringing at rest, same parameters
    and commands (the judge shares no circuit code). The issue's bounds: tip within 2 mm,
    chamber pressures within 3 % of their range on Exudyn (at least 1 MPa), pressures at the
    end within 0.1 MPa (measured 2026-11-26: 0.04–0.31 mm, 0.3–0.7 %, ≤ 0.054 MPa). Before
    the twin stepped its spools exactly and the judge normalised its edges as documented,
    this move was 2.7–5.5 mm apart; both defects fail this test (see
    benchmarks/results/twin_validation.md)."""
    from planner.simulation.dynamic.exudyn_plant import ExudynPlant
    crane = Crane.from_id(crane_id)
    n = crane.n
    q0 = _pose(crane)
    t_u = np.arange(0.0, 0.62, 0.02)
    u = np.zeros((len(t_u), n))
    u[:-1, 1] = 0.4
    t_end = 1.4
    ex = ExudynPlant(crane).integrate(t_u, u, q0, t_end=t_end)
    tw = Twin(crane).simulate(t_u, u, q0, t_end=t_end)
    assert ex.ok and tw.ok
    t = ex.t
    q = np.column_stack([np.interp(t, tw.t, tw.q[:, i]) for i in range(n)])
    tip = np.linalg.norm(crane.fk(q) - crane.fk(ex.q), axis=1)
    moved = np.linalg.norm(crane.fk(ex.q[-1]) - crane.fk(ex.q[0]))
    assert moved > 0.02                                   # the move is a move
    assert tip.max() < 2e-3, tip.max()
    for tw_p, ex_p in ((tw.p_a, ex.p_a), (tw.p_b, ex.p_b)):
        p = np.column_stack([np.interp(t, tw.t, tw_p[:, i]) for i in range(n)])
        rng = np.maximum(np.ptp(ex_p, axis=0), 1e6)
        assert np.max(np.abs(p - ex_p) / rng) < 0.03
        assert np.abs(p[-1] - ex_p[-1]).max() < 0.1e6


@pytest.mark.parametrize("crane_id, joint", [("cat215b", 0), ("s100f", 0)])
def test_the_oil_spring_frequency_is_the_one_the_twin_rings_at(crane_id, joint):
    """A short valve pulse on one joint, then closed valves: the twin's free oscillation (zero
    crossings of the joint about its rest, after the pulse) has the period
    oil_spring_frequencies names (linearised: a few per cent)."""
    crane = Crane.from_id(crane_id)
    tw = Twin(crane)
    L = crane.limit_arrays()
    q = (L["q_min"] + L["q_max"]) / 2
    f = tw.oil_spring_frequencies(q)[joint]
    T = 1.0 / f
    n = crane.n
    t_u = np.array([0.0, 0.1 * T, 0.2 * T])
    u = np.zeros((3, n))
    u[0, joint], u[1, joint] = 0.05, -0.05
    run = tw.simulate(t_u, u, q, t_end=8 * T)
    assert run.ok
    y = run.q[:, joint] - run.q[run.t > 4 * T, joint].mean()
    w = run.t > T
    z = np.flatnonzero(np.diff(np.sign(y[w])) != 0)
    period = 2 * np.mean(np.diff(run.t[w][z]))
    assert period == pytest.approx(T, rel=0.05)
