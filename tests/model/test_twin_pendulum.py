"""The grapple pendulum in the dynamic twin and the refiner's swing term (issue 29).

Oracles: the model's own pendulum integrated along the same prescribed tip motion
(:func:`planner.model.pendulum.predict_swing`: RK4 on the plan's analytic tip acceleration,
another grid and another way to the acceleration); for the coupled twin, the twin without the
load on its link (which a vanishing load must reproduce, boom and all) and the one-way
pendulum along the coupled twin's own boom (which a vanishing load must swing alike); the
refinement without the swing term (what the swing term must beat) and the arguments'
documented ranges.
"""
import numpy as np
import pytest

from planner import Crane
from planner.feedforward import commands, stored_commands
from planner.methods.ruckig import rest_to_rest
from planner.model.pendulum import Pendulum, predict_swing
from planner.model.twin import Twin
from planner.model.twin.pendulum import TwinSwing, grapple_of
from planner.refine import RefineOptions, refine_commands
from planner.trajectory import Trajectory
from tests.conftest import step_commands

MACHINE = "umea-lab"   # the lightest twin: the compiled code builds quickest


@pytest.fixture(scope="module")
def crane():
    return Crane.from_id(MACHINE)


@pytest.fixture(scope="module")
def pend(crane):
    return Pendulum.of(crane, 1.0, zeta=0.05)


def _quintic(crane, a, b, T, rest):
    """A smooth rest-to-rest joint motion over ``T`` s, then ``rest`` s at the goal."""
    L = crane.limit_arrays()
    qa, qb = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (a, b))
    d = (qb - qa)[None, :]

    def f(t):
        s = np.clip(np.asarray(t, float) / T, 0.0, 1.0)[:, None]
        on = (np.asarray(t, float) <= T)[:, None]
        return (qa[None, :] + (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5) * d,
                on * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T * d,
                on * (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2 * d)
    return Trajectory.from_function(f, T + rest, rate=200.0)


def test_the_twins_swing_is_the_models_pendulum_on_a_prescribed_tip_motion(crane, pend):
    tr = _quintic(crane, 0.3, 0.7, 2.5, 2.0)
    h = 2e-3
    tk = np.arange(0.0, tr.duration + 1e-9, h)
    q, qd, _, _ = tr.sample(tk)
    S = TwinSwing(crane, pend, h).integrate(q, qd)
    ref = predict_swing(crane, tr, pend, rate=500.0)
    off = pend.offset(np.column_stack([np.interp(ref.t, tk, S[:, i]) for i in range(4)]))
    assert ref.peak_during_m > 0.05          # the move swings the load visibly
    assert np.max(np.abs(off - ref.offset)) < 1e-3 * ref.peak_during_m
    assert pend.amplitude(S[-1]) == pytest.approx(ref.residual_m, rel=1e-3, abs=1e-5)


@pytest.fixture(scope="module")
def move(crane):
    L = crane.limit_arrays()
    q0, q1 = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (0.35, 0.65))
    tr = rest_to_rest(crane, q0, q1, scale=0.8).trajectory
    return commands(crane, tr, 50.0).attach(tr, knots=True)


def test_the_coupled_twin_with_a_vanishing_load_is_the_plain_twin(crane, move):
    """Without a grapple the twin's numbers are its own; a load of a microgram on the link
    leaves the boom as without one, and swings as the one-way pendulum along that boom."""
    t_u, u = stored_commands(move)
    plain = Twin(crane)
    a = plain.simulate(t_u, u, move.q[0], t_end=move.t[-1] + 1.0)
    assert a.ok and a.swing is None and "grapple" not in plain.provenance()
    assert plain.rest_state(move.q[0]).size == 5 * crane.n + 1
    light = Pendulum.of(crane, 1.0, zeta=0.05, mass=1e-9)
    hung = Twin(crane, grapple=light)
    b = hung.simulate(t_u, u, move.q[0], t_end=move.t[-1] + 1.0)
    assert b.ok and b.swing.shape == (len(b.t), 4)
    for k, tol in (("q", 1e-7), ("qd", 1e-6), ("p_a", 1.0), ("p_b", 1.0), ("p_s", 1.0)):
        assert np.max(np.abs(getattr(a, k) - getattr(b, k))) < tol, k     # [rad | m, Pa]
    one_way = TwinSwing(crane, light, hung.step).integrate(b.q, b.qd)
    peak = np.max(np.linalg.norm(light.offset(one_way), axis=1))
    assert peak > 0.05                                       # the load does swing
    assert np.max(np.abs(light.offset(b.swing) - light.offset(one_way))) < 5e-3 * peak
    assert hung.provenance()["fingerprint"] != plain.provenance()["fingerprint"]


def test_the_loads_pull_moves_the_boom(crane, pend, move):
    """The payload on its link pulls the tip about (the boom differs from the plain twin's
    by more than the vanishing load's rounding), and the state at rest stays at rest."""
    t_u, u = stored_commands(move)
    hung = Twin(crane, grapple=pend)
    a = Twin(crane).simulate(t_u, u, move.q[0], t_end=move.t[-1] + 1.0)
    b = hung.simulate(t_u, u, move.q[0], t_end=move.t[-1] + 1.0)
    tip = np.linalg.norm(crane.fk(a.q) - crane.fk(b.q), axis=1).max()
    assert tip > 1e-3
    still = hung.simulate([0.0], np.zeros((1, crane.n)), move.q[0], t_end=1.0)
    assert np.max(np.abs(still.swing)) < 1e-9 and np.max(np.abs(still.q - move.q[0])) < 1e-6


@pytest.mark.slow   # two refinements on the coupled twin (its adjoint compiled once: minutes)
def test_the_swing_term_leaves_less_predicted_swing_than_without_it(crane, pend, move):
    t_u, u = stored_commands(move)
    twin = Twin(crane, grapple=pend)
    runs = {w: refine_commands(crane, move, t_u, u, twin=twin,
                               options=RefineOptions(iterations=15, settle=1.5, swing_weight=w))
            for w in (0.0, 10.0)}
    nominal = runs[0.0].predicted["nominal"]["swing_after_m"]
    blind = runs[0.0].predicted["refined"]["swing_after_m"]
    aware = runs[10.0].predicted["refined"]["swing_after_m"]
    assert nominal > 5e-3                  # the nominal commands leave the load swinging
    assert aware < 0.5 * min(nominal, blind)
    assert runs[10.0].predicted["refined"]["rest_offset_m"] < \
        runs[10.0].predicted["nominal"]["rest_offset_m"]         # and the tip still lands
    assert runs[10.0].model["grapple"]["length_m"] == pytest.approx(1.0)


@pytest.mark.parametrize("value", [-1.0, 0.0, 25.0, "long"])
def test_a_bad_grapple_length_names_the_field(crane, value):
    with pytest.raises(ValueError, match="`grapple`.*allowed"):
        grapple_of(crane, value)


def test_a_bad_swing_weight_names_the_field(crane, move):
    with pytest.raises(ValueError, match="'swing_weight'"):
        RefineOptions(swing_weight=-1.0)
    t_u, u = stored_commands(move)       # a swing term needs a twin with the load on its link
    with pytest.raises(ValueError, match="'swing_weight'.*grapple"):
        refine_commands(crane, move, t_u, u, twin=Twin(crane),
                        options=RefineOptions(iterations=1, swing_weight=1.0))


@pytest.mark.slow   # a whole-process plan and a 150-iteration refinement on the coupled twin
def test_plan_with_the_twin_feedforward_and_a_grapple_leaves_less_swing():
    """`plan --feedforward twin --grapple L`: the refined commands are refined with the swing
    term on the twin carrying the load, and its predicted swing after arrival is smaller than
    the nominal commands'."""
    import json
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "planner", "plan", MACHINE, "--start",
                        "1.2,0.5,0", "--goal", "1.8,0.8,20deg", "--method", "ruckig",
                        "--feedforward", "twin", "--grapple", "0.5", "--json"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr
    ff = json.loads(r.stdout)["feedforward"]
    assert ff["commands"] == "refined" and ff["model"]["grapple"]["length_m"] == 0.5
    assert ff["options"]["swing_weight"] > 0
    nominal, refined = ff["predicted"]["nominal"], ff["predicted"]["refined"]
    assert refined["swing_after_m"] < 0.5 * nominal["swing_after_m"]
    assert refined["rest_offset_m"] < nominal["rest_offset_m"]


@pytest.mark.slow   # compiles the coupled twin's adjoint once per user (minutes when cold)
def test_the_coupled_twins_adjoint_gradient_matches_central_differences(crane, pend, move):
    """∂J/∂u of a cost on the swing's states and the joints, by the twin's adjoint on the
    longer state, against central differences of the same forward runs."""
    from planner.model.twin.shooting import Shooting
    twin = Twin(crane, grapple=pend)
    sh = Shooting(twin)
    t_u, u = stored_commands(move)
    R, K, us = step_commands(sh, u, 100)
    x0 = twin.rest_state(move.q[0])
    rng = np.random.default_rng(5)
    W = np.zeros((K + 1, sh.nx))
    W[:, -4:] = rng.normal(size=(K + 1, 4))
    W[:, :crane.n] = 0.1 * rng.normal(size=(K + 1, crane.n))

    def J(uu):
        return float(np.sum(W * sh.run(x0, uu).x))

    g = sh.gradient(sh.run(x0, us), us, W)
    m = len(u) * R
    for _ in range(2):
        d = np.zeros_like(us)
        d[:m] = np.repeat(0.05 * rng.normal(size=(len(u), crane.n)), R, axis=0)
        eps = 1e-4
        fd = (J(us + eps * d) - J(us - eps * d)) / (2 * eps)
        assert np.sum(g * d) == pytest.approx(fd, rel=5e-3, abs=1e-9)


def test_the_coupled_twin_swings_as_the_exudyn_plant(crane, pend):
    """Oracle: the Exudyn plant with the same grapple on its own two-pin tree (an independent
    multibody and circuit code). The same 50 Hz commands of a 2.5 s move, then 2 s: the load's
    horizontal offset from under the tip on the coupled twin within 3 mm of the plant's over
    the whole record (measured 1.1 mm of a 284 mm swing)."""
    from planner.model.effects import make
    from planner.simulation.plants import load_swing, make_plant
    tr = _quintic(crane, 0.3, 0.7, 2.5, 2.0)
    ff = commands(crane, tr, 50.0)
    t_u, u = np.asarray(ff.t, float), np.asarray(ff.u, float)
    t_end = float(t_u[-1]) + 2.0
    plant = make_plant("exudyn", crane, [make("grapple_swing", length=pend.length,
                                              damping=round(pend.damping, 3))])
    rec = plant.run(t_u, u, tr.q[0], t_end=t_end, rate=50.0)
    ts, sp = load_swing(plant, rec)
    run = Twin(crane, grapple=pend).simulate(t_u, u, tr.q[0], t_end=t_end)
    st = pend.offset(run.swing)
    grid = np.arange(0.0, t_end, 0.02)

    def at(t, x):
        return np.column_stack([np.interp(grid, t, x[:, i]) for i in range(2)])
    assert np.abs(sp).max() > 0.1
    assert np.linalg.norm(at(ts, sp) - at(run.t, st), axis=1).max() < 3e-3
