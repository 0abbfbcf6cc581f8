"""Valve feed-forward: round trip commands -> predict_motion, dead band, saturation, areas by
direction, CSV; seed 003's pressure-based progress estimate."""
from dataclasses import replace

import numpy as np
import pytest

from planner import Crane
from planner.feedforward import commands, predict_motion, progress_estimator, round_trip
from planner.methods.ruckig import rest_to_rest
from planner.model.valves import valve_params
from planner.trajectory import Trajectory

from tests.conftest import random_configs

ROUND_TRIP_MACHINES = ["s100f", "umea-lab", "cranab850"]


def _with_valves(crane, **changes):
    """Same machine with every actuator's valve data changed (e.g. deadband=0.1)."""
    spec = crane.spec
    joints = tuple(replace(j, actuator=replace(j.actuator, **changes)) for j in spec.joints)
    return Crane(replace(spec, joints=joints))


def _move(crane, seed=3, scale=1.0):
    q0, q1 = random_configs(crane, 2, seed=seed)
    r = rest_to_rest(crane, q0, q1, scale=scale)
    assert r.ok, r.reason
    return r.trajectory


def _smoothstep(q0, q1, T, rate=100.0, names=()):
    q0, q1 = np.asarray(q0, float), np.asarray(q1, float)
    d = q1 - q0

    def f(t):
        s = (t / T)[:, None]
        return (q0 + d * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5),
                d * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T,
                d * (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2)
    return Trajectory.from_function(f, T, rate=rate, joint_names=tuple(names))


def _linear(crane, q0, v, T=0.5):
    """Constant joint velocity v from q0 (piecewise-linear trajectory, two samples)."""
    q0 = np.asarray(q0, float)
    return Trajectory(np.array([0.0, T]), np.vstack([q0, q0 + np.asarray(v) * T]),
                      interpolation="linear", joint_names=tuple(crane.names))


def _speed_up(traj, k):
    """The same path k times faster."""
    return Trajectory(traj.t / k, traj.q, traj.qd * k, traj.qdd * k * k,
                      joint_names=traj.joint_names, limits=traj.limits)


# ----------------------------------------------------------------------------- round trip
@pytest.mark.parametrize("cid", ROUND_TRIP_MACHINES)
def test_round_trip_reproduces_the_planned_positions(cid):
    crane = Crane.from_id(cid)
    traj = _move(crane)
    assert np.max(np.abs(traj.q[-1] - traj.q[0])) > 0.1   # a real move, not a trivial one
    err = {}
    for rate in (50.0, 100.0):
        r = round_trip(crane, traj, rate, hold="mean", substeps=8)
        assert r["feedforward"].ok                       # planned within the valves' flow
        assert np.max(np.abs(r["feedforward"].u)) > 0.2  # ... and the commands are not trivial
        # held commands deliver each period's stroke displacement: exact at control instants
        assert np.max(r["at_samples"]) < 1e-9
        err[rate] = np.max(r["overall"])                 # between instants: O(a·Δt²/8)
        assert err[rate] < 1e-3
        pred = r["prediction"]
        np.testing.assert_allclose(pred.q[-1], traj.q[-1], atol=1e-9)
    assert 0 < err[100.0] < err[50.0] / 3                # second order in the control period


@pytest.mark.parametrize("cid", ROUND_TRIP_MACHINES)
def test_sample_and_hold_lags_half_a_period_and_converges(cid):
    crane = Crane.from_id(cid)
    traj = _move(crane)
    e = {rate: round_trip(crane, traj, rate, hold="sample", substeps=1) for rate in (50., 100.)}
    peak = {k: np.max(v["overall"]) for k, v in e.items()}
    vmax = np.max(np.abs(traj.qd))
    for rate, v in peak.items():
        assert 0.2 * vmax / rate < v < 1.0 * vmax / rate   # about q̇·Δt/2
    assert peak[100.0] < 0.6 * peak[50.0]                  # first order
    # rest-to-rest: the lag is recovered when the move stops
    assert np.max(np.abs(e[100.0]["prediction"].q[-1] - traj.q[-1])) < 1e-4


def test_round_trip_through_direction_changes_inside_a_period():
    crane = Crane.from_id("umea-lab")
    L = crane.limit_arrays()
    mid = 0.5 * (L["q_min"] + L["q_max"])
    amp = 0.05 * (L["q_max"] - L["q_min"])
    w = 2 * np.pi / 3.37   # reversals (every 1.685 s) fall between control instants

    def f(t):
        s, c = np.sin(w * t)[:, None], np.cos(w * t)[:, None]
        return mid + amp * s * s, amp * 2 * s * c * w, amp * 2 * (c * c - s * s) * w * w
    traj = Trajectory.from_function(f, 3.0, rate=400, joint_names=tuple(crane.names))
    ff = commands(crane, traj, rate=50.0)
    assert ff.ok and np.any(ff.u > 0.1) and np.any(ff.u < -0.1)
    pred = predict_motion(crane, ff.t, ff.u, traj.q[0])
    np.testing.assert_allclose(pred.q, traj.sample(ff.t)[0], atol=1e-9)


# ----------------------------------------------------------------------------- dead band
def test_dead_band_is_compensated_and_inverted_exactly():
    nominal = Crane.from_id("umea-lab")
    db = 0.12
    crane = _with_valves(nominal, deadband=db)
    q0 = random_configs(nominal, 1, seed=5)[0]
    q1 = q0 + np.array([0.002, -0.003, 0.002, 0.004])   # a tiny move
    traj = rest_to_rest(nominal, q0, q1).trajectory
    u0 = commands(nominal, traj, rate=50.0).u            # no dead band: flow ∝ command
    moving = u0 != 0
    assert moving.any() and np.max(np.abs(u0)) < db      # the move needs less than the dead band
    ff = commands(crane, traj, rate=50.0)
    # compensated: every moving command sits beyond the dead band, at rest it is exactly 0
    assert np.all(np.abs(ff.u[moving]) >= db)
    assert np.all(ff.u[~moving] == 0)
    expect = np.sign(u0[moving]) * (db + (1 - db) * np.abs(u0[moving]))
    np.testing.assert_allclose(ff.u[moving], expect, rtol=1e-12)
    pred = predict_motion(crane, ff.t, ff.u, q0)
    np.testing.assert_allclose(pred.q, traj.sample(ff.t)[0], atol=1e-12)
    # the uncompensated commands vanish in the dead band: the crane does not move at all
    stuck = predict_motion(crane, ff.t, u0, q0)
    np.testing.assert_array_equal(stuck.q, np.broadcast_to(q0, stuck.q.shape))


def test_missing_flow_gain_is_named():
    crane = Crane.from_id("umea-lab")
    spec = crane.spec
    j = spec.joints[2]
    joints = spec.joints[:2] + (replace(j, actuator=replace(j.actuator, flow_gain=np.inf)),) \
        + spec.joints[3:]
    bad = Crane(replace(spec, joints=joints))
    with pytest.raises(ValueError, match="jib"):
        commands(bad, _move(crane))


# ----------------------------------------------------------------------------- saturation
def test_saturation_is_reported_with_joint_time_and_size():
    crane = Crane.from_id("umea-lab")
    L = crane.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    q1 = q0.copy()
    q1[1] += 0.3 * (L["q_max"][1] - L["q_min"][1])       # boom only
    traj = rest_to_rest(crane, q0, q1).trajectory
    assert commands(crane, traj).ok
    fast = _speed_up(traj, 3.0)
    ff = commands(crane, fast, rate=100.0, hold="sample")
    assert set(ff.saturated) == {"boom"}
    assert np.max(np.abs(ff.u)) == 1.0 and np.max(np.abs(ff.u_raw)) > 1.0
    # oracle: the hydraulic model's flow drawn by the boom actuator exceeds the valve's gain
    q, qd, qdd, _ = fast.sample(ff.t)
    need = crane.hydraulics(q, qd, qdd)["q_act"][:, 1]
    gain = crane.spec.joints[1].actuator.flow_gain
    over = need > gain
    ivs = ff.saturated["boom"]
    flagged = np.zeros_like(over)
    for s in ivs:
        flagged |= (ff.t >= s.t_start - 1e-12) & (ff.t < s.t_end - 1e-12)
        assert 0 < s.t_start < s.t_end <= fast.duration + 0.01
        assert s.peak_command > 1 and s.excess > 0
        assert "boom" in str(s)
    np.testing.assert_array_equal(flagged, over)
    assert max(s.excess for s in ivs) == pytest.approx(need.max() / gain - 1, rel=1e-9)
    # a clipped replay falls behind the plan
    pred = predict_motion(crane, ff.t, ff.u, q0)
    assert np.max(np.abs(pred.q[:, 1] - fast.sample(pred.t)[0][:, 1])) > 1e-2
    # the valve saturates in the replay too: unclipped commands move it no faster
    raw = predict_motion(crane, ff.t, ff.u_raw, q0)
    np.testing.assert_allclose(raw.q, pred.q, atol=1e-12)


# ----------------------------------------------------------------------------- areas by direction
@pytest.mark.parametrize("cid,joint", [("umea-lab", 1), ("umea-lab", 2), ("cranab850", 3),
                                       ("s100f", 2)])
def test_extending_and_retracting_use_piston_and_annulus_areas(cid, joint):
    crane = Crane.from_id(cid)
    L = crane.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    v = np.zeros(crane.n)
    v[joint] = 0.5 * L["qd_max"][joint]
    act = crane.spec.joints[joint].actuator
    assert act.acting == "double" and act.area_a != act.area_b
    dxdq = crane.stroke(q0)[1][joint]
    u_up = commands(crane, _linear(crane, q0, v), hold="sample").u[0, joint]
    u_dn = commands(crane, _linear(crane, q0, -v), hold="sample").u[0, joint]
    u_ext, u_ret = (u_up, u_dn) if dxdq * v[joint] > 0 else (u_dn, u_up)
    assert u_ext > 0 > u_ret
    assert abs(u_ext / u_ret) == pytest.approx(act.area_a / act.area_b, rel=1e-9)
    assert u_ext == pytest.approx(act.area_a * abs(dxdq * v[joint]) / act.flow_gain, rel=1e-9)
    # same as the flow the hydraulic model draws from the pump in both directions
    for vv, u in ((v, u_up), (-v, u_dn)):
        qa = crane.hydraulics(q0, vv, 0 * vv)["q_act"][joint]
        assert abs(u) == pytest.approx(qa / act.flow_gain, rel=1e-9)


def test_single_acting_lift_cylinder_meters_the_piston_side_both_ways():
    crane = Crane.from_id("s100f")
    assert crane.spec.joints[1].actuator.acting == "single"
    vp = valve_params(crane)
    assert vp.area_retract[1] == vp.area_extend[1] == crane.spec.joints[1].actuator.area_a
    L = crane.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    v = np.zeros(crane.n)
    v[1] = 0.2
    u_up = commands(crane, _linear(crane, q0, v), hold="sample").u[0, 1]
    u_dn = commands(crane, _linear(crane, q0, -v), hold="sample").u[0, 1]
    assert u_up == pytest.approx(-u_dn, rel=1e-12) and u_up != 0
    traj = _move(crane, seed=8)
    ff = commands(crane, traj)
    assert np.any(ff.u[:, 1] > 0) or np.any(ff.u[:, 1] < 0)
    pred = predict_motion(crane, ff.t, ff.u, traj.q[0])
    np.testing.assert_allclose(pred.q, traj.sample(ff.t)[0], atol=1e-9)


# ----------------------------------------------------------------------------- CSV
def test_feedforward_csv_round_trip(tmp_path):
    crane = Crane.from_id("cranab850")
    traj = _move(crane)
    ff = commands(crane, traj, rate=50.0)
    path = tmp_path / "ff.csv"
    out = ff.to_csv(path, traj)
    header = path.read_text().splitlines()[0].split(",")
    assert header[0] == "t" and [f"u_{j}" for j in crane.names] == header[-crane.n:]
    back = Trajectory.from_csv(path)
    np.testing.assert_allclose(back.t, ff.t, atol=1e-9)
    np.testing.assert_allclose(back.u, ff.u, atol=1e-9)
    np.testing.assert_allclose(back.q, traj.sample(ff.t)[0], atol=1e-8)
    assert out.meta["feedforward"]["rate"] == 50.0


# ----------------------------------------------------------------------------- progress estimate
def test_progress_estimate_recovers_positions_on_a_monotone_motion():
    crane = Crane.from_id("umea-lab")
    L = crane.limit_arrays()
    mid, span = 0.5 * (L["q_min"] + L["q_max"]), L["q_max"] - L["q_min"]
    d = np.array([0.0, 0.2, 0.0, 0.0]) * span
    traj = _smoothstep(mid - d, mid + d, 20.0, names=crane.names)
    pe = progress_estimator(crane, traj)
    assert pe.monotone and not pe.ambiguous and pe.non_monotone == []
    # oracle: the chosen ΔP, recomputed from the hydraulic model, is monotone along the motion
    t = np.linspace(0, traj.duration, 2001)
    q, qd, qdd, _ = traj.sample(t)
    h = crane.hydraulics(q, qd, qdd)
    dp = (h["p_a"] - h["p_b"])[:, pe.index]
    assert np.all(pe.direction * np.diff(dp) >= -1e-3 * np.ptp(dp))
    est = pe.estimate(dp)
    assert est.shape == q.shape and pe.estimate(dp[100]).shape == (crane.n,)
    err = np.max(np.abs(est - q), axis=0)
    assert err[1] < 5e-3                                   # the moving boom, within 0.3°
    assert np.max(err) < 5e-3 and max(pe.rms.values()) < 2e-3


def test_progress_estimate_reports_where_pressure_is_not_monotone():
    # seed pricing: the machine pricing's pressures step at the start and end of a motion
    # (friction and the outlet's counter-pressure switch on with ẋ), so no half is monotone
    crane = Crane.from_id("umea-lab", pricing="seed")
    L = crane.limit_arrays()
    mid, span = 0.5 * (L["q_min"] + L["q_max"]), L["q_max"] - L["q_min"]
    d = np.array([0.0, 0.2, 0.1, 0.0]) * span
    T = 8.0
    out = _smoothstep(mid - d, mid + d, T)
    t = np.concatenate([out.t, out.t[1:] + T])
    q = np.vstack([out.q, out.q[::-1][1:]])                  # there and back
    qd = np.vstack([out.qd, -out.qd[::-1][1:]])
    qdd = np.vstack([out.qdd, out.qdd[::-1][1:]])
    traj = Trajectory(t, q, qd, qdd, joint_names=tuple(crane.names))
    pe = progress_estimator(crane, traj)
    assert not pe.monotone and pe.non_monotone
    assert len(pe.reversals) == len(pe.non_monotone) and min(pe.reversals) > 0
    edges = np.array(pe.non_monotone).ravel()
    assert np.min(np.abs(edges - T)) < 0.1                   # the reversal is where it turns
    assert sum(b - a for a, b in pe.non_monotone) > 0.4 * 2 * T
    assert sum(b - a for a, b in pe.ambiguous) > 0.9 * 2 * T  # every value is taken twice
    # the same half on its own is monotone
    assert progress_estimator(crane, out).monotone
