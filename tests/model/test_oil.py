"""The oil spring written once (planner/model/twin/oil.py) and the feed-forward that fills it
(``planner.feedforward.commands(..., oil=True)``, issue 30)."""
from dataclasses import replace

import numpy as np
import pytest

from planner.feedforward import commands, fills_oil, predict_motion
from planner.model import Crane
from planner.problems import crane_ids
from planner.model.dynamics_spec import P_ATM
from planner.model.twin import Twin
from planner.model.twin.oil import oil_stiffness, oil_stroke
from planner.trajectory import Trajectory, evaluate
from tests.methods.test_twin_judge import _move


def _with(crane, **dyn):
    return Crane(replace(crane.spec, dynamics=replace(crane.spec.dynamics, **dyn)))


def test_the_stiffness_is_bulk_modulus_over_volume(s100f):
    """Oracle by hand: κ = β/V with V the hose plus the swept volume at the stroke (the spec's
    hose volumes, areas and the cylinder's ends); and the twin's oil-spring frequencies, which
    are built on it, are √(k·(dx/dq)²/M)/2π with k = A_a²·κ_a + A_b²·κ_b."""
    tw = Twin(s100f)
    per, sc = tw.params.per, tw.params.scalar
    L = s100f.limit_arrays()
    q = L["q_min"] + 0.4 * (L["q_max"] - L["q_min"])
    x = np.asarray(s100f.stroke(q[None])[0]).ravel()
    beta = s100f.spec.dynamics.bulk_modulus
    for i, j in enumerate(s100f.spec.joints):
        hose_a, hose_b = s100f.spec.dynamics.joints[j.name].hose_volume
        va = hose_a + per["swept"][i] * per["area_a"][i] * (x[i] - per["x_lo"][i])
        vb = hose_b + per["swept"][i] * per["area_b"][i] * (per["x_hi"][i] - x[i])
        ka, kb = oil_stiffness(per, sc, i, x[i], 5e6, 2e6)
        assert ka[0] == pytest.approx(beta / va, rel=1e-12)
        assert kb[0] == pytest.approx(beta / vb, rel=1e-12)
    f = tw.oil_spring_frequencies(q)
    assert np.all(f > 0.3) and np.all(f < 30.0)       # hydraulic modes of a forwarder crane


def test_the_oil_stroke_is_the_integral_of_the_compliance(s100f):
    """Analytic oracle: with β(p) = β·(p + p_atm)/(p_ref + p_atm) (aerated oil, the law's
    linear part) and the stroke held, the oil that raises side a from p0 to p1 is
    V_a·(p_ref + p_atm)/β·ln((p1 + p_atm)/(p0 + p_atm)); as a stroke, divided by A_a. Side b
    rising takes oil out: the stroke goes the other way."""
    crane = _with(s100f, bulk_low=0.05, bulk_high=20.0, bulk_reference_pressure=8e6)
    prm = Twin(crane).params
    per, sc = prm.per, prm.scalar
    M = 4001
    x = np.tile(0.5 * (per["x_lo"] + per["x_hi"]), (M, 1))
    p0, p1 = 1e6, 15e6
    ramp = np.linspace(p0, p1, M)[:, None] * np.ones(crane.n)
    held = np.full((M, crane.n), 3e6)
    i = 2                                         # the jib: double acting
    va = per["hose_a"][i] + per["area_a"][i] * (x[0, i] - per["x_lo"][i])
    vb = per["hose_b"][i] + per["area_b"][i] * (per["x_hi"][i] - x[0, i])
    ln = np.log((p1 + P_ATM) / (p0 + P_ATM)) * (sc["beta_pref"] + P_ATM) / sc["beta"]
    dx_a = oil_stroke(prm, x, ramp, held)
    dx_b = oil_stroke(prm, x, held, ramp)
    assert dx_a[-1, i] == pytest.approx(va * ln / per["area_a"][i], rel=1e-6)
    assert dx_b[-1, i] == pytest.approx(-vb * ln / per["area_b"][i], rel=1e-6)
    assert dx_a[0, i] == 0.0 and np.all(np.diff(dx_a[:, i]) > 0)
    # the boom is single acting: its vented rod side takes no oil
    assert oil_stroke(prm, x, held, ramp)[-1, 1] == 0.0


def test_filling_the_oil_makes_the_twin_follow_the_plan_and_pay_its_price(s100f):
    """The plain feed-forward lags and rings the oil springs (the twin: the model's dynamic
    plant); filled, the twin follows the plan closer on every moving joint (its largest error
    at least 10 % smaller) and its pump work is the quasi-static price within 1 % (the plain
    one's is not: 4.9 % over on this move)."""
    traj = _move(s100f)
    tw = Twin(s100f)
    w_eval = evaluate(s100f, traj).energy_J
    res = {}
    for oil in (False, True):
        ff = commands(s100f, traj, 50.0, oil=oil)
        t_u = np.append(ff.t, ff.t[-1] + 0.02)
        u = np.vstack([ff.u, np.zeros((1, s100f.n))])
        run = tw.simulate(t_u, u, traj.q[0], t_end=float(t_u[-1]) + 2.0)
        assert run.ok
        err = np.abs(run.q - traj.sample(np.minimum(run.t, traj.t[-1]))[0])
        res[oil] = (err.max(axis=0), None, tw.pump_energy(run) / w_eval)
    moving = np.ptp(traj.q, axis=0) > 0
    assert np.all(res[True][0][moving] < 0.9 * res[False][0][moving])
    assert abs(res[True][2] - 1) < 0.01 < abs(res[False][2] - 1)


def test_a_closed_valve_stays_closed_and_none_is_reversed(s100f):
    traj = _move(s100f)
    plain = commands(s100f, traj, 50.0)
    oil = commands(s100f, traj, 50.0, oil=True)
    assert oil.meta["oil"] and not plain.meta["oil"]
    assert np.all(oil.u[plain.u == 0] == 0)
    assert np.all(oil.u * plain.u >= 0)
    assert np.max(np.abs(oil.u - plain.u)) > 0.02           # it does change the commands
    # the stored entry says which it carries
    assert oil.attach(traj).meta["feedforward"]["oil"]


def test_stiff_oil_needs_no_filling(s100f):
    """Limit: oil 10⁶ × stiffer has (almost) no compliance: the filled commands are the plain
    ones."""
    stiff = _with(s100f, bulk_modulus=s100f.spec.dynamics.bulk_modulus * 1e6)
    traj = _move(stiff)
    plain = commands(stiff, traj, 50.0)
    oil = commands(stiff, traj, 50.0, oil=True)
    assert np.max(np.abs(oil.u - plain.u)) < 1e-5


def test_no_dynamics_no_oil(s100f):
    crane = Crane(replace(s100f.spec, dynamics=None))
    assert not fills_oil(crane) and fills_oil(s100f)
    with pytest.raises(ValueError, match=r"oil=True: crane 's100f' has no \[dynamics\]"):
        commands(crane, _move(crane), 50.0, oil=True)


def test_the_move_delivers_the_plans_stroke_and_all_its_oil(s100f):
    """Kinematic oracle (the valve model's own inverse, predict_motion): over the whole move
    the filled commands deliver each moving joint's planned stroke plus the oil its chambers
    take from the plan's start to its end — also the oil of periods whose filled command was
    closed (spread over the joint's open periods), so a joint lands where the plant's
    compressed oil puts it on the plan."""
    traj = _move(s100f)
    ff = commands(s100f, traj, 50.0, oil=True)
    assert ff.ok
    pred = predict_motion(s100f, ff.t, ff.u, traj.q[0])
    x_end = np.asarray(s100f.stroke(pred.q[-1:])[0]).ravel()
    x_plan = np.asarray(s100f.stroke(traj.q[-1:])[0]).ravel()
    ev = evaluate(s100f, traj)
    oil = oil_stroke(Twin(s100f).params, ev.hyd["x"], ev.hyd["p_a"], ev.hyd["p_b"])[-1]
    moving = np.ptp(traj.q, axis=0) > 0
    assert np.any(np.abs(oil[moving]) > 1e-4)            # there is oil to deliver
    np.testing.assert_allclose(x_end[moving] - x_plan[moving], oil[moving], rtol=1e-3,
                               atol=1e-7)


def _gentle(crane, T):
    """A min-jerk move of every joint over 15 % of its range, from 55 % of it, in T s."""
    L = crane.limit_arrays()
    q0 = L["q_min"] + 0.55 * (L["q_max"] - L["q_min"])
    d = -0.15 * (L["q_max"] - L["q_min"])
    t = np.linspace(0.0, T, 201)
    s = t / T
    blend = np.stack([10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5,
                      (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T,
                      (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2])
    return Trajectory(t, q0 + np.outer(blend[0], d), np.outer(blend[1], d),
                      np.outer(blend[2], d), joint_names=tuple(crane.names))


@pytest.mark.parametrize("crane_id", [c for c in crane_ids()
                                      if fills_oil(Crane.from_id(c))])
def test_every_machine_with_oil_pays_the_price_and_follows_closer(crane_id):
    """Contract, every machine with [dynamics]: on a move within its limits (the duration grown
    until evaluate() finds none exceeded) the filled commands open no closed valve and reverse
    none; on the twin they follow the plan closer than the plain ones and the pump work is
    evaluate()'s within 4 % (the plain feed-forward's is up to 31 % off: cat215b)."""
    crane = Crane.from_id(crane_id)
    T = 4.0
    while evaluate(crane, _gentle(crane, T)).max_limit_violation > 0:
        T *= 1.5
    traj = _gentle(crane, T)
    tw = Twin(crane)
    w_eval = evaluate(crane, traj).energy_J
    got = {}
    for oil in (False, True):
        ff = commands(crane, traj, 50.0, oil=oil)
        got[oil] = ff.u
        run = tw.simulate(np.append(ff.t, ff.t[-1] + 0.02),
                          np.vstack([ff.u, np.zeros((1, crane.n))]), traj.q[0],
                          t_end=float(ff.t[-1]) + 2.0)
        assert run.ok
        tip = crane.fk(run.q)
        plan = crane.fk(traj.sample(np.minimum(run.t, traj.t[-1]))[0])
        got[oil, "track"] = np.linalg.norm(tip - plan, axis=1).max()
        got[oil, "price"] = tw.pump_energy(run) / w_eval
    assert np.all(got[True][got[False] == 0] == 0) and np.all(got[True] * got[False] >= 0)
    assert got[True, "track"] < got[False, "track"]
    assert abs(got[True, "price"] - 1) < 0.04
    assert abs(got[True, "price"] - 1) <= abs(got[False, "price"] - 1) + 0.005
