"""Where the twin's residual on a clean Exudyn log comes from (issue 28: why the clean s100f
log was not ``explained``): each source measured alone, as held-out RMS in noise units of the
diagnosis' nominal prediction (the twin at the spec's values) against the *noiseless* log.

* (a) the recording plant's step: the Exudyn plant at its 2 ms against itself at 0.125 ms;
* (b) the twin's step: the twin run free (one run from the plan's rest, no re-anchoring) at
  2, 1, 0.5 ms against itself at 0.25 ms;
* (c) a model difference: the twin at 0.25 ms against the Exudyn plant at 0.125 ms, free;
* (d) the diagnosis' re-anchoring: its nominal prediction (segments cut at holds, each
  started from the log) with the anchors from the noisy log or the noiseless one, with the
  per-chamber start rule of before and the per-joint rule of now; and the verdict rules'
  noise test on it (``judge`` with nothing fitted: explained or the reasons);
* (e) the start's sensitivity: the twin run free from the start pose shifted by one anchor's
  noise (σ/√m, m the samples of the 0.2 s anchor window) on one joint.

    python benchmarks/bench_twin_gap_sources.py [--machine s100f] [--seed 1000] [--out FILE]
"""
from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import time

import numpy as np

from planner import Crane
from planner.calibration.trials import excitation
from planner.calibration.twin_diagnosis import TwinDiagnosis
from planner.calibration.twin_fit import TwinFit
from planner.calibration.verdict import Evidence, judge
from planner.model.twin import Twin
from planner.simulation.dynamic.exudyn_plant import ExudynPlant
from planner.simulation.recording import NOISE_DEFAULTS, Recording


def exudyn(crane, plan, ff, step):
    t, u = np.asarray(ff.t, float), np.asarray(ff.u, float)
    run = ExudynPlant(crane, step=step).integrate(t, u, plan.q[0], t_end=float(t[-1]),
                                                  max_wall_s=3000.0)
    assert run.ok, run.reason
    q, pa, pb, uu = run.sample(t)
    return Recording(t, uu, q, pa, pb)


def twin_free(crane, plan, ff, step, dq0=0.0):
    t = np.asarray(ff.t, float)
    run = Twin(crane, step=step).simulate(t, np.asarray(ff.u, float), plan.q[0] + dq0,
                                          t_end=float(t[-1]))
    q, pa, pb, uu = run.sample(t)
    return Recording(t, uu, q, pa, pb)


def channels(crane, rec):
    return np.hstack([rec.q, np.stack([rec.p_a, rec.p_b], axis=2).reshape(len(rec.t), -1)])


def sigma(crane):
    sq = [NOISE_DEFAULTS["angle"] if j.revolute else NOISE_DEFAULTS["length"]
          for j in crane.spec.joints]
    return np.array(sq + [NOISE_DEFAULTS["pressure"]] * (2 * crane.n))


def names(crane):
    return [f"q_{j}" for j in crane.names] + [f"p_{j}_{s}" for j in crane.names for s in "ab"]


def per_chamber_start(self, tw, s, carry):
    """TwinFit's start rule before this fix: each chamber measured when its own spread is
    quiet (the other one of the joint possibly carried)."""
    n = self.crane.n
    x0 = tw.rest_state(s.q0)
    if carry is not None and carry[0] == s.rec and carry[1] == s.k0:
        run = carry[2]
        x0[n:2 * n] = run.qd[-1]
        x0[2 * n:3 * n], x0[3 * n:4 * n] = run.p_a[-1], run.p_b[-1]
        x0[4 * n] = run.p_s[-1]
        x0[4 * n + 1:] = run.spool[-1]
    if self.use_p and s.p_a0 is not None:
        sp = self.sig[s.rec][1]
        qa, qb = s.sd_a < 2.0 * sp[:n], s.sd_b < 2.0 * sp[n:]
        qb &= ~self.vented
        x0[2 * n:3 * n][qa] = s.p_a0[qa]
        x0[3 * n:4 * n][qb] = s.p_b0[qb]
    return x0


def diagnosis_prediction(crane, anchors, noisy, clean, step, old_rule):
    """(RMS per channel against the noiseless log on the held-out rows, the verdict's noise
    test on the noisy log): the diagnosis' nominal prediction with ``anchors`` (a log) for the
    segments' starts and the noisy log's noise levels."""
    now = TwinFit.start_state
    if old_rule:
        TwinFit.start_state = per_chamber_start
    try:
        td = TwinDiagnosis(crane, step=step)
        td._prepare(noisy)
        sig = td.pb.sig
        tda = TwinDiagnosis(crane, step=step)
        tda._prepare(anchors)
        tda.pb.sig, tda.sig, tda.Y = sig, td.sig, td.Y
        tda.pb.recs = [noisy]        # the residual against the noisy log, anchors from `anchors`
        Y0 = tda.predict(())
    finally:
        TwinFit.start_state = now
    truth = channels(crane, clean)[td.rows]
    E = (Y0 - truth) / td.sig
    rms = np.sqrt(np.mean(E[td.test] ** 2, axis=0))
    ev = Evidence(td.Y, td.sig, td.test, td.t, td.cols, td.predict, td.threshold, {},
                  crane.spec.id)
    v = judge(ev, Y0, [], None, None)
    return rms, v


def row(label, rms, cols, extra=""):
    worst = np.argsort(-rms)[:3]
    return (f"| {label} | {max(rms):.2f} | "
            + ", ".join(f"{cols[i]} {rms[i]:.2f}" for i in worst) + f" | {extra} |")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--machine", default="s100f")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    crane = Crane.from_id(a.machine)
    plan, ff = excitation(crane, a.duration, seed=a.seed)
    t0 = time.perf_counter()
    sig, cols = sigma(crane), names(crane)
    ex = {h: exudyn(crane, plan, ff, h) for h in (2e-3, 1.25e-4)}
    tw = {h: twin_free(crane, plan, ff, h) for h in (2e-3, 1e-3, 5e-4, 2.5e-4)}

    def rms(x, y):
        E = (channels(crane, x) - channels(crane, y)) / sig
        return np.sqrt(np.mean(E ** 2, axis=0))
    L = [f"# Where the twin's residual on a clean Exudyn log comes from ({a.machine}, seed "
         f"{a.seed})", "",
         f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.platform()}, "
         f"load {os.getloadavg()[0]:.1f}. `python benchmarks/bench_twin_gap_sources.py "
         f"--machine {a.machine} --seed {a.seed} --duration {a.duration:g}`. Judge: the "
         "Exudyn plant (the recordings), the twin (the diagnosis' model). RMS in noise units "
         "(seed 001's sensor accuracies for the free runs; the diagnosis' noise estimate for "
         "its prediction); free runs over the whole log, the diagnosis' prediction on its "
         "held-out rows, both against the noiseless log.", "",
         "| source | worst channel RMS [σ] | three worst channels | verdict rules on it |",
         "| --- | ---: | --- | --- |",
         row("(a) Exudyn 2 ms vs Exudyn 0.125 ms", rms(ex[2e-3], ex[1.25e-4]), cols)]
    for h in (2e-3, 1e-3, 5e-4):
        L.append(row(f"(b) twin {h * 1e3:g} ms vs twin 0.25 ms (free)", rms(tw[h], tw[2.5e-4]),
                     cols))
    L.append(row("(c) twin 0.25 ms vs Exudyn 0.125 ms (free)", rms(tw[2.5e-4], ex[1.25e-4]),
                 cols))
    L.append(row("twin 1 ms vs Exudyn 2 ms (free: what the diagnosis sees)",
                 rms(tw[1e-3], ex[2e-3]), cols))
    m = round(0.2 / float(ff.t[1] - ff.t[0]))     # the anchor window's samples (0.2 s)
    for j, name in enumerate(crane.names):
        dq = np.zeros(crane.n)
        dq[j] = sig[j] / math.sqrt(m)
        L.append(row(f"(e) twin 1 ms started {dq[j] / sig[j]:.2f} σ off on {name} (one "
                     "anchor's noise) vs from the start (free)",
                     rms(twin_free(crane, plan, ff, 1e-3, dq), tw[1e-3]), cols))
    clean = ex[2e-3]
    noisy = clean.with_noise(crane, True, a.seed)
    for old in (True, False):
        for step in (2e-3, 1e-3):
            for anch, lab in ((noisy, "noisy"), (clean, "noiseless")):
                r, v = diagnosis_prediction(crane, anch, noisy, clean, step, old)
                why = v["verdict"] + ("" if v["verdict"] == "explained" else
                                      ": " + "; ".join(v["reasons"][:2]))
                L.append(row(f"(d) diagnosis, {'per-chamber' if old else 'per-joint'} start, "
                             f"twin {step * 1e3:g} ms, anchors {lab}", r, td_cols(crane), why))
    L += ["", f"{time.perf_counter() - t0:.0f} s.", ""]
    text = "\n".join(L)
    print(text)
    if a.out:
        from planner.io import atomic_write_text
        atomic_write_text(a.out, text)


def td_cols(crane):
    return [f"q_{j}" for j in crane.names] + [f"p_{j}_{s}" for j in crane.names for s in "ab"]


if __name__ == "__main__":
    main()
