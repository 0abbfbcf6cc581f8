"""The noise floor of a recording, estimated from the data, and a check that the samples are
what the logger measured (not interpolated between measurements).

σ per channel = 1.4826·MAD(Δ²y)/√6: the second difference of white noise has variance 6σ²;
smooth motion contributes little at logger rates, sparse jumps are rejected by the median.

An upsampled (interpolated) log breaks that estimate: a linear interpolation makes Δ² zero
between the measured samples, a spline makes it smooth, and σ collapses towards the fixed
floor, so every model looks wrong (a false alarm). :func:`upsampling_factor` tells: for white
noise Δ² is negatively correlated with its neighbour (ρ = −2/3), so the spread of
Δ²ₖ + Δ²ₖ₊₁ is √(4/20) ≈ 0.45 of the spread of Δ²ₖ − Δ²ₖ₊₁; interpolated samples give about
1 or more. The factor is the least decimation m at which every m-th sample looks white again.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math

import numpy as np

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["noise_floor", "noise_floor_at", "logged_noise", "whiteness_ratio", "upsampling_factor", "WHITE_RATIO",
           "channel_noise"]

WHITE_RATIO = 0.7     # above: the samples are not independent measurements (white: ≈ 0.45)


def noise_floor(Y: np.ndarray) -> np.ndarray:
    """Per-column noise standard deviation estimated from the data (module doc)."""
    d2 = np.diff(Y, n=2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    return 1.4826 * mad / math.sqrt(6.0)


def noise_floor_at(t, Y) -> np.ndarray:
    """Per-column noise standard deviation of samples at any strictly increasing times ``t``
    (a logger's jittered stamps): each inner sample's offset from the straight line through
    its two neighbours, divided by that offset's white-noise spread √(1 + a² + b²) (a, b the
    neighbours' interpolation weights), then 1.4826·MAD. On a uniform grid the offset is
    −Δ²/2 and this equals :func:`noise_floor`. Use it on the samples as logged: a log resampled
    by interpolation mixes neighbouring readings, which shrinks Δ² more than the noise each
    reading carries (±10 % jitter: the uniform estimate comes out about 8 % low)."""
    t = np.asarray(t, float)
    Y = np.asarray(Y, float)
    h0, h1 = np.diff(t)[:-1], np.diff(t)[1:]
    a, b = h1 / (h0 + h1), h0 / (h0 + h1)         # weights of the left and right neighbour
    r = Y[1:-1] - (a[:, None] * Y[:-2] + b[:, None] * Y[2:])
    r /= np.sqrt(1.0 + a * a + b * b)[:, None]
    return 1.4826 * _mad(r)


def logged_noise(sig, Y, t_logged, Y_logged):
    """(σ per channel, note or None) for readings ``Y`` resampled on reading from the samples
    ``Y_logged`` at times ``t_logged``: interpolation mixed neighbouring readings, so σ is the
    larger of ``sig`` (the resampled readings' own, floored) and :func:`noise_floor_at` of the
    samples as logged (the resampled ones understate it)."""
    if len(t_logged) < 20:
        return sig, None
    s_log = noise_floor_at(t_logged, Y_logged)
    if s_log.shape != np.shape(sig):
        return sig, None
    k = float(np.median(s_log / np.maximum(noise_floor(Y), 1e-300)))
    return np.maximum(sig, s_log), (f"noise estimated on the samples as logged (before "
                                    f"resampling): x{k:.2f} the resampled readings' own estimate")


def _mad(x):
    return np.median(np.abs(x - np.median(x, axis=0)), axis=0)


def whiteness_ratio(Y: np.ndarray) -> np.ndarray:
    """Per column MAD(Δ²ₖ + Δ²ₖ₊₁) / MAD(Δ²ₖ − Δ²ₖ₊₁): ≈ 0.45 for white measurement noise,
    ≳ 1 for interpolated samples or noise-free smooth data (NaN where Δ² is all zero)."""
    d2 = np.diff(np.asarray(Y, float), n=2, axis=0)
    if len(d2) < 3:
        return np.full(np.shape(Y)[1], np.nan)
    a, b = _mad(d2[:-1] + d2[1:]), _mad(d2[:-1] - d2[1:])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(b > 0, a / b, np.nan)


def upsampling_factor(Y: np.ndarray, floor, max_factor: int = 8, min_samples: int = 200) -> int:
    """1 when the columns of ``Y`` (N, C) with noise above ``floor`` (C,) look like independent
    measurements; else the least m ≤ ``max_factor`` at which every m-th sample does (the log
    was probably upsampled ×m). 1 also when no column has measurable noise (exact data) or
    no decimation looks white (smooth data: nothing to correct)."""
    Y = np.asarray(Y, float)
    s = noise_floor(Y)
    # columns with noise: Δ² not dominated by the fixed floor at some decimation
    for m in range(1, max_factor + 1):
        Z = Y[::m]
        if len(Z) < min_samples:
            break
        sm = noise_floor(Z)
        use = sm > 10 * np.asarray(floor)
        if m == 1 and not use.any() and not (s > 0).any():
            return 1
        if not use.any():
            continue
        ratio = whiteness_ratio(Z[:, use])
        ratio = ratio[np.isfinite(ratio)]
        if ratio.size and float(np.median(ratio)) < WHITE_RATIO:
            return m
    return 1


def channel_noise(crane: Crane, rec) -> tuple[np.ndarray, np.ndarray | None]:
    """(σ of each position channel (n,), σ of each pressure channel (2n,) or None) of a
    recording: :func:`noise_floor_at` of the samples as logged, not below 5 % of seed 001's
    sensor accuracies (a noiseless synthetic log stays finite; the twin fit's scale)."""
    from planner.simulation.recording import NOISE_DEFAULTS
    src = rec.logged if rec.logged is not None else rec
    floor_q = np.array([NOISE_DEFAULTS["angle"] if j.type == "revolute"
                        else NOISE_DEFAULTS["length"] for j in crane.spec.joints])
    sq = np.maximum(noise_floor_at(src.t, src.q), 0.05 * floor_q)
    if rec.p_a is None:
        return sq, None
    sp = np.maximum(noise_floor_at(src.t, np.hstack([src.p_a, src.p_b])),
                    0.05 * NOISE_DEFAULTS["pressure"])
    return sq, sp
