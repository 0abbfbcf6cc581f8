"""CasADi NLP: minimum time against the analytic bound, limits judged by evaluate(), line mode."""
import numpy as np
import pytest

from planner import Crane
from planner.bounds import lower_bound
from planner.methods.nlp import MoveNLP
from planner.geometry.paths import tip_to_xyz
from planner.trajectory import evaluate


@pytest.mark.parametrize("cid,a,b", [("s100f", (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)),
                                     ("s100f", (7.0, 0.0, 0.0), (4.0, 0.0, 0.0)),
                                     ("umea-lab", (3.0, 1.8, 0.0), (2.5, 3.0, -0.5))])
def test_minimum_time_is_near_but_never_below_the_bound(cid, a, b):
    crane = Crane.from_id(cid)
    nlp = MoveNLP(crane, "time", "free", N=30)
    r = nlp.solve(a, b)
    assert r.ok, r.reason
    lb = lower_bound(crane, a, b)
    assert lb.combined_s * (1 - 1e-4) <= r.duration_s <= 1.05 * lb.combined_s
    ev = evaluate(crane, r.trajectory)
    assert ev.max_limit_violation <= 1e-3, ev
    np.testing.assert_allclose(crane.tip(r.trajectory.q[[0, -1]]), [a, b], atol=1e-6)
    np.testing.assert_allclose(r.trajectory.qd[[0, -1]], 0.0, atol=1e-7)


def test_line_mode_keeps_the_tip_on_the_line(s100f):
    a, b = (6.0, -1.0, 0.0), (4.0, 1.0, 0.0)
    r = MoveNLP(s100f, "time", "line", N=30).solve(a, b)
    assert r.ok, r.reason
    ev = evaluate(s100f, r.trajectory)
    assert ev.max_limit_violation <= 1e-3
    P, A = tip_to_xyz(ev.tip), tip_to_xyz(np.array(a))
    u = tip_to_xyz(np.array(b)) - A
    u /= np.linalg.norm(u)
    R = P - A
    assert np.linalg.norm(R - np.outer(R @ u, u), axis=1).max() < 2e-3


def test_build_once_solve_many(s100f):
    nlp = MoveNLP(s100f, "time", "free", N=20)
    r1 = nlp.solve((6.0, -1.0, 0.0), (3.0, 2.5, 1.5))
    r2 = nlp.solve((5.0, 0.5, 0.3), (7.0, -1.0, -0.5))
    assert r1.ok and r2.ok and r1.duration_s != r2.duration_s


def test_unreachable_end_is_a_status(s100f):
    r = MoveNLP(s100f, "time", "free", N=20).solve((30.0, 0.0, 0.0), (5.0, 0.0, 0.0))
    assert r.status == "unreachable" and "unreachable" in r.reason


def test_kinematic_line_nlp_not_slower_than_the_seed_dp():
    """Seed 000 setting (speed limits only, tip on the line): the continuous NLP is at most 1 %
    slower than the DP on its grid, and sits on or above the velocity bound."""
    from planner.methods.dp import dp
    from planner.methods.nlp import kinematic_line_nlp
    from planner.geometry.paths import Line
    crane = Crane.from_id("cranab850")
    a, b = (5.5, 1.0, 0.0), (5.5, -3.0, 0.0)
    d = dp(crane, Line(a, b), stages=400)
    r = kinematic_line_nlp(crane, a, b, N=100)
    assert r.ok
    assert r.duration_s <= 1.01 * d.duration_s
    q = r.trajectory.q
    assert r.duration_s >= lower_bound(crane, q_start=q[0], q_goal=q[-1]).velocity_s * (1 - 1e-6)
    assert evaluate(crane, r.trajectory).max_limit_violation <= 1e-6


def test_energy_optimal_saves_energy_and_the_front_is_monotone():
    """Under the seed pricing (the machine pricing's counter-pressure and valve-opening LS
    threshold leave this level move less to save at 1.2 T_min: measured 42.9 vs 44.2 kJ,
    −3.0 %, issue 30)."""
    from planner.methods.nlp import pareto_front
    s100f = Crane.from_id("s100f", pricing="seed")
    front = pareto_front(s100f, (7.0, 0.0, 0.0), (4.0, 0.0, 0.0), factors=(1.2, 1.6), N=30)
    assert all(r.ok for _, _, r, _ in front)
    T = [f[0] for f in front]
    E = [f[1] for f in front]
    assert T[0] < T[1] <= 1.2 * T[0] * (1 + 1e-6) and T[2] <= 1.6 * T[0] * (1 + 1e-6)
    assert front[1][3] == "nlp"        # the NLP found the 1.2 T_min point itself ...
    assert E[1] < 0.95 * E[0]          # ... and it saves energy
    assert E[2] <= E[1] * (1 + 1e-3)   # more time, no more energy: a monotone front
    for _, _, r, _ in front:
        assert evaluate(s100f, r.trajectory).max_limit_violation <= 1e-3


@pytest.mark.slow   # 17 s; tests/methods/test_obstacles.py clears the headboard in the default run
def test_headboard_wall_is_cleared(s100f):
    from planner.methods.nlp import Wall
    a, b = (6.0, -1.0, 0.0), (1.2, 0.8, 0.0)       # ground pick-up -> over the bunk
    wall = Wall(r=2.2, z_top=1.6, z_bottom=-0.5, clearance=0.3)

    def dist(r):
        tip = evaluate(s100f, r.trajectory).tip
        zc = np.clip(tip[:, 1], wall.z_bottom, wall.z_top)
        return np.hypot(tip[:, 0] - wall.r, tip[:, 1] - zc).min()
    free = MoveNLP(s100f, "time", "free", N=30).solve(a, b)
    walled = MoveNLP(s100f, "time", "free", N=30, obstacles=(wall,)).solve(a, b)
    assert free.ok and walled.ok
    assert dist(free) < 0.1                       # without it the tip passes through the wall
    assert dist(walled) >= 0.96 * wall.clearance  # the disc chain's guarantee
    assert evaluate(s100f, walled.trajectory).max_limit_violation <= 1e-3


def test_curve_mode_keeps_the_tip_on_seed_003s_circle():
    import math

    from planner.geometry.paths import circle, tip_to_xyz
    crane = Crane.from_id("umea-lab")
    cv = circle((3.0, 0.0, 2.5), 0.7, -math.pi / 2, math.pi / 2)
    r = MoveNLP(crane, "time", cv, N=30).solve()
    assert r.ok, r.reason
    ev = evaluate(crane, r.trajectory)
    assert ev.max_limit_violation <= 1e-3
    X = tip_to_xyz(ev.tip)
    rad = np.hypot(X[:, 0] - 3.0, X[:, 2] - 2.5)
    assert np.abs(rad - 0.7).max() < 0.01 and np.abs(X[:, 1]).max() < 1e-6
    np.testing.assert_allclose(X[[0, -1]], [[3.0, 0, 1.8], [3.0, 0, 3.2]], atol=1e-6)


def test_a_long_slew_move_is_never_slower_than_its_feasible_ruckig_move(s100f):
    """d01-p00 of the forwarder suite: the slew dominates and the pump does not bind. The N = 40
    grid loses about one interval against the exact jerk switches; the solver then returns the
    Ruckig move, which sits on the rest-to-rest bound, within every limit and clear of the
    headboard, represented exactly by its switch times."""
    from planner.tasks.suites import load_suite
    from planner.methods.ruckig import rest_to_rest
    info, moves = load_suite("forwarder-cycle")
    m = next(m for m in moves if m.id == "d01-p00")
    nlp = MoveNLP(s100f, "time", "free", N=40, obstacles=info["obstacles"])
    own = nlp.solve(m.start, m.goal, w0=nlp.default_guess(m.start, m.goal)[0])
    r = nlp.solve(m.start, m.goal)
    lb = lower_bound(s100f, m.start, m.goal)
    rk = rest_to_rest(s100f, s100f.ik(m.start, lb.tele_start), s100f.ik(m.goal, lb.tele_goal))
    assert own.ok and r.ok and rk.ok
    assert own.duration_s > 1.01 * rk.duration_s                 # the grid's loss
    assert r.stats["winner"] == "ruckig"
    assert r.duration_s == pytest.approx(rk.duration_s, rel=1e-12)
    assert r.duration_s >= lb.combined_s * (1 - 1e-4)
    ev = evaluate(s100f, r.trajectory)                            # pump flow included
    assert ev.max_limit_violation <= 1e-4 and "pump_flow" in ev.checked
    assert nlp.clears(r.trajectory)
    t = np.linspace(0, r.duration_s, 997)                        # exact between switch times
    np.testing.assert_allclose(r.trajectory.sample(t)[0], rk.trajectory.sample(t)[0], atol=1e-9)


def test_the_nlp_keeps_its_own_solution_when_ruckig_exceeds_the_pump(s100f):
    """p01-d03: the jerk-limited Ruckig move needs more oil than the pump gives; the NLP's
    solution (the pump as a constraint) is returned."""
    from planner.tasks.suites import load_suite
    info, moves = load_suite("forwarder-cycle")
    m = next(m for m in moves if m.id == "p01-d03")
    from planner.methods.ruckig import rest_to_rest
    r = MoveNLP(s100f, "time", "free", N=40, obstacles=info["obstacles"]).solve(m.start, m.goal)
    lb = lower_bound(s100f, m.start, m.goal)
    rk = rest_to_rest(s100f, s100f.ik(m.start, lb.tele_start), s100f.ik(m.goal, lb.tele_goal))
    assert rk.duration_s < r.duration_s                           # faster, but not feasible:
    assert evaluate(s100f, rk.trajectory, kinds=("pump_flow",)).max_limit_violation > 1e-3
    assert r.ok and "winner" not in r.stats
    assert len(r.trajectory.t) == 41
    assert evaluate(s100f, r.trajectory).max_limit_violation <= 1e-3


def test_layout_offsets_rows_and_parameters_by_name():
    """Layout against hand-counted offsets: blocks stacked column by column in the order added,
    bounds broadcast alike, constraint rows accumulated per name, parameters packed in the
    declared order whatever the keyword order."""
    import casadi as ca

    from planner.methods.nlp.transcription import Layout
    lay = Layout()
    par = lay.parameters(a=2, b=1)
    X = lay.add_var("X", (2, 3), np.array([[0.0], [1.0]]), 5.0)   # lo per row
    T = lay.add_var("T", 1, 0.1, 9.0)
    lay.add_con("c", X[:, 0] - par["a"], 0.0, 0.0)
    lay.add_con("d", T - par["b"], -ca.inf, 0.0)
    lay.add_con("c", X[0, 1:], -1.0, 1.0)
    assert lay.slice("X") == slice(0, 6) and lay.slice("T") == slice(6, 7) and lay.nw == 7
    lbw, ubw, lbg, ubg = lay.bounds()
    np.testing.assert_array_equal(lbw, [0, 1, 0, 1, 0, 1, 0.1])     # column-major
    np.testing.assert_array_equal(lay.rows("c"), [0, 1, 3, 4])
    np.testing.assert_array_equal(lay.rows("d"), [2])
    np.testing.assert_array_equal(lay.param_vector(b=7.0, a=[1.0, 2.0]), [1.0, 2.0, 7.0])
    w = np.arange(7.0)
    np.testing.assert_array_equal(lay.unpack(w, "X"), [[0, 2, 4], [1, 3, 5]])
    lay.pack(w, "X", np.zeros((2, 3)))
    assert w.tolist() == [0, 0, 0, 0, 0, 0, 6]
    with pytest.raises(ValueError, match="exists"):
        lay.add_var("X", 1, 0, 1)
    with pytest.raises(KeyError, match="known X, T"):
        lay.slice("Y")
    with pytest.raises(ValueError, match="missing"):
        lay.param_vector(a=[1.0, 2.0])


def test_layout_nlp_solves_to_the_analytic_optimum():
    """A small NLP written with Layout: min Σ (x_i − c_i)² subject to Σ x = 1, x ≥ 0.2 is the
    projection of c onto that set, known analytically (KKT): the component with the lowest
    c_i on its bound, the other two c_i − shift with the shift that makes the sum 1."""
    import casadi as ca

    from planner.methods.nlp.transcription import STATUS_OK, Layout
    lay = Layout()
    c = lay.parameters(c=3)["c"]
    x = lay.add_var("x", 3, 0.2, ca.inf)
    lay.add_con("sum", ca.sum1(x), 1.0, 1.0)
    S = ca.nlpsol("t", "ipopt", {"x": lay.w, "p": lay.P, "f": ca.sumsqr(x - c), "g": lay.g},
                  {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes"}})
    lbw, ubw, lbg, ubg = lay.bounds()
    cv = np.array([0.9, 0.7, -0.4])   # optimum (0.5, 0.3, 0.2): the bound strictly active
    sol = S(x0=np.full(3, 0.3), p=lay.param_vector(c=cv), lbx=lbw, ubx=ubw, lbg=lbg, ubg=ubg)
    assert S.stats()["return_status"] in STATUS_OK
    # third component sits on its bound 0.2; the other two share the rest equally shifted
    shift = (cv[0] + cv[1] - 0.8) / 2
    np.testing.assert_allclose(lay.unpack(sol["x"], "x").ravel(),
                               [cv[0] - shift, cv[1] - shift, 0.2], atol=1e-6)


def test_movenlp_layout_names_every_variable_once(s100f):
    """The move NLP's blocks tile the decision vector exactly (no gap, no overlap), in the
    documented order X, U, T, then the per-check-point slacks; its constraint blocks tile the
    constraints."""
    nlp = MoveNLP(s100f, "energy", "free", N=6)
    lay, n = nlp.layout, s100f.n
    assert lay.slice("X") == slice(0, 3 * n * 7)
    assert lay.slice("U") == slice(3 * n * 7, 3 * n * 7 + n * 6)
    assert lay.slice("T").start == lay.slice("U").stop == nlp._nx + n * 6
    names = lay.var_names
    spans = sorted((lay.slice(k).start, lay.slice(k).stop) for k in names)
    assert spans[0][0] == 0 and spans[-1][1] == nlp.nw == len(nlp.lbw)
    assert all(a[1] == b[0] for a, b in zip(spans, spans[1:]))
    rows = np.sort(np.concatenate([lay.rows(k) for k in lay.con_names]))
    np.testing.assert_array_equal(rows, np.arange(len(nlp.lbg)))
    assert len(lay.rows("dynamics")) == 3 * n * 6 and len(lay.rows("duration")) == 1


def test_energy_rounds_started_warm_reach_the_cold_answer(monkeypatch):
    """The energy NLP's later activity rounds start from the previous round's solution and
    multipliers: the same least energy as cold restarts (the oracle), within every limit, on
    a move whose mask grows over the rounds (under the seed pricing: the machine's counter-
    pressure settles this move's mask in the first round)."""
    from planner.methods.nlp.energy import stretch
    s100f = Crane.from_id("s100f", pricing="seed")
    a, b = (4.0, 2.0, 0.0), (7.5, 0.0, 2.0)
    rt = MoveNLP(s100f, "time", "free", N=12).solve(a, b)
    T = 1.2 * rt.duration_s
    en = MoveNLP(s100f, "energy", "free", N=12)
    rounds = []
    real = en.activity.still_optimal
    monkeypatch.setattr(en.activity, "still_optimal", lambda *a: rounds.append(1) or real(*a))
    got = {}
    for warm in ("0", "1"):
        monkeypatch.setenv("CRANE_PLANNER_NLP_WARM_ROUNDS", warm)
        r = en.solve(a, b, T_max=T, w0=en.guess_from(stretch(rt.trajectory, T)))
        assert r.ok, r.reason
        ev = evaluate(s100f, r.trajectory)
        assert ev.max_limit_violation <= 1e-3
        got[warm] = ev.energy_J
    assert len(rounds) >= 4           # the mask grew: later rounds were solved, both ways
    assert got["1"] == pytest.approx(got["0"], rel=5e-3)


def test_activity_round_ends_when_the_new_functions_already_hold():
    """An activity round is skipped when the functions it would switch on already meet their
    pressure rows at the solution: re-solving with them on returns the same optimum (the
    oracle: the re-solve itself); a function whose row is broken needs the round. (Seed
    pricing: under the machine's, whose LS threshold is the valve's opening, this move's
    first mask already holds every row — no broken function to show.)"""
    s100f = Crane.from_id("s100f", pricing="seed")
    from planner.geometry.paths import tip_to_xyz as xyz
    a, b = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)
    T = 1.2 * MoveNLP(s100f, "time", "free", N=12).solve(a, b).duration_s
    en = MoveNLP(s100f, "energy", "free", N=12)
    assert en.solve(a, b, T_max=T).ok
    lay = en.layout
    pars = dict(start=xyz(np.array(a)), goal=xyz(np.array(b)), T_max=T, lam=0.0,
                payload=s100f.spec.payload.total)

    def solve(mask, x0):
        sol = en.solver(x0=x0, p=lay.param_vector(**pars, activity=mask), lbx=en.lbw,
                        ubx=en.ubw, lbg=en.lbg, ubg=en.ubg)
        assert en.solver.stats()["return_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        return sol
    mask = en.activity.mask(en._last)
    sol = solve(mask, en._last)
    g = np.asarray(sol["g"]).ravel()[lay.rows("pressure")] - 1e3   # rows without the big M
    off = np.flatnonzero(mask == 0)
    node = off // (s100f.n + int((~en.acts.single).sum()))
    held = off[g[off] > 1e-3]
    broken = off[(g[off] < -1e-2) & (node > 0) & (node < en.N)]   # inner nodes: flow there
    broken = broken[np.argsort(g[broken])]                          # the most broken first
    assert held.size and broken.size
    new = mask.copy()
    new[held] = 1
    assert en.activity.still_optimal(sol, mask, new)
    again = solve(new, np.asarray(sol["x"]).ravel())
    assert float(again["f"]) == pytest.approx(float(sol["f"]), rel=1e-5)
    new[broken[0]] = 1
    assert not en.activity.still_optimal(sol, mask, new)
    assert float(solve(new, np.asarray(sol["x"]).ravel())["f"]) > float(sol["f"]) * (1 + 1e-5)
