"""The verdict of the discrepancy workflow: ``explained`` | ``named`` | ``ambiguous`` |
``unexplained`` (docs/design.md, "CONTRACT: command line").

* **explained** — no effect earns a name, and the nominal residual is noise: every channel's
  held-out mean square within :func:`noise_bound` (never 4 or more: a channel's RMS ≥ 2 σ),
  no slow residual above noise (:func:`smoothed_excess`) and no material shape in it
  (:mod:`planner.calibration.signature`).
* **named** — the best fit earns a name (held-out score above the threshold, which the
  clean-data trials calibrate) *and* is credible: the residual left after it is noise by the
  same two tests (on every channel's held-out mean square, with a looser bound, and no
  material shape left). ``confidence`` = Φ(margin / σ_margin) against the runner-up.
* **ambiguous** — credible, but a runner-up is within the noise of the score itself: for two
  fits i, j the held-out score difference is Σ(rⱼ² − rᵢ²) = D ± 2√D with D = Σ((ŷᵢ − ŷⱼ)/σ)²
  when i is right, so a margin below :data:`TIE_Z` · 2√D (or D below :data:`TIE_Z`² · 4,
  predictions the data cannot tell apart) is a tie. Up to :data:`MAX_CANDIDATES` candidates,
  each with where their predictions differ most (joint, direction, speed, load).
* **unexplained** — some channel is above noise and no credible fit removes it: the residual's
  signature (periodic / drift / step / outliers / unclassified, channel, size), and the best
  fit shown as ``not_credible`` with why.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.stats import norm

from planner.calibration.signature import describe, mean_square

__all__ = ["Evidence", "noise_bound", "smoothed_excess", "judge", "TIE_Z", "MAX_CANDIDATES"]

TIE_Z = 2.0
MAX_CANDIDATES = 3
SLACK_EXPLAINED = 0.35   # held-out mean square above 1 that σ's own error can explain
SLACK_NAMED = 0.4
SMOOTH_S = 0.5           # [s] window of the slow-residual test
EXCESS_MIN = 0.08        # [σ²] least slow residual called above noise (RMS 0.28 σ)


@dataclass
class Evidence:
    """What the verdict looks at: measured channels ``Y`` (N, C), their noise ``sigma`` (C,),
    the held-out rows ``test``, times ``t``, channel names ``columns``, ``predict`` (effects ->
    model channels), the naming ``threshold`` and ``conditions`` (joint -> condition name ->
    row mask: where a difference of predictions shows), ``machine`` (for the suggested
    ``excite`` command)."""
    Y: np.ndarray
    sigma: np.ndarray
    test: np.ndarray
    t: np.ndarray
    columns: list
    predict: Callable
    threshold: float
    conditions: dict
    machine: str = "MACHINE"


def noise_bound(n: int, slack: float = 0.1, n_sigma: int | None = None) -> float:
    """Largest held-out mean square (noise units) that is still noise over ``n`` samples:
    1 + max(``slack``, 4 standard errors) — of the χ² mean and, with ``n_sigma`` (the samples
    σ was estimated from), of σ² itself (the MAD of Δ² gives σ to about 1.2/√n_sigma)."""
    var = 2.0 / max(n, 1) + (4 * 1.44 / max(n_sigma, 1) if n_sigma else 0.0)
    return 1.0 + max(4.0 * math.sqrt(var), slack)


def smoothed_excess(R, t, mask, window_s: float = SMOOTH_S):
    """(per-column above-noise mean square of R (noise units) smoothed over ``window_s``, on
    ``mask`` rows; the largest value white noise reaches (6 standard errors, at least
    :data:`EXCESS_MIN`)). A moving average of w samples divides white noise's variance by w
    and keeps a slow systematic residual, so this barely depends on an error in σ (an
    interpolated log's slightly correlated noise, say)."""
    dt = float(np.median(np.diff(t)))
    w = max(1, int(round(window_s / dt)))
    f = uniform_filter1d(R, size=w, axis=0, mode="nearest")
    n = max(int(np.sum(mask)), 1)
    ex = np.mean(f[mask] ** 2, axis=0) - 1.0 / w
    return ex, max(EXCESS_MIN, 6.0 * math.sqrt(2.0 * w / n) / w)


def _noise_like(ev: Evidence, Yp, slack: float):
    """(is noise, reasons, per-channel held-out RMS/σ, signatures) of the residual Y − Yp."""
    R = (ev.Y - Yp) / ev.sigma
    ms = mean_square(R, ev.test)
    bound = min(noise_bound(int(ev.test.sum()), slack, len(ev.t)), 4.0)
    why = [f"{c}: held-out RMS {math.sqrt(m):.2f} σ (noise: ≤ {math.sqrt(bound):.2f} σ)"
           for c, m in zip(ev.columns, ms) if m > bound]
    ex, top = smoothed_excess(R, ev.t, ev.test)
    why += [f"{c}: a slow residual of {math.sqrt(max(e, 0.0)):.2f} σ RMS (noise: ≤ "
            f"{math.sqrt(top):.2f} σ)" for c, e, m in zip(ev.columns, ex, ms)
            if e > top and m <= bound]
    sigs = [s for s in describe(R, ev.t, ev.columns, ev.sigma)
            if s["kind"] != "unclassified"]
    why += [f"{s['channel']}: {s['kind']} left in the residual ({100 * s['share']:.0f} % of "
            "its excess)" for s in sigs]
    return (not why), why, dict(zip(ev.columns, map(float, np.sqrt(ms)))), sigs


def _difference(ev: Evidence, Yi, Yj) -> tuple[float, list]:
    """D = Σ_test ((ŷᵢ − ŷⱼ)/σ)² and the operating conditions where the two predictions differ
    most (mean squared difference in σ², the channel that shows it)."""
    Dm = (Yi - Yj) / ev.sigma
    D = float(np.sum(Dm[ev.test] ** 2))
    e2 = Dm ** 2
    rows = []
    for joint, split in ev.conditions.items():
        for cond, m in split.items():
            if m.sum() < 10:
                continue
            per = np.mean(e2[m], axis=0)
            c = int(np.argmax(per))
            rows.append(dict(joint=joint, condition=cond, channel=ev.columns[c],
                             mean_sq_difference=float(per[c])))
    rows.sort(key=lambda r: -r["mean_sq_difference"])
    return D, rows[:4]


def _entry(c) -> dict:
    e = c.effects[-1]
    return dict(effect=e.name, joint=e.joint, parameters=dict(e.values), score=float(c.score),
                uncertainty={p.name: c.std.get(f"{e.name}.{p.name}") for p in e.parameters})


def judge(ev: Evidence, Y0, ranked, final, single_best) -> dict:
    """The verdict (module doc). ``Y0``: nominal prediction; ``ranked``: single-effect fits,
    best first (``score``, ``effects``, ``excited``); ``final``: the fit the workflow would
    name (None: nothing passed the threshold); ``single_best``: the single-effect fit named
    first (one of ``ranked``). Returns dict verdict, confidence, candidates, signature,
    not_credible, reasons, suggest (ambiguous: the ``excite`` command that would tell the
    candidates apart)."""
    out = dict(verdict=None, confidence=None, candidates=[], signature=[], not_credible=None,
               reasons=[], suggest=None)
    if final is None:
        ok, why, _, _ = _noise_like(ev, Y0, SLACK_EXPLAINED)
        if ok:
            out["verdict"] = "explained"
            return out
        R0 = (ev.Y - Y0) / ev.sigma
        out.update(verdict="unexplained", reasons=why,
                   signature=describe(R0, ev.t, ev.columns, ev.sigma))
        return out
    Yf = ev.predict(final.effects)
    ok, why, _, _ = _noise_like(ev, Yf, SLACK_NAMED)
    if not ok:
        R0 = (ev.Y - Y0) / ev.sigma
        out.update(verdict="unexplained", reasons=why,
                   signature=describe(R0, ev.t, ev.columns, ev.sigma),
                   not_credible=dict(_entry(final), model=final.label,
                                     why="the residual left after it is not noise: "
                                         + "; ".join(why)))
        return out
    # a credible name: is a runner-up within the noise of the score?
    best = single_best
    if best is None:
        out["verdict"] = "named"
        return out
    Yb = ev.predict(best.effects)
    ties, margin_z = [], math.inf
    for c in [c for c in ranked if c is not best][:7]:
        if not c.excited or c.score <= ev.threshold:
            continue
        D, where = _difference(ev, Yb, ev.predict(c.effects))
        sd = 2.0 * math.sqrt(max(D, 1e-12))
        z = (best.score - c.score) / sd
        margin_z = min(margin_z, z)
        if z < TIE_Z or D < 4.0 * TIE_Z ** 2:
            ties.append((c, D, where))
    out["confidence"] = float(norm.cdf(margin_z)) if math.isfinite(margin_z) else 1.0
    if not ties:
        out["verdict"] = "named"
        return out
    cands = [dict(_entry(best), differs_most=[])]
    for c, D, where in ties[:MAX_CANDIDATES - 1]:
        cands.append(dict(_entry(c), prediction_difference=D, differs_most=where))
    sep = ",".join(c["effect"] + (f"@{c['joint']}" if c["joint"] else "") for c in cands)
    out.update(verdict="ambiguous", candidates=cands,
               suggest=f"crane-planner excite {ev.machine} --separate {sep} --duration "
                       f"{max(60, round(float(ev.t[-1] - ev.t[0]))):d} --out excitation.csv")
    return out
