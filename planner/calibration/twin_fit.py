"""Calibrating the dynamic twin from logs (issue 28, "the loop"): the twin's physical
parameters (:mod:`planner.calibration.twin_params`) fitted so that the twin, driven by the
logged commands, reproduces the logged positions and pressures.

**Segments.** The log is cut at its holds — every stretch of at least ``hold`` seconds with
every command at zero — into segments (a hold's last sample, the move that follows, the next
hold). With ``anchor="twin"`` (the default) each segment starts from the twin's own state
where the segment before ended, the first from the log's rest: the whole log open loop, as the
refined feed-forward will run. Measured on Exudyn's 120 s log of drawn machine m2 (2026-11-27),
noise-free, at the machine's true values: the twin's own state leaves 1.3 / 0.8 floor σ on
positions / pressures (the twin–Exudyn gap), the log's anchors 31 / 20 — a state pieced from
the log (averaged positions, measured quiet pressures, at rest) is not one the twin reaches,
and the fit bent the parameters to absorb that: the slew's dead band 0.851 % for a truth of
0.890 % (the rest offset of a drop → pick-up move 9.9 mm on Exudyn); anchored on the twin the
fit reaches 1.00 / 0.99 σ on the noisy log, the dead band 0.887 %, and that move rests 0.7 mm
off. It is only as right as the twin's family: without a command delay the twin put drawn
machine m1's 18 ms into the spool lag (53 ms for 34) and the oil, and its refined entries
rested 34 mm off; so the family has ``[dynamics] command_delay`` (fitted as
``command_delay``). ``anchor="log"`` (the diagnosis's,
:mod:`planner.calibration.twin_diagnosis`): each segment starts from the state measured
there: the logged
positions and chamber pressures averaged over the hold's last ``anchor`` seconds, at rest, the
spools closed, the pump line at its rest pressure. A hold's trapped pressures are thus taken
as they were, not as the quasi-static holding pressures. A hold does not always mean rest: a
lightly damped mode (the slew's trapped oil, 0.7 Hz on s100f) still rings through a short
hold, and its average over the window is not its state. So a chamber whose pressure spreads
over more than twice its noise in the window keeps the twin's own state, carried from the
previous segment (its pressures, velocities, pump and spools), and only the positions are
re-anchored; the test is per joint (both chambers quiet, else both carried: the rod side
swings by the piston side's swing times the area ratio and may pass it alone). A chamber
ringing by less than twice its noise passes that test, yet its window average is still not its
value at the cut: so a joint whose logged chambers agree with the twin's carried run over the
window, sample by sample (:func:`~planner.calibration.log_state.agrees_over_window`), keeps the
twin's pressures (s100f's clean seed-1001 log, Exudyn: ``p_slew_b`` 1.27 → 0.99 σ held out,
2.0–2.25 → 0.9 over the last segment, against a test of the window *average*).
No pressures: the model's holding pressures (or the carried state). No holds: one segment.

**Windows (the first stage).** A long segment simulated open loop from one start makes a
narrow valley: on a drawn s100f machine the misfit falls monotonically along the straight
line from the spec's values to the truth, yet 90 % of the way there it is still 3.4 × the
truth's, and the fit from the spec stalled at 3–8 × (the ringing's phase and the trapped
pressures carry every early error through the segment). The first stage therefore cuts each
segment into windows of :attr:`TwinFit.WINDOW` seconds (multiple shooting on the log): a
window after a segment's first starts from the log's own state there — positions and
velocities, both chamber pressures, from a Savitzky–Golay fit (order 2 over
:data:`_SG_SAMPLES` samples) — and the twin's own pump and spools, carried from the window
before. Each window then sees one second of error, not the segment's history; the valley is
wide. The second stage fits the whole segments (the samples as logged) from there, which is
what the refined feed-forward relies on: the twin run open loop for a whole move.

**Rounds.** Where the whole segments end with the misfit above :data:`AT_NOISE` σ on the
positions or the pressures, both stages run again from there (the windows' wide valley first),
up to :attr:`TwinFit.MORE_ROUNDS` more times. On a drawn s100f machine (m4: a 26 ms command
delay, a telescope valve 7 ms slower than the rest) 12 iterations left 1.8 / 2.3 σ — the
whole-segment stage converged there, in a local minimum, and more of it alone did not move —
and a twin whose refined moves rested 6–35 mm off on Exudyn; 12 window iterations before 12
whole-segment ones reached 1.02 / 1.00 σ and its refined moves landed 6 of 6 (0.5–2.1 mm),
with the delay and the spool lag split otherwise than the truth (34 / 23 ms for 26 / 31 ms):
the log fixes their effect, not their split. The rounds keep the answer with the least
whole-segment misfit (on m5 two rounds ended at 1.17 / 1.19 σ from 1.08 / 1.11: the windows
pull elsewhere where the twin lacks an effect). A fit at the noise stops where it did before.

**Polish.** Where the kept round's whole-segment stage ran out of its budget (half the
iterations), it goes on from there up to :attr:`TwinFit.POLISH` × the iterations more, until it
converges; its answer is kept when its misfit is lower. On drawn machine m6 (2026-11-28) the
rounds' best ended at 1.12 / 1.05 σ with the boom's dead band at 0.123 % for a truth of
0.059 % and its closed-spool leakage × 2.8: a drift over seconds, which the windows do not
see; the twin given the truth but these two put the refined moves 8–11 mm off their goal
again. Ten more evaluations reached 1.00 / 0.98 σ (the truth's own misfit: 1.02 / 0.99),
the dead band 0.057 %, the leakage within 4 %.

**Misfit.** Each channel's residual (twin − log) on the log's samples, divided by its noise
level: estimated from the data (:func:`planner.calibration.noise.noise_floor_at`), not below
5 % of seed 001's sensor accuracies (:data:`planner.simulation.recording.NOISE_DEFAULTS`) so
that a noiseless synthetic log stays finite. A twin run that diverges scores
:data:`DIVERGED` per remaining sample.

**Fit.** Both stages: scipy's trust-region reflective least squares on the scaled parameters
(bounded), its
Jacobian by forward differences of whole twin runs (one run per parameter; the twin's
parameters are inputs of its compiled step, so nothing is recompiled). **Intervals**: the
Gauss–Newton covariance s²·(JᵀJ)⁻¹ at the solution, s² the misfit per degree of freedom
(model error widens them honestly) and by the residual's long-run variance factor
1 + 2·Σ (1 − k/(L+1))·ρ_k over lags up to :attr:`TwinFit.WINDOW` (Bartlett weights,
Newey–West): a model error persists over many samples, so the log holds fewer independent
samples than it has (a drawn s100f machine: × 4.5 on the standard deviations; 22 of 29 truths
inside the intervals where the white-noise covariance held 7), mapped to values (log-scaled
parameters: a factor
interval); a parameter whose scaled standard deviation exceeds :data:`UNIDENTIFIED` (a factor
e or one typical size) is reported as not identified by these logs.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time

import numpy as np

from planner.calibration.log_segments import Segment, segments, windows
from planner.calibration.log_state import agrees_over_window, log_state, on_stroke_end
from planner.calibration.noise import channel_noise
from planner.calibration.twin_params import machine_of, select, twin_parameters
from planner.calibration.twin_result import UNIDENTIFIED, TwinFitResult, intervals
from planner.model.twin import Twin

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.simulation.recording import Recording

__all__ = ["Segment", "segments", "windows", "TwinFit", "TwinFitResult",
           "DIVERGED", "UNIDENTIFIED", "AT_NOISE"]

DIVERGED = 1e3          # [σ] residual per sample after a twin run diverged
#: [σ] the misfit (RMS in noise units, positions or pressures) above which the fit takes
#: another round of both stages (module doc, "Rounds")
AT_NOISE = 1.1
_FD_STEP = 1e-2         # forward-difference step in the scaled parameters: the twin's friction
#                         sticks and slips in holds, so a smaller step puts a jump of the
#                         base run into every column (excite_information.py measured it)
_SG_SAMPLES = 9         # Savitzky–Golay window of a window's start state (0.16 s at 50 Hz)


class TwinFit:
    """The least-squares problem of fitting ``parameters`` (names, groups or kinds; default
    all) of ``crane``'s twin to ``recordings`` (module doc)."""

    #: [s] moving-average window of the first stage: longer than a hydraulic mode's period
    #: (0.7–3 Hz on the machines here), so the stage sees the settled compression, not the phase
    SMOOTH = 0.5
    #: [s] the first stage's windows (module doc): a few periods of the slowest hydraulic
    #: mode would let its phase error grow again, one is short enough
    WINDOW = 1.0
    #: the bulk-modulus factors tried before the raw stage (6 % apart: the valley of the raw
    #: misfit is about ±15 % wide on the machines here)
    SCAN = np.geomspace(0.5, 2.0, 25)
    #: further rounds of both stages (each its budget again) while the whole segments end
    #: with the misfit above :data:`AT_NOISE` (module doc, "Rounds")
    MORE_ROUNDS = 2
    #: the polish's budget: this many × ``max_iterations`` more evaluations of the whole
    #: segments, from the best round, where their stage ran out of its budget (module doc,
    #: "Polish"); 0: none
    POLISH = 2

    def __init__(self, crane: Crane, recordings, parameters=None, hold: float = 0.5,
                 step: float = 2e-3, pressures: bool = True, workers: int = 1,
                 grapple=None, anchor: str = "twin"):
        self.crane = crane
        if anchor not in ("log", "twin"):
            raise ValueError(f"anchor: {anchor!r}; allowed: 'log' or 'twin'")
        #: a whole segment's start after a hold (module doc, Segments): "twin" — the twin's
        #: own state where the segment before ran up to it; "log" — the measured positions
        #: and quiet pressures
        self.anchor = anchor
        #: the load hanging on its link while the log was made (the twin's ``grapple``:
        #: True, a length or a Pendulum): its swing loads the boom (an 880 kg load swinging
        #: on s100f moves the slew's pressures by 20 σ), so the twin must carry it; the swing
        #: is not logged, each segment and window takes the twin's own, carried
        self.grapple = grapple
        self.recs = list(recordings)
        if not self.recs:
            raise ValueError("measured: no recording given; allowed: one or more logs")
        self.all_params = twin_parameters(crane)
        self.params = select(self.all_params, parameters)
        self.step = step
        self.segs = [s for i, r in enumerate(self.recs) for s in segments(r, i, hold)]
        if not self.segs:
            raise ValueError("measured: the logs hold no motion after their first sample; "
                             "allowed: a log of commanded moves")
        self.use_p = pressures and all(r.p_a is not None for r in self.recs)
        self.full_segs = self.segs
        self.windows = windows(self.recs, self.segs, self.WINDOW)
        self.sig = [channel_noise(crane, r) for r in self.recs]
        #: single-acting cylinders: the rod side is vented (the twin holds it at tank)
        self.vented = np.array([j.actuator.acting == "single" for j in crane.spec.joints])
        self.runs = 0
        self.smooth = 0.0
        self.workers = int(workers)
        self._pool = None
        if self.workers < 1:
            raise ValueError(f"workers: {workers!r}; allowed: an integer >= 1")

    # ----------------------------------------------------------------- the model
    def twin(self, values: dict) -> Twin:
        dyn, db = machine_of(self.crane, values)
        return Twin(self.crane, dynamics=dyn, deadband=db, step=self.step,
                    grapple=self.grapple)

    def values_of(self, z) -> dict:
        return {p.name: p.to_value(float(v)) for p, v in zip(self.params, z)}

    def z0(self) -> np.ndarray:
        """The start: the spec's values, moved off a bound (the trust-region method cannot
        move a variable that sits exactly on one): a quantity the spec has at 0 starts at
        half its typical size, one on a bound of its factor range 5 % of the range inside."""
        out = []
        for p in self.params:
            lo, hi = p.z_bounds
            z = p.to_z(p.nominal) if p.log or p.nominal > 0 else 0.5
            inset = 0.05 * (hi - lo) if p.log else 0.0
            out.append(float(np.clip(z, lo + inset, hi - inset)))
        return np.array(out)

    def residuals(self, z, split: bool = False):
        """The scaled residual vector at ``z`` (split: (position part, pressure part))."""
        tw = self.twin(self.values_of(z))
        self.runs += 1
        n = self.crane.n
        rq, rp = [], []
        carry = None
        for s in self.segs:
            r = self.recs[s.rec]
            sq, sp = self.sig[s.rec]
            t = r.t[s.k0:s.k1 + 1]
            x0 = self.start_state(tw, s, carry)
            # a command delay reads the commands logged before the segment's start
            ka = s.k0 if tw.delay <= 0 else max(s.k0 - self.history(r, tw.delay), 0)
            run = tw.simulate(r.t[ka:s.k1 + 1], r.u[ka:s.k1 + 1], s.q0, t_end=t[-1], x0=x0,
                              t_start=t[0])
            carry = (s.rec, s.k1, run) if run.ok else None
            ts = t[1:]
            good = ts <= run.t[-1] + 1e-9 if not run.ok else np.ones(ts.size, bool)
            q, pa, pb, _ = run.sample(np.minimum(ts, run.t[-1]))
            q, mq = self._low(q, ts), self._low(r.q[s.k0 + 1:s.k1 + 1], ts)
            eq = (q - mq) / sq
            eq[~good] = DIVERGED
            rq.append(eq.ravel())
            if self.use_p:
                ep = (self._low(np.hstack([pa, pb]), ts)
                      - self._low(np.hstack([r.p_a[s.k0 + 1:s.k1 + 1],
                                             r.p_b[s.k0 + 1:s.k1 + 1]]), ts)) / sp
                ep[~good] = DIVERGED
                rp.append(ep.ravel())
        rq = np.concatenate(rq)
        rp = np.concatenate(rp) if rp else np.zeros(0)
        rq, rp = np.nan_to_num(rq, nan=DIVERGED), np.nan_to_num(rp, nan=DIVERGED)
        return (rq, rp) if split else np.concatenate([rq, rp])

    @staticmethod
    def history(r, delay: float) -> int:
        """How many log samples before a start a ``delay`` [s] reads (one spare)."""
        dt = float(np.min(np.diff(r.t[:min(r.t.size, 50)]))) if r.t.size > 1 else 1.0
        return int(np.ceil(delay / dt)) + 1

    def start_state(self, tw: Twin, s: Segment, carry) -> np.ndarray:
        """A segment's start (module doc): the measured positions; the twin's own velocities,
        pressures, pump and spools where the previous segment of the same log ran up to
        here, else rest; the measured pressures of each chamber that was quiet over the
        anchor window (spread under twice its noise: not ringing)."""
        n = self.crane.n
        x0 = tw.rest_state(s.q0)
        if s.window:
            return self._window_start(x0, s, carry)
        if carry is not None and carry[0] == s.rec and carry[1] == s.k0:
            run = carry[2]
            if self.anchor == "twin":
                x0[:n], x0[n:2 * n] = run.q[-1], run.qd[-1]
                x0[2 * n:3 * n], x0[3 * n:4 * n] = run.p_a[-1], run.p_b[-1]
                _carry_machine(x0, run, n)
                return x0
            x0[n:2 * n] = run.qd[-1]
            x0[2 * n:3 * n], x0[3 * n:4 * n] = run.p_a[-1], run.p_b[-1]
            _carry_machine(x0, run, n)
            # on a stroke end, or logged chambers agreeing: the twin's own (module doc)
            end = on_stroke_end(self.crane, s.q0, run.q[-1], self.sig[s.rec][0])
            x0[:n][end] = run.q[-1][end]
            if self.use_p and s.p_a0 is not None:
                end |= agrees_over_window(self.recs[s.rec], s.k0, run, self.sig[s.rec][1],
                                          self.vented)
        else:
            end = np.zeros(n, bool)
        if self.use_p and s.p_a0 is not None:
            sp = self.sig[s.rec][1]
            # quiet per joint, not per chamber: a cylinder's chambers ring together, and one
            # measured beside one carried is a state that never was (a locked cylinder keeps
            # the wrong trapped oil for the rest of the segment)
            quiet = (s.sd_a < 2.0 * sp[:n]) & (s.sd_b < 2.0 * sp[n:]) & ~end
            qb = quiet & ~self.vented   # a single-acting rod side stays at tank (no sensor noise)
            x0[2 * n:3 * n][quiet] = s.p_a0[quiet]
            x0[3 * n:4 * n][qb] = s.p_b0[qb]
        return x0

    def _window_start(self, x0, s: Segment, carry) -> np.ndarray:
        """A window's start (module doc): the log's positions, velocities and pressures at
        its first sample, the twin's own pump and spools from the window before."""
        n = self.crane.n
        if carry is not None and carry[0] == s.rec and carry[1] == s.k0:
            _carry_machine(x0, carry[2], n)
        sg = log_state(self.recs[s.rec], s.k0, _SG_SAMPLES)
        x0[:n], x0[n:2 * n] = sg["q"], sg["qd"]
        if self.use_p:
            x0[2 * n:3 * n] = sg["p_a"]
            x0[3 * n:4 * n][~self.vented] = sg["p_b"][~self.vented]
        return x0

    def long_run(self, r) -> float:
        """The long-run variance factor of the residual ``r`` (module doc, Intervals): its
        autocorrelation along each channel of each segment, Bartlett-weighted up to
        :attr:`WINDOW` s, at least 1."""
        n, blocks, i = self.crane.n, [], 0
        for w in (n, 2 * n) if self.use_p else (n,):
            for s in self.segs:
                m = s.k1 - s.k0
                blocks.append(r[i:i + m * w].reshape(m, w))
                i += m * w
        dt = float(np.median(np.diff(self.recs[0].t)))
        L = max(int(round(self.WINDOW / dt)), 1)
        den = sum(float(np.sum(B * B)) for B in blocks)
        if den <= 0.0:
            return 1.0
        f = 1.0
        for k in range(1, L + 1):
            rho = sum(float(np.sum(B[k:] * B[:-k])) for B in blocks if len(B) > k) / den
            f += 2.0 * (1.0 - k / (L + 1)) * rho
        return max(f, 1.0)

    def _low(self, Y, t):
        """``Y`` (samples × channels) moving-averaged over :attr:`smooth` seconds (0: as is)."""
        if self.smooth <= 0 or len(t) < 3:
            return Y
        from scipy.ndimage import uniform_filter1d
        w = max(int(round(self.smooth / float(np.median(np.diff(t))))), 1)
        return uniform_filter1d(Y, w, axis=0, mode="nearest") if w > 1 else Y

    def jacobian(self, z, r0=None) -> np.ndarray:
        """Forward differences of :meth:`residuals` (one twin run per parameter), stepping
        away from the nearer bound; the runs spread over :attr:`workers` processes."""
        r0 = self.residuals(z) if r0 is None else r0
        steps, zs = [], []
        for i, p in enumerate(self.params):
            lo, hi = p.z_bounds
            h = _FD_STEP if z[i] + _FD_STEP <= hi else -_FD_STEP
            zi = np.array(z, float)
            zi[i] += h
            steps.append(h)
            zs.append(zi)
        cols = self._map(zs)
        return np.column_stack([(c - r0) / h for c, h in zip(cols, steps)])

    def _map(self, zs) -> list:
        """:meth:`residuals` at each of ``zs``: here, or on the worker processes (forked:
        they inherit this problem and its compiled twin)."""
        if self.workers <= 1 or len(zs) < 2:
            return [self.residuals(zi) for zi in zs]
        global _ACTIVE
        if self._pool is None:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor
            _ACTIVE = self
            self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("fork"))
        self.runs += len(zs)
        return list(self._pool.map(_residuals_in_worker, zs))

    def close(self) -> None:
        """Stop the worker processes (if any)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def _above_noise(self, z) -> bool:
        """Whether the misfit at ``z`` lies above :data:`AT_NOISE` on the positions or on
        the pressures (RMS in noise units)."""
        m = self.rms(z)
        return m["positions"] > AT_NOISE or (m["pressures"] or 0.0) > AT_NOISE

    def rms(self, z) -> dict:
        rq, rp = self.residuals(z, split=True)
        return dict(positions=float(np.sqrt(np.mean(rq ** 2))),
                    pressures=float(np.sqrt(np.mean(rp ** 2))) if rp.size else None)

    # ----------------------------------------------------------------- the fit
    def scan_oil(self, z, lb, ub) -> np.ndarray:
        """``z`` with the bulk modulus (when fitted) moved to the best of a geometric grid
        (×:data:`SCAN` around its value) on the raw misfit: the ringing's frequency goes as
        sqrt(β), so the raw misfit has one narrow valley per ringing phase and a local search
        started a few tens of per cent off stays in the wrong one (module doc)."""
        names = [p.name for p in self.params]
        if "bulk_modulus" not in names:
            return z
        i = names.index("bulk_modulus")
        best, best_z = None, z
        zs = []
        for f in np.log(self.SCAN):
            zi = np.array(z, float)
            zi[i] = float(np.clip(z[i] + f, lb[i], ub[i]))
            zs.append(zi)
        for zi, r in zip(zs, self._map(zs)):
            c = float(r @ r)
            if best is None or c < best:
                best, best_z = c, zi
        return best_z

    def solve(self, max_iterations: int = 12, tol: float = 1e-3) -> TwinFitResult:
        try:
            return self._solve(max_iterations, tol)
        finally:
            self.close()

    def _solve(self, max_iterations: int, tol: float) -> TwinFitResult:
        from scipy.optimize import least_squares
        wall0 = time.perf_counter()
        z0 = self.z0()
        lb = np.array([p.z_bounds[0] for p in self.params])
        ub = np.array([p.z_bounds[1] for p in self.params])
        z0 = np.clip(z0, lb, ub)
        before = self.rms(z0)
        cache = {}

        def fun(z):
            key = (z.tobytes(), self.smooth)
            if key not in cache:
                cache.clear()
                cache[key] = self.residuals(z)
            return cache[key]

        def jac(z):
            return self.jacobian(z, fun(z))
        z = z0
        # stage 1 on one-second windows from the log's own states (a wide valley), stage 2
        # on the whole segments, the samples as logged, from there (module doc)
        stages = ((self.windows, max(max_iterations // 2, 1)),
                  (self.full_segs, max(max_iterations - max_iterations // 2, 1)))
        rounds, best = 0, None
        while True:
            for segs, iters in stages:
                self.segs = segs
                cache.clear()
                if segs is self.full_segs and rounds == 0:
                    z = self.scan_oil(z, lb, ub)
                sol = least_squares(fun, z, jac=jac, bounds=(lb, ub), method="trf",
                                    x_scale=1.0, max_nfev=iters, ftol=tol, xtol=tol,
                                    gtol=1e-8)
                z = np.clip(sol.x, lb, ub)
            r = fun(z)
            if best is None or float(r @ r) < best[0]:
                best = (float(r @ r), z, sol, rounds)
            # both stages again from there while the whole segments end above the noise
            # (module doc, "Rounds"); the best round's answer is kept
            if rounds >= self.MORE_ROUNDS or not self._above_noise(z):
                break
            rounds += 1
        _, z, sol, kept = best
        self.segs = self.full_segs
        cache.clear()
        polished = 0
        if sol.status == 0 and self.POLISH:
            # the whole segments on from the best round while their stage ran out of its
            # budget, up to convergence (module doc, "Polish")
            pol = least_squares(fun, z, jac=jac, bounds=(lb, ub), method="trf",
                                x_scale=1.0, max_nfev=self.POLISH * max_iterations,
                                ftol=tol, xtol=tol, gtol=1e-8)
            zp = np.clip(pol.x, lb, ub)
            rp = fun(zp)
            if float(rp @ rp) < best[0]:
                z, sol, polished = zp, pol, int(pol.nfev)
        r = fun(z)
        J = sol.jac if sol.jac is not None else self.jacobian(z, r)
        m, k = r.size, len(self.params)
        s2 = float(r @ r) / max(m - k, 1) * self.long_run(r)
        JTJ = J.T @ J
        cov = s2 * np.linalg.pinv(JTJ, rcond=1e-12)
        sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        values, nominal, interval, ident, sds, units = intervals(self.params, z, sd)
        after = self.rms(z)
        dyn, db = machine_of(self.crane, values)
        return TwinFitResult(values=values, nominal=nominal, interval=interval,
                             identified=ident, sd_scaled=sds, rms_before=before,
                             rms_after=after, runs=self.runs,
                             runtime_s=time.perf_counter() - wall0,
                             status="converged" if sol.status > 0 else "stopped",
                             message=str(sol.message) + _rounds(rounds, kept, polished),
                             dynamics=dyn, deadband=db,
                             segments=len(self.segs),
                             samples=int(sum(s.k1 - s.k0 for s in self.segs)), units=units)


def _rounds(k: int, kept: int, polished: int = 0) -> str:
    out = ""
    if k:
        out = (f" (after {k} more round{'s' if k > 1 else ''} of both stages; "
               + ("the first" if kept == 0 else f"round {kept}'s") + " answer kept, the best)")
    if polished:
        out += f" (then the whole segments polished: {polished} more evaluations)"
    return out


def _carry_machine(x0, run, n: int) -> None:
    """Into start state ``x0``: what the log never shows, from the end of ``run`` — the pump
    line, the spools and (with the load on its link) the swing."""
    x0[4 * n] = run.p_s[-1]
    x0[4 * n + 1:5 * n + 1] = run.spool[-1]
    if getattr(run, "swing", None) is not None:
        x0[5 * n + 1:] = run.swing[-1]


_ACTIVE: TwinFit | None = None    # the problem the forked workers inherited


def _residuals_in_worker(z):
    return _ACTIVE.residuals(np.asarray(z, float))
