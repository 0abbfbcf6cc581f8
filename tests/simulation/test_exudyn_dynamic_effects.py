"""Effects only the dynamic plant has (issue 13, item 3): the oil's bulk modulus and an
actuator's hose volume, injected into the Exudyn plant, refused by everything quasi-static."""
from __future__ import annotations

import numpy as np
import pytest

from planner import Crane
from planner.calibration.discrepancy import Discrepancy, candidates
from planner.cli import main
from planner.model.effects import BulkModulus, HoseVolume, make, parse_effect
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.simulation.plant import respond


@pytest.fixture(scope="module")
def s100f():
    return Crane.from_id("s100f")


def free_frequency(crane, plant, i, q0):
    """Frequency [Hz] of joint i's free oscillation after a 0.2 s valve pulse (zero crossings
    of its stroke about the mean, after the valve closed)."""
    u = np.zeros((3, crane.n))
    u[0, i] = 0.3
    run = plant.run([0.0, 0.2, 3.0], u, q0)
    m = run.t > 0.45
    x = run.x[m, i] - run.x[m, i].mean()
    zc = np.flatnonzero(np.diff(np.sign(x)) != 0)
    return (len(zc) - 1) / 2 / (run.t[m][zc[-1]] - run.t[m][zc[0]])


def stiffness(crane, plant, i, q):
    """The analytic hydraulic stiffness β·(A_a²/V_a + A_b²/V_b) of actuator i at q [N/m]."""
    C = plant.circuit
    va, vb = C.volumes(crane.stroke(q)[0])
    return C.beta * (C.area_a[i] ** 2 / va[i]
                     + (0.0 if C.single[i] else C.area_b[i] ** 2 / vb[i]))


def test_neutral_values_leave_the_plant_as_specified(s100f):
    base = ExudynPlant(s100f).circuit
    same = ExudynPlant(s100f, [BulkModulus(scale=1.0), HoseVolume("boom", scale=1.0)]).circuit
    assert same.beta == base.beta
    assert np.array_equal(same.hose_a, base.hose_a) and np.array_equal(same.hose_b, base.hose_b)


def test_the_hydraulic_frequency_follows_the_analytic_law(s100f):
    """ω² ∝ β·(A_a²/V_a + A_b²/V_b): a quarter of the bulk modulus halves the slew's and the
    boom's free-oscillation frequency; four times the slew's hose volume lowers it as the
    analytic stiffness says (oracle: the circuit's own volumes)."""
    L = s100f.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    nominal = ExudynPlant(s100f)
    soft = ExudynPlant(s100f, [BulkModulus(scale=0.25)])
    for i in (0, 1):   # slew (rack cylinders), boom
        f0 = free_frequency(s100f, nominal, i, q0)
        assert free_frequency(s100f, soft, i, q0) / f0 == pytest.approx(0.5, rel=0.05)
    hose = ExudynPlant(s100f, [HoseVolume("slew", scale=4.0)])
    expect = np.sqrt(stiffness(s100f, hose, 0, q0) / stiffness(s100f, nominal, 0, q0))
    assert expect < 0.95
    assert (free_frequency(s100f, hose, 0, q0) / free_frequency(s100f, nominal, 0, q0)
            == pytest.approx(expect, rel=0.03))


def test_quasi_static_paths_refuse_them_naming_the_effect(s100f, tmp_path, capsys):
    u = np.zeros((3, s100f.n))
    q0 = 0.5 * (s100f.limit_arrays()["q_min"] + s100f.limit_arrays()["q_max"])
    with pytest.raises(ValueError, match="bulk_modulus.*`plant` = exudyn"):
        respond(s100f, [0.0, 0.5, 1.0], u, q0, [BulkModulus(scale=0.5)])
    with pytest.raises(ValueError, match="grapple_swing.*`plant` = exudyn"):
        respond(s100f, [0.0, 0.5, 1.0], u, q0, [make("grapple_swing", length=1.0)])
    with pytest.raises(ValueError, match="hose_volume.*quasi-static model cannot fit"):
        Discrepancy(s100f, candidates=["flow_gain", "hose_volume"])
    assert not any(e.stage == "dynamics" for e in candidates(s100f))
    rc = main(["simulate", "s100f", "--trajectory", str(tmp_path / "none.csv"), "--out",
               str(tmp_path / "m.csv"), "--effect", "bulk_modulus:scale=0.5"])
    err = capsys.readouterr().err
    assert rc == 2 and "bulk_modulus" in err and "--plant exudyn" in err
    assert not (tmp_path / "m.csv").exists()


def test_bad_values_are_refused_with_the_field_named(s100f):
    with pytest.raises(ValueError, match=r"scale = 0 .*plausible range \[0.1, 3\]"):
        make("bulk_modulus", scale=0.0)
    with pytest.raises(ValueError, match="needs joint"):
        make("hose_volume", scale=2.0)
    with pytest.raises(ValueError, match="unknown joint 'stick'"):
        ExudynPlant(s100f, [parse_effect("hose_volume:joint=stick,scale=2", None)])


# ----------------------------------------------------------------------------- grapple swing
def pin_swing(run, pin, after):
    """(frequency [Hz], exponential decay rate [1/s]) of a grapple pin's swing after ``after``
    [s] (zero crossings about the mean; a line through the log of the half-period peaks)."""
    from scipy.signal import find_peaks
    m = run.t > after
    t, x = run.t[m], run.grapple_q[m, pin] - run.grapple_q[m, pin].mean()
    zc = np.flatnonzero(np.diff(np.sign(x)) != 0)
    f = (len(zc) - 1) / 2 / (t[zc[-1]] - t[zc[0]])
    pk, _ = find_peaks(np.abs(x), distance=int(0.4 / f / (t[1] - t[0])))
    return f, -np.polyfit(t[pk], np.log(np.abs(x[pk])), 1)[0]


def test_the_grapple_hangs_still_at_rest_and_the_energy_balance_closes_when_it_swings(s100f):
    """Oracles: at rest the load hangs straight under the tip (the tree's own kinematics) and
    holds the rigid plant's pressures; swinging after slew and boom pulses, the pump's work
    equals the losses, the pins' damping and the change of mechanical energy of the crane and
    the swinging load within 2 % (the load's energy from the pin angles, not from Exudyn)."""
    from planner.simulation.dynamic.energy import energy_balance
    from planner.simulation.dynamic.grapple import link_frames
    L = s100f.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    plant = ExudynPlant(s100f, [make("grapple_swing", length=1.5, damping=200.0)])
    still = plant.run([0.0, 1.0], np.zeros((2, s100f.n)), q0)
    rigid = ExudynPlant(s100f).run([0.0, 1.0], np.zeros((2, s100f.n)), q0)
    assert still.ok and np.ptp(still.grapple_q, axis=0).max() < 1e-6
    assert np.abs(still.p_a - rigid.p_a).max() < 1e-3 * np.abs(rigid.p_a).max()
    _, links = link_frames(plant.tree, np.concatenate([q0, still.grapple_q[0]]))
    com = (links[-1] @ np.array([1.5, 0.0, 0.0, 1.0]))[:3]
    tip = links[s100f.n][:3, 3]
    assert np.allclose(com - tip, [0.0, 0.0, -1.5], atol=1e-9)

    u = np.zeros((3, s100f.n))
    u[0, 0], u[0, 1] = 0.4, 0.3
    run = plant.run([0.0, 1.0, 8.0], u, q0)
    assert run.ok and np.ptp(run.grapple_q[:, 1]) > 0.2    # it swings out of the boom plane
    bal = energy_balance(plant, run)
    assert bal["grapple_swing_J"] != 0 and bal["grapple_damping_J"] > 0
    assert abs(bal["residual_rel"]) < 0.02


@pytest.mark.slow
def test_the_grapple_swings_like_the_compound_pendulum(s100f):
    """Oracle: with the crane held stiff (oil 30× stiffer, valves closed after a short pulse)
    each pin swings at sqrt(g·L/(L²+k²))/2π (±1 %) and its damping decays the swing at
    c/(2·m·(L²+k²)) (±8 %; the pivot is still not perfectly still)."""
    from dataclasses import replace
    length, damping, k, m = 1.5, 400.0, 0.3, s100f.spec.payload.total
    I = length ** 2 + k ** 2
    f0 = np.sqrt(9.81 * length / I) / (2 * np.pi)
    dyn = replace(s100f.spec.dynamics, bulk_modulus=30 * s100f.spec.dynamics.bulk_modulus)
    plant = ExudynPlant(s100f, [make("grapple_swing", length=length, damping=damping)],
                        dynamics=dyn, step=1e-3)
    L = s100f.limit_arrays()
    q0 = 0.5 * (L["q_min"] + L["q_max"])
    for joint, pin in ((1, 0), (0, 1)):   # boom: swing in the boom plane; slew: out of it
        u = np.zeros((3, s100f.n))
        u[0, joint] = 0.15
        run = plant.run([0.0, 0.3, 8.0], u, q0)
        f, decay = pin_swing(run, pin, after=1.0)
        assert f == pytest.approx(f0, rel=0.01)
        assert decay == pytest.approx(damping / (2 * m * I), rel=0.08)
