"""`simulate --plant exudyn --json` reports the plant's pump energy beside evaluate()'s
(issue 30): the figure is the run's own pump work (its energy balance closes on it), and the
machine-priced quasi-static figure for the same plan is close to it."""
import json

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.simulation.dynamic.energy import energy_balance
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.trajectory import Trajectory, evaluate


def _move(crane):
    """A 2 s lift of boom and jib with a slew (min-jerk), from the middle of the ranges."""
    L = crane.limit_arrays()
    q0 = L["q_min"] + 0.45 * (L["q_max"] - L["q_min"])
    q1 = q0 + np.array([0.4, -0.15, -0.25, 0.0])
    t = np.linspace(0.0, 2.0, 101)
    s = t / 2.0
    d = q1 - q0
    return Trajectory(t, q0 + np.outer(10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5, d),
                      np.outer((30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / 2.0, d),
                      np.outer((60 * s - 180 * s ** 2 + 120 * s ** 3) / 4.0, d),
                      joint_names=tuple(crane.names))


def test_simulate_json_reports_the_plants_pump_energy(tmp_path, capsys, monkeypatch):
    crane = Crane.from_id("umea-lab")
    seen = {}
    real = ExudynPlant.pump_energy

    def spy(self, rec):
        seen.update(plant=self, rec=rec)
        return real(self, rec)
    monkeypatch.setattr(ExudynPlant, "pump_energy", spy)
    traj = _move(crane)
    plan = tmp_path / "plan.csv"
    traj.to_csv(plan)
    capsys.readouterr()
    rc = main(["simulate", "umea-lab", "--trajectory", str(plan), "--plant", "exudyn",
               "--out", str(tmp_path / "m.csv"), "--json", "-"])
    out = capsys.readouterr().out
    assert rc == 0, out
    r = json.loads(out)
    assert r["pricing"] == "machine"
    # the quasi-static figure is evaluate()'s for the plan the command read
    from planner.cli.common import read_trajectory
    ev = evaluate(crane, read_trajectory(crane, str(plan)))
    assert r["evaluate_energy_J"] == pytest.approx(ev.energy_J, rel=1e-9)
    # the plant's figure is its own pump work: the energy balance of the same run closes on it
    b = energy_balance(seen["plant"], seen["rec"].meta["run"])
    assert r["pump_energy_J"] == b["pump_shaft_J"] > 0
    assert abs(b["residual_rel"]) < 0.02
    # and the machine pricing is close to the plant (the seed's is not as close)
    seed = evaluate(Crane.from_id("umea-lab", pricing="seed"), traj).energy_J
    gap_m = abs(r["evaluate_energy_J"] / r["pump_energy_J"] - 1)
    gap_s = abs(seed / r["pump_energy_J"] - 1)
    assert gap_m < 0.25 and gap_m < gap_s      # measured: 0.18 and 0.29 (a fast 2 s move)
    # the twin's figure for the same commands: it carries the oil, the plant's pump within 2 %
    assert r["twin_energy_J"] == pytest.approx(r["pump_energy_J"], rel=0.02)
