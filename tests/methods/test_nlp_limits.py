"""The move NLP's limits between check points (planner.methods.nlp.limits), each against an
independent judge: the numpy pump draw of planner.model.flows, evaluate() on a 1 kHz resampling,
and the Ruckig optimum for a pure joint-space move."""
import numpy as np
import pytest

from planner.methods.nlp import MoveNLP
from planner.methods.nlp.limits import PUMP_SMOOTH, pump_draw
from planner.methods.ruckig import rest_to_rest
from planner.model.flows import actuator_table
from planner.model.flows import pump_draw as exact_draw
from planner.trajectory import evaluate

JOINT_KINDS = ("position", "velocity", "acceleration", "jerk")


def _configs(crane, n, seed):
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + 0.1 * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - 0.1 * (L["q_max"] - L["q_min"])
    return lo + rng.random((n, crane.n)) * (hi - lo)


def test_smooth_pump_draw_is_never_below_the_exact_draw(crane):
    """The NLP's smooth draw against the model's numpy draw (planner.model.flows): never below
    it, at most PUMP_SMOOTH of Q_max above it."""
    acts, Qm = actuator_table(crane.spec), crane.spec.pump.max_flow
    rng = np.random.default_rng(3)
    L = crane.limit_arrays()
    for q in _configs(crane, 40, 4):
        v = rng.uniform(L["qd_min"], L["qd_max"]) * rng.choice([0.0, 0.01, 1.0], crane.n)
        _, dxdq = crane.stroke(q[None])
        exact = exact_draw(crane.spec, dxdq[0] * v).sum() / Qm
        smooth = float(pump_draw(crane.f_stroke(q)[1], v, acts, Qm))
        assert exact - 1e-12 <= smooth <= exact + PUMP_SMOOTH + 1e-12


def test_a_pump_limited_solution_keeps_the_pump_flow_on_a_fine_resampling(s100f):
    """A move the pump limits, solved by the NLP itself (not the Ruckig swap): its peak pump
    flow on evaluate()'s 1 kHz resampling is within Q_max, and close to it (the limit binds)."""
    m = MoveNLP(s100f, "time", N=40, cache="off")
    r = m.solve((7.276, 0.793, -0.506), (7.259, 5.691, -0.124))
    assert r.ok, r.reason
    assert r.stats.get("winner", "nlp") == "nlp"
    ev = evaluate(s100f, r.trajectory)
    Qm = s100f.spec.pump.max_flow
    assert ev.peak_pump_flow <= Qm * (1 + 1e-6)
    assert ev.peak_pump_flow >= 0.95 * Qm            # the pump is what limits this move
    assert ev.max_limit_violation <= 1e-6


@pytest.fixture(scope="module")
def joint_move(umea_lab):
    """A pure joint-space move on umea-lab (no pump), solved by the NLP from its own default
    guess with the exact-Ruckig swap left out (a primal guess given)."""
    q0, q1 = _configs(umea_lab, 2, 17)
    m = MoveNLP(umea_lab, "time", N=40, pump=False, cache="off")
    w0, _ = m.default_guess(umea_lab.tip(q0), umea_lab.tip(q1), (q0, q1))
    r = m.solve(w0=w0, q_start=q0, q_goal=q1)
    assert r.ok, r.reason
    return q0, q1, r, m


def test_velocity_holds_between_the_knots_and_reaches_the_limit(umea_lab, joint_move):
    """evaluate() at 1 kHz finds no velocity excess between the knots, and the fastest joint
    cruises within 0.05 % of its limit (the earlier uniform tightening j_max·h²/32 kept it
    0.19 % below on this move)."""
    q0, q1, r, m = joint_move
    ev = evaluate(umea_lab, r.trajectory, kinds=JOINT_KINDS)
    assert ev.violations["velocity"] <= 1e-9
    assert ev.max_limit_violation <= 1e-6
    t = r.trajectory.resample(1000.0)
    qd = r.trajectory.sample(t)[1]
    L = umea_lab.limit_arrays()
    reach = np.max(np.maximum(qd / L["qd_max"], qd / L["qd_min"]), axis=0)
    assert reach.max() >= 0.9995


def test_joint_space_duration_within_one_percent_of_ruckig(umea_lab, joint_move):
    """The NLP's own duration on a pure joint-space move, no pump, against the time-optimal
    jerk-limited move (Ruckig): never below it, at most 1 % above it."""
    q0, q1, r, m = joint_move
    opt = rest_to_rest(umea_lab, q0, q1).duration_s
    assert opt * (1 - 1e-6) <= r.duration_s <= 1.01 * opt
    # and the solver's returned result is the exact Ruckig move when that is faster
    r2 = m.solve(q_start=q0, q_goal=q1)
    assert r2.ok and r2.duration_s <= r.duration_s + 1e-9
    assert np.allclose(r2.trajectory.q[0], q0) and np.allclose(r2.trajectory.q[-1], q1)


def test_fatrop_and_ipopt_agree_on_a_pump_limited_move(s100f):
    """The stage-wise FATROP solve against IPOPT on the same formulation: the same duration
    (to 1e-4 relative) and a trajectory that passes evaluate() (pump included)."""
    a, b = (7.276, 0.793, -0.506), (7.259, 5.691, -0.124)
    res = {s: MoveNLP(s100f, "time", N=20, cache="off", solver=s).solve(a, b)
           for s in ("ipopt", "fatrop")}
    assert all(r.ok for r in res.values()), {s: r.reason for s, r in res.items()}
    assert res["fatrop"].duration_s == pytest.approx(res["ipopt"].duration_s, rel=1e-4)
    assert evaluate(s100f, res["fatrop"].trajectory).max_limit_violation <= 1e-6


def test_stage_order_puts_states_controls_dynamics_and_path_rows_stage_by_stage():
    """Layout.stage_order on a two-stage toy: variables x0, u0, x1; rows dyn0, path0, path1."""
    import casadi as ca
    from planner.methods.nlp import Layout
    lay = Layout()
    X = lay.add_var("X", (2, 2), -1, 1, stage=0)      # w 0..3: x0 = (0, 1), x1 = (2, 3)
    U = lay.add_var("U", (1, 1), -1, 1, stage=1)      # w 4: u0
    lay.add_con("path", X[:, 1], -1, 1, stage=(1, 1))   # g 0, 1
    lay.add_con("path", U[0], -1, 1, stage=(0, 1))      # g 2
    lay.add_con("dyn", X[:, 1] - X[:, 0] - U[0], 0, 0, stage=(0, 0))   # g 3, 4
    wp, gp = lay.stage_order()
    assert wp.tolist() == [0, 1, 4, 2, 3]
    assert gp.tolist() == [3, 4, 2, 0, 1]
    lay.add_con("free", ca.sumsqr(X), 0, 1)
    with pytest.raises(ValueError):
        lay.stage_order()
