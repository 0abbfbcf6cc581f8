"""Open-loop replay simulator: round trip with the feed-forward, flow sharing, dead band, gain
error, initial mismatch, end stops, the measured-data CSV, robustness envelopes."""
import json
import math
from dataclasses import replace

import numpy as np
import pytest

from planner import Crane
from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.simulation.plant import simulate_to_csv
from planner.simulation.recording import NOISE_DEFAULTS, read_measured_csv, write_measured_csv
from planner.simulation.replay import (Plant, default_perturbations, pressures, replay,
                                       robustness, stroke_rates)
from planner.trajectory import evaluate

from tests.conftest import random_configs


def _move(crane, seed=3, scale=0.5):
    q0, q1 = random_configs(crane, 2, seed=seed)
    r = rest_to_rest(crane, q0, q1, scale=scale)
    assert r.ok, r.reason
    return r.trajectory


def _mid(crane):
    L = crane.limit_arrays()
    return 0.5 * (L["q_min"] + L["q_max"])


def _hold(crane, u_row, T=0.5, rate=50.0):
    """Constant command u_row held for T seconds."""
    t = np.arange(int(round(T * rate)) + 1) / rate
    return t, np.tile(np.asarray(u_row, float), (t.size, 1))


def _pump_flow_from_strokes(crane, sim):
    """Pump flow drawn, reconstructed from the replayed strokes (independent of the simulator)."""
    x, _ = crane.stroke(sim.q)
    xd = np.diff(x, axis=0) / np.diff(sim.t)[:, None]
    a_a = np.array([j.actuator.area_a for j in crane.spec.joints])
    a_b = np.array([j.actuator.area_b for j in crane.spec.joints])
    single = np.array([j.actuator.acting == "single" for j in crane.spec.joints])
    q = np.where(xd > 0, a_a * xd, np.where(single, 0.0, -a_b * xd))
    return q.sum(axis=1)


# ----------------------------------------------------------------------------- round trip
@pytest.mark.parametrize("cid", ["s100f", "umea-lab", "cranab850"])
def test_nominal_replay_reproduces_the_plan(cid):
    crane = Crane.from_id(cid)
    traj = _move(crane, scale=0.5)
    ev = evaluate(crane, traj, rate=200)
    assert ev.peak_pump_flow < crane.spec.pump.max_flow     # pump keeps up: no sharing
    err_plan = {}
    for rate in (50.0, 100.0):
        ff = commands(crane, traj, rate)
        assert ff.ok and np.max(np.abs(ff.u)) > 0.1
        sim = replay(crane, ff.t, ff.u, traj.q[0])
        assert sim.meta["pump"]["short_s"] == 0.0
        np.testing.assert_allclose(sim.t, ff.t, atol=1e-12)
        # exact at the control instants (held rates integrated exactly)
        assert np.max(np.abs(sim.q - traj.sample(sim.t)[0])) < 1e-9
        np.testing.assert_allclose(sim.q[-1], traj.q[-1], atol=1e-9)
        # between them (at the plan's own samples): shrinks with the rate
        err_plan[rate] = np.max(np.abs(sim.sample(traj.t)[0] - traj.q))
        # the commands in effect are carried along
        np.testing.assert_array_equal(sim.u, ff.u)
    assert 0 < err_plan[100.0] < err_plan[50.0] / 3 and err_plan[50.0] < 1e-3


def test_differences_and_pressures_converge_to_the_plan():
    # seed pricing: the machine pricing's pressures switch with the sign of ẋ (the outlet's
    # counter-pressure), so at a reversal the max-norm error shrinks only ~2× per 4× rate
    s100f = Crane.from_id("s100f", pricing="seed")
    traj = _move(s100f, scale=0.5)
    err = {}
    for rate in (50.0, 200.0):
        ff = commands(s100f, traj, rate)
        sim = replay(s100f, ff.t, ff.u, traj.q[0])
        q, qd, qdd, _ = traj.sample(sim.t)
        pa, _ = pressures(s100f, sim)
        h = s100f.hydraulics(q, qd, qdd)
        err[rate] = (np.max(np.abs(sim.qd - qd)) / np.max(np.abs(qd)),
                     np.max(np.abs(sim.qdd - qdd)) / np.max(np.abs(qdd)),
                     np.max(np.abs(pa - h["p_a"])) / np.max(h["p_a"]))
        # the replay's own derivatives are consistent: quintic sampling returns them
        np.testing.assert_allclose(sim.sample(sim.t)[1], sim.qd, atol=1e-9)
    assert err[50.0][0] < 0.01 and err[200.0][0] < err[50.0][0] / 10   # velocity: 2nd order
    assert err[200.0][1] < err[50.0][1] / 3                            # acceleration: 1st
    assert err[50.0][2] < 0.1 and err[200.0][2] < err[50.0][2] / 3     # pressures follow


def test_replay_matches_the_feedforward_dead_band_convention(s100f):
    spec = s100f.spec
    joints = tuple(replace(j, actuator=replace(j.actuator, deadband=0.08)) for j in spec.joints)
    crane = Crane(replace(spec, joints=joints))
    traj = _move(crane, seed=5, scale=0.4)
    ff = commands(crane, traj, 50.0)
    moving = np.abs(ff.u) > 0
    assert np.all(np.abs(ff.u[moving]) > 0.08)            # dead band compensated
    sim = replay(crane, ff.t, ff.u, traj.q[0])
    assert np.max(np.abs(sim.q - traj.sample(sim.t)[0])) < 1e-9


def test_finer_step_is_exact_too(s100f):
    traj = _move(s100f, scale=0.5)
    ff = commands(s100f, traj, 50.0)
    coarse = replay(s100f, ff.t, ff.u, traj.q[0])
    fine = replay(s100f, ff.t, ff.u, traj.q[0], dt=0.02 / 4)
    assert len(fine.t) == 4 * (len(coarse.t) - 1) + 1
    np.testing.assert_allclose(fine.q[::4], coarse.q, atol=1e-9)
    odd = replay(s100f, ff.t, ff.u, traj.q[0], dt=0.03)   # steps straddle command instants
    np.testing.assert_allclose(odd.q, traj.sample(odd.t)[0], atol=2e-3)


def test_pump_limited_plan_is_slowed_and_never_exceeds_the_pump(s100f):
    traj = _move(s100f, scale=1.0)                          # Ruckig ignores the pump
    ff = commands(s100f, traj, 50.0)
    sim = replay(s100f, ff.t, ff.u, traj.q[0])
    qmax = s100f.spec.pump.max_flow
    assert evaluate(s100f, traj, rate=200).peak_pump_flow > qmax
    assert sim.meta["pump"]["short_s"] > 0 and sim.meta["pump"]["min_share"] < 1
    assert np.max(_pump_flow_from_strokes(s100f, sim)) <= qmax * (1 + 1e-6)


# ----------------------------------------------------------------------------- flow sharing
def test_flow_sharing_slows_every_pump_function_in_proportion(s100f):
    q0 = _mid(s100f)
    # boom up (extend, draws), jib, tele, slew: all drawing; demand far beyond the pump
    u_row = [0.8, 0.8, 0.8, 0.8]
    t, u = _hold(s100f, u_row, T=0.4)
    _, demand, share = stroke_rates(s100f, u)
    assert share[0] < 0.5                                    # saturated even at full pump
    disp = {}
    for scale in (1.0, 0.6):
        sim = replay(s100f, t, u, q0, Plant(pump_flow_scale=scale))
        assert not sim.meta["clipped"]
        qp = _pump_flow_from_strokes(s100f, sim)
        assert np.max(qp) <= scale * s100f.spec.pump.max_flow * (1 + 1e-6)
        np.testing.assert_allclose(qp, scale * s100f.spec.pump.max_flow, rtol=1e-6)
        disp[scale] = (sim.q[-1] - q0, s100f.stroke(sim.q[-1])[0] - s100f.stroke(q0)[0])
    np.testing.assert_allclose(disp[0.6][1] / disp[1.0][1], 0.6, rtol=1e-9)   # strokes: exact
    np.testing.assert_allclose(disp[0.6][0] / disp[1.0][0], 0.6, rtol=0.02)   # joints: ≈


def test_single_acting_lowering_draws_no_pump_flow(s100f):
    q0 = _mid(s100f)
    boom = s100f.names.index("boom")
    assert s100f.spec.joints[boom].actuator.acting == "single"
    u_row = np.array([0.8, -0.5, 0.8, 0.8])                  # boom lowers (retracts)
    t, u = _hold(s100f, u_row, T=0.4)
    a = s100f.spec.joints[boom].actuator
    expected = -a.flow_gain * 0.5 / a.area_a                 # valve-limited, not pump-limited
    for scale in (1.0, 0.3):
        xd, _, share = stroke_rates(s100f, u, Plant(pump_flow_scale=scale))
        assert share[0] < 1
        assert xd[0, boom] == pytest.approx(expected, rel=1e-12)
        sim = replay(s100f, t, u, q0, Plant(pump_flow_scale=scale))
        x = s100f.stroke(sim.q)[0][:, boom]
        assert (x[-1] - x[0]) / (t[-1] - t[0]) == pytest.approx(expected, rel=1e-9)
        assert np.max(_pump_flow_from_strokes(s100f, sim)) <= \
            scale * s100f.spec.pump.max_flow * (1 + 1e-6)


# ----------------------------------------------------------------------------- dead band, gain
def test_commands_inside_the_dead_band_do_not_move(s100f):
    q0 = _mid(s100f)
    t, u = _hold(s100f, [0.09, -0.09, 0.05, -0.099])
    sim = replay(s100f, t, u, q0, Plant(deadband=0.1))
    np.testing.assert_array_equal(sim.q, np.tile(q0, (len(t), 1)))   # exactly still
    assert np.all(sim.qd == 0)
    # just beyond it: flow = gain·(|u| − db)/(1 − db)
    t, u = _hold(s100f, [0.0, 0.0, 0.0, 0.2])
    sim = replay(s100f, t, u, q0, Plant(deadband=0.1))
    a = s100f.spec.joints[3].actuator
    x = s100f.stroke(sim.q)[0][:, 3]
    rate = a.flow_gain * (0.2 - 0.1) / 0.9 / a.area_a
    assert (x[-1] - x[0]) / (t[-1] - t[0]) == pytest.approx(rate, rel=1e-9)
    assert np.all(sim.q[:, :3] == q0[:3])


def test_flow_gain_error_scales_a_single_joint_move(s100f):
    q0 = _mid(s100f)
    q1 = q0.copy()
    jib = s100f.names.index("jib")
    q1[jib] += 0.6
    traj = rest_to_rest(s100f, q0, q1, scale=0.5).trajectory
    ff = commands(s100f, traj, 50.0)
    assert np.count_nonzero(np.any(ff.u != 0, axis=0)) == 1
    nom = replay(s100f, ff.t, ff.u, q0)
    hot = replay(s100f, ff.t, ff.u, q0, Plant(flow_gain_scale=1.02))
    dx_nom = s100f.stroke(nom.q[-1])[0] - s100f.stroke(q0)[0]
    dx_hot = s100f.stroke(hot.q[-1])[0] - s100f.stroke(q0)[0]
    assert dx_hot[jib] / dx_nom[jib] == pytest.approx(1.02, rel=1e-9)
    ratio = (hot.q[-1, jib] - q0[jib]) / (nom.q[-1, jib] - q0[jib])
    assert ratio == pytest.approx(1.02, abs=0.004)          # nonlinear stroke map: ≈ 2 %
    others = [i for i in range(s100f.n) if i != jib]
    np.testing.assert_array_equal(hot.q[:, others], np.tile(q0[others], (len(hot.t), 1)))


def test_initial_offset_propagates(s100f):
    traj = _move(s100f, scale=0.5)
    off = np.array([math.radians(1.0), -math.radians(1.0), math.radians(0.5), 0.02])
    ff = commands(s100f, traj, 50.0)
    sim = replay(s100f, ff.t, ff.u, traj.q[0], Plant(q0_offset=off))
    np.testing.assert_allclose(sim.q[0], traj.q[0] + off, atol=1e-15)
    r = robustness(s100f, traj, {"off": Plant(q0_offset=off)})
    e0 = np.linalg.norm(s100f.fk(traj.q[0] + off) - s100f.fk(traj.q[0]))
    assert r["perturbations"]["off"]["initial_tip_error_m"] == pytest.approx(e0, rel=1e-9)
    # a slew offset is carried unchanged to the end (stroke map linear, commands identical)
    sl = np.zeros(4)
    sl[0] = math.radians(1.0)
    sim = replay(s100f, ff.t, ff.u, traj.q[0], Plant(q0_offset=sl))
    nom = replay(s100f, ff.t, ff.u, traj.q[0])
    np.testing.assert_allclose(sim.q[:, 0] - nom.q[:, 0], sl[0], atol=1e-12)


def test_end_stop_clips_and_reports(s100f):
    L = s100f.limit_arrays()
    q0 = _mid(s100f)
    tele = s100f.names.index("tele")
    q0[tele] = L["q_max"][tele] - 0.05
    t, u = _hold(s100f, [0.0, 0.0, 0.0, 1.0], T=1.0)        # would run 0.6 m past the stop
    sim = replay(s100f, t, u, q0)
    assert sim.q[-1, tele] == pytest.approx(L["q_max"][tele], abs=1e-12)
    assert np.all(sim.q[:, tele] <= L["q_max"][tele] + 1e-12)
    iv = sim.meta["clipped"]["tele"]
    assert len(iv) == 1 and iv[0][1] == pytest.approx(t[-1]) and iv[0][0] < 0.2


def test_replay_rejects_bad_input(s100f):
    t, u = _hold(s100f, [0, 0, 0, 0])
    with pytest.raises(ValueError, match="expected t_u"):
        replay(s100f, t, u[:, :3], _mid(s100f))
    with pytest.raises(ValueError, match="increasing"):
        replay(s100f, t[::-1], u, _mid(s100f))
    with pytest.raises(ValueError, match="q0_offset"):
        replay(s100f, t, u, _mid(s100f), Plant(q0_offset=[0.1, 0.2]))
    with pytest.raises(ValueError, match="pump_flow_scale"):
        Plant(pump_flow_scale=0)


def test_plant_is_printable_and_json_ready():
    p = Plant(q0_offset=np.array([0.01, 0, 0, 0.02]), flow_gain_scale=1.02,
              pump_flow_scale=0.9)
    s = str(p)
    assert "gain×1.02" in s and "pump×0.9" in s and "q0+" in s
    assert str(Plant()) == "Plant(nominal)" and Plant().nominal and not p.nominal
    assert json.loads(json.dumps(p.to_dict()))["q0_offset"] == [0.01, 0, 0, 0.02]


# ----------------------------------------------------------------------------- measured CSV
@pytest.fixture(scope="module")
def sim_s100f(s100f):
    traj = _move(s100f, scale=0.5)
    ff = commands(s100f, traj, 50.0)
    return replay(s100f, ff.t, ff.u, traj.q[0])


def test_measured_csv_follows_the_contract(s100f, sim_s100f, tmp_path):
    path = tmp_path / "m.csv"
    cols = write_measured_csv(path, s100f, sim_s100f)
    names = s100f.names
    header = path.read_text().splitlines()[0].split(",")
    assert header == cols and header[0] == "t"
    assert {f"u_{j}" for j in names} | {f"q_{j}" for j in names} | \
        {f"p_{j}_{s}" for j in names for s in "ab"} == set(header[1:])
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (len(sim_s100f.t), 1 + 4 * s100f.n)
    col = {c: i for i, c in enumerate(header)}
    np.testing.assert_allclose(data[:, 0], sim_s100f.t, atol=1e-9)
    np.testing.assert_allclose(data[:, [col[f"q_{j}"] for j in names]], sim_s100f.q,
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(data[:, [col[f"u_{j}"] for j in names]], sim_s100f.u,
                               rtol=1e-9, atol=1e-12)
    pa, pb = pressures(s100f, sim_s100f)
    np.testing.assert_allclose(data[:, [col[f"p_{j}_a"] for j in names]], pa, rtol=1e-9)
    np.testing.assert_allclose(data[:, [col[f"p_{j}_b"] for j in names]], pb, rtol=1e-9)
    assert np.max(pa) > 1e6                                  # the lift cylinder carries load
    back = read_measured_csv(path, names)
    np.testing.assert_allclose(back["q"], sim_s100f.q, rtol=1e-9, atol=1e-12)
    assert back["p_a"] is not None and back["u"] is not None


def test_measured_csv_noise_is_deterministic_and_at_seed_001_levels(s100f, sim_s100f, tmp_path):
    a, b, c, clean = (tmp_path / f"{k}.csv" for k in "abcd")
    write_measured_csv(a, s100f, sim_s100f, noise=True, seed=7)
    write_measured_csv(b, s100f, sim_s100f, noise=True, seed=7)
    write_measured_csv(c, s100f, sim_s100f, noise=True, seed=8)
    write_measured_csv(clean, s100f, sim_s100f)
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()
    A, C, D = (np.loadtxt(p, delimiter=",", skiprows=1) for p in (a, c, clean))
    n = s100f.n
    np.testing.assert_array_equal(A[:, :1 + n], D[:, :1 + n])          # t and u exact
    dq = A[:, 1 + n:1 + 2 * n] - D[:, 1 + n:1 + 2 * n]
    dp = A[:, 1 + 2 * n:] - D[:, 1 + 2 * n:]
    assert np.std(dq[:, :3]) == pytest.approx(NOISE_DEFAULTS["angle"], rel=0.1)
    assert np.std(dq[:, 3]) == pytest.approx(0.002, rel=0.15)          # telescope: 2 mm
    assert np.std(dp) == pytest.approx(0.17e6, rel=0.1)
    assert not np.allclose(A, C)
    write_measured_csv(a, s100f, sim_s100f, noise=dict(pressure=0.0, angle=0.0, length=0.0))
    assert a.read_bytes() == clean.read_bytes()
    with pytest.raises(ValueError, match="unknown key"):
        write_measured_csv(a, s100f, sim_s100f, noise=dict(volts=1.0))


def test_read_measured_csv_rejects_bad_files(s100f, tmp_path):
    names = s100f.names
    p = tmp_path / "bad.csv"
    p.write_text("t,q_slew,q_boom,q_jib,q_tele\n0,0,0,0,0\n0.1,0,nan,0,0\n")
    with pytest.raises(ValueError, match="line 3, column 3"):
        read_measured_csv(p, names)
    p.write_text("t,q_slew,q_boom,q_jib,q_tele\n0,0,0,0,0\n0,0,0,0,0\n")
    with pytest.raises(ValueError, match="line 3, column 1"):
        read_measured_csv(p, names)
    p.write_text("t,q_slew,q_boom,q_jib,q_arm\n0,0,0,0,0\n0.1,0,0,0,0\n")
    with pytest.raises(ValueError, match="column 5: unknown joint 'arm'"):
        read_measured_csv(p, names)
    p.write_text("time,q_slew\n0,0\n")
    with pytest.raises(ValueError, match="first column must be 't'"):
        read_measured_csv(p, names)
    p.write_text("t,q_slew,q_boom,q_jib,q_tele,extra\n0,0,0,0,0,1\n0.1,0,0,0,0,2\n")
    r = read_measured_csv(p, names)                          # extra columns ignored
    assert r["p_a"] is None and r["u"] is None and r["q"].shape == (2, 4)


def test_simulate_to_csv_uses_the_trajectory_commands(s100f, tmp_path):
    traj = _move(s100f, scale=0.5)
    ff = commands(s100f, traj, 50.0)
    with_u = ff.attach(traj)
    out = tmp_path / "meas.csv"
    info = simulate_to_csv(s100f, with_u, out, noise=True, seed=3)
    assert info["commands"] == "trajectory" and info["max_tip_error_m"] < 1e-6
    info2 = simulate_to_csv(s100f, traj, tmp_path / "m2.csv", Plant(flow_gain_scale=1.05))
    assert info2["commands"].startswith("feedforward") and info2["final_tip_error_m"] > 1e-3
    json.dumps(info2)


# ----------------------------------------------------------------------------- robustness
def test_robustness_envelopes(s100f):
    traj = _move(s100f, scale=0.5)
    r = robustness(s100f, traj, series=True)
    json.dumps(r)
    names = set(default_perturbations(s100f))
    assert set(r["perturbations"]) == names and len(names) == 2 * s100f.n + 3 + 4 * s100f.n
    for v in r["perturbations"].values():
        assert math.isfinite(v["max_tip_error_m"]) and math.isfinite(v["final_tip_error_m"])
        assert v["final_tip_error_m"] <= v["max_tip_error_m"] + 1e-15
    assert r["nominal"]["max_tip_error_m"] < 1e-6           # feed-forward alone: exact
    assert r["score_m"] == max(v["max_tip_error_m"] for v in r["perturbations"].values())
    assert r["score_m"] == r["perturbations"][r["worst"]]["max_tip_error_m"]
    # ±1° start mismatch at ~5 m reach: ~0.1 m; the tele offset shows 1:1 at the tip
    assert 0.03 < r["score_m"] < 0.3
    assert r["perturbations"]["q0:tele+2cm"]["initial_tip_error_m"] == pytest.approx(0.02, rel=1e-6)
    env = np.array(r["envelope_m"])
    assert env.shape == (len(r["t"]),) and np.isclose(env.max(), r["score_m"])
    # 2 % gain error on a rest-to-rest move: the final drift is about 2 % of the tip travel
    travel = np.sum(np.linalg.norm(np.diff(s100f.fk(traj.q), axis=0), axis=1))
    for k in ("gain+2%", "gain-2%"):
        fin = r["perturbations"][k]["final_tip_error_m"]
        assert 0.002 * travel < fin < 0.025 * travel, (k, fin, travel)
    # this half-speed move leaves the pump 10 % headroom: a weaker pump changes nothing
    assert r["perturbations"]["pump-10%"]["max_tip_error_m"] < 1e-6


def test_robustness_sees_a_pump_shortage(s100f):
    traj = _move(s100f, scale=0.5)
    peak = evaluate(s100f, traj, rate=200).peak_pump_flow
    scale = 0.8 * peak / s100f.spec.pump.max_flow
    r = robustness(s100f, traj, [Plant(pump_flow_scale=scale)])
    (name, v), = r["perturbations"].items()
    assert name.startswith("Plant(pump×") and v["pump_short_s"] > 0
    assert v["max_tip_error_m"] > 1e-3
