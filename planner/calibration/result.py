"""What the discrepancy search returns: a fitted :class:`Candidate` model and the
:class:`DiscrepancyResult` with its verdict (:mod:`planner.calibration.discrepancy`)."""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Candidate", "DiscrepancyResult", "channel_fields", "verdict_fields",
           "check_recording"]


@dataclass
class Candidate:
    """One fitted model: the effects (fitted values), its held-out score and diagnostics."""
    effects: tuple
    k: int
    J_train: float
    J_test: float
    score: float = 0.0
    std: dict = field(default_factory=dict)
    cond: float = 1.0
    excited: bool = True
    nfev: int = 0

    @property
    def label(self) -> str:
        return " + ".join(f"{e.name}" + (f"[{e.joint}]" if e.joint else "")
                          for e in self.effects) or "nominal"

    def summary(self) -> dict:
        return dict(model=self.label, effects=[e.to_dict() for e in self.effects],
                    k=self.k, J_train=self.J_train, J_test=self.J_test, score=self.score,
                    std=self.std, cond=self.cond, excited=self.excited)


@dataclass
class DiscrepancyResult:
    """``verdict`` (one of :data:`VERDICTS`, :mod:`planner.calibration.verdict`) with
    ``confidence`` (named), ``candidates`` (ambiguous), ``signature`` and ``not_credible``
    (unexplained), ``reasons`` and ``notes`` (how the data were read: upsampled, resampled),
    ``analysis`` (the rate analysed at, :func:`planner.calibration.rate.analysis_rate`);
    ``effect``: the named catalogue effect (None = nothing named; when ambiguous, the best of
    the candidates),
    ``joint``, ``parameters`` (fitted values) with ``uncertainty`` (standard errors),
    ``second``: a further effect (or None), per-channel ``rms_before``/``rms_after`` (held-out,
    channel units), ``vaf_before``/``vaf_after`` [%], ``noise``, ``gap_reduction`` (share of the
    above-noise held-out residual removed, overall and per channel), ``ranking`` (every
    candidate), ``where`` (:func:`locate`), ``runtime_s``."""
    effect: str | None
    joint: str | None
    parameters: dict
    uncertainty: dict
    effects: tuple
    second: dict | None
    rms_before: dict
    rms_after: dict
    vaf_before: dict
    vaf_after: dict
    noise: dict
    gap_reduction: float
    gap_reduction_channels: dict
    ranking: list
    where: dict
    identifiable: bool
    message: str
    runtime_s: float
    series: dict = field(default_factory=dict, repr=False)
    verdict: str = "explained"
    confidence: float | None = None
    candidates: list = field(default_factory=list)
    signature: list = field(default_factory=list)
    not_credible: dict | None = None
    suggest: str | None = None
    reasons: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    analysis: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        out = {k: getattr(self, k) for k in (
            "verdict", "effect", "joint", "parameters", "uncertainty", "confidence",
            "candidates", "suggest", "signature", "not_credible", "reasons", "notes", "second",
            "rms_before", "rms_after", "vaf_before", "vaf_after", "noise", "gap_reduction",
            "gap_reduction_channels", "identifiable", "message", "where", "runtime_s",
            "analysis")}
        out["effects"] = [e.to_dict() for e in self.effects]
        out["ranking"] = self.ranking
        return out


def channel_fields(cols, rms0, rms1, vaf0, vaf1, sig) -> dict:
    """The per-channel keys of a :class:`DiscrepancyResult` (``rms_before`` … ``noise``):
    channel name -> float, from arrays in ``cols`` order."""
    def d(a):
        return dict(zip(cols, map(float, a)))
    return dict(rms_before=d(rms0), rms_after=d(rms1), vaf_before=d(vaf0), vaf_after=d(vaf1),
                noise=d(sig))


def verdict_fields(v: dict) -> dict:
    """The keys a :class:`DiscrepancyResult` takes from the verdict's dict
    (:func:`planner.calibration.verdict.judge`)."""
    return {k: v[k] for k in ("verdict", "confidence", "candidates", "signature",
                              "not_credible", "reasons", "suggest")}


def check_recording(rec, n: int, block_s: float) -> None:
    """The checks every diagnosis makes of a log before it fits: commands and positions of
    shape (N, ``n``), and at least four train/test blocks of ``block_s`` seconds; ValueError
    naming what is wrong otherwise."""
    if rec.u is None or rec.u.shape != rec.q.shape or rec.q.shape[1] != n:
        raise ValueError(f"recording: expected u and q of shape (N, {n})")
    if rec.t[-1] - rec.t[0] < 4 * block_s or len(rec.t) < 20:
        raise ValueError(f"recording: {rec.t[-1] - rec.t[0]:.2f} s ({len(rec.t)} samples) "
                         f"is too short: need at least 4 blocks of {block_s:g} s")
