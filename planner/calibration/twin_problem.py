"""The twin diagnosis's fit problem (:mod:`planner.calibration.twin_diagnosis`): TwinFit over
the candidates' parameters, its residual as rows × channels with each segment's start pose a
nuisance.

**The start pose as a nuisance.** A segment starts from the log: its positions are the hold's
average over :data:`ANCHOR_S` s, so each carries the anchor's noise (σ/√m over m samples). The
residual's positions of a segment are shifted by their mean over the segment's training rows,
bounded by what that noise explains (± 3 σ/√m), as the quasi-static workflow fits its start
pose.

A joint still ringing through the hold (a chamber's pressure spread over twice its noise)
starts from the twin's own carried position instead — the hold's average is not its state at
the cut. Its error there is not this anchor's but the first anchor's of the chain plus what
the twin gathered since, which the anchor's noise does not bound: such a joint's shift is the
segment's mean, unbounded (one number per segment and joint, against hundreds of rows).
Measured: cat215b on Exudyn (seed 1002, boom friction 12.1 kN), the swing rings ±0.03 rad
through every hold; the first anchor 0.6 σ off, carried on and grown to 1.1 and 1.3 σ over the
next two segments — clipped at 0.95 σ it left the swing's segments 0.15 / 0.44 σ apart, a
material ``step`` that made the true fit not credible.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math

import numpy as np

from planner.calibration.twin_fit import TwinFit
from planner.calibration.twin_params import machine_of
from planner.model.twin import Twin

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["DiagnosisProblem", "ANCHOR_S"]

ANCHOR_S = 0.2      # [s] the window a segment's start is averaged over (TwinFit's)


class DiagnosisProblem(TwinFit):
    """:class:`TwinFit` whose parameters are the candidates' (some of them the twin's own
    inputs rather than spec numbers: hose factor, valve gain, payload, pump flow), its
    residual optionally restricted to the rows of ``mask`` (the training blocks)."""

    def __init__(self, crane: Crane, rec, params, hold, step, workers):
        super().__init__(crane, [rec], parameters=["bulk_modulus"], hold=hold, step=step,
                         workers=workers, anchor="log")
        self.params = list(params)
        self.mask = None        # rows the residual vector keeps (None: every row)
        self.fit_rows = None    # rows the anchors' position errors are estimated on
        self.carried = {}       # segment's first sample -> joints not at rest at the cut
        self.hold = float(hold)
        self._moving = {}       # (log, segment's first sample) -> moving(), computed once

    def twin(self, values: dict) -> Twin:
        crane, v = self.crane, dict(values)
        dyn0 = crane.spec.dynamics
        gain = np.ones(crane.n)
        for i, j in enumerate(crane.names):
            f = v.pop(f"hose.{j}", None)
            if f is not None:
                a, b = dyn0.joints[j].hose_volume
                v[f"hose_a.{j}"] = a * f
                if crane.spec.joints[i].actuator.acting != "single":   # rod side vented
                    v[f"hose_b.{j}"] = b * f
            gain[i] = v.pop(f"gain.{j}", 1.0)
        payload = v.pop("payload", None)
        pump = v.pop("pump_flow", 1.0)
        dyn, db = machine_of(crane, v)
        return Twin(crane, dynamics=dyn, deadband=db, payload=payload, gain_scale=gain,
                    pump_scale=pump, step=self.step)

    def start_state(self, tw: Twin, s, carry) -> np.ndarray:
        """TwinFit's start, except that a joint not at rest at the cut keeps the twin's own
        carried position too, not only its pressures and velocity — the hold's average
        position is not its state there: a chamber still ringing through the hold (TwinFit's
        test: a pressure spread over twice its noise) or the logged position still moving
        over the hold (:meth:`moving`). Such a joint's start error is the chain's
        (:meth:`matrix` shifts it freely)."""
        x0 = TwinFit.start_state(self, tw, s, carry)
        n = self.crane.n
        if s.window:        # a window starts from the log's own state (TwinFit's)
            self.carried[s.k0] = np.zeros(n, bool)
            return x0
        if (s.rec, s.k0) not in self._moving:      # the log's, the same on every run
            self._moving[(s.rec, s.k0)] = self.moving(s)
        free = self._moving[(s.rec, s.k0)].copy()
        if s.sd_a is not None and self.use_p:
            sp = self.sig[s.rec][1]
            free = free | (s.sd_a >= 2.0 * sp[:n]) | (s.sd_b >= 2.0 * sp[n:])
        self.carried[s.k0] = free
        if carry is not None and carry[0] == s.rec and carry[1] == s.k0:
            x0[:n][free] = carry[2].q[-1][free]
        return x0

    def moving(self, s) -> np.ndarray:
        """(n,) bool: the joints whose logged position is not at rest at the cut — a parabola
        least-squares fitted over the last :attr:`hold` s before it has there a slope, or a
        value off the anchor (the average of the last :data:`ANCHOR_S` s), beyond 3 of its
        standard errors (the sensor's σ through the fit's weights). A slew coasting through
        a soft hose's slow ringing keeps its pressures quiet (cat215b's swing, hoses × 3.77,
        on Exudyn: through a turning point at the cut, the anchor 2.1 σ off the true position
        there, its chambers within their noise)."""
        r, n = self.recs[s.rec], self.crane.n
        a = int(np.searchsorted(r.t, r.t[s.k0] - self.hold - 1e-9))
        if s.k0 + 1 - a < 6:
            return np.zeros(n, bool)
        tt = r.t[a:s.k0 + 1] - r.t[s.k0]
        P = np.linalg.pinv(np.vander(tt, 3))           # rows: t², t, 1 coefficients
        w = P[2].copy()
        last = tt >= -ANCHOR_S - 1e-9
        w[last] -= 1.0 / last.sum()                    # value at the cut − the anchor
        Y = r.q[a:s.k0 + 1]
        sq = self.sig[s.rec][0]
        return ((np.abs(w @ Y) > 3.0 * sq * np.linalg.norm(w))
                | (np.abs(P[1] @ Y) > 3.0 * sq * np.linalg.norm(P[1])))

    def matrix(self, z) -> np.ndarray:
        """The scaled residual (model − log) as rows × channels, each segment's positions
        shifted by their start's error (module doc): the mean position residual over the
        segment's training rows, within the anchor's noise (± 3 σ/√m), unbounded for a joint
        that started at the twin's carried position."""
        rq, rp = TwinFit.residuals(self, z, split=True)
        n = self.crane.n
        rq = rq.reshape(-1, n).copy()
        if self.fit_rows is not None:
            t = self.recs[0].t
            m = max(int(round(ANCHOR_S / float(t[1] - t[0]))), 1)
            lim = 3.0 / math.sqrt(m)
            k = 0
            for sg in self.segs:
                rows = slice(k, k + sg.k1 - sg.k0)
                tr = self.fit_rows[rows]
                if tr.any():
                    free = self.carried.get(sg.k0, np.zeros(n, bool))
                    rq[rows] -= np.where(free, rq[rows][tr].mean(axis=0),
                                         np.clip(rq[rows][tr].mean(axis=0), -lim, lim))
                k += sg.k1 - sg.k0
        if not rp.size:
            return rq
        P = rp.reshape(-1, 2 * n)     # p_a of every joint, then p_b: interleaved per joint
        return np.hstack([rq, np.stack([P[:, :n], P[:, n:]], axis=2).reshape(len(P), -1)])

    def residuals(self, z, split: bool = False):
        if split or self.mask is None:
            return TwinFit.residuals(self, z, split)
        return self.matrix(z)[self.mask].ravel()


