"""Measured vs simulated: locate the disagreement, name the missing effect, add it, show the gap.

Given a machine, a recording (measured CSV: commands, positions, pressures) and optionally the
commanded trajectory:

1. **Nominal model.** Replay the measured commands on the nominal plant
   (:func:`planner.simulation.plant.respond`); the start pose is fitted to the measured positions (a
   nuisance parameter of every model). Residual = measured − simulated, per channel
   (``q_<joint>``, ``p_<joint>_a``, ``p_<joint>_b``). Near a stroke end the model makes no
   claim (its residual there hinges on the fitted start): :mod:`planner.calibration.ends`.
2. **Noise floor** from the data: per channel, σ = 1.4826·MAD(Δ²y)/√6 (the second difference
   of white noise has variance 6σ²; smooth motion contributes little at 50 Hz, sparse jumps are
   rejected by the median). Nothing is claimed below it (seed 001's lesson).
3. **Where**: channels ranked by residual RMS / σ, time windows where the residual stands out,
   and the residual split by operating condition (direction of motion, speed, load, pump
   saturation) — :func:`locate`.
4. **Which effect**: every catalogue effect on every joint it can belong to is fitted (bounded
   least squares on the noise-normalised residual of the *training* blocks: the even ones of
   blocks ``block_s`` long (1 s: both splits see every move, rest and pump saturation);
   a grid scan first, as several effects are invisible near their neutral value; then a bounded
   scalar search for one parameter, trust-region least squares for several), then scored on
   the *held-out* blocks: score = J_nominal − J_effect − k·ln(n) (J = Σ (r/σ)², k parameters:
   a BIC-style complexity penalty). Identifiability: the condition number of the fit's scaled
   Jacobian, and parameter standard errors from it. The best effect is named if its score
   exceeds :attr:`Discrepancy.threshold`; else "none: the nominal model explains the data
   within noise". When the named effect leaves some channel's held-out mean square residual
   above noise (by more than 4 standard errors of a χ² mean and 10 %), a second effect is
   tried on top (both refitted) and named if its own score passes the threshold and the
   pair beats the second alone. The verdict: :mod:`planner.calibration.verdict`.
5. **Gap**: per channel held-out RMS before/after, VAF, and the share of the above-noise
   residual removed (``gap_reduction``, :func:`planner.calibration.verdict.smoothed_excess`
   summed over the channels in units of σ²): gap = 1 − √(after/before).

A log faster than 100 Hz is analysed at 50-100 Hz (anti-alias filtered, commands averaged:
:mod:`planner.calibration.rate`, which also bounds the memory before the work starts).

The calibrated model is the crane spec plus ``[[effects]]`` (:func:`calibrated_spec_text`);
:func:`planner.calibration.compensate.compensate` re-plans feed-forward commands on it and
:func:`planner.calibration.report.write_report` writes the report. The candidates are every
catalogue effect (:data:`planner.model.effects.CATALOGUE`) on every joint it can belong
to: a registered effect is searched with no change here.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time as _time

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from planner.calibration.ends import near_stroke_end
from planner.calibration.noise import logged_noise, noise_floor, upsampling_factor
from planner.calibration.rate import analysis_note, analysis_rate
from planner.calibration.result import (Candidate, DiscrepancyResult, channel_fields,
                                        check_recording, verdict_fields)
from planner.calibration.calibrated import calibrated_spec_text  # re-exported
from planner.calibration.signature import signature_text
from planner.calibration.verdict import Evidence, judge, smoothed_excess
from planner.calibration.where import locate, operating_conditions
from planner.model.effects import CATALOGUE, Effect, fittable, quasi_static
from planner.simulation.plant import respond
from planner.simulation.recording import Recording

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Discrepancy", "DiscrepancyResult", "Candidate", "candidates", "noise_floor",
           "locate", "calibrated_spec_text", "VERDICTS"]

VERDICTS = ("explained", "named", "ambiguous", "unexplained")

PRESSURE_FLOOR = 1e3     # [Pa] smallest σ used (noise-free data)
POSITION_FLOOR = 1e-6    # [rad | m]


def candidates(crane: Crane, names=None) -> list[Effect]:
    """The effects the search fits (at their neutral values): every catalogue effect named in
    ``names`` (default: :func:`fittable`, in catalogue order), per-joint ones on every joint."""
    out = []
    for name in (names or fittable()):
        cls = CATALOGUE[name]
        if cls.per_joint:
            out += [cls(j) for j in crane.names]
        else:
            out.append(cls())
    return out


class Discrepancy:
    """The workflow (module doc). ``fit(recording)`` -> :class:`DiscrepancyResult`.

    candidates: catalogue names to try (default: all); block_s: length [s] of the alternating
    train/held-out blocks; threshold: least held-out score to name an effect (calibrated on
    clean data); grid: scan points per parameter before the local fit."""

    def __init__(self, crane: Crane, candidates=None, block_s: float = 1.0,
                 threshold: float = 30.0,
                 grid: int = 13, second: bool = True):
        unknown = [c for c in (candidates or []) if c not in CATALOGUE]
        if unknown:
            raise ValueError(f"unknown effect(s) {unknown}; known: {', '.join(CATALOGUE)}")
        quasi_static(CATALOGUE[c] for c in candidates or [])   # classes: name and stage
        self.crane = crane
        self.names = list(candidates) if candidates else fittable()
        if not block_s > 0:
            raise ValueError(f"block_s must be > 0 s, got {block_s}")
        self.block_s = float(block_s)
        self.threshold = float(threshold)
        self.grid = int(grid)
        self.try_second = second

    def prepare(self, rec: Recording) -> None:
        """Read ``rec`` (checks, noise, train/held-out blocks) for :meth:`fit_one`."""
        self._prepare(rec)

    def fit_one(self, effect: Effect) -> Candidate:
        """Fit one effect (from its neutral values) to the prepared recording."""
        return self._fit((), effect)

    def held_out_misfit(self, effects=()) -> float:
        """Σ ((y − ŷ)/σ)² over the held-out blocks of the prepared recording, ``effects`` on."""
        return self._J(self.predict(effects), self._test)

    # ------------------------------------------------------------------ data
    def _prepare(self, rec: Recording):
        crane, n = self.crane, self.crane.n
        check_recording(rec, n, self.block_s)
        # uniform within the CSV's 10 significant digits of t (a long log's times carry them)
        if np.ptp(dt := np.diff(rec.t)) > 1e-6 * np.median(dt) + 2e-9 * np.abs(rec.t).max():
            raise ValueError("recording: the sample times must be uniform (one command per "
                             "sample, as the CSV contract's simulate writes them)")
        self._notes = list(getattr(rec, "notes", ()) or ())
        logged = getattr(rec, "logged", None)
        rec, self._analysis, sampled = analysis_rate(rec, len(self._floor(rec)))  # rate.py
        if sampled is not None:   # a fast log, filtered to the analysis rate
            logged = None
            self._notes.append(analysis_note(self._analysis))
        m = upsampling_factor(self._channels(rec), self._floor(rec))
        if m > 1:
            self._notes.append(
                f"warning: the log looks upsampled (interpolated) about x{m} from "
                f"~{1.0 / float(np.median(dt)) / m:.0f} Hz: its samples are not independent "
                f"measurements, so the noise estimate and the statistics use every {m}th sample")
            rec = Recording(*(None if a is None else a[::m]
                              for a in (rec.t, rec.u, rec.q, rec.p_a, rec.p_b)))
        has_p = rec.p_a is not None and rec.p_b is not None
        cols = [f"q_{j}" for j in crane.names] + (
            [f"p_{j}_{s}" for j in crane.names for s in ("a", "b")] if has_p else [])
        Y = self._channels(rec)
        sig = np.maximum(noise_floor(Y), self._floor(rec))
        if sampled is not None:   # σ: the noise of the samples a logger at that rate keeps
            sig = np.maximum(sig, noise_floor(self._channels(sampled)))
        if logged is not None:     # resampled on reading: the noise of the logged samples
            sig, note = logged_noise(sig, Y, logged.t, self._channels(logged))
            self._notes += [note] * bool(note)
        block = np.floor((rec.t - rec.t[0]) / self.block_s).astype(int)
        train = block % 2 == 0
        self._rec, self._Y, self._sig, self._cols, self._has_p = rec, Y, sig, cols, has_p
        self._train, self._test = train, ~train
        self._cache = {}
        # no claim near a stroke end (planner.calibration.ends): out of the fit and the verdict
        near = self._near = near_stroke_end(crane, self.response(()).state.q, sig[:n])
        self._train, self._test = train & ~near, ~train & ~near
        self._notes += [f"{int(near.sum())} samples within 3 σ of a stroke end left out (the "
                        "model's residual there hinges on its fitted start)"] * bool(near.any())

    def _channels(self, rec):
        """(N, C) measured channels: q, then p_a, p_b interleaved per joint (if present)."""
        if rec.p_a is None or rec.p_b is None:
            return np.asarray(rec.q, float)
        P = np.empty((len(rec.t), 2 * self.crane.n))
        P[:, 0::2], P[:, 1::2] = rec.p_a, rec.p_b
        return np.hstack([rec.q, P])

    def _floor(self, rec):  # the smallest σ per channel (noise-free data)
        k = 0 if (rec.p_a is None or rec.p_b is None) else 2 * self.crane.n
        return np.array([POSITION_FLOOR] * self.crane.n + [PRESSURE_FLOOR] * k)

    def predict(self, effects=()) -> np.ndarray:
        """Model channels (N, C) for the recording, with ``effects``."""
        r = self.response(effects)
        return self._channels(r if self._has_p else Recording(r.t, r.u, r.q))

    def response(self, effects=()):
        rec = self._rec
        return respond(self.crane, rec.t, rec.u, rec.q[0], tuple(effects), t_end=rec.t[-1],
                       dt=(rec.t[-1] - rec.t[0]) / (len(rec.t) - 1),   # one step per sample
                       q_fit=rec.q, fit_mask=self._train, replay_cache=self._cache)

    def _claimed(self, Yp):     # the measurement itself where the model makes no claim
        return np.where(self._near[:, None], self._Y, Yp)

    def _J(self, Yp, mask):
        R = (self._Y - Yp)[mask] / self._sig
        return float(np.sum(R * R))

    # ------------------------------------------------------------------ fitting
    def _fit(self, fixed: tuple, cand: Effect) -> Candidate:
        """Fit ``cand``'s parameters (``fixed`` effects refitted jointly) on the train blocks."""
        crane = self.crane
        parts = list(fixed) + [cand]
        sizes = [len(e.parameters) for e in parts]
        lo = np.concatenate([e.bounds()[0] for e in parts])
        hi = np.concatenate([e.bounds()[1] for e in parts])
        span = hi - lo
        mask = self._train

        def build(z):
            v = lo + z * span
            out, k = [], 0
            for e, s in zip(parts, sizes):
                out.append(e.with_vector(v[k:k + s]))
                k += s
            return tuple(out)

        def resid(z):
            Yp = self.predict(build(z))
            return ((self._Y - Yp)[mask] / self._sig).ravel()

        z0 = np.concatenate([(e.vector() - e.bounds()[0]) / (np.asarray(e.bounds()[1]) -
                                                             e.bounds()[0]) for e in fixed]
                            + [(cand.neutral_vector(crane) - lo[-sizes[-1]:]) / span[-sizes[-1]:]])
        nfev = 0
        # grid scan over the candidate's own parameter(s) (axis by axis), fixed ones held
        best_z, best_J = z0.copy(), None
        k_c = sizes[-1]
        Jg = []
        for a in range(len(z0) - k_c, len(z0)):
            for g in np.linspace(0.0, 1.0, self.grid):
                z = best_z.copy()
                z[a] = g
                J = float(np.sum(resid(z) ** 2))
                Jg.append(J)
                nfev += 1
                if best_J is None or J < best_J:
                    best_J, best_z = J, z
        # excited: the effect changes the prediction somewhere in its plausible range
        excited = bool(max(Jg) - min(Jg) > 1e-9 * max(min(Jg), 1.0))
        J0 = float(np.sum(resid(z0) ** 2))
        nfev += 1
        if J0 <= best_J:
            best_z = z0
        jac = None
        if len(z0) == 1:
            # one parameter: bounded scalar search in the grid cell pair around the best point
            # (robust where the residual is flat, e.g. a dead band wider than every command)
            d = 1.0 / max(self.grid - 1, 1)
            # a Gauss-Newton step from the neutral value too: a true value far inside the
            # first grid cell (a plausible range spanning decades) is found there
            r0, h = resid(z0), 1e-7
            zh = np.clip(z0 + h, 0, 1) if z0[0] + h <= 1 else z0 - h
            sens = (resid(zh) - r0) / (zh[0] - z0[0])
            nfev += 2
            if float(sens @ sens) > 0:
                zg = np.clip(z0 - float(sens @ r0) / float(sens @ sens), 0.0, 1.0)
                Jn = float(np.sum(resid(zg) ** 2))
                nfev += 1
                if Jn < min(best_J, J0) and abs(zg[0] - z0[0]) < d:
                    best_J, best_z = Jn, zg
                    d = max(abs(zg[0] - z0[0]), 1e-12)
            a, b = max(best_z[0] - d, 0.0), min(best_z[0] + d, 1.0)
            sol = minimize_scalar(lambda x: float(np.sum(resid(np.array([x])) ** 2)),
                                  bounds=(a, b), method="bounded",
                                  options=dict(xatol=min(1e-5, 1e-3 * d)))
            nfev += sol.nfev
            z = np.array([sol.x]) if sol.fun <= best_J else best_z
            h = 1e-4
            zp, zm = np.clip(z + h, 0, 1), np.clip(z - h, 0, 1)
            jac = ((resid(zp) - resid(zm)) / max(zp[0] - zm[0], 1e-12))[:, None]
            nfev += 2
        else:
            try:
                # start strictly inside: trf does not leave a bound it starts on
                sol = least_squares(resid, np.clip(best_z, 0.01, 0.99), bounds=(0.0, 1.0),
                                    x_scale=1.0, diff_step=1e-3, max_nfev=40, method="trf")
                z, jac, nfev = sol.x, sol.jac, nfev + sol.nfev
            except Exception:  # a failed local fit keeps the best grid point
                z = best_z
        effs = build(z)
        Yp = self.predict(effs)
        J_tr, J_te = self._J(Yp, mask), self._J(Yp, self._test)
        std, cond = {}, 1.0
        if jac is not None:
            sv = np.linalg.svd(jac, compute_uv=False)
            local = bool(sv[-1] > 1e-9 * max(sv[0], 1e-300) and sv[0] > 1e-12)
            cond = float(sv[0] / sv[-1]) if local else float("inf")
            m = jac.shape[0]
            s2 = J_tr / max(m - len(z), 1)
            if local:   # standard errors from the scaled Jacobian (noise-normalised residual)
                cov = np.linalg.pinv(jac.T @ jac) * s2
                sd = np.sqrt(np.maximum(np.diag(cov), 0.0)) * span
            else:       # flat in some direction here: the data only bound the parameter
                sd = np.full(len(z), np.inf)
            k = 0
            for e, s in zip(effs, sizes):
                for p, v in zip(e.parameters, sd[k:k + s]):
                    std[f"{e.name}.{p.name}"] = float(v)
                k += s
        return Candidate(effs, int(sum(sizes)), J_tr, J_te, std=std, cond=cond,
                         excited=excited, nfev=nfev)

    def fit(self, rec: Recording, progress: bool = False) -> DiscrepancyResult:
        t0 = _time.perf_counter()
        self._prepare(rec)
        crane = self.crane
        Y0 = self.predict(())
        nominal = Candidate((), 0, self._J(Y0, self._train), self._J(Y0, self._test))
        n_test = int(self._test.sum())
        pen = math.log(n_test)
        cands, todo = [], candidates(crane, self.names)
        if progress:
            from tqdm import tqdm
            todo = tqdm(todo, desc="effects", unit="fit")
        for c in todo:
            f = self._fit((), c)
            f.score = nominal.J_test - f.J_test - pen * f.k
            cands.append(f)
        cands.sort(key=lambda c: -c.score)
        ranking = [dict(c.summary(), rank=i + 1) for i, c in enumerate(cands)]
        best = cands[0] if cands else None
        chosen = best if (best is not None and best.score > self.threshold
                          and best.excited) else None
        second = None
        if chosen is not None and self.try_second:
            # more than noise left on the held-out blocks? then try a second effect on top
            Yc = self.predict(chosen.effects)
            R = (self._Y - Yc)[self._test] / self._sig
            ms = np.mean(R * R, axis=0)          # per channel, 1 = noise
            if float(ms.max()) > 1.0 + max(4.0 * math.sqrt(2.0 / len(R)), 0.1):
                seconds = []
                for c in candidates(crane, self.names):
                    if c.name == chosen.effects[0].name and c.joint == chosen.effects[0].joint:
                        continue
                    f = self._fit(chosen.effects, c)
                    f.score = chosen.J_test - f.J_test - pen * (f.k - chosen.k)
                    seconds.append(f)
                seconds.sort(key=lambda c: -c.score)
                if seconds and seconds[0].score > self.threshold and seconds[0].excited:
                    second = seconds[0]
                    alone = _single(cands, second.effects[-1])
                    if alone is not None and alone.J_test - second.J_test <= \
                            self.threshold + pen * (second.k - alone.k):
                        chosen, second = alone, None    # the first adds nothing to it
        final = second or chosen
        r0 = self.response(())
        conds = operating_conditions(crane, self._rec.u, r0.state)
        ev = Evidence(self._Y, self._sig, self._test, self._rec.t, self._cols,
                      lambda effects: self._claimed(self.predict(effects)),
                      self.threshold, conds, crane.spec.id)
        v = judge(ev, self._claimed(Y0), cands, final, chosen)
        if v["verdict"] == "unexplained":
            final = chosen = second = None
        Yf = self.predict(final.effects) if final else Y0
        return self._report(Y0, Yf, final, chosen, second, ranking, t0, v, conds)

    def _report(self, Y0, Yf, final, chosen, second, ranking, t0, v, conds):
        te, cols, sig = self._test, self._cols, self._sig
        E0 = (self._Y - Y0)[te]
        E1 = (self._Y - Yf)[te]
        Yt = self._Y[te]
        rms0 = np.sqrt(np.mean(E0 ** 2, axis=0))
        rms1 = np.sqrt(np.mean(E1 ** 2, axis=0))
        var = np.var(Yt, axis=0)
        vaf0 = 100 * (1 - np.var(E0, axis=0) / np.maximum(var, 1e-300))
        vaf1 = 100 * (1 - np.var(E1, axis=0) / np.maximum(var, 1e-300))
        R0, R1 = (self._Y - self._claimed(Y0)) / sig, (self._Y - self._claimed(Yf)) / sig
        ex0 = np.maximum(smoothed_excess(R0, self._rec.t, te)[0], 0.0)
        ex1 = np.maximum(smoothed_excess(R1, self._rec.t, te)[0], 0.0)
        tot0, tot1 = math.sqrt(ex0.sum()), math.sqrt(ex1.sum())
        gap = 1.0 - tot1 / tot0 if tot0 > 0 else 0.0
        per = {c: (1.0 - math.sqrt(b) / math.sqrt(a) if a > 0.05 else None)
               for c, a, b in zip(cols, ex0, ex1)}
        params, unc, eff, joint = {}, {}, None, None
        ident = True
        if final is not None:
            first = next(x for x in final.effects if chosen and x.name == chosen.effects[0].name
                         and x.joint == chosen.effects[0].joint)
            eff, joint = first.name, first.joint
            params = dict(first.values, **({"joint": first.joint} if first.joint else {}))
            unc = {p.name: final.std.get(f"{first.name}.{p.name}") for p in first.parameters}
            ident = bool(final.cond < 1e8 and final.excited)
        sec = None
        if second is not None:
            s = second.effects[-1]
            sec = dict(effect=s.name, joint=s.joint, parameters=s.values,
                       uncertainty={p.name: second.std.get(f"{s.name}.{p.name}")
                                    for p in s.parameters})
        if v["verdict"] == "unexplained":
            sg = v["signature"][0] if v["signature"] else None
            msg = ("unexplained: " + (signature_text(sg) if sg else "; ".join(v["reasons"][:2]))
                   + (f"; best fit {v['not_credible']['model']} is not credible ("
                      f"{v['not_credible']['why'][:160]})" if v["not_credible"] else ""))
        elif eff is None:
            msg = ("none: the nominal model explains the data within noise "
                   f"(best candidate {ranking[0]['model']} scored {ranking[0]['score']:.1f} "
                   f"< {self.threshold:g})" if ranking else "none")
        elif v["verdict"] == "ambiguous":
            msg = ("ambiguous: the data cannot tell apart "
                   + " | ".join(f"{c['effect']}" + (f" on {c['joint']}" if c["joint"] else "")
                                + f" (score {c['score']:.1f})" for c in v["candidates"])
                   + "; the calibrated model uses the best, "
                   + f"{eff}" + (f" on {joint}" if joint else ""))
        else:
            msg = (f"{eff}" + (f" on {joint}" if joint else "") + ": "
                   + ", ".join(f"{k} = {v:.4g}" for k, v in params.items() if k != "joint")
                   + ("" if ident else " (not identifiable here: the data only bound it, e.g. "
                      "a dead band wider than every command)")
                   + f"; {100 * gap:.0f} % of the above-noise held-out residual removed"
                   + (f"; second effect {sec['effect']}" + (f" on {sec['joint']}"
                                                            if sec['joint'] else "")
                      if sec else ""))
        where = locate(self.crane, self._rec.t, R0, cols, conds, self._has_p)
        series = dict(t=self._rec.t, Y=self._Y, Y0=Y0, Yf=Yf, test=te, columns=cols, sigma=sig,
                      threshold=self.threshold)
        return DiscrepancyResult(
            effect=eff, joint=joint, parameters=params, uncertainty=unc,
            effects=final.effects if final else (), second=sec,
            **channel_fields(cols, rms0, rms1, vaf0, vaf1, sig), gap_reduction=float(gap),
            gap_reduction_channels=per, ranking=ranking, where=where, identifiable=ident,
            message=msg, runtime_s=_time.perf_counter() - t0, series=series,
            **verdict_fields(v), notes=list(self._notes), analysis=self._analysis)


def _single(cands, effect):
    """The single-effect fit of ``effect``'s (name, joint) among ``cands`` (or None)."""
    return next((c for c in cands if (c.effects[0].name, c.effects[0].joint)
                 == (effect.name, effect.joint)), None)
