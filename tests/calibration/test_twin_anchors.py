"""Why the clean s100f log was not ``explained`` by the twin (issue 28): two causes, each
reproduced here against an oracle outside the code under test.

* **A segment's start mixed two sources.** A cylinder still ringing through a hold may show
  its rod-side swing under the ringing test while its piston side passes it (the swing goes
  with the area ratio); the start then took one chamber measured and the other carried from
  the twin, a state the machine never had, and the locked telescope kept the wrong trapped
  oil for the rest of the segment (0.84 σ on ``p_tele_b`` from 22.6 s on). The oracle for the
  rule is the carried run itself; for its effect, the Exudyn plant's clean log and the
  unchanged verdict rules (``verdict.judge`` with nothing fitted: ``explained`` or not).
* **The twin's own integration error.** BDF2 at 2 ms is 0.3 σ RMS off on the boom's pressure
  on that excitation, a residual the verdict cannot tell from a missing effect; the
  diagnosis' step is checked against the Exudyn plant (the independent judge).
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from planner.calibration.trials import excitation
from planner.calibration.twin_diagnosis import TwinDiagnosis
from planner.calibration.twin_fit import TwinFit
from planner.calibration.verdict import Evidence, judge
from planner.model import Crane
from planner.model.twin import Twin
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.simulation.recording import NOISE_DEFAULTS, Recording

SEED = 1000     # the bench's first fresh seed (benchmarks/bench_discrepancy_twin.py)
DURATION_SMALL = 30.0   # [s] the small umea-lab cases' log (the bench's)


@pytest.fixture(scope="module")
def s100f():
    """The s100f crane, its 30 s test sequence and the Exudyn plant's run of it (clean)."""
    crane = Crane.from_id("s100f")
    plan, ff = excitation(crane, 30.0, seed=SEED)
    t, u = np.asarray(ff.t, float), np.asarray(ff.u, float)
    run = ExudynPlant(crane).integrate(t, u, plan.q[0], t_end=float(t[-1]))
    assert run.ok, run.reason
    q, pa, pb, uu = run.sample(t)
    return SimpleNamespace(crane=crane, q0=plan.q[0], t=t, u=u, q=q, p_a=pa, p_b=pb, uu=uu)


def _lab_last_segment():
    """umea-lab's twin log (4 s excitation, seed 001's noise) fitted on log anchors: (n, the
    fit, its last segment, the pressure noise σ (2n,))."""
    crane = Crane.from_id("umea-lab")
    plan, ff = excitation(crane, duration=4.0, seed=3)
    run = Twin(crane).simulate(ff.t, ff.u, plan.q[0], t_end=ff.t[-1])
    q, pa, pb, u = run.sample(ff.t)
    rec = Recording(ff.t, u, q, pa, pb).with_noise(crane, True, seed=2)
    fit = TwinFit(crane, [rec], parameters=["bulk_modulus"], anchor="log")
    return crane.n, fit, fit.segs[-1], fit.sig[0][1]


def _carried(fit, seg, p_a, p_b, qd=0.0):
    """A twin run carried up to the segment's start over its anchor window: pressures
    ``p_a``, ``p_b`` (window samples × n, or one row held), velocity ``qd``."""
    from planner.model.twin import TwinRun
    n, rec = len(seg.q0), fit.recs[seg.rec]
    t = rec.t[int(np.searchsorted(rec.t, rec.t[seg.k0] - 0.3)):seg.k0 + 1]
    m = len(t)

    def rows(a):
        return np.broadcast_to(np.asarray(a, float), (m, n)).copy()
    return TwinRun(t=t, q=rows(seg.q0), qd=rows(qd), p_a=rows(p_a), p_b=rows(p_b),
                   p_s=np.full(m, 9.0e6), spool=np.zeros((m, n)), u=np.zeros((m, n)),
                   newton=np.zeros(m - 1))


def test_a_joint_ringing_in_one_chamber_keeps_both_chambers_carried():
    n, fit, seg, sp = _lab_last_segment()
    # joint 0: the piston side rings (3 σ of spread), the rod side passes (0.5 σ);
    # joint 1: both chambers quiet
    seg.sd_a, seg.sd_b = 0.5 * sp[:n].copy(), 0.5 * sp[n:].copy()
    seg.sd_a[0] = 3.0 * sp[0]
    carried = _carried(fit, seg, np.full(n, 7.0e6), np.full(n, 3.0e6), qd=0.01)
    x0 = fit.start_state(fit.twin({}), seg, (seg.rec, seg.k0, carried))
    p_a0, p_b0 = x0[2 * n:3 * n], x0[3 * n:4 * n]
    assert p_a0[0] == 7.0e6 and p_b0[0] == 3.0e6      # both from the carried run
    assert p_a0[1] == seg.p_a0[1] and p_b0[1] == seg.p_b0[1]    # both measured
    assert x0[n] == pytest.approx(0.01)                   # the carried velocity


def test_clean_s100f_log_is_noise_to_the_twin_at_the_spec(s100f):
    """The Exudyn plant's clean log (seed 001's noise), the twin at the spec's values: the
    unchanged verdict rules find only noise (before the fix: a step and a slow residual of
    0.46 σ on ``p_tele_b``, 0.47 σ RMS off the noiseless log there; now 0.10)."""
    c = s100f
    rec = Recording(c.t, c.uu, c.q, c.p_a, c.p_b).with_noise(c.crane, True, SEED)
    td = TwinDiagnosis(c.crane)
    td._prepare(rec)        # the diagnosis' own prediction, nothing fitted
    Y0 = td.predict(())
    ev = Evidence(td.Y, td.sig, td.test, td.t, td.cols, td.predict, td.threshold, {},
                  "s100f")
    v = judge(ev, Y0, [], None, None)
    assert v["verdict"] == "explained", v["reasons"]
    clean = Recording(c.t, c.uu, c.q, c.p_a, c.p_b)
    truth = np.hstack([clean.q, np.stack([clean.p_a, clean.p_b], axis=2)
                       .reshape(len(c.t), -1)])[td.rows]
    err = (Y0 - truth) / td.sig
    k = td.cols.index("p_tele_b")
    assert math.sqrt(np.mean(err[td.test, k] ** 2)) < 0.25


def test_the_diagnosis_twin_steps_finely_enough_for_a_noise_verdict(s100f):
    """The twin at the diagnosis' step against the Exudyn plant, from the same rest, on the
    s100f test sequence: every pressure within 0.15 σ RMS of the sensors' noise (at 1 ms:
    0.02 σ; BDF2 at 2 ms: 0.26 σ on the boom's, where the Exudyn plant is 0.07 σ off its own
    converged run)."""
    c = s100f
    for step, ok in ((TwinDiagnosis(c.crane).step, True), (2e-3, False)):
        run = Twin(c.crane, step=step).simulate(c.t, c.u, c.q0, t_end=float(c.t[-1]))
        q, pa, pb, _ = run.sample(c.t)
        worst = max(math.sqrt(np.mean(((a - b) / NOISE_DEFAULTS["pressure"]) ** 2))
                    for x, y in ((pa, c.p_a), (pb, c.p_b)) for a, b in zip(x.T, y.T))
        assert (worst < 0.15) == ok, (step, worst)


@pytest.mark.slow     # about 2 min each: the whole diagnosis, every candidate, as the bench
@pytest.mark.parametrize("effect, joint, value", [("payload_mass", None, 6.0),
                                                  ("coulomb_friction", "boom", 400.0)])
def test_small_umea_lab_effects_on_exudyn_are_named(effect, joint, value):
    """Issue 28's two small umea-lab cases, recorded by the Exudyn plant (the oracle: the
    value it was made with), diagnosed by the twin: 6 kg of payload and 400 N of Coulomb
    friction on the boom named (or a tie that holds them) with about the value (the bench's
    diagnosis: 6.03 kg and 402 N, named; on a 20 s log the 6 kg are not found)."""
    from planner.model.effects.base import make
    crane = Crane.from_id("umea-lab")
    plan, ff = excitation(crane, DURATION_SMALL, seed=SEED)
    truth = make(effect, joint, **({"mass": value} if effect == "payload_mass"
                                   else {"force": value}))
    t = np.asarray(ff.t, float)
    run = ExudynPlant(crane, (truth,)).integrate(t, np.asarray(ff.u, float), plan.q[0],
                                                 t_end=float(t[-1]))
    assert run.ok, run.reason
    q, pa, pb, u = run.sample(t)
    rec = Recording(t, u, q, pa, pb).with_noise(crane, True, SEED)
    res = TwinDiagnosis(crane).fit(rec)
    got = [(res.effect, res.joint)] if res.verdict == "named" else [
        (c["effect"], c["joint"]) for c in res.candidates]
    assert (effect, joint) in got, res.message
    if res.verdict == "named":
        assert list(res.parameters.values())[0] == pytest.approx(value, rel=0.25)


@pytest.mark.parametrize("machine", ["s100f", "cranab850", "umea-lab", "cat215b"])
def test_friction_candidates_reach_the_catalogues_largest_trial(machine):
    """The twin's friction candidates can take the largest friction the catalogue's trials
    hide (the oracle: :meth:`Effect.trial_values` at full magnitude, added to the spec's):
    the s100f slew's Coulomb candidate stopped at 6 kN·m (20 × the spec's 300 N·m) under a
    hidden 7.5 kN·m, so its best fit could not be credible."""
    from planner.calibration.twin_params import twin_parameters
    from planner.model.effects.loads import CoulombFriction, ViscousFriction
    crane = Crane.from_id(machine)
    tp = {p.name: p for p in twin_parameters(crane)}
    for i, j in enumerate(crane.names):
        for kind, cls, key in (("coulomb", CoulombFriction, "force"),
                               ("viscous", ViscousFriction, "coefficient")):
            p = tp[f"{kind}.{j}"]
            need = p.nominal + cls.trial_values(crane, i, 1.0, 1, None, None)[key]
            assert p.to_value(p.z_bounds[1]) >= need, (j, kind)


def test_chambers_that_ring_with_the_twin_over_the_window_keep_the_twins_own_pressures():
    """A chamber ringing by less than twice its noise passes as quiet, but its window average
    is not its value at the cut: where the logged chambers follow the twin's carried run
    over the window sample by sample (their mean difference within 3 σ/√m), the run's
    pressures at the cut start the segment — here the run rings at 0.7 Hz with 1.5 σ about
    the log's samples, 0.5 σ off them, so its value at the cut is not the window's average;
    a joint the log contradicts (its run 10 MPa off) starts from the log."""
    n, fit, seg, sp = _lab_last_segment()
    rec = fit.recs[seg.rec]
    seg.sd_a, seg.sd_b = 0.5 * sp[:n].copy(), 0.5 * sp[n:].copy()     # all quiet
    t = rec.t[int(np.searchsorted(rec.t, rec.t[seg.k0] - 0.3)):seg.k0 + 1]
    k = np.searchsorted(rec.t, t[0])
    ring = 1.5 * np.sin(2 * np.pi * 0.7 * t)[:, None]
    rec.p_a[k:seg.k0 + 1] += ring * sp[:n]             # the log rings, the run with it
    rec.p_b[k:seg.k0 + 1] -= ring * sp[n:]
    run_a = rec.p_a[k:seg.k0 + 1] + 0.5 * sp[:n]
    run_b = rec.p_b[k:seg.k0 + 1] - 0.5 * sp[n:]
    run_a[:, 1] += 10e6                                # joint 1: the log contradicts it
    x0 = fit.start_state(fit.twin({}), seg, (seg.rec, seg.k0, _carried(fit, seg, run_a, run_b)))
    p_a0, p_b0 = x0[2 * n:3 * n], x0[3 * n:4 * n]
    keep = np.arange(n) != 1
    np.testing.assert_allclose(p_a0[keep], run_a[-1, keep])
    np.testing.assert_allclose(p_b0[keep], run_b[-1, keep])
    assert p_a0[1] == seg.p_a0[1] and p_b0[1] == seg.p_b0[1]
