"""What a recording of a test sequence would teach the twin's calibration (issue 28, item 3):
the Fisher information of the twin's parameters (:mod:`planner.calibration.twin_params`) in a
log of the sequence, computed before anything is recorded.

**The log.** The twin at the spec's values replays the sequence's commands from rest at its
first pose; its positions and chamber pressures, noise-free, sampled on the command grid,
are the log the machine would give if the spec were right. The calibration's own misfit
(:class:`planner.calibration.twin_fit.TwinFit`: the log cut at its holds, each segment
simulated from the state measured at its start) is built on it, with each channel scaled by
the sensor noise the recording will have (seed 001's levels by default,
:data:`planner.simulation.recording.NOISE_DEFAULTS`) — not by a noise estimate from the
noise-free log, which would be the 5 % floor and promise twenty times too much.

**The Jacobian.** J = ∂r/∂z of the scaled residuals in the scaled parameters z, by *central*
differences of whole twin runs with the step :data:`FD_STEP` (1 % of a factor, or of a
parameter's physical scale). Forward differences from the nominal run with a tiny step (the
fit's own Jacobian) are not used here: the twin's friction sticks and slips in the holds, so
a run's pressures jump by a few noise units with perturbations of 10⁻⁴–10⁻³, and a difference
taken against one base run carries that base run's jump in every column — a common direction
that looks like information and is not. A difference between two perturbed runs 2 % apart is
smooth to a few per cent. At a bound (a leakage, a dead band or a friction that is zero in the
spec) the slope between z + h and z + 2h is taken (inside the bounds, still no base run).

**The information.** With unit-variance scaled residuals, a recording's Fisher information is
JᵀJ, and the Cramér–Rao bound on the scaled standard deviation of parameter i is
sqrt([(JᵀJ)⁻¹]ᵢᵢ) — the sd the fit would report on a recording of the sequence
(:data:`planner.calibration.twin_fit.UNIDENTIFIED` marks a parameter as not identified). The
segments are independent (each starts from a measured state), so the information is a sum over
segments: :class:`Information` keeps each segment's JᵀJ, and any prefix of the sequence that ends
at a hold, or the sequence repeated, has its information without another twin run.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time
from dataclasses import dataclass

import numpy as np

from planner.calibration.twin_fit import TwinFit, UNIDENTIFIED
from planner.model.twin import Twin
from planner.simulation.recording import Recording, noise_levels

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Information", "information", "twin_log", "FD_STEP", "RIDGE"]

FD_STEP = 0.01          # central-difference step in the scaled parameters (module doc)
RIDGE = 1e-12           # relative floor of JᵀJ's eigenvalues (numerically null directions)


def twin_log(crane: Crane, plan, ff, step: float = 2e-3) -> Recording:
    """The noise-free log of the twin at the spec's values replaying ``ff`` from rest at the
    plan's first pose (module doc). ValueError when the twin diverges on it."""
    run = Twin(crane, step=step).simulate(ff.t, ff.u, plan.q[0], t_end=ff.t[-1])
    if not run.ok:
        raise ValueError(f"sequence: the {crane.spec.id} twin diverges at t = {run.t_fail:.2f} "
                         f"s ({run.reason}); allowed: a sequence the twin can replay")
    q, pa, pb, u = run.sample(ff.t)
    return Recording(ff.t, u, q, pa, pb)


@dataclass
class Information:
    """The Fisher information of ``params`` (the twin's :class:`TwinParameter` list) in a
    recording of one sequence, per segment of the calibration: ``t_end`` (k,) the time each
    segment ends [s from the sequence's start], ``blocks`` (k, p, p) each segment's JᵀJ,
    ``runs`` twin runs and ``runtime_s`` it took, ``crane`` the machine. Any prefix ending at a
    segment's end (a hold) has the sum of its segments' blocks (module doc)."""
    params: list
    t_end: np.ndarray
    blocks: np.ndarray
    runs: int = 0
    runtime_s: float = 0.0
    crane: object = None

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.params]

    @property
    def duration(self) -> float:
        return float(self.t_end[-1]) if self.t_end.size else 0.0

    def matrix(self, upto: float | None = None) -> np.ndarray:
        """JᵀJ of the prefix ending at the last hold at or before ``upto`` s (None: all)."""
        keep = slice(None) if upto is None else self.t_end <= upto + 1e-9
        return self.blocks[keep].sum(axis=0)

    def visible(self) -> np.ndarray:
        """Which parameters the sequence's residuals depend on at all (JᵀJ's diagonal above
        10⁻¹² of its largest): the others (e.g. the hose of a vented rod side) carry no
        information on any length of it and are left out of the criterion."""
        d = np.diag(self.matrix())
        return d > 1e-12 * max(float(d.max()), 1e-300)

    def logdet(self, A=None) -> float:
        """The D-criterion ln det(JᵀJ) (of ``A``, default the whole sequence's) over the
        :meth:`visible` parameters, its eigenvalues floored at :data:`RIDGE` × the largest (a
        null direction costs a large finite amount instead of −∞, so two poor designs still
        compare)."""
        v = self.visible()
        A = self.matrix() if A is None else A
        return float(np.sum(np.log(_eig(A[np.ix_(v, v)]))))

    def sd(self, A=None) -> np.ndarray:
        """The predicted scaled standard deviations sqrt(diag((JᵀJ)⁻¹)) (module doc); ∞ for a
        parameter without information in ``A`` (or not :meth:`visible`)."""
        A = self.matrix() if A is None else A
        d = np.diag(A)
        v = self.visible() & (d > 1e-12 * max(float(d.max()), 1e-300))
        out = np.full(len(d), np.inf)
        if v.any():
            S = A[np.ix_(v, v)]
            lam, V = np.linalg.eigh(0.5 * (S + S.T))
            lam = np.maximum(lam, RIDGE * max(float(lam.max()), 1e-300))
            out[v] = np.sqrt((V ** 2) @ (1.0 / lam))
        return out

    def alone(self, A=None) -> np.ndarray:
        """Each parameter's scaled sd were it the only one fitted, 1/sqrt((JᵀJ)ᵢᵢ): how much
        signal the sequence gives it at all (∞ where none)."""
        d = np.diag(self.matrix() if A is None else A)
        with np.errstate(divide="ignore"):
            return np.where(d > 0, 1.0 / np.sqrt(np.maximum(d, 1e-300)), np.inf)

    def partner(self, i: int, A=None) -> tuple[str, float]:
        """(name, |correlation|) of the parameter whose sensitivity is most nearly parallel to
        parameter ``i``'s (the one the fit trades it against)."""
        A = self.matrix() if A is None else A
        d = np.sqrt(np.maximum(np.diag(A), 1e-300))
        c = np.abs(A[i] / (d[i] * d))
        c[i] = -1.0
        k = int(np.argmax(c))
        return self.names[k], float(c[k])

    def identified(self, A=None) -> np.ndarray:
        """Every :meth:`visible` parameter's predicted sd at most UNIDENTIFIED (the others
        False)."""
        return self.sd(A) <= UNIDENTIFIED


def _eig(A) -> np.ndarray:
    lam = np.linalg.eigvalsh(0.5 * (A + A.T))
    return np.maximum(lam, RIDGE * max(float(lam.max()), 1e-300))


def _rows(fit: TwinFit, size: int) -> np.ndarray:
    """The segment of every row of ``fit``'s residual vector: positions (samples × n) of every
    segment in turn, then pressures (samples × 2n) in turn (TwinFit.residuals' layout)."""
    n = fit.crane.n
    m = np.array([s.k1 - s.k0 for s in fit.segs])
    seg = np.arange(len(m))
    rows = np.repeat(seg, m * n)
    if fit.use_p:
        rows = np.concatenate([rows, np.repeat(seg, m * 2 * n)])
    if rows.size != size:
        raise RuntimeError(f"residual layout: {size} rows, {rows.size} expected from the "
                           "segments (TwinFit.residuals changed its layout)")
    return rows


def information(crane: Crane, plan, ff, parameters=None, noise=True, step: float = 2e-3,
                fd: float = FD_STEP, log: Recording | None = None) -> Information:
    """The Fisher information of ``parameters`` (names or groups as
    :func:`planner.calibration.twin_params.select` takes them; None: all) in a recording of
    (``plan``, ``ff``) with sensor ``noise`` (:func:`planner.simulation.recording.noise_levels`
    form), per segment (module doc). ``log``: the twin's noise-free log when already made."""
    wall0 = time.perf_counter()
    levels = noise_levels(noise)
    if levels is None:
        raise ValueError("noise: None; allowed: True (seed 001's levels) or a dict of levels "
                         "(the information of a noise-free recording is unbounded)")
    if not 1e-4 <= fd <= 0.2:
        raise ValueError(f"fd = {fd!r}; allowed: 1e-4 … 0.2 (scaled units)")
    rec = twin_log(crane, plan, ff, step) if log is None else log
    fit = TwinFit(crane, [rec], parameters, step=step, anchor="log")
    sq = np.array([levels["angle"] if j.revolute else levels["length"]
                   for j in crane.spec.joints])
    sp = np.full(2 * crane.n, levels["pressure"])
    fit.sig = [(sq, sp)]
    z0 = fit.z0()
    J = None
    for i, p in enumerate(fit.params):
        lo, hi = p.z_bounds
        if z0[i] - fd >= lo and z0[i] + fd <= hi:
            a, b, h = z0[i] - fd, z0[i] + fd, 2.0 * fd
        elif z0[i] + 2.0 * fd <= hi:
            a, b, h = z0[i] + fd, z0[i] + 2.0 * fd, fd
        else:
            a, b, h = z0[i] - 2.0 * fd, z0[i] - fd, fd
        za, zb = z0.copy(), z0.copy()
        za[i], zb[i] = a, b
        col = (fit.residuals(zb) - fit.residuals(za)) / h
        if J is None:
            J = np.empty((col.size, len(fit.params)))
        J[:, i] = col
    rows = _rows(fit, J.shape[0])
    k = len(fit.segs)
    blocks = np.zeros((k, J.shape[1], J.shape[1]))
    for s in range(k):
        Js = J[rows == s]
        blocks[s] = Js.T @ Js
    t0 = float(rec.t[0])
    t_end = np.array([float(rec.t[s.k1]) - t0 for s in fit.segs])
    return Information(list(fit.params), t_end, blocks, runs=fit.runs + 1,
                       runtime_s=time.perf_counter() - wall0, crane=crane)
