"""The discrepancy workflow on hidden effects: every catalogue effect injected into the plant
(the workflow sees only the recording) must be named, clean data must give "none", the gap must
shrink, the CLI must write its JSON/report/model only on success, and results are deterministic.
Short recordings (25 s) keep this in the default suite; the ≥ 100-trial statistics are in
benchmarks/bench_discrepancy.py."""
import json
import math

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.calibration.compensate import closed_loop
from planner.calibration.discrepancy import Discrepancy, noise_floor
from planner.model.effects import CATALOGUE
from planner.calibration.trials import excitation, hidden_trial

DUR = 25.0


def test_noise_floor_recovers_white_noise_under_a_smooth_signal():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 60, 3000)
    y = np.column_stack([np.sin(0.5 * t) * 2.0 + rng.normal(0, 0.01, t.size),
                         1e6 * np.cos(0.3 * t) + rng.normal(0, 1.7e5, t.size)])
    s = noise_floor(y)
    assert s[0] == pytest.approx(0.01, rel=0.08) and s[1] == pytest.approx(1.7e5, rel=0.08)


# the default run checks one effect; the whole catalogue runs with -m slow (make bench)
FAST = ("flow_gain",)   # a valve effect (coulomb_friction and the rest: -m slow)


@pytest.mark.parametrize("name", [pytest.param(n, marks=() if n in FAST else pytest.mark.slow)
                                  for n in CATALOGUE])
def test_each_hidden_effect_is_named(cat215b, name):
    seed = 300 + list(CATALOGUE).index(name)
    rec, _, _, truth = hidden_trial(cat215b, name, seed, DUR)
    res = Discrepancy(cat215b, second=False).fit(rec)
    assert res.effect == name, (truth, res.message, res.ranking[:3])
    if name in FAST:                            # the verdict as the CLI reports it
        assert res.verdict == "named" and res.confidence is not None and res.confidence > 0.99
        assert res.to_json()["verdict"] == "named"
    if truth.joint:
        assert res.joint == truth.joint
    assert res.gap_reduction >= 0.5
    for k, v in truth.values.items():           # the estimate within 5 standard errors
        sd = res.uncertainty[k]
        assert abs(res.parameters[k] - v) <= 5 * sd + 1e-3 * max(abs(v), 1e-12) + 1e-9, \
            (k, v, res.parameters[k], sd)


@pytest.mark.slow   # clean data are also judged in test_verdicts (the explained verdict)
@pytest.mark.parametrize("machine,seed", [("cat215b", 11), ("s100f", 12), ("umea-lab", 13)])
def test_clean_data_give_none(machine, seed):
    crane = Crane.from_id(machine)
    rec, _, _, _ = hidden_trial(crane, None, seed, DUR)
    res = Discrepancy(crane).fit(rec)
    assert res.effect is None and res.effects == ()
    assert res.verdict == "explained"
    assert res.message.startswith("none: the nominal model explains the data within noise")


@pytest.mark.slow   # two effects, two searches (~20 s)
def test_a_second_effect_is_found_on_top(cat215b):
    from planner.model.effects import make
    from planner.calibration.trials import record
    plan, ff = excitation(cat215b, 40.0, seed=5)
    truth = (make("flow_gain", "stick", scale=0.85), make("coulomb_friction", "boom", force=8e3))
    rec = record(cat215b, plan, ff, truth, seed=5)
    res = Discrepancy(cat215b).fit(rec)
    names = {(res.effect, res.joint), (res.second["effect"], res.second["joint"])}
    assert names == {("flow_gain", "stick"), ("coulomb_friction", "boom")}


@pytest.mark.slow   # a study-sized check (~15 s): make bench
def test_replanned_feedforward_tracks_the_true_plant_better(cat215b):
    from planner.calibration.trials import trackable
    rec, plan, _, truth = hidden_trial(cat215b, "flow_gain", 21, DUR)
    res = Discrepancy(cat215b, second=False).fit(rec)
    cl = closed_loop(cat215b, trackable(cat215b, plan), res.effects, plant_effects=(truth,))
    assert cl["after"]["rms_m"] < 0.05 * cl["before"]["rms_m"]


@pytest.mark.slow   # ~7 s: make bench
def test_position_only_recordings_work(cat215b):
    from planner.calibration.trials import record
    plan, ff = excitation(cat215b, DUR, seed=8)
    from planner.model.effects import make
    rec = record(cat215b, plan, ff, (make("valve_lag", "boom", tau=0.15),), seed=8,
                 positions_only=True)
    res = Discrepancy(cat215b, second=False).fit(rec)
    assert res.effect == "valve_lag" and res.joint == "boom"
    assert all(c.startswith("q_") for c in res.rms_before)


def _excitation_csv(tmp_path, crane, seed=3, dur=DUR):
    plan, ff = excitation(crane, dur, seed=seed)
    path = tmp_path / "exc.csv"
    ff.to_csv(path, plan)
    return path


@pytest.mark.slow   # 13 s: simulate → discrepancy → saved model; the README tour runs the same chain
def test_cli_simulate_then_discrepancy_end_to_end(tmp_path, capsys):
    crane = Crane.from_id("cat215b")
    exc = _excitation_csv(tmp_path, crane)
    meas = tmp_path / "meas.csv"
    assert main(["simulate", "cat215b", "--trajectory", str(exc), "--effect",
                 "coulomb_friction:joint=boom,force=8000", "--noise", "--seed", "1",
                 "--out", str(meas)]) == 0
    capsys.readouterr()
    rep, model = tmp_path / "rep", tmp_path / "cal.toml"
    assert main(["discrepancy", "cat215b", "--measured", str(meas), "--trajectory", str(exc),
                 "--report", str(rep), "--save-model", str(model), "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    for k in ("verdict", "effect", "parameters", "candidates", "signature", "rms_before",
              "rms_after", "gap_reduction"):
        assert k in js
    assert js["verdict"] == "named"
    assert js["effect"] == "coulomb_friction" and js["parameters"]["joint"] == "boom"
    assert js["parameters"]["force"] == pytest.approx(8000, rel=0.1)
    assert js["rms_after"]["p_boom_a"] < js["rms_before"]["p_boom_a"]
    for f in ("report.md", "result.json", "residuals.png", "overlay.png", "ranking.png"):
        assert (rep / f).stat().st_size > 0
    assert "coulomb_friction" in (rep / "report.md").read_text()
    # the calibrated model explains the same data: nothing left to name
    assert main(["discrepancy", str(model), "--measured", str(meas), "--json", "-"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["effect"] is None and js["verdict"] == "explained"


def test_cli_refuses_bad_input_and_writes_nothing(tmp_path, capsys):
    crane = Crane.from_id("cat215b")
    exc = _excitation_csv(tmp_path, crane)
    meas = tmp_path / "meas.csv"
    assert main(["simulate", "cat215b", "--trajectory", str(exc), "--out", str(meas)]) == 0
    lines = meas.read_text().splitlines()
    cells = lines[40].split(",")
    cells[3] = "abc"
    lines[40] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    rep, model = tmp_path / "rep", tmp_path / "cal.toml"
    capsys.readouterr()
    assert main(["discrepancy", "cat215b", "--measured", str(bad), "--report", str(rep),
                 "--save-model", str(model)]) == 2
    err = capsys.readouterr().err
    assert "line 41" in err and "column 4" in err and "abc" in err
    assert not rep.exists() and not model.exists()
    assert main(["simulate", "cat215b", "--trajectory", str(exc), "--effect",
                 "coulomb_friction:joint=arm,force=1", "--out", str(tmp_path / "x.csv")]) == 2
    assert "unknown joint 'arm'" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.slow   # a study-sized check (~15 s): make bench
def test_same_inputs_same_outputs(tmp_path):
    crane = Crane.from_id("cat215b")
    exc = _excitation_csv(tmp_path, crane, dur=15.0)
    outs = []
    for k in range(2):
        m = tmp_path / f"m{k}.csv"
        assert main(["simulate", "cat215b", "--trajectory", str(exc), "--effect",
                     "flow_gain:joint=stick,scale=1.1", "--noise", "--seed", "4",
                     "--out", str(m)]) == 0
        outs.append(m.read_bytes())
    assert outs[0] == outs[1]
    from planner.simulation.recording import Recording
    rec = Recording.from_csv(tmp_path / "m0.csv", crane)
    a = Discrepancy(crane, second=False).fit(rec)
    b = Discrepancy(crane, second=False).fit(rec)
    assert a.to_json()["parameters"] == b.to_json()["parameters"]
    assert a.rms_after == b.rms_after and math.isfinite(a.gap_reduction)


def test_commands_come_from_the_trajectory_when_the_csv_has_none(tmp_path):
    from planner.model.effects import make
    from planner.calibration.trials import record
    from planner.simulation.recording import Recording
    crane = Crane.from_id("cat215b")
    plan, ff = excitation(crane, DUR, seed=9)
    rec = record(crane, plan, ff, (make("flow_gain", "boom", scale=1.1),), seed=9)
    path = tmp_path / "m.csv"
    rec.to_csv(path, crane)
    lines = path.read_text().splitlines()
    keep = [i for i, c in enumerate(lines[0].split(",")) if not c.startswith("u_")]
    path.write_text("\n".join(",".join(r.split(",")[i] for i in keep) for r in lines) + "\n")
    with pytest.raises(ValueError, match="no command columns"):
        Recording.from_csv(path, crane)
    back = Recording.from_csv(path, crane, plan)
    np.testing.assert_allclose(back.u, rec.u, atol=1e-12)
