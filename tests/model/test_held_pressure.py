"""The held (trapped) chamber pressures of the machine pricing (planner.model.pricing
.held_pressures, flows.held_hydraulics): the pressure the LS pump must reach on a function whose
outlet still holds an earlier load, against hand calculations from the spec's numbers; the
redistribution of a load change on a trapped pair against a direct solution of the two
chambers' oil springs; make-up; the quasi-static pressures wherever nothing is held; the seed
pricing untouched; the compiled chunked map against the plain step."""
import casadi as ca
import numpy as np
import pytest

from planner import Crane
from planner.model import flows
from planner.model.pricing import CHUNK, held_pressures, held_step

JIB = 2   # s100f: double-acting lever cylinder


def _jib():
    crane = Crane.from_id("s100f")
    j = crane.spec.joints[JIB]
    d = crane.spec.dynamics
    return crane, j.actuator, d.joints[j.name], d


def _series(n, N, **cols):
    """(N, n) arrays: each named column of the jib set, the other joints at rest, unloaded."""
    out = {}
    for k in ("force", "xd", "x", "moving", "p_a", "p_b"):
        a = np.zeros((N, n))
        if k in cols:
            a[:, JIB] = cols[k]
        out[k] = a
    return out


def test_outlet_bleeds_through_the_margin_and_the_pump_pushes_against_it():
    """The jib extending at 0.2 m/s at a light load (F = 5 kN, friction in) with its rod side
    still at 8 MPa from an earlier braking: by hand, V_b = hose + A_b·(stroke − x),
    V_a = hose + A_a·x, K = β·A²/V, the rod side falls at m·β·A_b·v/V_b·K_a/(K_a + K_b)
    (x held, so the rate is constant); after 0.5 s the piston side must hold
    (F + A_b·p_b)/A_a and the LS pump that plus its margin."""
    crane, act, jd, d = _jib()
    pt = crane.spec.pump.tank_pressure
    Aa, Ab, beta, m = act.area_a, act.area_b, d.bulk_modulus, d.meter_out_margin
    x, v, F, pb0 = 0.6, 0.2, 5.0e3, 8.0e6
    Va, Vb = jd.hose_volume[0] + Aa * x, jd.hose_volume[1] + Ab * (act.stroke - x)
    Ka, Kb = beta * Aa ** 2 / Va, beta * Ab ** 2 / Vb
    rate = m * beta * Ab * v / Vb * Ka / (Ka + Kb)        # [Pa/s], ≈ 5 MPa/s here
    assert 1e6 < rate < 2e7
    t = np.linspace(0.0, 0.5, 501)
    pa0 = (F + Ab * pb0) / Aa                              # the trapped pair balances F
    back = crane.prices.back[JIB]
    pbq = pt + back                                        # the quasi-static outlet
    paq = (F + Ab * pbq) / Aa
    c = _series(crane.n, len(t), force=F, xd=v, x=x, moving=1.0, p_a=paq, p_b=pbq)
    c["p_a"][0, JIB], c["p_b"][0, JIB] = pa0, pb0
    pa, pb = held_pressures(crane.prices, t, c["x"], c["xd"], c["force"], c["moving"] > 0.5,
                            c["p_a"], c["p_b"])
    pb_hand = pb0 - rate * 0.5
    assert pb[-1, JIB] == pytest.approx(pb_hand, rel=1e-9)
    p_in = (F + Ab * pb_hand) / Aa
    assert pa[-1, JIB] == pytest.approx(p_in, rel=1e-9)
    assert p_in > paq + 2e6                                # what the quasi-static price misses
    # the others have nothing held: their quasi-static pressures pass through
    np.testing.assert_array_equal(pa[:, 0], c["p_a"][:, 0])
    # the pump: the jib is the only drawing function, so p_in + the LS margin
    q = np.zeros((len(t), crane.n))
    q[:, JIB] = Aa * v
    hyd = dict(x=c["x"], xd=c["xd"], force=c["force"] - flows.friction(crane.prices, c["xd"]),
               p_a=c["p_a"], p_b=c["p_b"], q_act=q, q_pump=q.sum(1))
    h = flows.held_hydraulics(crane, t, hyd)
    assert h["p_pump"][-1] == pytest.approx(p_in + crane.spec.pump.margin, rel=1e-9)


def test_the_outlet_stops_at_its_quasi_static_pressure():
    """Long enough, the held rod side reaches the load-holding valve's counter-pressure and
    stays there: then the pair is the quasi-static one (to round-off)."""
    crane, act, jd, d = _jib()
    Aa, Ab = act.area_a, act.area_b
    t = np.linspace(0.0, 10.0, 2001)
    F, pb0 = 5.0e3, 8.0e6
    pbq = crane.spec.pump.tank_pressure + crane.prices.back[JIB]
    paq = (F + Ab * pbq) / Aa
    c = _series(crane.n, len(t), force=F, xd=0.2, x=0.6, moving=1.0, p_a=paq, p_b=pbq)
    c["p_a"][0, JIB], c["p_b"][0, JIB] = (F + Ab * pb0) / Aa, pb0
    pa, pb = held_pressures(crane.prices, t, c["x"], c["xd"], c["force"], c["moving"] > 0.5,
                            c["p_a"], c["p_b"])
    assert np.all(np.diff(pb[:, JIB]) <= 1e-6)
    assert pb[-1, JIB] == pytest.approx(pbq, rel=1e-12)
    assert pa[-1, JIB] == pytest.approx(paq, rel=1e-12)


def test_a_load_change_at_rest_compresses_the_trapped_oil():
    """Valve closed, both chambers trapped (4 and 9 MPa); the carried force rises by 20 kN.
    Oracle: the piston moves by δ until the two oil springs (Δp = ∓β·A·δ/V, V at the stroke)
    carry the new force — solved directly; then the force drops far enough that the rod side
    would fall below tank: make-up refills it and the piston side takes the whole load."""
    crane, act, jd, d = _jib()
    pt = crane.spec.pump.tank_pressure
    Aa, Ab, beta = act.area_a, act.area_b, d.bulk_modulus
    x = 0.9
    Va, Vb = jd.hose_volume[0] + Aa * x, jd.hose_volume[1] + Ab * (act.stroke - x)
    pa0, pb0 = 4.0e6, 9.0e6
    F0 = pa0 * Aa - pb0 * Ab
    F1 = F0 + 2.0e4
    # (pa0 + β·A_a·δ/V_a)·A_a − (pb0 − β·A_b·δ/V_b)·A_b = F1, δ the compression of the rod side
    delta = (F1 - F0) / (beta * Aa ** 2 / Va + beta * Ab ** 2 / Vb)
    want = (pa0 + beta * Aa * delta / Va, pb0 - beta * Ab * delta / Vb)
    F2 = 2.0e5                                            # far above what the rod side can give
    t = np.array([0.0, 0.1, 0.2])
    force = np.array([F0, F1, F2])
    c = _series(crane.n, 3, force=force, x=x, p_a=np.array([pa0, 0, 0]),
                p_b=np.array([pb0, 0, 0]))
    pa, pb = held_pressures(crane.prices, t, c["x"], c["xd"], c["force"], c["moving"] > 0.5,
                            c["p_a"], c["p_b"])
    assert (pa[1, JIB], pb[1, JIB]) == pytest.approx(want, rel=1e-12)
    assert pa[1, JIB] * Aa - pb[1, JIB] * Ab == pytest.approx(F1, rel=1e-12)
    assert (pa[2, JIB], pb[2, JIB]) == pytest.approx(((F2 + Ab * pt) / Aa, pt), rel=1e-12)


def test_a_passive_load_that_grows_holds_nothing():
    """The jib extending at 0.2 m/s from its quasi-static pair while its passive load grows
    5 → 15 kN: a growing load only lowers the outlet, which the counter-pressure floors, so
    the pair is the quasi-static one by hand: p_b = p_t + Δp_b, p_a = (F + A_b·p_b)/A_a."""
    crane, act, jd, d = _jib()
    Aa, Ab = act.area_a, act.area_b
    t = np.linspace(0.0, 1.0, 101)
    F = np.linspace(5.0e3, 1.5e4, len(t))
    pbq = crane.spec.pump.tank_pressure + crane.prices.back[JIB]
    paq = (F + Ab * pbq) / Aa
    c = _series(crane.n, len(t), force=F, xd=0.2, x=0.6, moving=1.0, p_a=paq, p_b=pbq)
    pa, pb = held_pressures(crane.prices, t, c["x"], c["xd"], c["force"], c["moving"] > 0.5,
                            c["p_a"], c["p_b"])
    np.testing.assert_allclose(pb[:, JIB], pbq, rtol=1e-12)
    np.testing.assert_allclose(pa[:, JIB], paq, rtol=1e-12)


def test_seed_pricing_holds_nothing():
    crane = Crane.from_id("s100f", pricing="seed")
    assert not np.any(crane.prices.held)
    hyd = dict(p_a=np.ones((3, crane.n)))
    assert flows.held_hydraulics(crane, np.arange(3.0), hyd) is hyd


def test_machine_pricing_holds_the_double_acting_functions_only():
    crane = Crane.from_id("s100f")
    single = np.array([j.actuator.acting == "single" for j in crane.spec.joints])
    np.testing.assert_array_equal(crane.prices.held, ~single)


def test_compiled_chunks_equal_the_plain_step():
    """The compiled map over CHUNK-sample pieces (the last one padded) equals stepping the
    one CasADi definition sample by sample, across two chunk boundaries."""
    crane = Crane.from_id("s100f")
    pr = crane.prices
    rng = np.random.default_rng(3)
    N, n = 2 * CHUNK + 37, crane.n
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, N))
    force = rng.normal(0, 2e4, (N, n))
    xd = rng.normal(0, 0.1, (N, n))
    x = rng.uniform(0.1, 0.7, (N, n))
    moving = rng.random((N, n)) > 0.3
    p_a = rng.uniform(0, 5e6, (N, n))
    p_b = rng.uniform(0, 5e6, (N, n))
    pa, pb = held_pressures(pr, t, x, xd, force, moving, p_a, p_b)
    for i in (JIB,):   # one held function is enough: the map is per function alike
        za, zb = p_a[0, i], p_b[0, i]
        for k in range(1, N):
            ya, yb = held_step(ca.DM(za), ca.DM(zb), force[k, i], xd[k, i], x[k, i],
                               float(moving[k, i]), p_a[k, i], p_b[k, i], t[k] - t[k - 1],
                               pr.area_a[i], pr.area_b[i], pr.hose_a[i], pr.hose_b[i],
                               pr.x_lo[i], pr.x_hi[i], pr.swept[i], pr.beta, pr.margin,
                               pr.p_tank)
            za, zb = float(ya), float(yb)
            assert (pa[k, i], pb[k, i]) == pytest.approx((za, zb), rel=1e-9, abs=1e-3)
    np.testing.assert_array_equal(pa[:, ~pr.held], p_a[:, ~pr.held])
