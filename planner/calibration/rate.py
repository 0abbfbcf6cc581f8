"""The rate the discrepancy workflow analyses a recording at, and what a recording may cost.

What the quasi-static model explains is the valve commands and the slow motion and pressures
they cause: all of it lies far below 25 Hz, the Nyquist frequency of the 50 Hz control rate at
which every plan is commanded and ``simulate`` writes by default. A data logger's 1-10 kHz
holds nothing more of it, but every replay and every fit of every candidate effect used to run
at the logged rate: a 4.5 s log took 10 s at 50 Hz, 200 s and 1.4 GB at 1 kHz and was killed
(> 300 s, > 4 GB) at 5 and 10 kHz.

So a faster log is brought down to :data:`ANALYSIS_RATE_HZ` by the integer factor
m = ⌊rate / ANALYSIS_RATE_HZ⌋ (:func:`decimate`; the analysis rate is then 50-100 Hz):

- readings (positions, pressures): an anti-alias filter, then every m-th sample (sample i
  stays at t[i·m]). The filter is the centred mean over one interval around each kept sample
  (:func:`boxcar`: symmetric, a first-order CIC decimator); its response |sinc(f / rate)| is
  zero at the multiples of the analysis rate, exactly the frequencies that would alias onto
  0 Hz (a 100 Hz pump ripple would otherwise read as a pressure offset), and it never
  overshoots. Sharper filters were tried on a 10 kHz log of a hidden Coulomb friction
  (3000 N): a linear-phase FIR (``scipy.signal.resample_poly``) rings at the pressure step
  the friction causes when the boom starts, and a triangle (two boxcars) spreads that step
  over two samples; both left a residual read as an unexplained step. The filter averages
  the sensor noise down (14 × at 10 kHz), but the noise floor σ is that of the samples a
  logger at the analysis rate would keep (every m-th reading, unfiltered): the statistics,
  the threshold and the verdicts mean what they mean for a 50 Hz log (the model's own 50 Hz
  resolution at the pressure steps stays below σ, as it does there), and the filter only
  lowers the residual's noise (the 10 kHz log: the friction fitted at 2998 N);
- commands: the mean over each interval [t[i·m], t[(i+1)·m]) (what the valves integrate:
  the stroke each interval's commands ask for), held over it as before.

The cost is bounded before it is paid, as the DP's grid is (:func:`estimate_bytes`, measured
per cell read and per analysed sample and channel by ``benchmarks/bench_discrepancy_rates.py``):
reading a CSV holds its text and every value, about :data:`BYTES_PER_CELL` per cell; the
analysis holds the replays and the predictions of the candidates, about
:data:`BYTES_PER_SAMPLE` per analysed sample and channel. Above :data:`MAX_BYTES` the
recording is refused with the sizes and what to do.
"""
from __future__ import annotations

import math
import os

import numpy as np

ANALYSIS_RATE_HZ = 50.0
MAX_BYTES = 2 * 2 ** 30    # [B] largest estimated peak of one discrepancy run (as the DP's)
BYTES_PER_CELL = 40.0      # [B] reading the CSV, per cell (its text, the parsed values)
BYTES_PER_SAMPLE = 5000.0  # [B] the analysis, per analysed sample and channel
BYTES_FIXED = 200 * 2 ** 20  # the interpreter, NumPy, SciPy, the model


def factor(rate_hz: float) -> int:
    """The decimation factor for a log at ``rate_hz``: ⌊rate / ANALYSIS_RATE_HZ⌋, at least 1."""
    return max(1, int(math.floor(rate_hz / ANALYSIS_RATE_HZ + 1e-9)))


def boxcar(a, m: int, k: int) -> np.ndarray:
    """The centred mean over one interval (m samples) of the columns of ``a`` (N, C) at the
    samples 0, m, …, (k − 1)·m: for odd m the m samples around each, for even m the m + 1
    samples a[j − m/2 … j + m/2] with half weights at both ends (symmetric: no time shift); the
    ends padded with the first and last rows. One running sum: O(N), whatever m."""
    a = np.asarray(a, float)
    h = m // 2
    ap = np.concatenate([np.repeat(a[:1], h, axis=0), a, np.repeat(a[-1:], h, axis=0)])
    c = np.concatenate([np.zeros((1, a.shape[1])), np.cumsum(ap, axis=0)])
    j = np.arange(k) * m                  # ap[j:j + 2h + 1] is a[j - h:j + h + 1]
    total = c[j + 2 * h + 1] - c[j]
    if m % 2:
        return total / m
    return (total - 0.5 * (ap[j] + ap[j + 2 * h])) / m


def decimate(rec, m: int):
    """``rec`` (a :class:`planner.simulation.recording.Recording`, uniform times) at every m-th
    sample: readings anti-alias filtered, commands averaged over each interval (module doc)."""
    from planner.simulation.recording import Recording
    if m <= 1:
        return rec
    n = len(rec.t)
    k = (n + m - 1) // m
    t = rec.t[::m][:k]

    def readings(a):
        return None if a is None else boxcar(a, m, k)

    u = np.asarray(rec.u, float)
    starts = np.arange(k) * m
    ends = np.minimum(starts + m, n)
    csum = np.vstack([np.zeros((1, u.shape[1])), np.cumsum(u, axis=0)])
    u_mean = (csum[ends] - csum[starts]) / (ends - starts)[:, None]
    return Recording(t, u_mean, readings(rec.q), readings(rec.p_a), readings(rec.p_b),
                     tuple(rec.notes))


def estimate_bytes(rows: int, columns: int, analysed: int, channels: int) -> float:
    """Estimated peak memory [B] of reading ``rows`` × ``columns`` cells and analysing
    ``analysed`` samples of ``channels`` channels (module doc)."""
    return (BYTES_FIXED + BYTES_PER_CELL * float(rows) * columns
            + BYTES_PER_SAMPLE * float(analysed) * channels)


def check_file(path) -> dict:
    """Before reading: the rows, columns, rate and estimated peak memory of the measured CSV
    ``path`` (counted from its bytes and its first rows, without parsing it all); ValueError
    naming the file when the estimate exceeds :data:`MAX_BYTES`."""
    rows, head = 0, []
    try:
        with open(path, "rb") as fh:
            for i, line in enumerate(fh):
                if i < 4:
                    head.append(line)
                rows += bool(line.strip())
    except OSError:
        return dict(rows=0, estimated_bytes=BYTES_FIXED)   # the reader says what is wrong
    if rows < 3:
        return dict(rows=rows, estimated_bytes=BYTES_FIXED)   # the reader says what is wrong
    cols = head[0].count(b",") + 1
    try:
        t1, t2 = (float(r.split(b",", 1)[0]) for r in head[1:3])
        rate = 1.0 / (t2 - t1) if t2 > t1 else ANALYSIS_RATE_HZ
    except ValueError:
        rate = ANALYSIS_RATE_HZ   # not numbers: the reader names the line
    if not math.isfinite(rate) or rate <= 0:
        rate = ANALYSIS_RATE_HZ
    samples = rows - 1
    analysed = -(-samples // factor(rate))
    # the channels analysed: the q and p columns (about all but t and the commands)
    channels = max(1, cols - 1 - (cols - 1) // 4)
    need = estimate_bytes(samples, cols, analysed, channels)
    if need > MAX_BYTES:
        raise ValueError(
            f"{path}: {samples} samples × {cols} columns at {rate:.4g} Hz need ~"
            f"{need / 2 ** 30:.1f} GiB to read and analyse; allowed up to "
            f"{MAX_BYTES / 2 ** 30:.1f} GiB: analyse a shorter stretch of the log (a few "
            "minutes are plenty), or write it at a lower rate (crane-planner resample)")
    return dict(rows=samples, columns=cols, rate_hz=rate, analysed=analysed,
                estimated_bytes=need, size_bytes=os.path.getsize(path))


def analysis_rate(rec, channels: int) -> tuple:
    """(the recording to analyse, what was done: a JSON-ready dict with the logged and the
    analysis rate, the factor, the samples, the method and the estimated peak memory, and the
    samples a logger at the analysis rate would have kept: every m-th, unfiltered; None when
    the log is analysed as it is). The noise floor is taken from those (module doc)."""
    from planner.simulation.recording import Recording
    h = (rec.t[-1] - rec.t[0]) / (len(rec.t) - 1)
    rate = 1.0 / h
    m = factor(rate)
    out = decimate(rec, m)
    sampled = None if m == 1 else Recording(*(None if a is None else np.asarray(a)[::m]
                                              for a in (rec.t, rec.u, rec.q, rec.p_a, rec.p_b)))
    info = dict(rate_logged_hz=rate, rate_analysed_hz=rate / m, factor=m,
                samples_logged=len(rec.t), samples_analysed=len(out.t),
                method=("none: logged at the analysis rate" if m == 1 else
                        f"readings: anti-alias filter (centred mean of {m} samples) and every "
                        f"{m}th sample; commands: mean over each interval"),
                estimated_bytes=estimate_bytes(0, 0, len(out.t), channels))
    return out, info, sampled


def analysis_note(info: dict) -> str:
    """The line that says what :func:`analysis_rate` did (the CLI prints it on stderr)."""
    return (f"note: the {info['rate_logged_hz']:.4g} Hz log is analysed at "
            f"{info['rate_analysed_hz']:.4g} Hz ({info['samples_logged']} -> "
            f"{info['samples_analysed']} samples; readings anti-alias filtered, commands "
            "averaged over each interval): what the quasi-static model explains lies below "
            f"{ANALYSIS_RATE_HZ / 2:g} Hz")

