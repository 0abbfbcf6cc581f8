"""The Exudyn plant's opt-in pressure-dependent bulk modulus (issue 27's mismatched machines):
a closed chamber compressed by a known volume against the closed-form pressure of the law, the
fast path against the numpy circuit with the law on, and the plant with the law off (or
neutral) giving the very same run as before."""
import numpy as np
import pytest
from dataclasses import replace
from scipy.integrate import solve_ivp

from planner import Crane
from planner.methods.ruckig import rest_to_rest
from planner.simulation.dynamic.bodies import StrokeTable
from planner.simulation.dynamic.circuit import Circuit, PressureBulk
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.simulation.dynamic.fastpath import state_function
from planner.simulation.dynamic.simulate import slowed
from planner.simulation.replay import stroke_stops

from tests.conftest import random_configs


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


def _compress(C, i, p0, dx, side="a", T=1.0):
    """Chamber ``side`` of actuator i, valve closed, no leakage, compressed by a stroke change
    dx [m] at a constant rate over T s (numpy circuit, tight ODE solve): (V0, V1, p1)."""
    n = C.n
    x0 = 0.5 * (C.x_lo + C.x_hi)
    xd = np.zeros(n)
    xd[i] = dx / T

    def f(t, y):
        x = x0 + xd * t
        pa = np.full(n, y[0] if side == "a" else 5e6)
        pb = np.full(n, y[0] if side == "b" else 5e6)
        dpa, dpb, _ = C.rhs(pa, pb, 2e6, np.zeros(n), x, xd)
        return [(dpa if side == "a" else dpb)[i]]
    sol = solve_ivp(f, (0.0, T), [p0], rtol=1e-11, atol=1e-3)
    va0, vb0 = C.volumes(x0)
    va1, vb1 = C.volumes(x0 + xd * T)
    V0, V1 = (va0[i], va1[i]) if side == "a" else (vb0[i], vb1[i])
    return V0, V1, sol.y[0, -1]


@pytest.mark.parametrize("i,side,dx", [(1, "a", -2e-3), (2, "b", 3e-3)])
def test_closed_chamber_compressed_follows_the_law_in_closed_form(s100f, i, side, dx):
    """β(p) = β0·(p + p_a)/(p_ref + p_a) in a closed chamber: (p + p_a) = (p0 + p_a)·
    (V0/V)^(β0/(p_ref + p_a)); above the clip β = hi·β0: p = p0 + hi·β0·ln(V0/V); with the
    law off p = p0 + β0·ln(V0/V). Three different answers for the same compression."""
    law = PressureBulk(p_ref=8e6, p_abs=1e5, lo=0.2, hi=1.25)
    base = Circuit.from_crane(s100f, s100f.spec.dynamics, stroke_stops(s100f))
    C = replace(base, bulk=law)
    b0, pa_, k = base.beta, law.p_abs, base.beta / (law.p_ref + law.p_abs)
    p0 = 4e6                            # inside the linear range (factor 0.51 .. 1.25)
    V0, V1, p1 = _compress(C, i, p0, dx, side)
    assert V1 < V0
    expect = (p0 + pa_) * (V0 / V1) ** k - pa_
    assert expect < law.hi * (law.p_ref + pa_) - pa_     # stayed inside the linear range
    assert p1 == pytest.approx(expect, rel=1e-6)
    p_hi = 1.2e7                        # above the clip
    _, _, p2 = _compress(C, i, p_hi, dx, side)
    assert p2 == pytest.approx(p_hi + law.hi * b0 * np.log(V0 / V1), rel=1e-6)
    _, _, p3 = _compress(base, i, p0, dx, side)
    assert p3 == pytest.approx(p0 + b0 * np.log(V0 / V1), rel=1e-6)
    assert abs(p1 - p3) > 0.05 * (p3 - p0)   # the law changes the answer noticeably


def test_fast_path_equals_the_numpy_circuit_with_the_law_on(s100f):
    """The plain-Python evaluation the integrator calls, with the law on, against the numpy
    circuit at random states spanning the law's clipped and linear ranges (pump starving)."""
    C = replace(Circuit.from_crane(s100f, s100f.spec.dynamics, stroke_stops(s100f),
                                   pump_scale=0.05), bulk=PressureBulk())
    S = StrokeTable(s100f)
    evaluate = state_function(C, S)
    rng = np.random.default_rng(7)
    L = s100f.limit_arrays()
    for _ in range(40):
        q = rng.uniform(L["q_min"], L["q_max"])
        qd = rng.normal(0, 0.1, 4)
        pa, pb = rng.uniform(-2e5, 2.5e7, (2, 4))
        ps = rng.uniform(2e6, 2.6e7)
        o = rng.uniform(-1, 1, 4)
        x, d = (np.array(a) for a in S(q.tolist()))
        _, pdot = evaluate(q.tolist(), qd.tolist(), pa.tolist() + pb.tolist() + [ps],
                           o.tolist(), [0.0] * 4)
        dpa, dpb, dps = C.rhs(pa, pb, ps, o, x, d * qd)
        np.testing.assert_allclose(pdot, np.concatenate([dpa, dpb, [dps]]), rtol=1e-9,
                                   atol=1e-6)


def test_plant_without_the_law_or_with_a_neutral_one_runs_identically(s100f):
    """Off by default: a neutral law (factor 1 everywhere) gives the very same run, bit for
    bit; the default law changes where the crane comes to rest."""
    q0, q1 = random_configs(s100f, 2, seed=3)
    traj = slowed(rest_to_rest(s100f, q0, q1, scale=1.0).trajectory, 1.0)
    from planner.feedforward import commands
    ff = commands(s100f, traj, 50.0)
    t_u = np.append(ff.t, ff.t[-1] + 0.02)
    u = np.vstack([ff.u, np.zeros((1, 4))])
    t_end = float(t_u[-1]) + 1.0
    off = ExudynPlant(s100f).integrate(t_u, u, q0, t_end=t_end)
    neutral = ExudynPlant(s100f, bulk=PressureBulk(lo=1.0, hi=1.0)).integrate(
        t_u, u, q0, t_end=t_end)
    on = ExudynPlant(s100f, bulk=PressureBulk()).integrate(t_u, u, q0, t_end=t_end)
    assert off.ok and neutral.ok and on.ok
    for k in ("q", "p_a", "p_b", "p_s"):
        assert np.array_equal(getattr(off, k), getattr(neutral, k)), k
    tip = np.linalg.norm(s100f.fk(on.q[-1:]) - s100f.fk(off.q[-1:]))
    assert tip > 1e-4, tip


def test_a_bad_law_is_refused_naming_the_field(s100f):
    with pytest.raises(ValueError, match="field 'hi' = 0.5; allowed: 1 .. 10"):
        PressureBulk(hi=0.5)
    with pytest.raises(ValueError, match="bulk = 3; allowed: None or a PressureBulk"):
        ExudynPlant(s100f, bulk=3)
