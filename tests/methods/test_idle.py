"""Idle means idle (planner/methods/nlp/idle.py): creep found on the NLP's nodes, held still,
and the energy NLP's least-energy move under the machine pricing never costs more than the
minimum-time move it starts from."""
import numpy as np
import pytest

from planner import Crane
from planner.methods.nlp import MoveNLP
from planner.methods.nlp.energy import energy_optimal
from planner.methods.nlp.idle import USEFUL, creep_nodes, pinned
from planner.trajectory import evaluate


def _rates_for_fractions(crane, q, frac):
    """Joint rates (K, n) whose metered flow is ``frac`` (K, n) of each valve's full flow, built
    from the definition: extending meters A_a, retracting A_b (single-acting: A_a)."""
    _, dxdq = crane.stroke(q)
    G = np.array([j.actuator.flow_gain for j in crane.spec.joints])
    Aa = np.array([j.actuator.area_a for j in crane.spec.joints])
    Ab = np.array([j.actuator.area_b for j in crane.spec.joints])
    single = np.array([j.actuator.acting == "single" for j in crane.spec.joints])
    area = np.where((frac >= 0) | single, Aa, Ab)
    return frac * G / area / dxdq


def test_creep_is_a_run_of_small_openings_not_a_reversal(s100f):
    crane = s100f
    K = 8
    L = crane.limit_arrays()
    q = np.tile(0.5 * (L["q_min"] + L["q_max"]), (K, 1))
    frac = np.full((K, crane.n), 0.3)
    frac[2:5, 0] = [1e-5, -2e-3, 0.5 * USEFUL]   # a run of three small openings: creep
    frac[6, 1] = 1e-6                            # one node: a reversal, not creep
    frac[0:2, 2] = -1e-4                         # a run at the start, retracting
    frac[:, 3] = 2 * USEFUL                      # working, however slowly
    got = creep_nodes(crane, q, _rates_for_fractions(crane, q, frac))
    want = np.zeros((K, crane.n), bool)
    want[2:5, 0] = True
    want[0:2, 2] = True
    np.testing.assert_array_equal(got, want)
    # a longer minimum run leaves the two-node run out
    want[0:2, 2] = False
    np.testing.assert_array_equal(
        creep_nodes(crane, q, _rates_for_fractions(crane, q, frac), min_run=3), want)


@pytest.mark.parametrize("kw,field", [(dict(useful=0.0), "useful"), (dict(useful=1.5), "useful"),
                                      (dict(min_run=0), "min_run"),
                                      (dict(min_run=1.5), "min_run")])
def test_bad_creep_settings_name_the_field(s100f, kw, field):
    q = np.zeros((3, s100f.n)) + 0.5 * sum(s100f.limit_arrays()[k] for k in ("q_min", "q_max"))
    with pytest.raises(ValueError, match=rf"^{field}: .*allowed"):
        creep_nodes(s100f, q, np.zeros_like(q), **kw)


@pytest.fixture(scope="module")
def energy_nlp(s100f):
    return MoveNLP(s100f, "energy", "free", N=20)


def test_pinned_holds_the_joint_still_between_its_nodes_and_restores_the_bounds(s100f,
                                                                               energy_nlp):
    """Inside ``pinned`` the NLP's move keeps the held joint at rest over the held run, also
    between the nodes (sampled at 1 kHz, the trajectory's own interpolation); outside, the
    bounds are the NLP's own again."""
    en, crane = energy_nlp, s100f
    a, b = (7.0, 0.0, 0.0), (4.0, 0.5, 0.3)
    T = 6.0
    free = en.solve(a, b, T_max=T)
    assert free.ok
    idle = np.zeros((en.N + 1, crane.n), bool)
    idle[5:12, 0] = True                      # slew held over nodes 5..11
    lb, ub = en.lbw.copy(), en.ubw.copy()
    with pinned(en, idle, en.guess_from(free.trajectory)) as w0:
        X = en.layout.unpack(w0, "X")
        assert np.all(X[crane.n, 5:12] == 0) and np.all(X[2 * crane.n, 5:12] == 0)
        held = en.solve(a, b, T_max=T, w0=w0)
    np.testing.assert_array_equal(en.lbw, lb)
    np.testing.assert_array_equal(en.ubw, ub)
    assert held.ok
    tr = held.trajectory
    t = np.linspace(tr.t[5], tr.t[11], 500)
    q, qd = tr.sample(t)[:2]
    assert np.max(np.abs(qd[:, 0])) <= 1e-9
    assert np.ptp(q[:, 0]) <= 1e-9
    assert np.max(np.abs(tr.qd[:5, 0])) > 1e-3 or np.max(np.abs(tr.qd[12:, 0])) > 1e-3


def test_pinned_rejects_a_mask_of_the_wrong_shape(energy_nlp):
    with pytest.raises(ValueError, match=r"^idle: shape \(3, 4\); allowed: \(21, 4\)"):
        with pinned(energy_nlp, np.zeros((3, 4), bool), np.zeros(energy_nlp.lbw.shape)):
            pass


def test_energy_entry_under_machine_pricing_never_costs_more_than_its_time_entry(
        s100f, energy_nlp, monkeypatch):
    """A short move under the machine pricing: the least-energy move within 1.2 T_min costs no
    more than the minimum-time move by evaluate(), and holding the NLP's creep still
    (HOLD_ROUNDS) finds a cheaper move than the NLP alone (measured 59.0 against 62.0 kJ, the
    minimum-time move 68.3 kJ; since the closing spools' tails are priced — a function held
    still after moving keeps the pump at its holding pressure for ~0.4 s — 62.0 against
    63.2 kJ)."""
    from planner.methods.nlp import energy
    crane = s100f
    assert crane.pricing == "machine"
    tn = MoveNLP(crane, "time", "free", N=20)
    a, b = (7.0, 0.0, 0.0), (4.0, 0.5, 0.3)
    rt = tn.solve(a, b)
    assert rt.ok
    e_time = evaluate(crane, rt.trajectory).energy_J
    got = {}
    for rounds in (0, energy.HOLD_ROUNDS):
        monkeypatch.setattr(energy, "HOLD_ROUNDS", rounds)
        res, info = energy_optimal(crane, a, b, 1.2 * rt.duration_s, time_result=rt,
                                   time_nlp=tn, energy_nlp=energy_nlp)
        assert res.ok and res.duration_s <= 1.2 * rt.duration_s * (1 + 1e-6)
        ev = evaluate(crane, res.trajectory)
        assert ev.max_limit_violation <= 1e-3
        assert ev.energy_J == pytest.approx(info["energy_J"], rel=1e-12)
        assert ev.energy_J <= e_time
        got[rounds] = (ev.energy_J, info["held"])
    assert got[0][1] == 0 and got[energy.HOLD_ROUNDS][1] > 0
    assert got[energy.HOLD_ROUNDS][0] < 0.99 * got[0][0]
