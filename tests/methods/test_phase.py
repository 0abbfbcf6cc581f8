"""Seed 003 phase-plane planning (planner.methods.phase): paths, envelope, telescope
optimisation, the 90 % profile and the Ruckig from-rest redesign."""
import math

import numpy as np
import pytest

from planner import Crane
from planner.methods import phase as ph
from planner.geometry.paths import circle as shared_circle
from planner.geometry.paths import parabola as shared_parabola
from planner.trajectory import evaluate

# near-optimal coefficients found by benchmarks/seed003_paths.py (feasible on umea-lab)
CIRCLE_C = [1.04996, 0.49381, -0.14137, -0.02579, 0.02375, 0.01883, -0.00690]
PARABOLA_P = [0.00155, 0.0, 0.35681, 0.69128, 0.90293, 1.54845]
ALPHA = -math.pi / 4


@pytest.fixture(scope="module")
def lab():
    return Crane.from_id("umea-lab")


@pytest.fixture(scope="module")
def circ():
    return ph.seed_setup("circle")


@pytest.fixture(scope="module")
def para():
    return ph.seed_setup("parabola", alpha=ALPHA)


# ---------------------------------------------------------------------- paths
def test_parabola_vertex_check():
    p = ph.parabola_path(alpha=-math.pi / 3)           # (θ − h): what the seed means
    h = p.params["h"]
    z = p.xyz(np.array([1.6, h, 3.07]))[:, 2]
    assert z == pytest.approx([1.5, 3.0, 1.5], abs=1e-12)
    th = p.grid(3001)
    assert th[np.argmax(p.xyz(th)[:, 2])] == pytest.approx(h, abs=1e-3)
    assert p.params["a"] < 0
    printed = ph.parabola_path(alpha=-math.pi / 3, vertex="plus")  # (θ + h) as printed
    zp = printed.xyz(np.array([1.6, 3.07]))[:, 2]
    assert abs(zp[0] - 1.5) > 10 and abs(zp[1] - 1.5) > 10  # the printed form is not the lift
    # same curve as the shared planner.geometry.paths.parabola (whose docstring makes the same choice)
    shared = shared_parabola(1.6, 3.07, 1.5, 3.0, -math.pi / 3)
    assert np.allclose(shared.p(th), p.xyz(th), atol=1e-12)


def test_circle_parameter_and_shared_curve(circ):
    path, _ = circ
    th = np.linspace(-math.pi + 1e-9, math.pi - 1e-9, 101)
    assert np.allclose(path.theta_of(path.xyz(th)), th, atol=1e-12)
    shared = shared_circle((3.0, 0.0, 2.5), 0.7)
    assert np.allclose(shared.p(th), path.xyz(th), atol=1e-12)


@pytest.mark.parametrize("which", ["circle", "parabola"])
def test_path_and_telescope_derivatives(which):
    path, tele = ph.seed_setup(which, alpha=ALPHA)
    c = np.array(CIRCLE_C if which == "circle" else PARABOLA_P)
    th = np.linspace(path.theta0 + 0.01, path.theta1 - 0.01, 37)
    h = 1e-6
    fd = (path.xyz(th + h) - path.xyz(th - h)) / (2 * h)
    assert np.allclose(path.dxyz(th), fd, atol=1e-7)
    for der in (1, 2):
        fd = (tele.value(c, th + h, der - 1) - tele.value(c, th - h, der - 1)) / (2 * h)
        assert np.allclose(tele.value(c, th, der), fd, atol=1e-5)


def test_rate_bounds_asymmetric():
    dq = np.array([[0.5, -0.5, 0.0, np.nan]])
    b = ph.rate_bounds(dq, np.full(4, -0.2), np.full(4, 0.4))
    assert b[0, 0] == pytest.approx(0.8)      # Φ' > 0: q̇_max / Φ'
    assert b[0, 1] == pytest.approx(0.4)      # Φ' < 0: q̇_min / Φ' (the smaller |q̇_min|)
    assert b[0, 2] == np.inf and np.isnan(b[0, 3])


# ---------------------------------------------------------------------- envelope
@pytest.mark.parametrize("which", ["circle", "parabola"])
def test_envelope_is_min_of_curves_and_matches_finite_differences(lab, which):
    path, tele = ph.seed_setup(which, alpha=ALPHA)
    c = np.array(CIRCLE_C if which == "circle" else PARABOLA_P)
    th = np.linspace(path.theta0 + 1e-3, path.theta1 - 1e-3, 61)
    e = ph.envelope(lab, path, tele, c, th)
    assert e.ok
    assert np.array_equal(e.envelope, np.min(e.bounds, axis=1))
    # Φ' against central differences of the IK itself
    h = 1e-6
    qp, _, _ = ph.joint_path(lab, path, tele, c, th + h)
    qm, _, _ = ph.joint_path(lab, path, tele, c, th - h)
    dq_fd = (qp - qm) / (2 * h)
    assert np.allclose(e.dq, dq_fd, atol=2e-6, rtol=1e-5)
    # each joint's curve from the finite-difference Φ' (asymmetric limits, θ̇ > 0)
    L = lab.limit_arrays()
    for i in range(lab.n):
        d = dq_fd[:, i]
        big = np.abs(d) > 1e-3
        expect = np.where(d > 0, L["qd_max"][i] / np.where(big, d, 1), L["qd_min"][i] /
                          np.where(big, d, 1))
        assert np.allclose(e.bounds[big, i], expect[big], rtol=1e-4)
    # joint rates at θ̇ = envelope touch a limit and respect all of them
    qd = e.dq * e.envelope[:, None]
    assert np.all(qd <= L["qd_max"] * (1 + 1e-12)) and np.all(qd >= L["qd_min"] * (1 + 1e-12))
    touch = np.isclose(qd, L["qd_max"], rtol=1e-9) | np.isclose(qd, L["qd_min"], rtol=1e-9)
    assert np.all(touch.any(axis=1))
    # the tip lies on the path: FK of Φ(θ) = p(θ)
    assert np.allclose(lab.fk(e.q), path.xyz(th), atol=1e-9)


# ---------------------------------------------------------------------- optimisation
def test_optimised_telescope_beats_best_constant(lab, circ):
    path, tele = circ
    opt = ph.optimise_telescope(lab, path, tele, n_theta=121, n_fine=401, maxfev=300,
                                restarts=1)
    assert opt.ok
    assert opt.const_best is not None
    # the reported best constant really is the best on a 1 cm grid (independent envelope calls)
    th = opt.env.theta
    areas = []
    for t in np.arange(0.0, 1.5501, 0.01):
        e = ph.envelope(lab, path, tele, tele.constant(t), th)
        areas.append(e.area if e.ok else -np.inf)
    assert opt.const_area == pytest.approx(max(areas), rel=1e-9)
    assert opt.area >= opt.const_area
    assert opt.area > 1.5 * opt.const_area    # a moving telescope opens the envelope widely
    # ... and the optimiser itself adds to its deterministic starts (constant, band-middle fit)
    start_areas = [ph.envelope(lab, path, tele, np.array(s["x0"]), th).area for s in opt.starts]
    assert {s["start"] for s in opt.starts} == {"best_constant", "band_middle_fit"}
    assert opt.area > 1.2 * max(start_areas)
    # the optimum keeps every joint (the telescope included) inside its limits
    L = lab.limit_arrays()
    assert np.all(opt.env.q >= L["q_min"]) and np.all(opt.env.q <= L["q_max"])


def test_seed_parabola_is_unreachable(lab):
    path, tele = ph.seed_setup("parabola")      # α = −π/3 as printed
    with pytest.raises(ValueError, match="no telescope value"):
        ph.optimise_telescope(lab, path, tele, n_theta=41)


# ---------------------------------------------------------------------- profiles
@pytest.fixture(scope="module")
def circle_profile(lab, circ):
    path, tele = circ
    return ph.time_efficient_profile(lab, path, tele, CIRCLE_C, 0.9, n=1201)


@pytest.fixture(scope="module")
def parabola_profile(lab, para):
    path, tele = para
    return ph.time_efficient_profile(lab, path, tele, PARABOLA_P, 0.9, n=801)


@pytest.mark.parametrize("which", ["circle", "parabola"])
def test_profile_under_envelope_and_within_rate_limits(lab, which, circle_profile,
                                                        parabola_profile):
    prof = circle_profile if which == "circle" else parabola_profile
    # never above the envelope, re-computed independently on a finer, shifted grid
    th = 0.5 * (prof.theta[1:] + prof.theta[:-1])
    e = ph.envelope(lab, prof.path, prof.tele, prof.coef, th)
    f_mid = np.interp(th, prof.theta, prof.f)
    assert np.all(f_mid <= e.envelope)
    assert np.allclose(prof.f, 0.9 * prof.envelope)
    # timing: t = ∫ dθ / f
    T_env = ph.envelope(lab, prof.path, prof.tele, prof.coef, prof.theta).time_at_envelope
    assert prof.duration == pytest.approx(T_env / 0.9, rel=1e-9)
    traj = prof.trajectory(lab)
    ev = evaluate(lab, traj)
    assert ev.checked == ("position", "velocity")
    assert ev.violations["velocity"] == 0.0 and ev.max_limit_violation == 0.0
    # the joint trajectory keeps the tip on the path between the samples too
    t = np.linspace(0, traj.duration, 997)
    q = traj.sample(t)[0]
    xyz = lab.fk(q)
    back = prof.path.xyz(prof.path.theta_of(xyz))
    assert np.max(np.linalg.norm(xyz - back, axis=1)) < 1e-4


# ---------------------------------------------------------------------- from rest
@pytest.mark.parametrize("space", ["theta", "joint"])
def test_from_rest_junctions_continuous(lab, parabola_profile, space):
    prof = parabola_profile
    fr = ph.from_rest(lab, prof, space=space)
    path = prof.path
    assert [j.where for j in fr.junctions] == ["start", "end"]
    assert fr.junctions[0].theta == pytest.approx(1.6 + 0.05 * 1.47)
    assert fr.junctions[1].theta == pytest.approx(1.6 + 0.95 * 1.47)
    for j in fr.junctions:
        assert j.pos_err <= 1e-6 and j.vel_err <= 1e-6 and j.acc_err <= 1e-6, j
    tr = fr.trajectory
    # starts and ends at rest on the path ends
    q0 = prof.joint_state(lab, np.array([path.theta0, path.theta1]), np.zeros(2),
                               np.zeros(2))[0]
    assert np.allclose(tr.q[0], q0[0], atol=1e-9) and np.allclose(tr.q[-1], q0[1], atol=1e-9)
    for k in (0, -1):
        assert np.allclose(tr.qd[k], 0, atol=1e-9) and np.allclose(tr.qdd[k], 0, atol=1e-9)
    # the assembled trajectory is continuous through the junctions: q, q̇, q̈ just left and
    # right of the junction agree with the nominal state there
    for j in fr.junctions:
        (f, a), (qn, vn, an) = prof.nominal_state(lab, np.array([j.theta]),
                                                  side=1 if j.where == "start" else -1)
        for dt in (-1e-6, 1e-6):
            q, qd, qdd, _ = tr.sample(np.array([j.t + dt]))
            assert np.allclose(q[0], qn[0], atol=1e-5)
            assert np.allclose(qd[0], vn[0], atol=1e-4)
            assert np.allclose(qdd[0], an[0], atol=1e-3)
    ev = evaluate(lab, tr)
    assert ev.max_limit_violation <= 1e-6
    if space == "theta":
        # never backwards along the path, and the tip stays on it
        _, th, thd = fr.phase
        assert np.all(thd >= -1e-12)
        assert np.all(np.diff(th) >= -1e-12)
        assert fr.max_path_deviation < 1e-3
        for t in fr.transitions:
            assert t["max_speed_over_envelope"] <= 1.0
    assert fr.duration > prof.duration  # starting and stopping at rest costs time


def test_from_rest_circle_keeps_cycling(lab, circle_profile):
    fr = ph.from_rest(lab, circle_profile)
    assert len(fr.junctions) == 1 and fr.junctions[0].where == "start"
    assert fr.junctions[0].theta == pytest.approx(-math.pi + 0.1 * math.pi)
    j = fr.junctions[0]
    assert max(j.pos_err, j.vel_err, j.acc_err) <= 1e-6
    assert max(j.path_err) <= 1e-9
    tr = fr.trajectory
    assert np.allclose(tr.qd[0], 0, atol=1e-12) and np.allclose(tr.qdd[0], 0, atol=1e-12)
    # ends on the nominal profile at θ = π (moving), where the revolution closes
    (f, _), (qn, vn, _) = circle_profile.nominal_state(lab, np.array([math.pi]))
    assert np.allclose(tr.q[-1], qn[0], atol=1e-9) and np.allclose(tr.qd[-1], vn[0], atol=1e-9)
    assert evaluate(lab, tr).max_limit_violation <= 1e-6


@pytest.mark.parametrize("which", ["circle", "parabola"])
def test_seed_path_arc_length_face(which):
    """SeedPath.arc_length(): the same curve by arc length. Oracles: the half circle's length is
    πR; the parabola's is the quadrature of |dp/dθ| (its analytic derivative); points at equal
    arc steps are equally far apart along the curve; the shared circle()/parabola() are the
    seed paths' arc-length faces."""
    from planner.geometry.paths import Curve, circle, parabola
    if which == "circle":
        sp = ph.circle_path()
        cv = sp.arc_length()
        assert cv.length == pytest.approx(2 * math.pi * 0.7, rel=1e-6)
        half = circle((3.0, 0.0, 2.5), 0.7, -math.pi / 2, math.pi / 2)
        assert half.length == pytest.approx(math.pi * 0.7, rel=1e-6)
    else:
        sp = ph.parabola_path(alpha=ALPHA)
        cv = sp.arc_length()
        th = sp.grid(20001)
        ref = np.trapezoid(np.linalg.norm(sp.dxyz(th), axis=1), th)
        assert cv.length == pytest.approx(ref, rel=1e-6)
        other = parabola(1.6, 3.07, 1.5, 3.0, ALPHA)
        assert other.length == cv.length and other.source.params == sp.params
    assert isinstance(cv, Curve) and cv.source is sp and cv.name == sp.name
    s = np.linspace(0.0, cv.length, 401)   # short chords: chord ≈ arc to O(κ²Δs²)
    steps = np.linalg.norm(np.diff(cv.xyz(s), axis=0), axis=1)
    assert steps == pytest.approx(np.full(400, cv.length / 400), rel=1e-4)
    np.testing.assert_allclose(cv.xyz([0.0, cv.length]), sp.xyz([sp.theta0, sp.theta1]),
                               atol=1e-9)
