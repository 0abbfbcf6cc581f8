"""Excitation design: a test trajectory within every limit of the machine on which candidate
effects that the data could not tell apart show as differently as possible (issue 14, item 4)
— the planner serving identification.

Criterion (distance between predictions): for every ordered pair (A, B) of the candidates,
A at a realistic magnitude (its class's trial magnitude, or the values given) is recorded on
the design with seed 001's sensor noise, and B is fitted to that recording exactly as the
discrepancy workflow fits it; the separation is B's held-out misfit above A's,
D = J_B − J_A (noise units, σ² summed: what a recording of the design adds to the score
margin between the right and the wrong name). A design's value is its smallest D over all
ordered pairs. Every design is judged with the same noise draw (common random numbers), so
the criterion is a deterministic function of the design.

Family (:class:`Family`): periodic test sequences — ``moves`` poses visited in turn, over and
over until the duration is reached, each reached by a Ruckig rest-to-rest move at its own
speed fraction and held for its own time (the conditions under which an ``ambiguous`` result
says the candidates' predictions differ: which joints move, direction, speed, pose/load, rest).
The design vector z ∈ [0, 1]^d holds, per pose, the position of every moving joint in
[5 %, 95 %] of its range, the speed fraction (15–100 % of the velocity/acceleration limits)
and the hold (0.3–3 s). The moving joints are the candidates' own joints when every candidate
acts on one joint, else every joint (a machine-wide effect such as ``payload_mass`` shows
with the reach). Every member is built by the project's Ruckig planner, so every position,
speed, acceleration and jerk limit holds by construction (checked by ``evaluate``).

Optimiser (``method="optimise"``, the default): ``candidates`` members drawn at random
(seeded) and the best of them polished by bounded Nelder–Mead (scipy) for ``budget``
criterion evaluations. The objective is the mean over the ordered pairs of D capped at
:data:`CAP` (a pair that no design separates does not freeze the search), tie-broken by the
smallest D. Members that would ask more of the pump's flow or the pressures than allowed
(limits Ruckig does not see) are slowed until ``evaluate`` passes. The default sequence of
the trials (:func:`planner.calibration.trials.excitation`) is evaluated too: its value is
reported, and it is returned instead only if no member of the family beats it and it keeps
every limit (its first move drives the pump to saturation, which ``evaluate`` may flag). ``method="random"`` is the earlier best-of-K search over the
trials' random sequences.

Where the best design found still leaves a pair below the verdict's tie floor (D < 16 σ²:
:data:`planner.calibration.verdict.TIE_Z`), the design says so (``unseparated``): B fitted to
A reproduces A's prediction to within a share of A's own signal — from these channels, over
the designs tried, the pair is not separable, and ``ambiguous`` is the right verdict.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize

from planner.calibration.discrepancy import Discrepancy
from planner.calibration.trials import SequenceBuilder, excitation, record
from planner.calibration.verdict import TIE_Z
from planner.model.effects import CATALOGUE, Effect
from planner.trajectory import evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Design", "Family", "parse_candidates", "candidates_from_result", "separation",
           "separation_details", "design_excitation", "lengthen", "needed_duration",
           "METHODS"]

METHODS = ("optimise", "random")
TIE_FLOOR = 4.0 * TIE_Z ** 2      # [σ²] a pair below it stays a tie for the verdict
MAX_NEEDED_S = 600.0              # [s] longest recording a design proposes (ten minutes)
CAP = 4.0 * TIE_FLOOR             # [σ²] a pair separated this well needs no more (objective)


@dataclass
class Design:
    """The chosen test sequence: ``plan`` (commanded trajectory), ``ff`` (its feed-forward),
    ``seed``, ``separation`` (smallest D over the ordered candidate pairs, σ²),
    ``pairs`` (each pair's D), ``default_separation`` (the same for the default sequence,
    seed ``seed``), ``effects`` (the candidate effects at the magnitudes used), ``tried``
    (label -> separation of the starting designs), ``method``, ``source`` ("optimised",
    "random" or "default": where the returned sequence comes from), ``optimised_separation``
    (the best member of the family, even when the default is returned), ``evaluations``,
    ``runtime_s``, ``z`` (the design vector, optimise only), ``signal`` (each candidate's
    own held-out signal on the design, σ²), ``unseparated`` (pairs left below the tie floor,
    each with why and ``duration_needed_s``: the length of the same periodic sequence at which
    the pair would reach the floor, None when no practical length does; see
    :func:`lengthen`), ``rate`` and ``moves`` of the family."""
    plan: object
    ff: object
    seed: int
    separation: float
    pairs: dict
    default_separation: float
    effects: tuple
    tried: dict
    method: str = "optimise"
    source: str = "optimised"
    optimised_separation: float | None = None
    evaluations: int = 0
    runtime_s: float = 0.0
    z: list | None = None
    signal: dict = field(default_factory=dict)
    unseparated: list = field(default_factory=list)
    rate: float = 50.0
    moves: int = 3


def parse_candidates(crane: Crane, text: str, joint: str | None = None, seed: int = 0) -> tuple:
    """``NAME[@JOINT],…`` -> effects at a realistic magnitude (the class's trial magnitude
    drawn from ``seed``); a per-joint effect without ``@JOINT`` takes ``joint``."""
    rng = np.random.default_rng(seed)
    out = []
    for item in filter(None, (x.strip() for x in text.split(","))):
        name, _, j = item.partition("@")
        name, j = name.strip(), (j.strip() or joint)
        if name not in CATALOGUE:
            raise ValueError(f"`text`: unknown effect {name!r}; known: "
                             f"{', '.join(CATALOGUE)}")
        cls = CATALOGUE[name]
        if cls.per_joint and not j:
            raise ValueError(f"`text`: {name} acts on one joint: write {name}@JOINT or "
                             f"give `joint` (joints: {', '.join(crane.names)})")
        if j and j not in crane.names:
            raise ValueError(f"`text`: unknown joint {j!r} for {name}; joints of "
                             f"{crane.spec.id}: {', '.join(crane.names)}")
        if cls.trial_range is None:
            raise ValueError(f"`text`: {name} has no trial magnitude to design with")
        out.append(cls.trial(crane, rng, j if cls.per_joint else None))
    if len(out) < 2:
        raise ValueError(f"`text` {text!r}: name at least two effects, e.g. "
                         "viscous_friction@swing,coulomb_friction@swing")
    return tuple(out)


def candidates_from_result(crane: Crane, result: dict, where: str = "result") -> tuple:
    """The candidates of an ``ambiguous`` discrepancy result (the dict its JSON holds) at the
    values each was fitted to: a design for them separates the effects at the magnitudes the
    data showed (a weak effect needs a stronger design than its trial magnitude suggests)."""
    verdict = result.get("verdict") if isinstance(result, dict) else None
    if verdict != "ambiguous":
        raise ValueError(f"{where}: verdict = {verdict!r}; allowed: 'ambiguous' (only an "
                         "ambiguous result has candidates to separate)")
    out = []
    for k, c in enumerate(result.get("candidates") or []):
        name, joint = c.get("effect"), c.get("joint")
        if name not in CATALOGUE:
            raise ValueError(f"{where}: candidates[{k}].effect = {name!r}; allowed: a "
                             f"catalogue effect ({', '.join(CATALOGUE)})")
        if joint is not None and joint not in crane.names:
            raise ValueError(f"{where}: candidates[{k}].joint = {joint!r}; joints of "
                             f"{crane.spec.id}: {', '.join(crane.names)}")
        try:
            out.append(CATALOGUE[name](joint, **(c.get("parameters") or {})))
        except ValueError as e:
            raise ValueError(f"{where}: candidates[{k}]: {e}") from None
    if len(out) < 2:
        raise ValueError(f"{where}: {len(out)} candidate(s); at least two are needed")
    return tuple(out)


def _neutral(e: Effect) -> Effect:
    return type(e)(e.joint)


def _label(e: Effect) -> str:
    return e.name + (f"@{e.joint}" if e.joint else "")


def separation_details(crane: Crane, plan, ff, effects, seed: int = 0) -> tuple[dict, dict]:
    """((A label, B label) -> D for every ordered pair, A label -> A's own held-out signal
    J_nominal − J_A [σ²]) on the sequence (module doc)."""
    out, signal = {}, {}
    d = Discrepancy(crane, block_s=1.0)
    for a in effects:
        rec = record(crane, plan, ff, (a,), noise=True, seed=seed)
        d.prepare(rec)
        fa = d.fit_one(_neutral(a))
        signal[_label(a)] = float(d.held_out_misfit(()) - fa.J_test)
        for b in effects:
            if b is a:
                continue
            fb = d.fit_one(_neutral(b))
            out[(_label(a), _label(b))] = float(fb.J_test - fa.J_test)
    return out, signal


def separation(crane: Crane, plan, ff, effects, seed: int = 0) -> dict:
    """(A label, B label) -> D for every ordered pair of ``effects`` on the sequence
    (module doc)."""
    return separation_details(crane, plan, ff, effects, seed)[0]


class Family:
    """Periodic test sequences parametrised by z ∈ [0, 1]^d (module doc): ``moves`` poses of
    the ``joints`` (names; the others hold mid-range), each with a speed fraction and a hold.
    ``build(z)`` -> (plan, feed-forward) at least ``duration`` [s] long and at least one
    whole period."""

    SPEED = (0.15, 1.0)
    HOLD = (0.3, 3.0)        # [s]
    MARGIN = 0.05

    def __init__(self, crane: Crane, duration: float, rate: float = 50.0, joints=None,
                 moves: int = 3):
        if moves < 2:
            raise ValueError(f"moves = {moves}; allowed: 2 or more")
        self.crane, self.duration, self.rate, self.moves = crane, float(duration), rate, moves
        names = list(crane.names)
        self.joints = [names.index(j) for j in (joints or names)]
        L = crane.limit_arrays()
        span = L["q_max"] - L["q_min"]
        self.lo, self.hi = L["q_min"] + self.MARGIN * span, L["q_max"] - self.MARGIN * span
        self.per = len(self.joints) + 2
        self.dim = moves * self.per

    def poses(self, z) -> list:
        z = np.clip(np.asarray(z, float), 0.0, 1.0).reshape(self.moves, self.per)
        out = []
        for row in z:
            q = 0.5 * (self.lo + self.hi)
            q[self.joints] = self.lo[self.joints] + row[:len(self.joints)] * \
                (self.hi - self.lo)[self.joints]
            s = self.SPEED[0] + row[-2] * (self.SPEED[1] - self.SPEED[0])
            h = self.HOLD[0] + row[-1] * (self.HOLD[1] - self.HOLD[0])
            out.append((q, float(s), float(h)))
        return out

    def build(self, z):
        """The sequence of ``z``; where it would ask more than a limit that Ruckig does not
        see (the pump's flow, pressures: :func:`planner.trajectory.evaluate`), every speed
        fraction is lowered by the excess and the sequence rebuilt (at most 5 times)."""
        slow = 1.0
        for _ in range(5):
            plan, ff = self._build(z, slow)
            ev = evaluate(self.crane, plan)
            if ev.ok():
                break
            slow /= 1.03 * (1.0 + ev.max_limit_violation)
        return plan, ff

    def _build(self, z, slow):
        steps = self.poses(z)
        b = SequenceBuilder(self.crane, steps[-1][0], self.rate)
        b.hold(0.5)
        k = 0
        while b.t_now < self.duration or k < self.moves:     # at least one whole period
            q, s, h = steps[k % self.moves]
            b.move(q, s * slow)
            b.hold(h)
            k += 1
        return b.finish(dict(duration=self.duration, z=[float(x) for x in np.ravel(z)]),
                        method="excitation-design")


def _moving_joints(effects) -> list | None:
    """The candidates' own joints when every one acts on a joint, else None (all move)."""
    if all(e.joint for e in effects):
        return sorted({e.joint for e in effects})
    return None


def needed_duration(D: float, duration: float) -> float | None:
    """Length [s] of the same periodic sequence at which a pair separated by ``D`` σ² over
    ``duration`` s reaches the tie floor with a 1.5× margin (D, a sum over the samples, grows
    in proportion to the length); None beyond :data:`MAX_NEEDED_S`."""
    if not D > 0:
        return None
    need = 10.0 * math.ceil(1.5 * TIE_FLOOR / D * duration / 10.0)
    return need if need <= MAX_NEEDED_S else None


def _unseparated(pairs: dict, signal: dict, duration: float) -> list:
    out = []
    for (a, b), D in pairs.items():
        if D < TIE_FLOOR:
            s = signal.get(a, 0.0)
            share = D / s if s > 0 else float("nan")
            need = needed_duration(D, duration)
            out.append(dict(pair=f"{a} vs {b}", D=D, signal_A=s, duration_needed_s=need, why=(
                f"{b} fitted to a recording of {a} reproduces it to within {D:.1f} σ² "
                f"(of {a}'s own signal {s:.1f} σ², {100 * share:.1f} %) on the best design "
                f"found; below the verdict's tie floor {TIE_FLOOR:g} σ², so from these "
                f"{duration:.0f} s the pair stays ambiguous; "
                + (f"about {need:g} s of the same sequence would separate it"
                   if need else f"no recording shorter than {MAX_NEEDED_S:g} s would"))))
    return out


def lengthen(crane: Crane, design: Design, duration: float) -> Design:
    """The same design (the same periodic sequence, or the default sequence of its seed) run
    for ``duration`` s, its separation recomputed: what a longer recording of it buys."""
    effects = design.effects
    if design.source == "optimised" and design.z is not None:
        fam = Family(crane, duration, design.rate, _moving_joints(effects), design.moves)
        plan, ff = fam.build(np.asarray(design.z, float))
    elif design.source == "default":
        plan, ff = excitation(crane, duration, rate=design.rate, seed=design.seed)
    else:
        raise ValueError(f"lengthen: a {design.source!r} design cannot be lengthened; allowed: "
                         "an optimised or default one")
    pairs, signal = separation_details(crane, plan, ff, effects, seed=design.seed)
    return replace(design, plan=plan, ff=ff, separation=min(pairs.values()),
                   pairs={f"{a} vs {b}": x for (a, b), x in pairs.items()}, signal=signal,
                   unseparated=_unseparated(pairs, signal, float(plan.duration)))


def design_excitation(crane: Crane, effects, duration: float = 60.0, rate: float = 50.0,
                      candidates: int = 6, seed: int = 0, budget: int = 40,
                      method: str = "optimise", moves: int = 3, progress=None) -> Design:
    """The design (module doc). ``candidates``: random starting designs (optimise) or
    random sequences besides the default one (random); ``budget``: Nelder–Mead criterion
    evaluations after the starts; ``progress``: a callable taking a line of text."""
    if method not in METHODS:
        raise ValueError(f"method = {method!r}; allowed: {', '.join(METHODS)}")
    if candidates < 1:
        raise ValueError(f"candidates = {candidates}; allowed: 1 or more")
    if budget < 0:
        raise ValueError(f"budget = {budget}; allowed: 0 or more")
    if not duration >= 10.0:
        raise ValueError(f"duration = {duration!r} s; allowed: 10 s or more")
    t0 = time.perf_counter()
    effects = tuple(effects)
    say = progress or (lambda s: None)

    def value(plan, ff):
        pairs, signal = separation_details(crane, plan, ff, effects, seed=seed)
        return min(pairs.values()), pairs, signal

    def objective(pairs):
        # every pair up to CAP (a pair no design separates does not freeze the search),
        # then the smallest D as the tie-break among designs that separate every pair well
        D = np.array(list(pairs.values()))
        return float(np.mean(np.minimum(D, CAP)) + 1e-3 * D.min())

    plan0, ff0 = excitation(crane, duration, rate=rate, seed=seed)
    v0, pairs0, sig0 = value(plan0, ff0)
    tried = {"default": v0}
    say(f"default sequence: separation {v0:.1f} σ²")
    if method == "random":
        return _random(crane, effects, duration, rate, candidates, seed, (v0, plan0, ff0, pairs0,
                                                                        sig0), tried, t0)
    fam = Family(crane, duration, rate, _moving_joints(effects), moves)
    memo, n_eval = {}, [0]
    best = [None]

    def f(z):
        z = np.clip(np.asarray(z, float), 0.0, 1.0)
        key = tuple(np.round(z, 6))
        if key not in memo:
            plan, ff = fam.build(z)
            v, pairs, signal = value(plan, ff)
            memo[key] = (objective(pairs), v)
            n_eval[0] += 1
            if best[0] is None or memo[key][0] > best[0][6]:
                best[0] = (v, z.copy(), plan, ff, pairs, signal, memo[key][0])
                say(f"evaluation {n_eval[0]}: separation {v:.1f} σ² (best)")
        return -memo[key][0]

    rng = np.random.default_rng(seed)
    starts = [rng.uniform(0.0, 1.0, fam.dim) for _ in range(candidates)]
    for k, z in enumerate(starts):
        f(z)
        tried[f"start {k}"] = memo[tuple(np.round(np.clip(z, 0.0, 1.0), 6))][1]
    if budget > 0:
        z0 = best[0][1]
        simplex = [z0] + [np.clip(z0 + np.where(np.arange(fam.dim) == i,
                                                0.25 if z0[i] < 0.5 else -0.25, 0.0), 0, 1)
                          for i in range(fam.dim)]
        minimize(f, z0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * fam.dim,
                 options=dict(maxfev=budget, initial_simplex=np.array(simplex),
                              xatol=1e-3, fatol=0.1))
    v, z, plan, ff, pairs, signal, _ = best[0]
    source = "optimised"
    if (objective(pairs0) > best[0][6] or v0 > v) and evaluate(crane, plan0).ok():
        # the family did not beat the default sequence (which keeps every limit): keep it
        plan, ff, pairs, signal, source = plan0, ff0, pairs0, sig0, "default"
    return Design(plan, ff, seed, min(pairs.values()),
                  {f"{a} vs {b}": x for (a, b), x in pairs.items()},
                  v0, effects, tried, method="optimise", source=source,
                  optimised_separation=v, evaluations=n_eval[0] + 1,
                  runtime_s=time.perf_counter() - t0, z=[float(x) for x in z],
                  signal=signal, unseparated=_unseparated(pairs, signal, float(plan.duration)),
                  rate=rate, moves=moves)


def _random(crane: Crane, effects, duration, rate, candidates, seed, first, tried, t0) -> Design:
    """The best-of-K search over the trials' random sequences (module doc)."""
    own = sorted({e.joint for e in effects if e.joint})
    best = first
    for k in range(1, candidates + 1):
        s = seed + k
        # wider poses, every other one moving only the candidates' own joints
        alone = k % 2 == 0 and own
        plan, ff = excitation(crane, duration, rate=rate, seed=s, margin=0.05,
                              joints=own if alone else None)
        pairs, signal = separation_details(crane, plan, ff, effects, seed=s)
        v = min(pairs.values())
        tried[f"seed {s}"] = v
        if v > best[0]:
            best = (v, plan, ff, pairs, signal)
    v, plan, ff, pairs, signal = best
    return Design(plan, ff, seed, v, {f"{a} vs {b}": x for (a, b), x in pairs.items()},
                  first[0], effects, tried, method="random",
                  source="default" if best is first else "random", optimised_separation=v,
                  evaluations=candidates + 1, runtime_s=time.perf_counter() - t0,
                  signal=signal, unseparated=_unseparated(pairs, signal, float(plan.duration)),
                  rate=rate)
