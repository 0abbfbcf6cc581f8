"""Excitation design: a test trajectory within every limit of the machine on which candidate
effects that the data could not tell apart show as differently as possible (issue 14, item 4)
— the planner serving identification.

Criterion (distance between predictions): for every ordered pair (A, B) of the candidates,
A at a realistic magnitude (its class's trial magnitude, or the values given) is recorded on
the design with seed 001's sensor noise, and B is fitted to that recording exactly as the
discrepancy workflow fits it; the separation is B's held-out misfit above A's,
D = J_B − J_A (noise units, σ² summed: what a recording of the design adds to the score
margin between the right and the wrong name). A design's value is its smallest D over all
ordered pairs.

Search: the designs are the trials' test sequences (:func:`planner.calibration.trials.
excitation`: Ruckig rest-to-rest moves between poses in the inner joint ranges at random
speeds, holds between them — every position, speed, acceleration and jerk limit holds by
construction): the default sequence and ``candidates`` more from other seeds, with poses
drawn over 90 % of every joint range (the default: 70 %), every other one moving only the
joints the candidates act on; the best is kept (never worse than the default). A random search over a
feasible family, not an optimum: it is as good as the best of the designs tried, and its
value is reported next to the default sequence's so the gain is visible.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.calibration.discrepancy import Discrepancy
from planner.calibration.trials import excitation, record
from planner.model.effects import CATALOGUE, Effect

__all__ = ["Design", "parse_candidates", "separation", "design_excitation"]


@dataclass
class Design:
    """The chosen test sequence: ``plan`` (commanded trajectory), ``ff`` (its feed-forward),
    ``seed``, ``separation`` (smallest D over the ordered candidate pairs, σ²),
    ``pairs`` (each pair's D), ``default_separation`` (the same for the default sequence,
    seed 0), ``effects`` (the candidate effects at the magnitudes used), ``tried`` (seed ->
    separation)."""
    plan: object
    ff: object
    seed: int
    separation: float
    pairs: dict
    default_separation: float
    effects: tuple
    tried: dict


def parse_candidates(crane, text: str, joint: str | None = None, seed: int = 0) -> tuple:
    """``NAME[@JOINT],…`` -> effects at a realistic magnitude (the class's trial magnitude
    drawn from ``seed``); a per-joint effect without ``@JOINT`` takes ``joint``."""
    rng = np.random.default_rng(seed)
    out = []
    for item in filter(None, (x.strip() for x in text.split(","))):
        name, _, j = item.partition("@")
        name, j = name.strip(), (j.strip() or joint)
        if name not in CATALOGUE:
            raise ValueError(f"--separate: unknown effect {name!r}; known: "
                             f"{', '.join(CATALOGUE)}")
        cls = CATALOGUE[name]
        if cls.per_joint and not j:
            raise ValueError(f"--separate: {name} acts on one joint: write {name}@JOINT or "
                             f"give --joint (joints: {', '.join(crane.names)})")
        if j and j not in crane.names:
            raise ValueError(f"--separate: unknown joint {j!r} for {name}; joints of "
                             f"{crane.spec.id}: {', '.join(crane.names)}")
        if cls.trial_range is None:
            raise ValueError(f"--separate: {name} has no trial magnitude to design with")
        out.append(cls.trial(crane, rng, j if cls.per_joint else None))
    if len(out) < 2:
        raise ValueError(f"--separate {text!r}: name at least two effects, e.g. "
                         "viscous_friction@swing,coulomb_friction@swing")
    return tuple(out)


def _neutral(e: Effect) -> Effect:
    return type(e)(e.joint)


def separation(crane, plan, ff, effects, seed: int = 0) -> dict:
    """(A label, B label) -> D for every ordered pair of ``effects`` on the sequence
    (module doc)."""
    out = {}
    d = Discrepancy(crane, block_s=1.0)
    for a in effects:
        rec = record(crane, plan, ff, (a,), noise=True, seed=seed)
        d.prepare(rec)
        fa = d.fit_one(_neutral(a))
        for b in effects:
            if b is a:
                continue
            fb = d.fit_one(_neutral(b))
            out[(_label(a), _label(b))] = float(fb.J_test - fa.J_test)
    return out


def _label(e: Effect) -> str:
    return e.name + (f"@{e.joint}" if e.joint else "")


def design_excitation(crane, effects, duration: float = 60.0, rate: float = 50.0,
                      candidates: int = 6, seed: int = 0) -> Design:
    """The design (module doc): the default sequence (seed ``seed``) and ``candidates``
    more (seeds ``seed`` + 1 …)."""
    if candidates < 1:
        raise ValueError(f"candidates = {candidates}; allowed: 1 or more")
    if not duration >= 10.0:
        raise ValueError(f"duration = {duration!r} s; allowed: 10 s or more")
    effects = tuple(effects)
    own = sorted({e.joint for e in effects if e.joint})
    tried, best = {}, None
    for k, s in enumerate([seed] + [seed + 1 + k for k in range(candidates)]):
        # the default sequence; then wider poses, every other one moving only the
        # candidates' own joints (no cross-talk from the others)
        alone = k % 2 == 0 and k > 0 and own
        plan, ff = excitation(crane, duration, rate=rate, seed=s,
                              margin=0.15 if k == 0 else 0.05, joints=own if alone else None)
        pairs = separation(crane, plan, ff, effects, seed=s)
        value = min(pairs.values())
        tried[s] = value
        if best is None or value > best[0]:
            best = (value, s, plan, ff, pairs)
    value, s, plan, ff, pairs = best
    return Design(plan, ff, s, value, {f"{a} vs {b}": v for (a, b), v in pairs.items()},
                  tried[seed], effects, tried)
