"""What a residual looks like when no catalogue effect explains it: its signature.

A residual r (measured − model) in units of the channel's noise σ is white with unit variance
when the model explains the data. Anything else is described by the simple shape that removes
most of its above-noise part (:func:`describe`):

* ``outliers`` — isolated samples far from their neighbours (|r − median of 5| > 6 σ), few;
* ``periodic`` — a sinusoid at the periodogram's peak (frequency, amplitude, phase free);
* ``drift`` — a straight line in time (rate);
* ``step`` — one jump of the mean at the best time (time, size);
* ``unclassified`` — none of these removes at least :data:`SHARE` of the excess.

Each shape is fitted by least squares to the whole recording (outliers removed first); its
"reduction" is how much of Σ r² it removes. A shape is *material* when it removes more than
:data:`MIN_REDUCTION` (chance: a free-frequency sinusoid or a free step time removes ~2 ln N of
pure noise) and at least :data:`MIN_SHARE_OF_NOISE` · N (its RMS ≥ 0.17 σ: a disagreement a
user would care about at any sample rate).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import median_filter

__all__ = ["describe", "channel_signature", "mean_square", "signature_text", "OUTLIER_Z", "SHARE",
           "MIN_REDUCTION", "MIN_SHARE_OF_NOISE"]

OUTLIER_Z = 6.0            # a spike: this many σ from the median of its 5 neighbours
SHARE = 0.6                # a shape names the residual when it removes this share of the excess
MIN_REDUCTION = 30.0       # [σ²] least Σ r² a shape must remove (chance level ~ 2 ln N)
MIN_SHARE_OF_NOISE = 0.03  # … and at least this × N (RMS ≥ 0.17 σ)


def mean_square(R: np.ndarray, mask=None) -> np.ndarray:
    """Per-column mean of R² (R in noise units: 1 = white noise) over ``mask`` rows."""
    R = R if mask is None else R[mask]
    return np.mean(R * R, axis=0)


def _ls_reduction(r: np.ndarray, X: np.ndarray) -> tuple[float, np.ndarray]:
    """(Σ r² − Σ (r − X β)², β) of the least-squares fit of r on the columns of X."""
    beta, *_ = np.linalg.lstsq(X, r, rcond=None)
    e = r - X @ beta
    return float(r @ r - e @ e), beta


def _step(r: np.ndarray, t: np.ndarray, edge: float = 0.02):
    """Best single jump of the mean: (reduction over a constant, time, size)."""
    n = len(r)
    c = np.cumsum(r)
    k = np.arange(1, n)
    m1 = c[:-1] / k
    m2 = (c[-1] - c[:-1]) / (n - k)
    red = k * (n - k) / n * (m2 - m1) ** 2
    lo = max(1, int(edge * n))
    red[:lo - 1] = 0.0
    red[n - lo:] = 0.0
    i = int(np.argmax(red))
    return float(red[i]), float(0.5 * (t[i] + t[i + 1])), float(m2[i] - m1[i])


def _periodic(r: np.ndarray, t: np.ndarray):
    """Sinusoid at the periodogram's peak (at least 2 periods in the record, up to Nyquist):
    (reduction over a constant, frequency [Hz], amplitude in σ)."""
    n = len(r)
    dt = float(np.median(np.diff(t)))
    x = r - r.mean()
    pad = 4 * n
    X = np.fft.rfft(x, pad)
    f = np.fft.rfftfreq(pad, dt)
    T = t[-1] - t[0]
    ok = f >= 2.0 / max(T, 1e-9)
    if not ok.any():
        return 0.0, 0.0, 0.0
    k = int(np.flatnonzero(ok)[np.argmax(np.abs(X[ok]))])
    fk = float(f[k])
    w = 2 * math.pi * fk * (t - t[0])
    red, beta = _ls_reduction(x, np.column_stack([np.sin(w), np.cos(w), np.ones(n)]))
    return red, fk, float(math.hypot(beta[0], beta[1]))


def channel_signature(r: np.ndarray, t: np.ndarray, sigma: float = 1.0) -> dict:
    """The signature of one channel's residual ``r`` (noise units) at times ``t``: a dict with
    ``kind`` (outliers | periodic | drift | step | unclassified | none), ``share`` (of the
    excess the shape removes), ``reduction`` [σ²], ``excess`` (Σ r² − N) [σ²] and the shape's
    size in channel units (``sigma``: the channel's σ): ``frequency_hz`` + ``amplitude``;
    ``rate`` (per s); ``time_s`` + ``size``; ``count`` + ``times_s`` + ``largest``."""
    r = np.asarray(r, float)
    n = len(r)
    excess = float(r @ r - n)
    out = dict(kind="none", excess=excess, share=0.0, reduction=0.0)
    # outliers first: they would dominate every smooth shape
    med = median_filter(r, size=5, mode="nearest")
    spikes = np.flatnonzero(np.abs(r - med) > OUTLIER_Z)
    clean = r
    red_out = 0.0
    if 0 < len(spikes) <= max(1, int(0.02 * n)):
        clean = r.copy()
        clean[spikes] = med[spikes]
        red_out = float(r @ r - clean @ clean)
    if excess <= 0:
        return out
    shapes = {}
    if red_out > 0:
        shapes["outliers"] = (red_out, dict(count=int(len(spikes)),
                                            times_s=[float(x) for x in t[spikes[:10]]],
                                            largest=float(np.max(np.abs(r - med)[spikes]))
                                            * sigma))
    base = clean - clean.mean()
    red0 = float(clean @ clean - base @ base)       # what a constant alone removes
    tt = t - t[0]
    red_d, beta = _ls_reduction(base, np.column_stack([tt - tt.mean()]))
    shapes["drift"] = (red0 + red_d, dict(rate=float(beta[0]) * sigma))
    red_s, ts, size = _step(clean, t)
    shapes["step"] = (red0 + red_s, dict(time_s=ts, size=size * sigma))
    red_p, fp, amp = _periodic(clean, t)
    shapes["periodic"] = (red0 + red_p, dict(frequency_hz=fp, amplitude=amp * sigma))
    if "outliers" in shapes:     # the smooth shapes act on the cleaned residual
        for k in ("drift", "step", "periodic"):
            shapes[k] = (shapes[k][0] + red_out, shapes[k][1])
    kind = max(shapes, key=lambda k: shapes[k][0])
    red, info = shapes[kind]
    if kind != "outliers" and "outliers" in shapes and red_out >= SHARE * excess:
        kind, (red, info) = "outliers", shapes["outliers"]
    share = red / excess
    out.update(reduction=red, share=float(min(share, 1.0)))
    material = red > MIN_REDUCTION and red > MIN_SHARE_OF_NOISE * n
    if material and share >= SHARE:
        out.update(kind=kind, **info)
    elif excess > MIN_REDUCTION and excess > MIN_SHARE_OF_NOISE * n:
        out["kind"] = "unclassified"
    return out


def describe(R: np.ndarray, t: np.ndarray, columns, sigma, channels=None) -> list[dict]:
    """Signatures of the columns of ``R`` (N, C) (noise units) named in ``channels`` (default:
    all), each with ``channel`` and ``rms_over_noise``; the ones that are not noise
    (kind ≠ none), the largest excess first."""
    out = []
    for c, name in enumerate(columns):
        if channels is not None and name not in channels:
            continue
        s = channel_signature(R[:, c], t, float(sigma[c]))
        if s["kind"] == "none":
            continue
        s = dict(channel=name, rms_over_noise=float(math.sqrt(np.mean(R[:, c] ** 2))), **s)
        out.append(s)
    out.sort(key=lambda s: -s["excess"])
    return out


def signature_text(s: dict) -> str:
    """One line for a residual signature (:mod:`planner.calibration.signature`)."""
    c = s["channel"]
    k = s["kind"]
    if k == "periodic":
        return f"periodic at {s['frequency_hz']:.2f} Hz, amplitude {s['amplitude']:.3g} on {c}"
    if k == "drift":
        return f"drift at {s['rate']:.3g} per s on {c}"
    if k == "step":
        return f"step of {s['size']:.3g} at t = {s['time_s']:.2f} s on {c}"
    if k == "outliers":
        return (f"{s['count']} outlier(s) on {c} (largest {s['largest']:.3g}; at "
                + ", ".join(f"{x:.2f}" for x in s["times_s"][:5]) + " s)")
    return f"{c} at {s['rms_over_noise']:.1f} x noise, no simple shape"
