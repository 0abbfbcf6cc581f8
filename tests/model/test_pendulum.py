"""The grapple pendulum against analytic oracles: its small-angle frequency, the response of a
rest-to-rest bang-bang move (superposed step responses of a harmonic oscillator), energy
conservation without damping, the decay rate with it, and the tip acceleration of the crane's
kinematics against finite differences."""
import math

import casadi as ca
import numpy as np
import pytest

from planner import Crane
from planner.model.pendulum import Pendulum, predict_swing, tip_motion
from planner.trajectory import Trajectory

G = 9.81


def test_the_swing_function_is_a_named_casadi_function():
    p = Pendulum(length=1.5, mass=880.0)
    assert isinstance(p.f_swing, ca.Function) and p.f_swing.name() == "swing_rhs"
    assert p.f_swing.size1_in(0) == 4 and p.f_swing.size1_in(1) == 12   # the drive
    # hanging at rest with the tip still: an equilibrium
    assert np.allclose(p.rhs([0, 0, 0, 0], [0, 0, 0]), 0.0)


def test_small_angle_frequency_is_sqrt_g_over_l_for_a_point_mass():
    L = 1.5
    p = Pendulum(length=L, mass=100.0, gyration=0.0, gravity=G)
    assert p.omega == pytest.approx(math.sqrt(G / L))
    # linearise the rhs numerically: d(alpha_ddot)/d(alpha) = -omega²
    eps = 1e-6
    for i in (0, 1):
        x = np.zeros(4)
        x[i] = eps
        assert p.rhs(x, [0, 0, 0])[2 + i] / eps == pytest.approx(-G / L, rel=1e-5)
    # free swing from a small angle: the period of the integrated motion
    t = np.linspace(0, 10, 5001)
    x = p.integrate(t, lambda s: np.zeros((len(s), 3)), x0=(0.01, 0, 0, 0))
    up = np.where((x[:-1, 0] < 0) & (x[1:, 0] >= 0))[0]
    period = np.mean(np.diff(t[up]))
    assert period == pytest.approx(2 * math.pi * math.sqrt(L / G), rel=1e-3)


def test_gyration_lowers_the_frequency():
    p = Pendulum(length=1.5, mass=880.0, gyration=0.3)
    assert p.omega == pytest.approx(math.sqrt(G * 1.5 / (1.5 ** 2 + 0.09)))
    assert p.omega / (2 * math.pi) == pytest.approx(0.40, abs=0.005)   # exudyn_grapple.md


@pytest.mark.parametrize("tau_periods", [0.37, 0.5, 1.0, 1.6])
def test_rest_to_rest_move_leaves_the_analytic_residual_swing(tau_periods):
    """Accelerate a0 for τ, brake −a0 for τ: steps +a0, −2a0, +a0 of the forcing of
    β̈ + ω²β = −ω² a/g, so after the move the offset L β swings with amplitude
    L (a0/g) |1 − e^{−iωτ}|² = L (a0/g) 4 sin²(ωτ/2) — zero when τ is a whole period."""
    L, a0 = 1.5, 0.3
    p = Pendulum(length=L, mass=880.0, gyration=0.0)
    tau = tau_periods * 2 * math.pi / p.omega

    def acc(s):
        s = np.asarray(s)
        ax = np.where(s < tau, a0, np.where(s < 2 * tau, -a0, 0.0))
        return np.column_stack([ax, 0 * s, 0 * s])

    # grid aligned with the switch times so RK4 never straddles a step
    t = np.unique(np.concatenate([np.linspace(0, tau, 800), np.linspace(tau, 2 * tau, 800)]))
    x = p.integrate(t, acc)
    want = L * a0 / G * 4 * math.sin(p.omega * tau / 2) ** 2
    got = p.amplitude(x[-1])
    assert got == pytest.approx(want, rel=2e-2, abs=2e-3)
    # the swing is in the x direction only
    assert np.max(np.abs(p.offset(x)[:, 1])) < 1e-9


def test_energy_is_conserved_without_damping_and_decays_with_it():
    p = Pendulum(length=1.5, mass=880.0, gyration=0.3, damping=0.0)
    x0 = (0.3, -0.2, 0.4, 0.5)              # large angles, both pins, spinning
    t = np.linspace(0, 20, 8001)
    x = p.integrate(t, lambda s: np.zeros((len(s), 3)), x0=x0)
    E = p.energy(x)
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-6
    pd = Pendulum(length=1.5, mass=880.0, gyration=0.3, damping=516.0)
    assert pd.zeta == pytest.approx(0.05, abs=0.002)
    xs = pd.integrate(t, lambda s: np.zeros((len(s), 3)), x0=(0.02, 0, 0, 0))
    Ed = pd.energy(xs)
    # small swing: energy ∝ exp(−2 ζ ω t)
    k = np.searchsorted(t, 10.0)
    assert Ed[k] / Ed[0] == pytest.approx(math.exp(-2 * pd.zeta * pd.omega * t[k]), rel=0.05)


def test_amplitude_of_a_planar_swing_is_its_largest_offset():
    p = Pendulum(length=1.5, mass=880.0, gyration=0.3)
    t = np.linspace(0, 5, 4001)
    x = p.integrate(t, lambda s: np.zeros((len(s), 3)), x0=(0.0, 0.0, 0.0, 0.2))
    peak = np.max(np.linalg.norm(p.offset(x), axis=1))
    assert p.amplitude(x[0]) == pytest.approx(peak, rel=1e-3)


def test_bad_values_are_refused_in_one_line():
    with pytest.raises(ValueError, match=r"`length` = -1.*allowed"):
        Pendulum(length=-1, mass=880.0)
    with pytest.raises(ValueError, match="no \\[dynamics.grapple\\]"):
        Pendulum.of(Crane.from_id("umea-lab"))


def test_of_takes_the_payload_and_the_damping_ratio():
    crane = Crane.from_id("s100f")
    p = Pendulum.of(crane, 1.5, zeta=0.05)
    assert p.mass == crane.spec.payload.total and p.zeta == pytest.approx(0.05)
    assert p.damping == pytest.approx(516, abs=1.0)          # exudyn_grapple.md's pins


def test_tip_acceleration_matches_finite_differences_of_the_kinematics():
    crane = Crane.from_id("s100f")
    rng = np.random.default_rng(3)
    lim = np.array([j.limits.q for j in crane.spec.joints])
    q0 = lim[:, 0] + (0.3 + 0.4 * rng.random(crane.n)) * (lim[:, 1] - lim[:, 0])
    qd0, qdd0 = 0.2 * rng.standard_normal(crane.n), 0.3 * rng.standard_normal(crane.n)
    path = lambda s: q0 + qd0 * s + 0.5 * qdd0 * s * s     # noqa: E731
    h = 1e-4
    fd = (crane.fk(path(h)) - 2 * crane.fk(path(0.0)) + crane.fk(path(-h))) / h ** 2
    p, v, a = (np.array(o).ravel() for o in tip_motion(crane)(q0, qd0, qdd0)[:3])
    assert np.allclose(p, crane.fk(q0))
    assert np.allclose(a, fd, atol=1e-4)


def test_a_plan_held_still_leaves_no_swing_and_a_moving_one_does():
    crane = Crane.from_id("s100f")
    pend = Pendulum.of(crane, 1.5, zeta=0.05)
    lim = np.array([j.limits.q for j in crane.spec.joints])
    qa = lim[:, 0] + 0.4 * (lim[:, 1] - lim[:, 0])
    qb = lim[:, 0] + 0.6 * (lim[:, 1] - lim[:, 0])
    T = 2.0
    t = np.linspace(0, T, 201)
    s = t / T
    sh = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
    sd = (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T
    sdd = (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2
    dq = qb - qa
    tr = Trajectory(t, qa + sh[:, None] * dq, sd[:, None] * dq, sdd[:, None] * dq)
    pred = predict_swing(crane, tr, pend)
    assert pred.residual_m > 0.05 and pred.peak_during_m > 0.05
    still = Trajectory(t, np.tile(qa, (len(t), 1)), np.zeros((len(t), crane.n)),
                       np.zeros((len(t), crane.n)))
    quiet = predict_swing(crane, still, pend)
    assert quiet.residual_m < 1e-9 and quiet.peak_during_m < 1e-9


def test_the_plants_load_swings_as_the_model_says_when_the_pins_turn_with_the_boom():
    """Oracle: the Exudyn plant, whose grapple hangs on two pins of its own kinematic tree
    (an independent multibody code). Driven by the plant's recorded joints (a slew and boom
    pulse, then 5 s of free swing; measured 0.0 / 24 mm), the model's swing is the plant's
    within 2 mm; the same
    model on a pivot that does not turn (the tip's acceleration alone: the load not spinning
    with the slew) is off by more than 5 times that: the drive's link rotation is needed."""
    from scipy.interpolate import CubicSpline

    from planner.model.effects import make
    from planner.simulation.dynamic.exudyn_plant import ExudynPlant
    from planner.simulation.dynamic.grapple import link_frames
    crane = Crane.from_id("s100f")
    L = crane.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    plant = ExudynPlant(crane, [make("grapple_swing", length=1.5, damping=200.0)])
    u = np.zeros((3, crane.n))
    u[0, 0], u[0, 1] = 0.4, 0.3
    run = plant.integrate([0.0, 1.0, 6.0], u, q0)
    assert run.ok
    tree, n = plant.tree, crane.n
    _, links = link_frames(tree, np.hstack([run.q, run.grapple_q]))
    swing = (links[-1] @ np.array([1.5, 0.0, 0.0, 1.0]))[:, :2] - links[n][:, :2, 3]
    t = np.asarray(run.t)
    spline = CubicSpline(t, run.q)
    tr = Trajectory(t, run.q, spline(t, 1), spline(t, 2))
    pend = Pendulum(length=1.5, mass=crane.spec.payload.total, damping=200.0, gyration=0.3)
    pred = predict_swing(crane, tr, pend, rate=500.0)
    at = np.column_stack([np.interp(t, pred.t, pred.offset[:, i]) for i in range(2)])
    assert np.abs(swing).max() > 0.1                           # it does swing
    gap = np.linalg.norm(at - swing, axis=1).max()
    assert gap < 2e-3
    f = tip_motion(crane)
    acc = lambda s: np.array(f.map(len(s))(*(v.T for v in tr.sample(s)[:3]))[2]).T  # noqa
    blind = pend.offset(pend.integrate(pred.t, acc))
    at = np.column_stack([np.interp(t, pred.t, blind[:, i]) for i in range(2)])
    assert np.linalg.norm(at - swing, axis=1).max() > 5 * max(gap, 2e-3)


def _lagrange_rhs(x, drive, L, m, k, c, g):
    """A second derivation of the swing's equations (the oracle): Lagrange's equations of the
    kinetic energy ½ m |ḋ|² + ½ m k² |ω_b|² in the pivot's frame, differentiated by CasADi,
    the pins' damping as a Rayleigh function ½ c |r|² of the pin rates."""
    th, thd = x[:2], x[2:]
    a, e1, wl, wld = drive[0:3], drive[3:6], drive[6:9], drive[9:12]
    d = L * ca.vertcat(ca.sin(th[1]), -ca.sin(th[0]) * ca.cos(th[1]),
                       -ca.cos(th[0]) * ca.cos(th[1]))
    J = ca.jacobian(d, th)
    u, ud = d / L, J @ thd / L
    e2 = ca.cross(u, e1) / ca.norm_2(ca.cross(u, e1))
    A = ca.horzcat(ca.cross(e1, u), ca.cross(e2, u))
    r = ca.solve(A.T @ A, A.T @ (ud - ca.cross(wl, u)))
    wb = wl + r[0] * e1 + r[1] * e2
    T = 0.5 * m * ca.dot(J @ thd, J @ thd) + 0.5 * m * k * k * ca.dot(wb, wb)
    p = ca.gradient(T, thd)
    dp = (ca.jacobian(p, th) @ thd + ca.jacobian(p, e1) @ ca.cross(wl, e1)
          + ca.jacobian(p, wl) @ wld)
    Q = m * J.T @ (ca.vertcat(0, 0, -g) - a) - c * ca.jacobian(r, thd).T @ r
    return ca.solve(ca.jacobian(p, thd), Q - dp + ca.gradient(T, th))


def test_the_swing_equations_are_lagranges():
    """Oracle: Lagrange's equations of the same body (above), on random swing states and
    drives (the pivot accelerating, the boom turning about a tilted axis): the model's
    Newton–Euler right-hand side agrees to round-off."""
    x, dv = ca.SX.sym("x", 4), ca.SX.sym("d", 12)
    L, m, k, c, g = 1.5, 880.0, 0.3, 516.0, 9.81
    oracle = ca.Function("lagrange", [x, dv], [_lagrange_rhs(x, dv, L, m, k, c, g)])
    p = Pendulum(length=L, mass=m, damping=c, gyration=k, gravity=g)
    rng = np.random.default_rng(7)
    for _ in range(50):
        s = rng.normal(0.0, 0.3, 4)
        e1 = np.array([-np.sin(rng.uniform(0, 6)), np.cos(rng.uniform(0, 6)), 0.1])
        drive = np.concatenate([rng.normal(0, 1, 3), e1 / np.linalg.norm(e1),
                                rng.normal(0, 0.5, 3), rng.normal(0, 1, 3)])
        want = np.array(oracle(s, drive)).ravel()
        assert np.allclose(p.rhs(s, drive)[2:], want, rtol=1e-9, atol=1e-9)
