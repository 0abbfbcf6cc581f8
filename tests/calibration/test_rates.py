"""Issue 32 defects 4 and 9: ``discrepancy`` on fast and long logs. A log faster than 100 Hz is
analysed at 50-100 Hz (planner.calibration.rate: anti-alias filtered readings, averaged
commands), says so, finds what the 50 Hz log finds, and its memory is estimated before the
file is read; a long log's rounded times no longer break the replay grid (the IndexError)."""
import math

import numpy as np
import pytest

from planner import Crane
from planner.calibration import rate
from planner.calibration.discrepancy import Discrepancy
from planner.cli import main
from planner.methods.ruckig import rest_to_rest
from planner.model.effects import parse_effect
from planner.simulation.plant import simulate_to_csv
from planner.simulation.recording import Recording

FRICTION = "coulomb_friction:joint=boom,force=3000"
CANDIDATES = ["coulomb_friction", "joint_offset"]


def test_decimate_filters_readings_and_averages_commands():
    """Oracle: a slow sine survives; a 201 Hz tone (pump ripple, say), which plain picking at
    50 Hz turns into a slow 1 Hz wave of full amplitude, is removed (the filter's nulls lie at
    the multiples of 50 Hz); the commands' integral over each interval is kept."""
    fs, m = 1000.0, 20
    t = np.arange(0, 4.0, 1 / fs)
    slow = np.sin(2 * np.pi * 0.5 * t)
    q = np.column_stack([slow + 0.3 * np.sin(2 * np.pi * 201.0 * t), slow])
    u = np.column_stack([np.sign(np.sin(2 * np.pi * 7.0 * t)), np.cos(t)])
    d = rate.decimate(Recording(t, u, q), m)
    np.testing.assert_array_equal(d.t, t[::m])
    inner = slice(5, -5)   # away from the ends (the filter's start-up)
    assert np.max(np.abs(d.q[inner, 0] - slow[::m][inner])) < 0.01      # the tone is gone
    assert np.max(np.abs(q[::m][inner, 0] - slow[::m][inner])) > 0.2    # picking keeps it
    np.testing.assert_allclose(d.q[inner, 1], slow[::m][inner], atol=2e-3)
    np.testing.assert_allclose(d.u * m, u.reshape(-1, m, 2).sum(axis=1), atol=1e-12)
    assert rate.factor(50.0) == rate.factor(99.0) == 1 and rate.factor(1000.0) == 20


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """One s100f move with a hidden boom friction (3000 N: the oracle), logged at 50 Hz and at
    1 kHz with seed 001's sensor noise."""
    d = tmp_path_factory.mktemp("rates")
    crane = Crane.from_id("s100f")
    move = rest_to_rest(crane, crane.ik(np.array([3.0, 1.0, 0.0])),
                        crane.ik(np.array([7.0, 0.0, math.pi / 2]))).trajectory
    eff = [parse_effect(FRICTION, crane)]
    out = {}
    for hz in (50.0, 60.0, 1000.0):
        out[hz] = d / f"log{hz:g}.csv"
        simulate_to_csv(crane, move, out[hz], rate=hz, effects=eff, noise=True, seed=1)
    return crane, out


def test_a_1khz_log_is_analysed_at_50_hz_and_finds_what_the_50_hz_log_finds(logs):
    crane, path = logs
    res = {hz: Discrepancy(crane, candidates=CANDIDATES, second=False).fit(
        Recording.from_csv(p, crane)) for hz, p in path.items() if hz != 60.0}
    a = res[1000.0].analysis
    assert (a["factor"], a["rate_analysed_hz"]) == (20, pytest.approx(50.0))
    assert abs(a["samples_analysed"] - res[50.0].analysis["samples_analysed"]) <= 1  # the end
    assert a["samples_logged"] > 4000 and res[50.0].analysis["factor"] == 1
    assert any("1000 Hz log is analysed at 50 Hz" in n for n in res[1000.0].notes)
    assert not res[50.0].notes
    for r in res.values():
        assert (r.effect, r.joint) == ("coulomb_friction", "boom"), r.message
        assert r.parameters["force"] == pytest.approx(3000.0, rel=0.05)
    assert res[1000.0].to_json()["analysis"] == a


def test_rounded_times_of_a_long_log_keep_one_replay_step_per_sample(logs):
    """The IndexError of a 10^6-row log: its times, written with 10 significant digits, made
    the shortest step (the replay's default) shorter than the mean by more than 1/N, so the
    replay grid had a sample more than the recording. The same here: a 60 Hz log (a step
    that 10 digits cannot write exactly) with t from 10^5 s."""
    crane, path = logs
    rec = Recording.from_csv(path[60.0], crane)
    t = np.array([float(f"{v:.10g}") for v in 1e5 + rec.t])
    assert np.ptp(np.diff(t)) > 1e-5 and len(t) * (1 - np.diff(t).min() / np.diff(t).mean()) > 1
    res = Discrepancy(crane, candidates=CANDIDATES, second=False).fit(
        Recording(t, rec.u, rec.q, rec.p_a, rec.p_b))
    assert (res.effect, res.joint) == ("coulomb_friction", "boom")


def test_the_memory_is_estimated_before_the_file_is_read(logs, capsys, monkeypatch):
    crane, path = logs
    info = rate.check_file(path[1000.0])
    assert info["rows"] == 4688 and info["rate_hz"] == pytest.approx(1000.0)
    assert info["analysed"] == math.ceil(4688 / 20)
    assert info["estimated_bytes"] == rate.estimate_bytes(4688, 17, info["analysed"], 12)
    monkeypatch.setattr(rate, "MAX_BYTES", info["estimated_bytes"] - 1)
    assert main(["discrepancy", "s100f", "--measured", str(path[1000.0])]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"crane-planner: error: {path[1000.0]}: 4688 samples × 17 "
                          "columns at 1000 Hz need ~") and "allowed up to" in err, err
    assert "\n" not in err
