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
    with pytest.raises(ValueError, match="bulk_modulus.*--plant exudyn"):
        respond(s100f, [0.0, 0.5, 1.0], u, q0, [BulkModulus(scale=0.5)])
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
