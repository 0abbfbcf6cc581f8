"""Excitation for the twin's dynamics (issue 28, item 3): a test sequence within every limit
of the machine on which the dynamic twin's parameters (:mod:`planner.calibration.twin_params`:
oil, hoses, valves, pump, friction, leakage) show as separately as possible, and how long a
recording of it the calibration needs.

**Blocks** (:class:`BlockPool`): short sequences that start and end at rest in one seeded home
pose — so any order of them is a sequence — each made of the features that make parameters
visible:

- *hard stop* (every joint together, toward the far ends of the ranges, and toward the near
  ends; and each joint alone): full speed, stopped at the jerk limit, then a hold under load of
  1.2–2 s — the hydraulic mode rings (bulk modulus and hose volumes: its frequency goes as
  sqrt(β/V), and V changes with the stroke, which the two ends and the single joints vary),
  and the hold shows the trapped pressure settling and leaking away (leakage, on a joint that
  holds load); the way back home is at full speed too, every joint at once: the pump at its
  flow limit (the regulator's lag);
- *reversals*: four moves about the home pose, each joint its own way, at 60–100 % speed and
  without a hold between them (each turn a stop at the jerk limit), then home at full speed —
  the spools cross their dead bands and friction changes sign, at several speeds (Coulomb
  against viscous);
- *creep*: a short move at 6–15 % speed out and back — small commands, where the dead band and
  Coulomb friction are a large share of what the valve does — with a hold under load between;
- *tours* (``candidates`` of them, seeded): three poses anywhere in the ranges, each at a
  random speed (30–100 %) with a short hold, then home at full speed — as the trials' plain
  excitation moves, so that the choice is never poorer than it per second.

Every move is a Ruckig rest-to-rest move (every position, speed, acceleration and jerk limit
holds by construction); a move whose feed-forward would ask more than a valve can open or the
pump can give, or whose pressures would exceed the relief (limits Ruckig does not see), is
slowed until :func:`planner.trajectory.evaluate` passes it and no valve saturates, and the
assembled sequence is checked again. Every block ends with a hold of at least 0.6 s at home,
where the calibration cuts its segments (:func:`planner.calibration.twin_fit.segments`).

**Criterion and choice** (D-optimal over the pool). Each block's Fisher information JᵀJ at the
spec's values is computed once, the block replayed alone from rest at home
(:mod:`planner.calibration.excite_information`); the calibration's segments are independent, so
a sequence of blocks has (to the small difference of the trapped pressures it starts each block
with) the sum of its blocks' information. Blocks are chosen greedily — each time the one that
adds the most ln det(JᵀJ) per second of recording, from a small ridge — until the duration is
reached: the first blocks cover what no other block covers, later ones the weakest directions.
The chosen sequence's information is then computed on the whole sequence as it will be
recorded (what is reported); ``compare``: the trials' plain excitation
(:func:`planner.calibration.trials.excitation`) of the same length too.

**Needed duration.** The information is a sum over the calibration's segments, so every prefix
that ends at a hold has its own predicted standard deviations without another twin run; the
needed duration is the shortest prefix at which every parameter's predicted scaled sd is at
most :data:`planner.calibration.twin_fit.UNIDENTIFIED`; past the sequence's end the sequence is
repeated (its information added once per repetition), up to :data:`MAX_NEEDED_S`. A parameter
that stays above it is reported with why: too little signal of its own (its sd alone, with the
feature its kind needs — e.g. leakage on a joint that never holds load) or traded against
another parameter (the one whose sensitivity is most nearly parallel, and how nearly).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time
from dataclasses import dataclass, field

import numpy as np

from planner.calibration.excite_information import Information, information
from planner.calibration.trials import SequenceBuilder, excitation
from planner.calibration.twin_fit import UNIDENTIFIED
from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["BlockPool", "DynamicsDesign", "design_dynamics", "choose", "needed_duration",
           "why_unidentified", "MAX_NEEDED_S"]

MAX_NEEDED_S = 600.0      # [s] the longest recording a design proposes (ten minutes)
_TOL = 1e-3               # relative excess of a limit that evaluate's ok() also accepts

#: what a parameter of each kind needs to show (the "why" of a parameter left unidentified)
_NEEDS = {
    "bulk_modulus": "pressure ringing after hard stops",
    "spool_time_constant": "fast command steps",
    "pump_time_constant": "several joints at full speed together (the pump at its limit)",
    "hose_a": "ringing of the piston-side chamber at different strokes",
    "hose_b": "ringing of the rod-side chamber at different strokes",
    "coulomb": "moves at several speeds in both directions",
    "viscous": "moves at several speeds in both directions",
    "leakage": "holds with the joint under load (a trapped pressure to leak)",
    "deadband": "small commands (slow moves)",
}


class BlockPool:
    """The blocks (module doc) of ``crane`` for ``seed`` at ``rate`` [Hz]: ``home`` (n,),
    ``blocks`` (list of (name, steps); a step is ("move", goal, speed fraction, kind) or
    ("hold", T, kind)), ``plan(names)`` -> (plan, feed-forward) of those blocks in turn from a
    1 s hold at home."""

    MARGIN = 0.08            # share of each joint's range kept clear of its ends
    HOLD_LOAD = (1.2, 2.0)   # [s]
    HOLD_SHORT = (0.6, 0.8)  # [s]
    REVERSAL = (0.6, 1.0)    # speed fraction
    REVERSALS = 4            # moves without a stop between them
    CREEP = (0.06, 0.15)     # speed fraction
    TOUR = 3                 # poses of a random tour

    def __init__(self, crane: Crane, seed: int = 0, rate: float = 50.0, candidates: int = 2):
        if not 5.0 <= rate <= 1000.0:
            raise ValueError(f"rate = {rate!r} Hz; allowed: 5 … 1000")
        if not 0 <= candidates <= 20:
            raise ValueError(f"candidates = {candidates!r}; allowed: 0 … 20")
        self.crane, self.rate, self.seed = crane, float(rate), int(seed)
        L = crane.limit_arrays()
        span = L["q_max"] - L["q_min"]
        self.lo, self.hi = L["q_min"] + self.MARGIN * span, L["q_max"] - self.MARGIN * span
        self.span = self.hi - self.lo
        rng = np.random.default_rng([self.seed, 28])
        self.home = self.lo + rng.uniform(0.35, 0.65, crane.n) * self.span
        self._scales = {}
        self.blocks = self._blocks(rng, candidates)

    def _blocks(self, rng, candidates) -> list[tuple[str, list]]:
        lo, hi, span, h, n = self.lo, self.hi, self.span, self.home, self.crane.n
        far = np.where(h - lo < hi - h, hi, lo)
        near = np.where(far == hi, lo, hi)

        def out_back(goal, speed, back, kind):
            return [("move", goal, speed, kind),
                    ("hold", rng.uniform(*self.HOLD_LOAD), "hold under load"),
                    ("move", h, back, "pump limit" if back >= 1.0 else kind),
                    ("hold", rng.uniform(*self.HOLD_SHORT), "hold")]

        out = [("hard stop far", out_back(h + rng.uniform(0.85, 1.0, n) * (far - h), 1.0, 1.0,
                                          "hard stop")),
               ("hard stop near", out_back(h + rng.uniform(0.85, 1.0, n) * (near - h), 1.0,
                                           1.0, "hard stop"))]
        steps, q = [], h.copy()
        d = rng.choice([-1.0, 1.0], n) * rng.uniform(0.12, 0.25, n) * span
        for k in range(self.REVERSALS):
            q = np.clip(h + (d if k % 2 == 0 else -rng.uniform(0.5, 1.0, n) * d), lo, hi)
            steps.append(("move", q, rng.uniform(*self.REVERSAL), "reversal"))
        steps += [("move", h, 1.0, "reversal"), ("hold", rng.uniform(*self.HOLD_SHORT), "hold")]
        out.append(("reversals", steps))
        c = rng.uniform(*self.CREEP)
        out.append(("creep", out_back(np.clip(h + rng.choice([-1.0, 1.0], n) *
                                              rng.uniform(0.04, 0.08, n) * span, lo, hi),
                                      c, c, "creep")))
        for j, name in enumerate(self.crane.names):
            goal = h.copy()
            goal[j] = h[j] + rng.uniform(0.85, 1.0) * (far[j] - h[j])
            out.append((f"{name} alone", out_back(goal, 1.0, 1.0, "hard stop")))
        for k in range(candidates):
            steps = []
            for _ in range(self.TOUR):
                steps += [("move", rng.uniform(lo, hi), rng.uniform(0.3, 1.0), "tour"),
                          ("hold", rng.uniform(*self.HOLD_SHORT), "hold")]
            steps += [("move", h, 1.0, "pump limit"),
                      ("hold", rng.uniform(*self.HOLD_SHORT), "hold")]
            out.append((f"tour {k}", steps))
        return out

    def feasible_scale(self, q0, goal, scale: float) -> float:
        """``scale`` lowered until the move q0 -> goal passes :func:`evaluate` (pump flow,
        pressures, every kinematic limit) and its feed-forward saturates no valve."""
        key = (tuple(np.round(q0, 9)), tuple(np.round(goal, 9)), scale)
        if key in self._scales:
            return self._scales[key]
        s = scale
        for _ in range(12):
            res = rest_to_rest(self.crane, q0, goal, scale=s)
            if res.trajectory is None:
                raise ValueError(f"sequence: no move from {np.round(q0, 4).tolist()} to "
                                 f"{np.round(goal, 4).tolist()}: {res.reason}")
            # every kind: a Ruckig move's own list checks only the kinematic ones
            worst = max(evaluate(self.crane, res.trajectory).violations.values())
            u = float(np.max(np.abs(commands(self.crane, res.trajectory, self.rate).u_raw)))
            if worst <= _TOL and u <= 1.0:
                self._scales[key] = s
                return s
            s /= 1.03 * (1.0 + max(worst, u - 1.0))
        raise ValueError(f"sequence: the move to {np.round(goal, 4).tolist()} keeps exceeding "
                         f"a limit at {s:.3g} of the speed limits")

    def plan(self, names):
        """(plan, feed-forward) of the blocks ``names`` in turn from a 1 s hold at home, every
        move slowed where a limit asks (module doc); its ``meta["blocks"]``: (block, kind,
        start, end) of every step."""
        steps = dict(self.blocks)
        b = SequenceBuilder(self.crane, self.home, self.rate)
        b.hold(1.0)
        log = []
        for name in names:
            for step in steps[name]:
                t0 = b.t_now
                if step[0] == "move":
                    b.move(step[1], self.feasible_scale(b.q, step[1], step[2]))
                else:
                    b.hold(step[1])
                log.append((name, step[-1], round(t0, 3), round(b.t_now, 3)))
        plan, ff = b.finish(dict(seed=self.seed, blocks=log, home=self.home.tolist()),
                            method="excitation-dynamics")
        worst = max(evaluate(self.crane, plan).violations.values())
        if worst > _TOL or float(np.max(np.abs(ff.u_raw))) > 1.0 + 1e-9:
            raise ValueError(f"sequence (seed {self.seed}): exceeds a limit after assembly "
                             f"(by {worst:.3g}); allowed: none")
        return plan, ff


def choose(pool: dict, duration: float, lead: float = 1.0) -> list[str]:
    """Block names in order (module doc): greedily the block of ``pool`` (name ->
    :class:`Information` of the block alone after a ``lead`` s hold) that adds the most
    ln det(JᵀJ) per second, from a ridge of 10⁻⁶ of the pool's mean information per second,
    among the blocks that still fit in ``duration`` [s] (when none does, among all: the last
    block reaches the duration), until it is reached."""
    names = list(pool)
    A_b = {k: pool[k].matrix() for k in names}
    T_b = {k: max(pool[k].duration - lead, 1e-3) for k in names}
    p = next(iter(A_b.values())).shape[0]
    per_s = sum(np.trace(A) for A in A_b.values()) / sum(T_b.values()) / p
    A = 1e-6 * per_s * np.eye(p)
    order, t = [], lead
    while t < duration:
        base = np.linalg.slogdet(A)[1]
        fit = [k for k in names if t + T_b[k] <= duration] or names
        gain = {k: (np.linalg.slogdet(A + A_b[k])[1] - base) / T_b[k] for k in fit}
        k = max(fit, key=lambda x: (gain[x], -names.index(x)))
        order.append(k)
        A = A + A_b[k]
        t += T_b[k]
    return order


@dataclass
class DynamicsDesign:
    """The chosen sequence for the twin's dynamics: ``plan`` and ``ff``, ``seed`` (of the
    pool), ``duration`` asked for, ``order`` (the blocks in turn), ``info`` (its
    :class:`Information` on the whole sequence as recorded), ``logdet``, ``predicted_logdet``
    (the sum of the chosen blocks' information, each alone: what the choice saw), ``sd``
    (name -> predicted scaled sd), ``needed_s`` (the shortest recording at which every
    parameter is identified, None beyond :data:`MAX_NEEDED_S`), ``unidentified`` (name ->
    why, for the parameters a recording of the design's own length leaves unidentified),
    ``unidentified_at_limit`` (the same at :data:`MAX_NEEDED_S` when ``needed_s`` is None),
    ``sd_needed`` (name -> sd at the needed length, or at the limit), ``pool`` (block name ->
    its length [s], ln det alone, times chosen), ``plain`` (the trials' plain excitation of the
    same length: logdet, sd, needed_s; when compared), ``runs`` (twin runs), ``runtime_s``."""
    plan: object
    ff: object
    seed: int
    duration: float
    order: list
    info: Information
    logdet: float
    predicted_logdet: float
    sd: dict
    needed_s: float | None
    unidentified: dict
    pool: dict
    plain: dict | None = None
    runs: int = 0
    runtime_s: float = 0.0
    sd_needed: dict = field(default_factory=dict)
    unidentified_at_limit: dict = field(default_factory=dict)
    threshold: float = UNIDENTIFIED

    def to_dict(self) -> dict:
        return dict(seed=self.seed, duration_s=float(self.plan.duration), order=self.order,
                    parameters=self.info.names, logdet=self.logdet,
                    predicted_logdet=self.predicted_logdet, sd_scaled=self.sd,
                    needed_duration_s=self.needed_s, sd_scaled_at_needed=self.sd_needed,
                    unidentified=self.unidentified,
                    unidentified_at_limit=self.unidentified_at_limit,
                    unidentified_threshold=self.threshold, pool=self.pool, plain=self.plain,
                    twin_runs=self.runs, runtime_s=self.runtime_s,
                    blocks=self.plan.meta.get("blocks"))


def why_unidentified(info: Information, A) -> dict:
    """name -> why, for every parameter whose predicted scaled sd exceeds
    :data:`UNIDENTIFIED` under the information ``A`` (module doc)."""
    sd, alone, vis = info.sd(A), info.alone(A), info.visible()
    out = {}
    for i, p in enumerate(info.params):
        if sd[i] <= UNIDENTIFIED:
            continue
        where = f" of {p.joint}" if p.joint else ""
        if not vis[i]:
            out[p.name] = ("no signal: the twin's positions and pressures on this sequence do "
                           "not depend on it" + _vented(info, p) + "; no length identifies it")
        elif alone[i] > UNIDENTIFIED:
            out[p.name] = (f"too little signal: sd {sd[i]:.3g} (alone {alone[i]:.3g}); it "
                           f"needs {_NEEDS.get(p.kind, 'motion that excites it')}{where}")
        else:
            other, c = info.partner(i, A)
            out[p.name] = (f"traded against {other} (sensitivities {100 * c:.1f} % parallel):"
                           f" sd {sd[i]:.3g}, alone {alone[i]:.3g}")
    return out


def _vented(info: Information, p) -> str:
    crane = getattr(info, "crane", None)
    if crane is None or p.kind != "hose_b":
        return ""
    a = crane.spec.joints[crane.names.index(p.joint)].actuator
    return (f" ({p.joint} is single-acting: its rod side is vented to tank)"
            if getattr(a, "acting", "double") == "single" else "")


def needed_duration(info: Information, cycle: Information | None = None,
                    limit: float = MAX_NEEDED_S) -> tuple[float | None, np.ndarray]:
    """(the shortest prefix length [s] at which every parameter's predicted scaled sd is at
    most :data:`UNIDENTIFIED` (every :meth:`Information.visible` one: a parameter the
    sequence carries no signal of is reported, not waited for), its information matrix), past
    ``info``'s end adding ``cycle``'s
    information (the sequence repeated: ``info`` itself) once per repetition (module doc);
    (None, the information at ``limit``) when no length up to ``limit`` does."""
    A = np.zeros_like(info.blocks[0])
    vis = info.visible()
    for t, B in zip(info.t_end, info.blocks):
        A = A + B
        if t > limit:
            break
        if np.all(info.sd(A)[vis] <= UNIDENTIFIED):
            return float(t), A
    T = info.duration
    if cycle is None or cycle.duration <= 0.0:
        return None, A
    C = cycle.matrix()
    reps = int(math.floor((limit - T) / cycle.duration))
    for m in range(1, reps + 1):
        A = A + C
        if np.all(info.sd(A)[vis] <= UNIDENTIFIED):
            return float(T + m * cycle.duration), A
    return None, A


def design_dynamics(crane: Crane, duration: float = 120.0, seed: int = 0,
                    candidates: int = 2, parameters=None, rate: float = 50.0,
                    compare: bool = False, noise=True, blocks=None,
                    progress=None) -> DynamicsDesign:
    """The design (module doc) of about ``duration`` [s] (it ends with the block that reaches
    it) from the pool of ``seed`` with ``candidates`` random tours (``blocks``: only these of
    its block names); ``parameters``: the twin's parameters to design for (names or groups;
    None: all); ``compare``: score the plain excitation of the same length too; ``progress``:
    a callable taking a line of text."""
    if not 10.0 <= duration <= MAX_NEEDED_S:
        raise ValueError(f"duration = {duration!r} s; allowed: 10 … {MAX_NEEDED_S:g}")
    wall0 = time.perf_counter()
    say = progress or (lambda s: None)
    pool = BlockPool(crane, seed, rate, candidates)
    known = [name for name, _ in pool.blocks]
    use = known if blocks is None else list(blocks)
    bad = [b for b in use if b not in known]
    if bad or not use:
        raise ValueError(f"blocks: {bad[0] if bad else 'none'!r} unknown; allowed: "
                         f"{', '.join(known)}")
    infos, runs = {}, 0
    for name in use:
        plan, ff = pool.plan([name])
        infos[name] = information(crane, plan, ff, parameters, noise)
        runs += infos[name].runs
        say(f"block {name}: {plan.duration - 1.0:.1f} s, ln det alone "
            f"{infos[name].logdet():.1f} ({infos[name].runtime_s:.0f} s)")
    order = choose(infos, duration)
    plan, ff = pool.plan(order)
    info = information(crane, plan, ff, parameters, noise)
    runs += info.runs
    need, A_need = needed_duration(info, info)
    names = info.names
    plain = None
    if compare:
        p0, f0 = excitation(crane, duration, rate=rate, seed=seed)
        i0 = information(crane, p0, f0, parameters, noise)
        runs += i0.runs
        n0, A0 = needed_duration(i0, i0)
        plain = dict(duration_s=float(p0.duration), logdet=i0.logdet(),
                     sd_scaled=dict(zip(names, map(float, i0.sd()))), needed_duration_s=n0,
                     unidentified=why_unidentified(i0, i0.matrix()), runtime_s=i0.runtime_s)
        say(f"plain excitation: ln det {plain['logdet']:.1f}")
    return DynamicsDesign(
        plan=plan, ff=ff, seed=int(seed), duration=float(duration), order=order, info=info,
        logdet=info.logdet(),
        predicted_logdet=info.logdet(sum(infos[k].matrix() for k in order)),
        sd=dict(zip(names, map(float, info.sd()))), needed_s=need,
        unidentified=why_unidentified(info, info.matrix()),
        unidentified_at_limit={} if need is not None else why_unidentified(info, A_need),
        pool={k: dict(duration_s=infos[k].duration - 1.0, logdet_alone=infos[k].logdet(),
                      chosen=order.count(k)) for k in infos},
        plain=plain, runs=runs, runtime_s=time.perf_counter() - wall0,
        sd_needed=dict(zip(names, map(float, info.sd(A_need)))))
