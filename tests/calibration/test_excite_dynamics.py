"""Excitation for the twin's dynamics (issue 28, item 3): every block and the assembled design
keep every limit (the independent evaluator at 1 kHz is the oracle) and are the same for a
seed; the information is the calibration's own (a prefix's equals the information of the
prefix alone, sd scales with the sensor noise); the predicted sd falls with the recording's
length and the needed duration is where every parameter first reaches the threshold; the
design beats the trials' plain excitation of the same length on the D-criterion, and —
independently of the criterion — the calibration recovers a hidden oil from a twin log of it
better than from the plain excitation's; the CLI writes what `simulate` replays and
`calibrate` reads."""
from __future__ import annotations

import json

import numpy as np
import pytest

from planner import Crane, evaluate
from planner.calibration.excite_dynamics import (BlockPool, choose, design_dynamics,
                                                 needed_duration)
from planner.calibration.excite_information import Information, information, twin_log
from planner.calibration.trials import excitation
from planner.calibration.twin_fit import UNIDENTIFIED, TwinFit, segments
from planner.calibration.twin_params import machine_of
from planner.model.twin import Twin
from planner.simulation.recording import NOISE_DEFAULTS, Recording

PARAMS = ["bulk_modulus", "hose_b.boom", "deadband.tele"]
FEW = ["bulk_modulus", "hose_b.boom"]


@pytest.fixture(scope="module")
def lab():
    return Crane.from_id("umea-lab")


@pytest.fixture(scope="module")
def pool(lab):
    return BlockPool(lab, seed=3, candidates=1)


def test_blocks_and_design_keep_every_limit_and_repeat_for_a_seed(lab, pool):
    names = [b for b, _ in pool.blocks]
    assert names[:4] == ["hard stop far", "hard stop near", "reversals", "creep"]
    assert f"{lab.names[1]} alone" in names and "tour 0" in names
    plan, ff = pool.plan(names)
    ev = evaluate(lab, plan)                     # 1 kHz resampling, every limit kind
    assert ev.ok() and max(ev.violations.values()) <= 1e-3, ev.violations
    assert np.max(np.abs(ff.u_raw)) <= 1.0        # no valve asked beyond its opening
    L = lab.limit_arrays()
    assert np.all(plan.q >= L["q_min"]) and np.all(plan.q <= L["q_max"])
    # every block ends at rest at home, with a hold the calibration cuts its segments at
    ends = [max(e for (b, _, _, e) in plan.meta["blocks"] if b == name) for name in names]
    q_end, qd_end, _, _ = plan.sample(np.array(ends))
    np.testing.assert_allclose(q_end, np.repeat(pool.home[None], len(names), 0),
                               atol=1e-9)
    assert np.max(np.abs(qd_end)) < 1e-5
    q, _, _, _ = plan.sample(ff.t)
    segs = segments(Recording(ff.t, ff.u, q), hold=0.5)
    holds = {b: sum(1 for s in steps if s[0] == "hold") for b, steps in pool.blocks}
    assert holds["reversals"] == 1 and holds["tour 0"] == 4 and holds["creep"] == 2
    assert len(segs) == sum(holds.values())
    # the same seed, the same sequence; another seed, another
    again, ff2 = BlockPool(lab, seed=3, candidates=1).plan(names)
    assert np.array_equal(again.q, plan.q) and np.array_equal(ff2.u, ff.u)
    other = BlockPool(lab, seed=4, candidates=1)
    assert not np.allclose(other.home, pool.home)
    with pytest.raises(ValueError, match="candidates = 21; allowed: 0 … 20"):
        BlockPool(lab, candidates=21)


def test_information_is_the_calibrations_and_adds_over_segments(lab, pool):
    """The information of a prefix of a sequence (first block) equals that of the prefix run
    alone (the segment bookkeeping), and ten times the sensor noise gives ten times the sd."""
    first, second = "tele alone", "jib alone"
    plan1, ff1 = pool.plan([first])
    plan2, ff2 = pool.plan([first, second])
    i1 = information(lab, plan1, ff1, PARAMS)
    i2 = information(lab, plan2, ff2, PARAMS)
    assert i1.names == PARAMS and len(i2.t_end) > len(i1.t_end)
    # (the prefix's last hold ends one command sample earlier when a move follows it)
    np.testing.assert_allclose(i2.matrix(upto=i1.duration), i1.matrix(), rtol=0.01)
    assert not np.allclose(i2.matrix(), i1.matrix(), rtol=0.1)
    assert i2.matrix(upto=i1.duration - 0.5).shape == (3, 3)
    # J scales as 1/σ: every channel's noise × 10 -> every sd × 10 (the log is reused)
    loud = {k: 10 * v for k, v in NOISE_DEFAULTS.items()}
    i1b = information(lab, plan1, ff1, PARAMS, noise=loud, log=twin_log(lab, plan1, ff1))
    np.testing.assert_allclose(i1b.sd(), 10 * i1.sd(), rtol=1e-6)
    # the sd falls with the recording's length, prefix by prefix
    sds = [i2.sd(i2.matrix(upto=t)) for t in i2.t_end]
    assert all(np.all(b <= a * (1 + 1e-9)) for a, b in zip(sds, sds[1:]))
    assert np.all(sds[-1] < sds[0])
    # needed duration: the first segment end where every sd reaches the threshold; past the
    # end the sequence repeats (sd / sqrt(m)); with a hundred times the noise it is longer
    need, A = needed_duration(i1b, i1b)
    sd_need = i1b.sd(A)
    assert np.all(sd_need <= UNIDENTIFIED)
    if need <= i1b.duration:
        k = int(np.searchsorted(i1b.t_end, need))
        assert k == 0 or np.any(i1b.sd(i1b.matrix(upto=i1b.t_end[k - 1])) > UNIDENTIFIED)
    else:
        m = round((need - i1b.duration) / i1b.duration)
        np.testing.assert_allclose(sd_need, i1b.sd() / np.sqrt(m + 1), rtol=1e-9)
        assert np.any(i1b.sd() / np.sqrt(m) > UNIDENTIFIED)
    i1c = Information(i1b.params, i1b.t_end, i1b.blocks / 100.0)     # ten times louder
    need_c, _ = needed_duration(i1c, i1c)
    assert need_c is None or need_c > need


def test_greedy_choice_covers_what_one_block_cannot(lab, pool):
    """A synthetic pool: block a informs parameter 0 only, b parameter 1 only, c both at half
    the rate: D-optimal per second picks a and b first (a block adding nothing new scores 0)."""
    def info(d, T):
        return Information(PARAMS[:2], np.array([1.0, T + 1.0]),
                           np.array([np.zeros((2, 2)), np.diag(d)]))
    order = choose({"a": info([10.0, 0.0], 5.0), "b": info([0.0, 10.0], 5.0),
                    "c": info([5.0, 5.0], 10.0)}, duration=12.0)
    assert sorted(order[:2]) == ["a", "b"] and len(order) == 3


def test_design_beats_the_plain_excitation_on_the_d_criterion(lab):
    d = design_dynamics(lab, duration=10.0, seed=1, candidates=0, parameters=FEW,
                        compare=True, blocks=["hard stop far", "boom alone"])
    assert evaluate(lab, d.plan).ok() and d.plan.duration >= 10.0
    T, T0 = d.plan.duration, d.plain["duration_s"]
    # per recording of the same length (ln det grows by p·ln of the length ratio)
    p = len(FEW)
    assert d.logdet - p * np.log(T / 10.0) > d.plain["logdet"] - p * np.log(T0 / 10.0) + 1.0
    assert d.predicted_logdet == pytest.approx(d.logdet, abs=2.0)   # blocks ≈ additive
    assert set(d.sd) == set(FEW) and d.needed_s is not None
    js = d.to_dict()
    assert js["needed_duration_s"] == d.needed_s and js["order"] == d.order
    json.dumps(js)                                                  # JSON-ready


def _fit(crane, plan, ff, truth, seed):
    """The calibration of ``truth``'s parameters on a log (seed 001's noise) of the twin with
    those values, replaying ``ff``."""
    dyn, db = machine_of(crane, truth)
    run = Twin(crane, dynamics=dyn, deadband=db).simulate(ff.t, ff.u, plan.q[0],
                                                          t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    rec = Recording(ff.t, u, q, pa, pb).with_noise(crane, True, seed=seed)
    return TwinFit(crane, [rec], parameters=list(truth)).solve(max_iterations=6)


@pytest.mark.slow
def test_calibrating_on_the_design_recovers_the_hidden_oil_better_than_on_plain(lab):
    """The independent check: a twin with the oil × 0.8, recorded (seed 001's noise) on the
    design for the oil and on the plain excitation of the same length, calibrated as
    `calibrate --parameters oil` does (its own Jacobian and noise estimate): the design's
    estimate is the closer, and its 95 % interval holds the truth. (With a hose fitted beside
    the oil, the fit on the ringing-rich design can stop in a local minimum of the hose:
    benchmarks/results/excite_dynamics_fit.md.)"""
    truth = {"bulk_modulus": 0.8 * lab.spec.dynamics.bulk_modulus}
    d = design_dynamics(lab, duration=20.0, seed=2, candidates=0, parameters=list(truth),
                        compare=True)
    p0, f0 = excitation(lab, 20.0, seed=2)
    assert d.sd["bulk_modulus"] < d.plain["sd_scaled"]["bulk_modulus"]
    rd, rp = _fit(lab, d.plan, d.ff, truth, 1), _fit(lab, p0, f0, truth, 1)
    err = [abs(np.log(r.values["bulk_modulus"] / truth["bulk_modulus"])) for r in (rd, rp)]
    assert err[0] <= err[1], err
    lo, hi = rd.interval["bulk_modulus"]
    assert lo <= truth["bulk_modulus"] <= hi


def test_cli_refuses_bad_input_in_one_line(tmp_path, capsys):
    from planner.cli import main
    out = tmp_path / "exc.csv"
    cases = [(["--duration", "5"], "--duration 5: allowed 10 ... 600 s"),
             (["--parameters", "oils"], "'oils' unknown; allowed: all, groups oil"),
             (["--separate", "leakage@boom,viscous_friction@boom"],
              "--separate is for --for effects"),
             (["--candidates", "21"], "--candidates 21: allowed 0 ... 20")]
    for extra, msg in cases:
        capsys.readouterr()
        rc = main(["excite", "umea-lab", "--for", "dynamics", "--out", str(out)] + extra)
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and msg in err[0], (extra, err)
        assert not out.exists()
    rc = main(["excite", "umea-lab", "--compare", "--separate", "a,b", "--out", str(out)])
    assert rc == 2 and "--compare is for --for dynamics" in capsys.readouterr().err


@pytest.mark.slow
def test_cli_design_is_replayed_by_simulate_and_read_by_calibrate(lab, tmp_path, capsys):
    """`excite --for dynamics` writes the trajectory CSV that `simulate` replays; the log it
    makes is what `calibrate` reads (the twin plant stands in for the machine here)."""
    from planner.cli import main
    exc, js, log = tmp_path / "exc.csv", tmp_path / "exc.json", tmp_path / "log.csv"
    assert main(["excite", "umea-lab", "--for", "dynamics", "--duration", "12",
                 "--candidates", "0", "--parameters", "bulk_modulus", "--out", str(exc),
                 "--json", str(js), "--seed", "5"]) == 0
    r = json.loads(js.read_text())
    assert r["mode"] == "dynamics" and r["parameters"] == ["bulk_modulus"]
    assert r["duration_s"] >= 12.0 and r["needed_duration_s"] is not None
    assert r["sd_scaled"]["bulk_modulus"] < UNIDENTIFIED
    assert main(["simulate", "umea-lab", "--trajectory", str(exc), "--plant", "twin",
                 "--noise", "--out", str(log)]) == 0
    cal = tmp_path / "cal.toml"
    assert main(["calibrate", "umea-lab", "--measured", str(log), "--parameters", "oil",
                 "--iterations", "3", "--out", str(cal)]) == 0
    assert cal.exists()


def test_a_parameter_without_signal_is_reported_not_waited_for(lab):
    """A parameter the sequence's residuals do not depend on (diag 0: e.g. the rod-side hose of
    a single-acting cylinder) has sd ∞, stays out of ln det and of the needed duration, and
    is named with why."""
    from planner.calibration.excite_dynamics import why_unidentified
    from planner.calibration.twin_params import select, twin_parameters
    params = select(twin_parameters(lab), ["bulk_modulus", "hose_b.boom"])
    blocks = np.array([np.diag([4.0, 0.0]), np.diag([4.0, 0.0])])
    info = Information(params, np.array([5.0, 10.0]), blocks, crane=lab)
    assert list(info.visible()) == [True, False]
    sd = info.sd()
    assert sd[0] == pytest.approx(1 / np.sqrt(8.0)) and np.isinf(sd[1])
    assert info.logdet() == pytest.approx(np.log(8.0))
    need, _ = needed_duration(info, info)
    assert need == 5.0                      # sd 0.5 after the first segment
    why = why_unidentified(info, info.matrix())
    assert list(why) == ["hose_b.boom"] and why["hose_b.boom"].startswith("no signal")
