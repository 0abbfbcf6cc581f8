"""The dynamic twin calibrated from logs (issue 28, the loop): hidden physical parameters
recovered from a log the twin itself made (the oracle: the values it was made with), the
calibrated machine written as a spec that reads back to exactly those values, the CLI, and
the refinement's twin carrying the spec's effects or refusing them by name."""
from __future__ import annotations

import json
import tomllib
from dataclasses import replace

import numpy as np
import pytest

from planner.calibration.trials import excitation
from planner.calibration.log_state import log_state
from planner.calibration.twin_fit import TwinFit, TwinFitResult, segments, windows
from planner.calibration.twin_params import machine_of, select, twin_parameters
from planner.calibration.twin_spec import calibrated_twin_text
from planner.cli import main
from planner.model import Crane
from planner.model.spec import parse_spec
from planner.model.twin import Twin
from planner.simulation.recording import Recording


@pytest.fixture(scope="module")
def lab():
    return Crane.from_id("umea-lab")


def twin_log(crane, truth, duration=4.0, seed=3, noise_seed=2):
    """A log of ``crane``'s twin with the parameters ``truth``, seed 001's sensor noise."""
    plan, ff = excitation(crane, duration=duration, seed=seed)
    dyn, db = machine_of(crane, truth)
    run = Twin(crane, dynamics=dyn, deadband=db).simulate(ff.t, ff.u, plan.q[0],
                                                          t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    return Recording(ff.t, u, q, pa, pb).with_noise(crane, True, seed=noise_seed)


def test_fit_finds_the_oil_and_a_dead_band_it_was_not_told(lab):
    """β × 0.6 lies two valleys of the raw misfit away from the spec's β (the ringing's
    phase): the window stage and the scan must bring the fit there."""
    boom = lab.names[1]
    truth = {"bulk_modulus": 0.6 * lab.spec.dynamics.bulk_modulus, f"deadband.{boom}": 0.02}
    rec = twin_log(lab, truth)
    fit = TwinFit(lab, [rec], parameters=list(truth))
    res = fit.solve(max_iterations=6)
    assert res.values["bulk_modulus"] == pytest.approx(truth["bulk_modulus"], rel=0.02)
    assert res.values[f"deadband.{boom}"] == pytest.approx(0.02, abs=0.001)
    assert res.rms_after["positions"] < 1.5 and res.rms_after["pressures"] < 1.5
    assert res.rms_before["pressures"] > 3 * res.rms_after["pressures"]
    lo, hi = res.interval["bulk_modulus"]
    assert lo < res.values["bulk_modulus"] < hi
    assert res.identified["bulk_modulus"]


def test_a_fit_that_ends_above_the_noise_goes_on_and_one_at_the_noise_stops(
        lab, monkeypatch):
    """A fit that ends above AT_NOISE takes more rounds of both stages (its message says how
    many) and ends lower than without them; a fit at the noise takes none. (AT_NOISE lowered
    below this log's reach so that the rounds run out.)"""
    from planner.calibration import twin_fit
    monkeypatch.setattr(TwinFit, "POLISH", 0)    # the rounds alone (the polish: next test)
    boom = lab.names[1]
    truth = {"bulk_modulus": 0.6 * lab.spec.dynamics.bulk_modulus, f"deadband.{boom}": 0.02}
    rec = twin_log(lab, truth, duration=3.0)
    a = TwinFit(lab, [rec], parameters=list(truth)).solve(max_iterations=3)
    assert a.status == "stopped" and "more round" not in a.message
    assert max(a.rms_after.values()) <= twin_fit.AT_NOISE
    monkeypatch.setattr(twin_fit, "AT_NOISE", 0.5)
    b = TwinFit(lab, [rec], parameters=list(truth)).solve(max_iterations=3)
    assert "after 2 more rounds of both stages" in b.message and "kept, the best" in b.message
    assert b.runs > a.runs
    assert b.rms_after["positions"] < a.rms_after["positions"]


def test_a_whole_segment_stage_out_of_budget_is_polished_until_it_converges(
        lab, monkeypatch):
    """Where the whole segments' stage ran out of its budget, the fit goes on from there until
    it converges (the message says how many evaluations more), and ends with a lower misfit
    and nearer the truth than where the budget stopped it."""
    boom = lab.names[1]
    truth = {"bulk_modulus": 0.6 * lab.spec.dynamics.bulk_modulus, f"deadband.{boom}": 0.02}
    rec = twin_log(lab, truth, duration=3.0)
    monkeypatch.setattr(TwinFit, "POLISH", 0)
    a = TwinFit(lab, [rec], parameters=list(truth)).solve(max_iterations=3)
    monkeypatch.setattr(TwinFit, "POLISH", 2)
    b = TwinFit(lab, [rec], parameters=list(truth)).solve(max_iterations=3)
    assert a.status == "stopped" and "polished" not in a.message
    assert b.status == "converged" and "whole segments polished" in b.message
    assert b.runs > a.runs
    assert b.rms_after["positions"] < a.rms_after["positions"]
    err = [abs(r.values[f"deadband.{boom}"] / 0.02 - 1) for r in (a, b)]
    assert err[1] < 0.02 and err[1] < err[0] / 2


def test_jacobian_on_worker_processes_is_the_same(lab):
    rec = twin_log(lab, {}, duration=3.0)
    one = TwinFit(lab, [rec], parameters="oil,pump")
    two = TwinFit(lab, [rec], parameters="oil,pump", workers=2)
    try:
        z = one.z0() + 0.1
        np.testing.assert_array_equal(one.jacobian(z), two.jacobian(z))
        assert two.runs == 1 + len(two.params)
    finally:
        two.close()
    with pytest.raises(ValueError, match="workers: 0; allowed"):
        TwinFit(lab, [rec], workers=0)


def test_segments_start_at_the_end_of_each_hold(lab):
    rec = twin_log(lab, {}, duration=4.0)
    segs = segments(rec, hold=0.5)
    still = np.all(np.abs(rec.u) < 1e-9, axis=1)
    assert segs[0].k0 >= 0 and segs[-1].k1 == len(rec.t) - 1
    for a, b in zip(segs, segs[1:]):
        assert a.k1 == b.k0                       # contiguous
    for s in segs:
        assert still[s.k0] and not still[s.k0 + 1]   # the hold's last sample, then motion
        np.testing.assert_allclose(s.q0, rec.q[s.k0], atol=0.01)


def test_windows_cut_every_segment_into_seconds_and_cover_it(lab):
    rec = twin_log(lab, {}, duration=4.0)
    segs = segments(rec, hold=0.5)
    wins = windows([rec], segs, 1.0)
    for s in segs:
        mine = [w for w in wins if s.k0 <= w.k0 < s.k1]
        assert mine[0].k0 == s.k0 and mine[-1].k1 == s.k1 and not mine[0].window
        assert all(a.k1 == b.k0 for a, b in zip(mine, mine[1:]))     # contiguous, no gap
        assert all(w.window for w in mine[1:])                       # the log's own state
        for w in mine:
            assert rec.t[w.k1] - rec.t[w.k0] <= 1.2 + 1e-9           # a last short piece joins
        assert len(mine) == max(1, round((rec.t[s.k1] - rec.t[s.k0]) / 1.0 + 0.3))


def test_a_cylinder_on_its_stroke_end_is_told_apart_from_one_off_it():
    """on_stroke_end: the boom lowered onto its stroke end (s100f: x = 0 at about 0.393 rad,
    past its joint limit) is on it when the twin rests there (a stop's penetration past the
    end) and the log's anchor lies within its noise; not when the anchor is far off it, nor
    when the twin is, nor for a joint in mid-stroke."""
    from planner.calibration.log_state import on_stroke_end
    s100f = Crane.from_id("s100f")
    L = s100f.limit_arrays()
    q = 0.5 * (L["q_min"] + L["q_max"])
    qe = q.copy()
    qs = np.linspace(0.35, 0.40, 5001)
    x = s100f.stroke(np.column_stack([np.full_like(qs, q[0]), qs, np.full_like(qs, q[2]),
                                      np.full_like(qs, q[3])]))[0][:, 1]
    qe[1] = qs[np.argmin(np.abs(x))]            # the boom's x = 0
    sig = np.array([5e-4, 5e-4, 5e-4, 1e-3])
    twin = qe.copy()
    twin[1] += 0.4e-3 / 0.43                     # 0.4 mm into the stop
    log = qe.copy()
    log[1] -= 1.0 * sig[1]                       # the anchor one noise σ off the end
    assert list(on_stroke_end(s100f, log, twin, sig)) == [False, True, False, False]
    far = qe.copy()
    far[1] -= 20 * sig[1]
    assert not on_stroke_end(s100f, far, twin, sig)[1]
    assert not on_stroke_end(s100f, log, far, sig)[1]


def test_log_state_is_exact_on_a_parabola_and_follows_a_sine():
    from types import SimpleNamespace
    t = np.arange(0.0, 2.0, 0.02)
    q = np.c_[0.3 + 0.5 * t - 0.7 * t ** 2, np.sin(2.0 * t)]
    rec = SimpleNamespace(t=t, q=q, p_a=None, p_b=None)
    for k in (0, 3, 50, 99):          # the log's ends too (the window shifts inward)
        s = log_state(rec, k)
        assert s["q"][0] == pytest.approx(q[k, 0], abs=1e-12)
        assert s["qd"][0] == pytest.approx(0.5 - 1.4 * t[k], abs=1e-10)
        assert s["qd"][1] == pytest.approx(2.0 * np.cos(2.0 * t[k]), abs=5e-3 if 3 < k < 96 else 0.03)
    assert "p_a" not in log_state(rec, 10)
    with pytest.raises(ValueError, match="sample: 100; allowed: 0 .. 99"):
        log_state(rec, 100)


def test_windows_see_the_truth_and_not_the_spec(lab):
    """On the twin's own log with β × 0.6, the window stage's misfit is noise at the truth
    and far above it at the spec's β: the stage can tell them apart without the history."""
    truth = {"bulk_modulus": 0.6 * lab.spec.dynamics.bulk_modulus}
    rec = twin_log(lab, truth)
    fit = TwinFit(lab, [rec], parameters=["bulk_modulus"])
    fit.segs = fit.windows
    assert any(w.window for w in fit.windows)
    at_truth = np.sqrt(np.mean(fit.residuals(np.array([np.log(0.6)])) ** 2))
    at_spec = np.sqrt(np.mean(fit.residuals(fit.z0()) ** 2))
    assert at_truth < 1.3 and at_spec > 3.0 * at_truth


def test_anchored_on_the_twin_the_truth_reproduces_its_own_log(lab):
    """``anchor="twin"``: each segment after a hold starts from the twin's own state where the
    one before ended (the whole log open loop), so at the truth the twin's noise-free log is
    reproduced to round-off, far below the sensor floor, and the spec's values are not.
    (On Exudyn's log of machine m2, at the truth, the log anchors cost 31 / 20 floor σ on
    positions / pressures, the twin's own state 1.3 / 0.8: the re-anchoring, not the twin,
    moved the fitted slew dead band off its truth.)"""
    boom = lab.names[1]
    truth = {"bulk_modulus": 0.6 * lab.spec.dynamics.bulk_modulus, f"deadband.{boom}": 0.02}
    plan, ff = excitation(lab, duration=8.0, seed=3)
    dyn, db = machine_of(lab, truth)
    run = Twin(lab, dynamics=dyn, deadband=db).simulate(ff.t, ff.u, plan.q[0], t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    fit = TwinFit(lab, [Recording(ff.t, u, q, pa, pb)], parameters=list(truth), anchor="twin")
    assert len(fit.segs) >= 2                       # holds inside the log: carried across
    z_true = np.array([p.to_z(truth[p.name]) for p in fit.params])
    at_truth = np.sqrt(np.mean(fit.residuals(z_true) ** 2))
    at_spec = np.sqrt(np.mean(fit.residuals(fit.z0()) ** 2))
    assert at_truth < 0.05 and at_spec > 100 * at_truth
    by_log = TwinFit(lab, [Recording(ff.t, u, q, pa, pb)], parameters=list(truth),
                     anchor="log")
    assert np.sqrt(np.mean(by_log.residuals(z_true) ** 2)) > 100 * at_truth   # 0.43 vs 5e-4
    with pytest.raises(ValueError, match="anchor: 'measured'; allowed: 'log' or 'twin'"):
        TwinFit(lab, [Recording(ff.t, u, q, pa, pb)], anchor="measured")


def test_intervals_widen_by_the_residuals_long_run_variance(lab):
    """White residuals: the factor is 1; an AR(1) residual with ρ = 0.9 along time: the
    analytic long-run factor (1 + ρ)/(1 − ρ) = 19, less the Bartlett weights' taper."""
    rec = twin_log(lab, {}, duration=30.0)
    fit = TwinFit(lab, [rec], parameters=["bulk_modulus"])
    n, rng = lab.n, np.random.default_rng(0)
    size = sum(s.k1 - s.k0 for s in fit.segs)
    white = rng.standard_normal(size * 3 * n)
    assert fit.long_run(white) == pytest.approx(1.0, abs=0.15)
    parts = []
    for w in (n, 2 * n):
        for s in fit.segs:
            e = rng.standard_normal((s.k1 - s.k0, w))
            x = np.zeros_like(e)
            x[0] = e[0] / np.sqrt(1 - 0.81)
            for k in range(1, len(e)):
                x[k] = 0.9 * x[k - 1] + e[k]
            parts.append(x.ravel())
    L = int(round(TwinFit.WINDOW / 0.02))
    expect = 1 + 2 * sum((1 - k / (L + 1)) * 0.9 ** k for k in range(1, L + 1))
    assert fit.long_run(np.concatenate(parts)) == pytest.approx(expect, rel=0.15)


def test_a_log_with_the_load_swinging_is_fitted_on_the_twin_that_carries_it(lab):
    """A log made with the load hanging on a link (the coupled twin, oracle: its own
    values): the fit's twin with the same link sees noise at those values, the bare twin a
    misfit it would explain with wrong oil; and the carried swing crosses the segments."""
    plan, ff = excitation(lab, duration=6.0, seed=3)
    run = Twin(lab, grapple=1.2).simulate(ff.t, ff.u, plan.q[0], t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    rec = Recording(ff.t, u, q, pa, pb).with_noise(lab, True, seed=2)
    hung = TwinFit(lab, [rec], parameters=["bulk_modulus"], grapple=1.2)
    bare = TwinFit(lab, [rec], parameters=["bulk_modulus"])
    assert len(hung.segs) > 1
    r_hung = np.sqrt(np.mean(hung.residuals(hung.z0()) ** 2))
    r_bare = np.sqrt(np.mean(bare.residuals(bare.z0()) ** 2))
    assert r_hung < 1.3 and r_bare > 2.0 * r_hung


def test_parameters_select_and_refuse_by_name(lab):
    ps = twin_parameters(lab)
    assert {p.name for p in select(ps, "oil")} == {"bulk_modulus", "bulk_low", "bulk_high",
                                                   "bulk_reference_pressure"}
    assert {p.kind for p in select(ps, "friction")} == {"coulomb", "viscous"}
    assert "command_delay" in {p.name for p in select(ps, "valves")}
    assert len(select(ps, "hose_a")) == lab.n
    assert len(select(ps, None)) == 7 + 6 * lab.n
    with pytest.raises(ValueError, match="'bogus' unknown; allowed: all, groups oil"):
        select(ps, "bogus")
    with pytest.raises(ValueError, match="'hose_c.slew' unknown"):
        machine_of(lab, {"hose_c.slew": 1e-3})
    for p in ps:   # the scaling round-trips and its bounds contain the spec's value
        v = p.nominal if p.nominal > 0 else p.scale
        assert p.to_value(p.to_z(v)) == pytest.approx(v)
        lo, hi = p.z_bounds
        assert lo <= p.to_z(max(p.nominal, p.lo) if p.log else p.nominal) <= hi


def fake_result(crane, values):
    dyn, db = machine_of(crane, values)
    return TwinFitResult(values=values, nominal={k: 1.0 for k in values},
                         interval={k: (0.9 * v, 1.1 * v) for k, v in values.items()},
                         identified={k: True for k in values}, sd_scaled={k: 0.01 for k in values},
                         rms_before={}, rms_after={}, runs=0, runtime_s=0.0, status="converged",
                         message="", dynamics=dyn, deadband=db,
                         units={p.name: p.unit for p in twin_parameters(crane)})


@pytest.mark.parametrize("cid", ["s100f", "umea-lab", "cranab850", "cat215b"])
def test_calibrated_spec_reads_back_the_fitted_machine(cid):
    crane = Crane.from_id(cid)
    assert crane.spec.dynamics is not None      # every shipped machine has [dynamics]
    j0, j1 = crane.names[0], crane.names[-1]
    values = {"bulk_modulus": 0.913e9, "spool_time_constant": 0.0517, "bulk_low": 0.55,
              "bulk_high": 1.3, "bulk_reference_pressure": 9.5e6,
              f"hose_a.{j0}": 1.234e-3, f"hose_b.{j1}": 2.5e-4, f"coulomb.{j1}": 777.5,
              f"leakage.{j0}": 3.3e-14, f"deadband.{j0}": 0.0123, f"deadband.{j1}": 0.004}
    res = fake_result(crane, values)
    text = calibrated_twin_text(crane, res, "on log.csv")
    spec = parse_spec(tomllib.loads(text), "cal.toml", text)
    assert replace(spec.dynamics, source="") == replace(res.dynamics, source="")
    assert [j.actuator.deadband for j in spec.joints] == list(res.deadband)
    assert "calibrated by crane-planner calibrate on log.csv" in spec.dynamics.source
    # everything else is the same machine
    for a, b in zip(spec.joints, crane.spec.joints):
        assert replace(a.actuator, deadband=0.0) == replace(b.actuator, deadband=0.0)
        assert a.limits == b.limits and a.dh == b.dh and a.mass == b.mass
    assert spec.pump == crane.spec.pump and spec.payload == crane.spec.payload
    assert "95 % interval" in text and "spec's value, not fitted" in text


def test_cli_calibrate_writes_a_machine_that_refine_reads(lab, tmp_path, capsys):
    boom = lab.names[1]
    truth = {f"deadband.{boom}": 0.03}
    log = tmp_path / "log.csv"
    twin_log(lab, truth).to_csv(log, lab)
    out, js = tmp_path / "cal.toml", tmp_path / "cal.json"
    rc = main(["calibrate", "umea-lab", "--measured", str(log), "--out", str(out),
               "--parameters", f"deadband.{boom}", "--iterations", "8", "--json", str(js)])
    assert rc == 0
    r = json.loads(js.read_text())
    db = r["parameters"][f"deadband.{boom}"]["value"]
    assert db == pytest.approx(0.03, abs=0.002)
    assert r["judge"] == "twin vs the logs"
    cal = Crane.from_file(out)
    assert cal.spec.joints[1].actuator.deadband == db
    assert Twin(cal).params.per["deadband"][1] == db    # what `library refine --model` uses
    # bad input: one line naming the flag and what is allowed, exit 2, nothing written
    capsys.readouterr()
    bad = tmp_path / "bad.toml"
    assert main(["calibrate", "umea-lab", "--measured", str(log), "--out", str(bad),
                 "--parameters", "oils"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'oils' unknown" in err[0] and not bad.exists()
    assert main(["calibrate", "umea-lab", "--measured", str(log), "--out", str(log)]) == 2
    assert "the same file" in capsys.readouterr().err


def test_cli_calibrate_carries_the_grapple_the_log_was_made_with(lab, tmp_path, capsys):
    plan, ff = excitation(lab, duration=4.0, seed=3)
    run = Twin(lab, grapple=1.2).simulate(ff.t, ff.u, plan.q[0], t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    log = tmp_path / "log.csv"
    Recording(ff.t, u, q, pa, pb).with_noise(lab, True, seed=2).to_csv(log, lab)
    js = tmp_path / "cal.json"
    base = ["calibrate", "umea-lab", "--measured", str(log), "--out", str(tmp_path / "c.toml"),
            "--parameters", "bulk_modulus", "--iterations", "2"]
    assert main(base + ["--grapple", "1.2", "--json", str(js)]) == 0
    r = json.loads(js.read_text())
    assert r["grapple_m"] == 1.2 and r["rms_after"]["pressures"] < 1.3
    capsys.readouterr()
    assert main(base + ["--grapple", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--grapple" in err[0]


def test_refine_twin_carries_the_spec_effects_or_refuses_them(lab, tmp_path):
    from planner.simulation.twin_plant import twin_of
    base = lab.spec.text.rstrip()
    p = tmp_path / "m.toml"
    p.write_text(base + '\n[[effects]]\nname = "bulk_modulus"\nscale = 0.5\n')
    tw = twin_of(Crane.from_file(p))
    assert tw.params.scalar["beta"] == pytest.approx(0.5 * lab.spec.dynamics.bulk_modulus)
    p.write_text(base + '\n[[effects]]\nname = "time_delay"\ndelay = 0.1\n')
    with pytest.raises(ValueError, match="'time_delay' acts through commands"):
        twin_of(Crane.from_file(p))


def test_twin_bulk_modulus_rises_with_pressure_as_the_spec_says(lab):
    """The twin's chamber stiffness follows [dynamics] β(p) = β·clip((p + p_atm)/(p_ref +
    p_atm), low, high): the compression rate of a closed chamber moved at a fixed speed, at
    several pressures, against the law written out here."""
    dyn = replace(lab.spec.dynamics, bulk_low=0.5, bulk_high=1.25, bulk_reference_pressure=8e6)
    tw = Twin(lab, dynamics=dyn)
    n, i = lab.n, 1
    q = 0.5 * (lab.limit_arrays()["q_min"] + lab.limit_arrays()["q_max"])
    rates = {}
    for p in (0.3e6, 2e6, 8e6, 12e6, 25e6):
        x = tw.rest_state(q)
        x[n + i] = 0.01                        # the joint moves, its spool closed
        x[2 * n + i] = p                       # piston side at p
        rates[p] = tw.rhs(x, np.zeros(n))[2 * n + i]
    law = {p: float(np.clip((p + 1e5) / (8e6 + 1e5), 0.5, 1.25)) for p in rates}
    for p in rates:
        assert rates[p] / rates[8e6] == pytest.approx(law[p], rel=1e-9)
    const = Twin(lab)                          # the default: constant β
    x = const.rest_state(q)
    x[n + i], x[2 * n + i] = 0.01, 0.3e6
    assert const.rhs(x, np.zeros(n))[2 * n + i] == pytest.approx(rates[8e6], rel=1e-9)
