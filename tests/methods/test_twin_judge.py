"""The energy planner's second price (issue 30): a candidate's pump energy on the dynamic twin
(:mod:`planner.methods.nlp.twin_judge`) is the Exudyn plant's for the same commands (the
plant is independent code), and ``energy_optimal(judge="twin")`` keeps the candidate the twin
prices lowest, saying so."""
from dataclasses import replace

import numpy as np
import pytest

from planner import Crane
from planner.feedforward import commands
from planner.methods.nlp import energy
from planner.methods.nlp.energy import energy_optimal
from planner.methods.nlp.move import MoveNLP
from planner.methods.nlp.twin_judge import RATE, SETTLE, has_twin, twin_pump_energy
from planner.simulation.dynamic.claims import replay_move
from planner.simulation.dynamic.energy import energy_balance
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.trajectory import Trajectory, evaluate


def _move(crane, T=2.5):
    """A min-jerk move of slew, boom and jib from the middle of the ranges."""
    L = crane.limit_arrays()
    q0 = L["q_min"] + 0.45 * (L["q_max"] - L["q_min"])
    d = np.array([0.4, -0.15, -0.25, 0.0])
    t = np.linspace(0.0, T, 126)
    s = t / T
    return Trajectory(t, q0 + np.outer(10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5, d),
                      np.outer((30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T, d),
                      np.outer((60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2, d),
                      joint_names=tuple(crane.names))


def test_the_twins_pump_energy_is_the_plants(s100f):
    """Oracle: the Exudyn plant's own pump work (its energy balance) for the same 50 Hz
    feed-forward (the library's: the oil springs filled), valves closed after the end, the same
    settle — independent code."""
    traj = _move(s100f)
    w_twin = twin_pump_energy(s100f, traj)
    ff = commands(s100f, traj, RATE, oil=True)
    plant = ExudynPlant(s100f)
    m, run, _ = replay_move(s100f, traj, t_u=ff.t, u=ff.u, settle=SETTLE, plant=plant,
                            keep_runs=True)
    assert m.status == "ok"
    w_plant = energy_balance(plant, run)["pump_shaft_J"]
    assert w_twin == pytest.approx(w_plant, rel=0.01)
    # the plain feed-forward (no oil filled) rings the oil springs: the twin sees the plant pay
    # more than the quasi-static figure; filled, the plant pays what evaluate() prices
    w_eval = evaluate(s100f, traj).energy_J
    plain = commands(s100f, traj, RATE)
    from planner.methods.nlp.twin_judge import commands_pump_energy
    w_plain = commands_pump_energy(s100f, np.append(plain.t, plain.t[-1] + 1 / RATE),
                                   np.vstack([plain.u, np.zeros((1, s100f.n))]), traj.q[0],
                                   plain.t[-1] + 1 / RATE + SETTLE)
    assert w_plain / w_eval - 1 > 0.03
    assert w_plant == pytest.approx(w_eval, rel=0.01)


def test_no_twin_no_price(s100f):
    crane = Crane(replace(s100f.spec, dynamics=None))
    assert not has_twin(crane) and has_twin(s100f)
    assert twin_pump_energy(crane, _move(crane)) is None


def test_energy_optimal_keeps_what_the_twin_prices_lowest(s100f, monkeypatch):
    """A fake twin price that makes the minimum-time move the cheapest: the twin judge keeps
    it (and says so); the default judge keeps evaluate()'s cheapest, as before."""
    tn = MoveNLP(s100f, "time", "free", N=12)
    en = MoveNLP(s100f, "energy", "free", N=12)
    a, b = (7.0, 0.0, 0.0), (4.0, 0.5, 0.3)
    rt = tn.solve(a, b)
    assert rt.ok
    T = 1.2 * rt.duration_s
    kw = dict(time_result=rt, time_nlp=tn, energy_nlp=en)
    base, info0 = energy_optimal(s100f, a, b, T, **kw)
    assert info0["judge"] == "evaluate" and info0["winner"] != "time_optimal"
    seen = []

    def fake(crane, traj, twin=None):
        seen.append(traj.duration)
        return 1.0 if traj.duration < rt.duration_s * (1 + 1e-9) else 2.0
    monkeypatch.setattr(energy, "twin_pump_energy", fake)
    res, info = energy_optimal(s100f, a, b, T, judge="twin", **kw)
    assert info["judge"] == "twin" and info["winner"] == "time_optimal"
    assert res is rt
    assert len(info["twin_J"]) == len(seen) >= 3   # stretched, time-optimal, the NLP's
    assert info["energy_J"] == pytest.approx(evaluate(s100f, rt.trajectory).energy_J)
    # no twin figure for any candidate: evaluate()'s choice stands, and says so
    monkeypatch.setattr(energy, "twin_pump_energy", lambda *a, **k: None)
    res2, info2 = energy_optimal(s100f, a, b, T, judge="twin", **kw)
    assert info2["judge"] == "evaluate" and info2["winner"] == info0["winner"]


def test_energy_optimal_rejects_an_unknown_judge(s100f):
    with pytest.raises(ValueError, match=r"^judge: 'exudyn' is not a judge; allowed: "
                                         r"evaluate, twin$"):
        energy_optimal(s100f, (7.0, 0.0, 0.0), (4.0, 0.5, 0.3), 5.0, judge="exudyn")
