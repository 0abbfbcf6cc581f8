"""ZV / ZVD input shaping: the impulse trains against the damped oscillator's residual-vibration
formula, a shaped bang-bang move leaving a linear pendulum (nearly) still, and the registered
``zv`` / ``zvd`` methods on s100f (limits, duration, the model's predicted swing)."""
import math

import numpy as np
import pytest

from planner import Crane
from planner.methods import PlanRequest, UnsupportedRequest, plan
from planner.methods.shaping import shape, shaper
from planner.model.pendulum import Pendulum, predict_swing
from planner.trajectory import Trajectory, evaluate

MOVE = ((6.0, 1.5, -0.25), (4.8, 0.2, 0.25))


def residual(times, amps, omega, zeta):
    """Residual vibration of a damped oscillator after the impulse train, relative to one
    unit impulse (Singer & Seering's V)."""
    wd = omega * math.sqrt(1 - zeta ** 2)
    tN = times[-1]
    C = sum(A * math.exp(zeta * omega * t) * math.cos(wd * t) for t, A in zip(times, amps))
    S = sum(A * math.exp(zeta * omega * t) * math.sin(wd * t) for t, A in zip(times, amps))
    return math.exp(-zeta * omega * tN) * math.hypot(C, S)


@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.2])
@pytest.mark.parametrize("kind", ["zv", "zvd"])
def test_shapers_cancel_their_mode_and_sum_to_one(kind, zeta):
    w = 2.5
    times, amps = shaper(kind, w, zeta)
    assert amps.sum() == pytest.approx(1.0) and np.all(amps > 0)
    assert residual(times, amps, w, zeta) < 1e-12
    # off-frequency by 10 %: ZVD's residual is second order in the error, ZV's first
    off = residual(times, amps, 1.1 * w, zeta)
    assert off < (0.03 if kind == "zvd" else 0.2)
    assert off > (0.0 if kind == "zvd" else 0.1)


def test_a_bad_shaper_is_refused_in_one_line():
    with pytest.raises(ValueError, match="`kind` = 'zx'.*allowed zv, zvd"):
        shaper("zx", 2.0)
    with pytest.raises(ValueError, match="`omega`"):
        shaper("zv", 0.0)


@pytest.mark.parametrize("kind", ["zv", "zvd"])
def test_a_shaped_move_leaves_a_linear_pendulum_still(kind):
    """A one-axis tip move (bang-bang in acceleration, 2 s, 1 m) shaped at the pendulum's
    frequency: the small-angle residual swing drops from tens of cm to under a few mm."""
    p = Pendulum(length=1.5, mass=880.0, gyration=0.3, damping=516.0)
    T, D = 2.0, 1.0
    t = np.linspace(0, T, 401)
    a0 = 4 * D / T ** 2
    acc = np.where(t < T / 2, a0, -a0)
    vel = np.where(t < T / 2, a0 * t, a0 * (T - t))
    pos = np.where(t < T / 2, 0.5 * a0 * t ** 2, D - 0.5 * a0 * (T - t) ** 2)
    tr = Trajectory(t, pos[:, None], vel[:, None], acc[:, None])
    times, amps = shaper(kind, p.omega, p.zeta)
    sh = shape(tr, times, amps)
    assert sh.duration == pytest.approx(T + times[-1])
    assert sh.q[-1, 0] == pytest.approx(D) and sh.qd[-1, 0] == pytest.approx(0.0, abs=1e-12)

    def run(traj):
        def a_of(s):
            return np.column_stack([traj.sample(s)[2][:, 0], 0 * s, 0 * s])
        grid = np.unique(np.concatenate([traj.resample(500.0), traj.t]))
        return p.amplitude(p.integrate(grid, a_of)[-1])
    before, after = run(tr), run(sh)
    assert before > 0.1
    assert after < 0.02 * before


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


@pytest.mark.parametrize("kind", ["zv", "zvd"])
def test_zv_and_zvd_plan_within_limits_and_cut_the_predicted_swing(s100f, kind):
    opts = {"grapple": 1.5, "grapple_zeta": 0.05}
    res = plan(s100f, PlanRequest(*MOVE, options=opts), kind)
    assert res.ok, res.reason
    pend = Pendulum.of(s100f, 1.5, zeta=0.05)
    times, _ = shaper(kind, pend.omega, pend.zeta)
    assert res.duration_s == pytest.approx(res.base_duration_s * res.stretched_by + times[-1],
                                           rel=1e-6)
    assert evaluate(s100f, res.trajectory).max_limit_violation <= 1e-3
    base = plan(s100f, PlanRequest(*MOVE), "nlp")
    before = predict_swing(s100f, base.trajectory, pend).residual_m
    after = predict_swing(s100f, res.trajectory, pend).residual_m
    assert after == pytest.approx(res.swing_residual_m)
    assert after < (0.25 if kind == "zv" else 0.1) * before


def test_without_a_grapple_the_shapers_refuse_naming_the_machine():
    crane = Crane.from_id("umea-lab")
    with pytest.raises(UnsupportedRequest, match="umea-lab.*`grapple`") as e:
        plan(crane, PlanRequest((1.8, 0.4, -0.25), (3.0, 1.3, 0.25)), "zv")
    assert "\n" not in str(e.value)
    with pytest.raises(UnsupportedRequest, match="`grapple` = -1"):
        plan(crane, PlanRequest((1.8, 0.4, -0.25), (3.0, 1.3, 0.25),
                                options={"grapple": -1}), "zvd")
