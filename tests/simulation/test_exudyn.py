"""The independent dynamic plant (Exudyn): its [dynamics] spec section, the circuit's fast path
against its numpy definition, rest against the model's load-holding pressures, slow moves
against the fast replay plant, the energy balance, bounded failure, the measured-CSV contract.
Long studies live in benchmarks/bench_exudyn.py (marked slow here)."""
import copy
import tomllib

import numpy as np
import pytest

from planner import Crane
from planner.methods.ruckig import rest_to_rest
from planner.model.effects import make
from planner.model.spec import SpecError, parse_spec
from planner.simulation.dynamic.bodies import StrokeTable
from planner.simulation.dynamic.circuit import Circuit
from planner.simulation.dynamic.energy import energy_balance
from planner.simulation.dynamic.exudyn_plant import ExudynPlant, PlantDiverged
from planner.simulation.dynamic.fastpath import state_function
from planner.simulation.dynamic.simulate import exudyn_to_csv, simulate_trajectory, slowed
from planner.simulation.plant import respond
from planner.simulation.recording import read_measured_csv
from planner.simulation.replay import stroke_stops
from planner.problems import crane_path

from tests.conftest import random_configs


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


def _raw(cid):
    with open(crane_path(cid), "rb") as fh:
        return tomllib.load(fh)


# ----------------------------------------------------------------------------- spec
@pytest.mark.parametrize("path,value,field", [
    (("bulk_modulus",), 0.0, "dynamics.bulk_modulus"),
    (("joint", "boom", "hose_volume"), [-1e-3, 1e-3], "dynamics.joint.boom.hose_volume"),
    (("spool_time_constant",), -0.02, "dynamics.spool_time_constant"),
    (("joint", "nope"), {"hose_volume": [1e-3, 1e-3]}, "dynamics.joint.nope"),
    (("grapple",), {"link_length": -1.0}, "dynamics.grapple.link_length"),
    (("grapple",), {"link_length": 1.0, "swing": 2.0}, "dynamics.grapple.swing"),
    (("grapple",), {"link_length": 1.0, "swing_max": 0.0}, "dynamics.grapple.swing_max"),
])
def test_bad_dynamics_parameters_are_refused_naming_the_field(path, value, field):
    data = copy.deepcopy(_raw("s100f"))
    tbl = data["dynamics"]
    for k in path[:-1]:
        tbl = tbl[k]
    tbl[path[-1]] = value
    with pytest.raises(SpecError) as e:
        parse_spec(data, "s100f.toml")
    assert field in str(e.value)


def test_the_operators_swing_limit_is_read_from_the_spec():
    data = copy.deepcopy(_raw("s100f"))
    data["dynamics"]["grapple"] = {"link_length": 1.5, "swing_max": 0.4}
    assert parse_spec(data, "s100f.toml").dynamics.grapple.swing_max == 0.4
    del data["dynamics"]["grapple"]["swing_max"]
    assert parse_spec(data, "s100f.toml").dynamics.grapple.swing_max is None


def test_missing_dynamics_section_is_refused_by_the_plant():
    data = copy.deepcopy(_raw("umea-lab"))
    del data["dynamics"]
    crane = Crane(parse_spec(data, "umea-lab.toml"))
    assert crane.spec.dynamics is None
    with pytest.raises(ValueError, match="'dynamics': missing section"):
        ExudynPlant(crane)


def _fast_path(cid):
    crane = Crane.from_id(cid)
    C = Circuit.from_crane(crane, crane.spec.dynamics, stroke_stops(crane),
                           leak=np.full(crane.n, 1e-12))
    S = StrokeTable(crane)
    return crane, C, S, state_function(C, S)


def _random_state(crane, rng, beyond):
    L = crane.limit_arrays()
    span = L["q_max"] - L["q_min"]
    q = rng.uniform(L["q_min"] - beyond * span, L["q_max"] + beyond * span)
    qd = rng.normal(0, 0.1, crane.n)
    pa, pb = rng.uniform(-2e5, 2.5e7, (2, crane.n))
    ps = rng.uniform(2e6, 2.6e7)
    o = rng.uniform(-1, 1, crane.n) * (rng.random(crane.n) > 0.2)
    extra = rng.normal(0, 1e3, crane.n) * (rng.random(crane.n) > 0.5)
    return q, qd, pa, pb, ps, o, extra


def _numpy_reference(C, x, d, q, qd, pa, pb, ps, o, extra):
    xd = d * qd
    dpa, dpb, dps = C.rhs(pa, pb, ps, o, x, xd)
    return d * (C.force(pa, pb, x, xd) - extra), np.concatenate([dpa, dpb, [dps]])


@pytest.mark.parametrize("cid", ["s100f", "umea-lab", "cranab850", "cat215b"])
def test_fast_path_equals_the_numpy_circuit_on_the_stroke_table(cid):
    """The plain-Python evaluation the integrator calls (stroke lookup, actuator force, valve
    flows, pressure rates in one pass) against the batched numpy circuit on the table's
    lookup, at states inside and beyond the joint limits (end stops engaged)."""
    crane, C, S, evaluate = _fast_path(cid)
    rng = np.random.default_rng(1)
    for _ in range(60):
        q, qd, pa, pb, ps, o, extra = _random_state(crane, rng, beyond=0.02)
        x, d = (np.array(a) for a in S(q.tolist()))
        tau, pdot = evaluate(q.tolist(), qd.tolist(), pa.tolist() + pb.tolist() + [ps],
                             o.tolist(), extra.tolist())
        T, P = _numpy_reference(C, x, d, q, qd, pa, pb, ps, o, extra)
        np.testing.assert_allclose(tau, T, rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(pdot, P, rtol=1e-9, atol=1e-6)


@pytest.mark.parametrize("cid", ["s100f", "cat215b"])
def test_leakage_is_continuous_where_the_two_sides_balance(cid):
    """A closed valve holding a load that turns to and fro (a slew under a swinging grapple)
    sits where p_a·A_a = p_b·A_b: the pressure rates must not jump there (a jump made the
    implicit integrator's Newton iteration fail at every step), and 1 MPa away the loaded
    side alone leaks, as before. Finite differences across the surface, fast path and numpy."""
    crane, C, S, evaluate = _fast_path(cid)
    L = crane.limit_arrays()
    q = 0.5 * (L["q_min"] + L["q_max"])
    x, d = (np.array(a) for a in S(q.tolist()))
    pb = np.full(crane.n, 6e6)
    o, zero = np.zeros(crane.n), np.zeros(crane.n)

    def rates(dp):
        pa = pb * C.area_b / C.area_a + dp
        _, fast = evaluate(q.tolist(), zero.tolist(), pa.tolist() + pb.tolist() + [2e6],
                           o.tolist(), zero.tolist())
        np.testing.assert_allclose(fast, _numpy_reference(C, x, d, q, zero, pa, pb, 2e6, o,
                                                          zero)[1], rtol=1e-9, atol=1e-6)
        return np.array(fast)

    full = C.beta / C.volumes(x)[0] * C.leak * 6e6     # a whole leak's rate on side a
    assert np.all(full > 1.0)
    jump = np.abs(rates(1.0) - rates(-1.0))[:2 * crane.n]
    assert np.all(jump < 1e-3 * np.concatenate([full, full]))
    la, lb = C.leak_flows(pb * C.area_b / C.area_a + 1e6, pb)
    np.testing.assert_allclose(la, C.leak * (pb * C.area_b / C.area_a + 1e6 - C.p_tank),
                               rtol=1e-9)
    np.testing.assert_allclose(lb, 0.0, atol=1e-30)
    la, lb = C.leak_flows(pb * C.area_b / C.area_a - 1e6, pb)
    np.testing.assert_allclose(la, 0.0, atol=1e-30)
    np.testing.assert_allclose(lb, np.where(C.single, 0.0, C.leak * (pb - C.p_tank)),
                               rtol=1e-9)


@pytest.mark.parametrize("cid", ["s100f", "umea-lab", "cranab850", "cat215b"])
def test_the_stroke_table_is_the_exact_map_past_the_joint_limits_to_the_stroke_ends(cid):
    """A joint driven past its limit runs on to its cylinder's stroke end: there too the
    table's stroke and lever arm are the exact map's (the twin's), to the interpolation error
    (held at the limit's dx/dq, s100f's boom was 9 % off at its stroke end); the table reaches
    the stroke end, or where the exact map itself ends (a lever at its dead point)."""
    from planner.model.actuators import stroke_range
    crane = Crane.from_id(cid)
    S = StrokeTable(crane)
    L = crane.limit_arrays()
    ends = np.array([stroke_range(j.actuator) for j in crane.spec.joints], float)
    checked = 0
    for i in range(crane.n):
        if not np.isfinite(ends[i]).all():
            continue
        span = L["q_max"][i] - L["q_min"][i]
        for side, lim, edge in ((-1, L["q_min"][i], S.Q[0, i]), (1, L["q_max"][i], S.Q[-1, i])):
            q = 0.5 * (L["q_min"] + L["q_max"])
            for frac in np.linspace(0.0, 0.15, 31)[1:]:
                q[i] = lim + side * frac * span
                x, d = (np.asarray(a)[0] for a in crane.stroke(q[None]))
                if side * (q[i] - edge) > 0:
                    break
                xt, dt = S(q.tolist())
                assert xt[i] == pytest.approx(x[i], abs=1e-6), (cid, i, q[i])
                assert dt[i] == pytest.approx(d[i], rel=1e-3), (cid, i, q[i])
                checked += 1
            # just past the table: beyond the stroke end, or the exact map ends there
            q[i] = edge + side * 0.005 * span
            x, d = (np.asarray(a)[0] for a in crane.stroke(q[None]))
            with np.errstate(invalid="ignore"):
                past = not (ends[i, 0] - 1e-3 <= x[i] <= ends[i, 1] + 1e-3)
            assert past or not np.isfinite(d[i]) or side * (edge - lim) >= 0.2 * span - 1e-9 \
                or abs(d[i]) > 1.5 * abs(S(q.tolist())[1][i]), (cid, i, side, edge)
    assert checked >= 4


@pytest.mark.parametrize("cid", ["s100f", "cat215b"])
def test_fast_path_equals_the_numpy_circuit_on_the_exact_stroke_map(cid):
    """Inside the joint limits the table is the model's exact stroke map to within its
    interpolation error: the fast path against the numpy circuit on crane.stroke(q)."""
    crane, C, S, evaluate = _fast_path(cid)
    rng = np.random.default_rng(2)
    for _ in range(40):
        q, qd, pa, pb, ps, o, extra = _random_state(crane, rng, beyond=0.0)
        x, d = (np.asarray(a)[0] for a in crane.stroke(q[None]))
        tau, pdot = evaluate(q.tolist(), qd.tolist(), pa.tolist() + pb.tolist() + [ps],
                             o.tolist(), extra.tolist())
        T, P = _numpy_reference(C, x, d, q, qd, pa, pb, ps, o, extra)
        np.testing.assert_allclose(tau, T, rtol=1e-5, atol=1e-3)
        np.testing.assert_allclose(pdot, P, rtol=1e-5, atol=1.0)


def test_the_integrator_converges_on_the_coupled_jacobian(s100f, monkeypatch):
    """The cost of a run is the number of times the engine evaluates the plant's physics (its
    Newton residuals and Jacobian columns). With the Jacobian of the whole residual (joint
    forces depend on the pressures, pressure rates on the joint motion) a brisk 1.6 s move
    takes under 15 evaluations per step; with per-object Jacobians (the coupling missing,
    Newton converging linearly) it took ~37."""
    from planner.simulation.dynamic import exudyn_plant
    calls = [0]

    def counting(circuit, strokes):
        evaluate = state_function(circuit, strokes)

        def counted(*args):
            calls[0] += 1
            return evaluate(*args)
        return counted
    monkeypatch.setattr(exudyn_plant, "state_function", counting)
    q0 = random_configs(s100f, 1, seed=7)[0]
    u = np.array([[0.0, 0.6, 0.0, 0.0], [0.5, -0.5, 0.6, 0.4], [0.0, 0.0, 0.0, 0.0]])
    run = ExudynPlant(s100f).integrate([0.0, 0.6, 1.4], u, q0, t_end=1.6)
    assert run.ok, run.reason
    assert np.ptp(run.q, axis=0).min() > 0.01          # every joint moved
    assert calls[0] / run.meta["steps"] < 15


# ----------------------------------------------------------------------------- physics
@pytest.mark.parametrize("cid", ["s100f", "umea-lab"])
def test_at_rest_pressures_hold_the_models_load_holding_pressures(cid):
    """Exudyn's own multibody (kinematic tree) must hold still under the pressures the model's
    inverse dynamics asks for: within 1 % after 1 s, with no drift of the joints."""
    crane = Crane.from_id(cid)
    plant = ExudynPlant(crane)
    q0 = random_configs(crane, 1, seed=4)[0]
    run = plant.integrate([0.0, 1.0], np.zeros((2, crane.n)), q0)
    assert run.ok, run.reason
    pa0, pb0 = plant.initial_pressures(q0)
    scale = np.maximum(np.maximum(np.abs(pa0), np.abs(pb0)), 1e5)
    assert np.all(np.abs(run.p_a[-1] - pa0) <= 0.01 * scale)
    assert np.all(np.abs(run.p_b[-1] - pb0) <= 0.01 * scale)
    assert np.abs(run.q[-1] - q0).max() < 1e-6


def test_slow_move_follows_the_fast_plant_and_the_energy_balance_closes(s100f):
    q0, q1 = random_configs(s100f, 2, seed=3)
    traj = slowed(rest_to_rest(s100f, q0, q1, scale=0.5).trajectory, 4.0)
    plant = ExudynPlant(s100f)
    run, t_u, u, _ = simulate_trajectory(s100f, traj, 50.0, settle=0.5, plant=plant)
    assert run.ok, run.reason
    fast = respond(s100f, t_u, u, traj.q[0], t_end=run.t[-1], dt=0.02)
    q = run.sample(fast.t)[0]
    lo, hi = stroke_stops(s100f)
    err = np.abs(s100f.stroke(q)[0] - s100f.stroke(fast.state.q)[0]).max(axis=0) / (hi - lo)
    assert np.all(err < 0.01), err
    eb = energy_balance(plant, run)
    assert eb["pump_work_J"] > 0
    assert abs(eb["residual_rel"]) < 0.02, eb


def test_effects_act_on_the_dynamic_plant(s100f):
    """A payload effect raises the holding pressure of the lift cylinder by the model's
    amount; a joint offset moves only the reported position."""
    q0 = random_configs(s100f, 1, seed=5)[0]
    heavy = ExudynPlant(s100f, [make("payload_mass", mass=300.0)])
    base = ExudynPlant(s100f)
    assert heavy.payload == pytest.approx(base.payload + 300.0)
    tau = s100f.inverse_dynamics(q0, np.zeros(4), np.zeros(4), base.payload + 300.0)
    run = heavy.integrate([0.0, 0.3], np.zeros((2, 4)), q0)
    F = tau[1] / s100f.stroke(q0)[1][1]
    area = s100f.spec.joints[1].actuator.area_a
    assert run.p_a[-1, 1] == pytest.approx(F / area, rel=0.01)
    off = ExudynPlant(s100f, [make("joint_offset", joint="jib", offset=0.01)])
    q, pa, pb = off.sense(np.array([q0]), run.p_a[-1:], run.p_b[-1:])
    assert q[0, 2] - q0[2] == pytest.approx(0.01)


def test_a_run_out_of_wall_time_stops_with_status_and_time(s100f):
    q0 = random_configs(s100f, 1, seed=6)[0]
    run = ExudynPlant(s100f).integrate([0.0, 5.0], np.zeros((2, 4)), q0, max_wall_s=0.0)
    assert run.status == "timeout" and run.t_fail is not None and run.t_fail < 5.0
    assert not run.ok


def test_exudyn_csv_follows_the_measured_data_contract(s100f, tmp_path):
    q0, q1 = random_configs(s100f, 2, seed=3)
    traj = rest_to_rest(s100f, q0, q1, scale=0.5).trajectory
    out = tmp_path / "m.csv"
    summary = exudyn_to_csv(s100f, traj, out, rate=50.0)
    d = read_measured_csv(out, tuple(s100f.names))
    assert summary["status"] == "ok" and len(d["t"]) == summary["samples"]
    assert d["p_a"] is not None and np.all(np.isfinite(d["p_a"]))
    np.testing.assert_allclose(d["q"][0], traj.q[0], atol=1e-9)
    with pytest.raises(PlantDiverged):
        exudyn_to_csv(s100f, traj, tmp_path / "x.csv", max_wall_s=0.0)
    assert not (tmp_path / "x.csv").exists()
