"""Ruckig rest-to-rest moves: optimal duration (analytic oracle), all limits incl. jerk."""
import numpy as np
import pytest

from planner import Crane
from planner.bounds import lower_bound, rest_to_rest_time
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import evaluate

from tests.conftest import MACHINES, random_configs


@pytest.mark.parametrize("cid", MACHINES)
def test_duration_is_the_slowest_joints_minimum_and_limits_hold(cid):
    crane = Crane.from_id(cid)
    L = crane.limit_arrays()
    qs = random_configs(crane, 6, seed=11)
    for q0, q1 in zip(qs[:3], qs[3:]):
        r = rest_to_rest(crane, q0, q1)
        assert r.ok
        d = q1 - q0
        v = np.where(d >= 0, L["qd_max"], -L["qd_min"])
        expect = np.max(rest_to_rest_time(d, v, L["qdd_max"], L["qddd_max"]))
        assert r.duration_s == pytest.approx(expect, rel=1e-6)
        ev = evaluate(crane, r.trajectory)
        assert ev.max_limit_violation <= 1e-5, ev
        np.testing.assert_allclose(r.trajectory.q[[0, -1]], [q0, q1], atol=1e-9)
        np.testing.assert_allclose(r.trajectory.qd[[0, -1]], 0.0, atol=1e-9)


def test_between_bound_optimal_ends_it_meets_the_bound():
    crane = Crane.from_id("s100f")
    a, b = (6.0, -1.0, 0.0), (3.0, 2.5, 1.5)
    lb = lower_bound(crane, a, b)
    r = rest_to_rest(crane, crane.ik(a, lb.tele_start), crane.ik(b, lb.tele_goal))
    assert r.duration_s == pytest.approx(lb.rest_to_rest_s, rel=1e-6)


def test_out_of_limit_configuration_is_refused():
    crane = Crane.from_id("umea-lab")
    q = np.array([0.0, 0.5, -1.0, 0.5])
    bad = q.copy()
    bad[1] = 2.0
    r = rest_to_rest(crane, q, bad)
    assert r.status == "invalid" and "boom" in r.reason


def test_state_to_state_sampling_reproduces_the_profile():
    """The shared Ruckig wrapper: a 1-DOF move from a moving state to rest. Oracle: the samples
    at the switch times lie on Ruckig's own profile, the sampled motion integrates (trapezoid
    on the fine grid) to the travelled distance, and the limits hold at every sample."""
    from planner.methods.ruckig import sample, state_to_state, switch_times
    tr = state_to_state(([0.0], [0.5], [0.2]), ([1.0], [0.0], [0.0]), [1.0], [-1.0], [2.0],
                        [10.0])
    t, q, qd, qdd = sample(tr, 1000.0)
    sw = switch_times(tr)
    assert sw[0] == 0.0 and sw[-1] == pytest.approx(tr.duration) and np.all(np.diff(sw) > 0)
    assert np.abs(t[:, None] - sw[None, :]).min(axis=0).max() < 1e-4  # every switch sampled
    k = np.argmin(np.abs(t[:, None] - sw[None, :]), axis=0)
    np.testing.assert_allclose(q[k, 0], [tr.at_time(x)[0][0] for x in t[k]], atol=1e-12)
    assert np.all(np.diff(t) >= 1e-4 - 1e-15) and t[-1] == tr.duration
    assert q[-1, 0] == pytest.approx(1.0, abs=1e-9) and qd[-1, 0] == pytest.approx(0, abs=1e-9)
    assert np.trapezoid(qd[:, 0], t) == pytest.approx(1.0, abs=1e-5)
    assert qd.max() <= 1.0 + 1e-9 and np.abs(qdd).max() <= 2.0 + 1e-9


def test_state_to_state_relaxed_raises_the_limits_until_a_move_exists():
    """Arriving at 0.9 m/s² with only 0.5 m/s² allowed is impossible for Ruckig; the relaxed
    wrapper scales acceleration and jerk by 1.25 until 0.9 fits: 1.25³ = 1.95 ≥ 1.8."""
    from planner.methods.ruckig import state_to_state, state_to_state_relaxed
    cur, tgt = ([0.0], [0.0], [0.0]), ([1.0], [0.3], [0.9])
    with pytest.raises(RuntimeError, match="Ruckig"):
        state_to_state(cur, tgt, [1.0], [-1.0], [0.5], [5.0])
    tr, scale = state_to_state_relaxed(cur, tgt, [1.0], [-1.0], [0.5], [5.0])
    assert scale == pytest.approx(1.25 ** 3) and tr.at_time(tr.duration)[2][0] == \
        pytest.approx(0.9)


@pytest.mark.parametrize("cid", MACHINES)
def test_vectorised_sampling_equals_ruckig_at_time(cid):
    """The numpy sampling of the jerk profile (JerkProfile.at, used by rest_to_rest and
    sample) against Ruckig's own ``at_time``, sample by sample, to 1e-12: random moves between
    moving states (some starting above the velocity limit, so Ruckig brakes first), at random
    times, at every switching time and past the end (Ruckig keeps constant acceleration)."""
    from planner.methods.ruckig import JerkProfile, _switch_list, state_to_state
    crane = Crane.from_id(cid)
    L = crane.limit_arrays()
    J = np.where(np.isfinite(L["qddd_max"]), L["qddd_max"], 50.0)
    rng = np.random.default_rng(5)
    qs = random_configs(crane, 8, seed=7)
    braked = 0
    for q0, q1 in zip(qs[:4], qs[4:]):
        v0 = rng.uniform(1.3 * L["qd_min"], 1.3 * L["qd_max"])   # some beyond the limits
        a0 = rng.uniform(-0.5, 0.5, crane.n) * L["qdd_max"]
        v1 = rng.uniform(0.3 * L["qd_min"], 0.3 * L["qd_max"])
        tr = state_to_state((q0, v0, a0), (q1, v1, np.zeros(crane.n)), L["qd_max"],
                            L["qd_min"], L["qdd_max"], J)
        braked += any(p.brake is not None and p.brake.duration > 0 for p in tr.profiles[0])
        prof = JerkProfile(tr)
        t = np.concatenate([prof.switch_times(), rng.uniform(0, 1.1 * tr.duration, 300),
                            [tr.duration * 1.05]])
        got = prof.at(t)
        want = [np.array([tr.at_time(x)[i] for x in t]) for i in range(3)]
        for merge in (0.0, 1e-6, 1e-2):   # the table-free switch list rest_to_rest reads
            assert _switch_list(tr, merge) == prof.switch_times(merge).tolist()
        for g, w in zip(got, want):
            np.testing.assert_allclose(g, w, rtol=0, atol=1e-12)
    assert braked > 0  # the brake pre-trajectory was exercised


def test_rest_to_rest_at_the_switch_times_only_is_the_same_motion(umea_lab):
    """sample_rate=None samples the switching times only; the motion is cubic between them, so
    the trajectory's quintic interpolation equals the 200 Hz sampling (and Ruckig) everywhere."""
    q0, q1 = random_configs(umea_lab, 2, seed=21)
    coarse = rest_to_rest(umea_lab, q0, q1, sample_rate=None)
    fine = rest_to_rest(umea_lab, q0, q1)
    assert coarse.ok and fine.ok and coarse.duration_s == fine.duration_s
    np.testing.assert_array_equal(coarse.trajectory.t, coarse.trajectory.meta["switch_times"])
    assert len(coarse.trajectory.t) < len(fine.trajectory.t) / 4
    t = np.linspace(0, fine.duration_s, 997)
    for a, b in zip(coarse.trajectory.sample(t)[:3], fine.trajectory.sample(t)[:3]):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="sample_rate"):
        rest_to_rest(umea_lab, q0, q1, sample_rate=0.0)


def test_rest_to_rest_is_the_same_from_threads_and_across_cranes():
    """rest_to_rest keeps one Ruckig input per thread and DOF count, its limits set again when
    the crane (or scale) changes: interleaved cranes of the same and other DOF counts, in two
    threads, give exactly the serial answers; the Trajectory it builds without the
    constructor's checks equals a checked one."""
    from concurrent.futures import ThreadPoolExecutor
    from planner.trajectory import Trajectory
    cranes = [Crane.from_id(c) for c in ("umea-lab", "s100f", "cat215b", "cranab850")]
    jobs = [(c, *random_configs(c, 2, seed=30 + k), sc) for k, c in enumerate(cranes * 3)
            for sc in (1.0, 0.5)]

    def run(job):
        c, a, b, sc = job
        r = rest_to_rest(c, a, b, sample_rate=None, scale=sc)
        return r.duration_s, r.trajectory.q
    serial = [run(j) for j in jobs]
    with ThreadPoolExecutor(2) as ex:
        threaded = list(ex.map(run, jobs[::-1]))[::-1]
    for (d1, q1), (d2, q2) in zip(serial, threaded):
        assert d1 == d2
        np.testing.assert_array_equal(q1, q2)
    tr = rest_to_rest(cranes[0], *random_configs(cranes[0], 2, seed=3), sample_rate=None)
    tr = tr.trajectory
    checked = Trajectory(tr.t, tr.q, tr.qd, tr.qdd, joint_names=tr.joint_names,
                         method=tr.method, objective=tr.objective, limits=tr.limits,
                         meta=tr.meta)
    for k, v in vars(checked).items():
        w = getattr(tr, k)
        assert np.array_equal(v, w) if isinstance(v, np.ndarray) else v == w, k
    bad = tr.q.copy()
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        Trajectory.trusted(tr.t, bad, tr.qd, tr.qdd, joint_names=tr.joint_names)
