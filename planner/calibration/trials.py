"""Hidden-effect trials: recordings of a plant with a hidden effect, for testing the discrepancy
workflow (:mod:`planner.calibration.discrepancy`), which sees only the measured CSV and the
commands.

:func:`excitation` builds the commanded trajectory of a recording: rest-to-rest moves (Ruckig,
every joint at once) between random poses in the inner part of the joint ranges — the first
one across the whole inner range at full speed, the others at random speeds (30–100 % of the
limits) — with holds of 0.5–2 s between them: the kind of test sequence a calibration run uses
(motion in both directions, several speeds, the pump at its limit, loads held at rest).
:func:`hidden_trial` draws an effect and a realistic magnitude (the effect class's own
``trial_range`` and ``trial_values``, on a joint its ``observable`` rule allows), records the
plant with it and with sensor noise, and returns the recording with the truth. Every effect of
the catalogue that has a ``trial_range`` can be drawn; nothing here names one.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from collections.abc import Mapping
from functools import cached_property

import numpy as np

from planner.feedforward import commands
from planner.methods.nlp import stretch
from planner.methods.ruckig import rest_to_rest
from planner.model.effects import CATALOGUE, Effect
from planner.simulation.plant import respond
from planner.simulation.recording import Recording
from planner.simulation.replay import stroke_rates
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["excitation", "SequenceBuilder", "TrialSequence", "record", "hidden_trial", "trackable", "draw",
           "observable_joints", "TRIAL_MAGNITUDES"]


class _TrialMagnitudes(Mapping):
    """Effect name -> (low, high) of the magnitude its trials draw (the class's
    ``trial_range``, documented per class with its unit), for every catalogue effect that
    trials draw; a live view of the catalogue."""

    def _ranges(self):
        return {k: c.trial_range for k, c in CATALOGUE.items() if c.trial_range is not None}

    def __getitem__(self, name):
        return self._ranges()[name]

    def __iter__(self):
        return iter(self._ranges())

    def __len__(self):
        return len(self._ranges())

    def __repr__(self):
        return f"TRIAL_MAGNITUDES({self._ranges()!r})"


# Realistic magnitudes of the hidden effects in the trials — several relative to the machine,
# so that a lab crane and a log loader get comparable effects — drawn uniformly, sign random
# where both signs are physical. Assumed: typical of a worn or mis-calibrated mobile crane, and
# large enough to stand out of seed 001's sensor noise over a 60 s recording (the workflow's
# job is to name effects that are there, not to find the undetectable).
TRIAL_MAGNITUDES = _TrialMagnitudes()


class TrialSequence:
    """The test sequence of a trial (commanded plan and its feed-forward ``ff``) as the effects'
    ``trial_values`` see it: ``peak_demand`` = its peak pump demand / the pump's maximum flow
    (computed when first asked for)."""

    def __init__(self, crane: Crane, plan: Trajectory, ff):
        self.crane, self.plan, self.ff = crane, plan, ff

    @cached_property
    def peak_demand(self) -> float:
        return float(np.max(stroke_rates(self.crane, self.ff.u)[1])) / \
            self.crane.spec.pump.max_flow


class SequenceBuilder:
    """A test sequence assembled from holds and Ruckig rest-to-rest moves (every position,
    speed, acceleration and jerk limit holds by construction), sampled at ``rate`` [Hz]:
    ``hold(T)``, ``move(goal, scale)``, ``t_now``, ``q`` (the current pose), ``finish(meta)``
    -> (plan, feed-forward)."""

    def __init__(self, crane: Crane, q0, rate: float = 50.0):
        self.crane, self.rate, self.q = crane, float(rate), np.asarray(q0, float)
        n = crane.n
        self._t, self._q = [np.zeros(1)], [self.q[None]]
        self._qd, self._qdd = [np.zeros((1, n))], [np.zeros((1, n))]
        self.t_now = 0.0

    def hold(self, T: float) -> None:
        """Stay at rest for ``T`` [s] (at least one sample)."""
        k = max(1, int(round(T * self.rate)))
        tt = self.t_now + np.arange(1, k + 1) / self.rate
        self._t.append(tt)
        self._q.append(np.repeat(self._q[-1][-1:], k, axis=0))
        self._qd.append(np.zeros((k, self.crane.n)))
        self._qdd.append(np.zeros((k, self.crane.n)))
        self.t_now = float(tt[-1])

    def move(self, goal, scale: float = 1.0) -> None:
        """Rest-to-rest to ``goal`` at ``scale`` of every speed/acceleration limit (nothing
        when already there)."""
        goal = np.asarray(goal, float)
        if np.max(np.abs(goal - self.q)) < 1e-9:
            return
        seg = rest_to_rest(self.crane, self.q, goal, scale=scale).trajectory
        self._t.append(self.t_now + seg.t[1:] - seg.t[0])
        self._q.append(seg.q[1:])
        self._qd.append(seg.qd[1:])
        self._qdd.append(seg.qdd[1:])
        self.t_now = float(self._t[-1][-1])
        self.q = goal

    def finish(self, meta=None, method: str = "excitation") -> tuple[Trajectory, object]:
        plan = Trajectory(np.concatenate(self._t), np.vstack(self._q), np.vstack(self._qd),
                          np.vstack(self._qdd), joint_names=tuple(self.crane.names),
                          method=method, meta=dict(meta or {}))
        return plan, commands(self.crane, plan, self.rate)


def excitation(crane: Crane, duration: float = 60.0, rate: float = 50.0, seed: int = 0,
               margin: float = 0.15, joints=None, speed=(0.3, 1.0),
               first_full: bool = True) -> tuple[Trajectory, object]:
    """(plan, feed-forward) of a test sequence at least ``duration`` [s] long (see module doc).
    Poses are drawn in [margin, 1 − margin] of every joint range; ``joints`` (names): only
    these move, the others hold mid-range (default: all move); ``speed``: the range of the
    speed fractions of the moves after the first; ``first_full``: the first move crosses the
    whole inner range at full speed (False: it is drawn like the others — a slow, small
    sequence with a large ``margin`` and a low ``speed``)."""
    still = (np.zeros(crane.n, bool) if joints is None else
             ~np.isin(np.asarray(crane.names), list(joints)))
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + margin * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - margin * (L["q_max"] - L["q_min"])
    q = 0.5 * (lo + hi)
    b = SequenceBuilder(crane, q, rate)
    b.hold(rng.uniform(0.5, 1.0))
    first = first_full
    while b.t_now < duration:
        if first:   # one long full-speed move of every joint: the pump gets to its limit
            side = rng.uniform(size=crane.n) < 0.5
            goal, scale = np.where(side, lo, hi), 1.0
            first = False
        else:
            goal, scale = rng.uniform(lo, hi), float(rng.uniform(*speed))
        goal = np.where(still, q, goal)
        b.move(goal, scale)
        b.hold(rng.uniform(0.5, 2.0))
    return b.finish(dict(seed=seed, duration=duration))


def trackable(crane: Crane, plan: Trajectory, margin: float = 0.8,
              rate: float = 50.0) -> Trajectory:
    """``plan`` slowed uniformly until its nominal feed-forward asks at most ``margin`` of
    every valve (|u|) and of the pump: a plan the nominal plant can follow open loop (as every
    library entry is), for judging re-planned feed-forward on a calibrated model."""
    ff = commands(crane, plan, rate)
    need = max(float(np.max(np.abs(ff.u_raw))),
               float(np.max(stroke_rates(crane, ff.u_raw)[1])) / crane.spec.pump.max_flow)
    if need <= margin:
        return plan
    return stretch(plan, plan.duration * need / margin)


def record(crane: Crane, plan: Trajectory, ff, effects=(), noise=True, seed: int = 0,
           positions_only: bool = False) -> Recording:
    """Replay ``ff`` on the plant with ``effects`` from the plan's start; sensor noise at
    seed 001's levels (``noise`` as in :func:`planner.simulation.recording.noise_levels`)."""
    r = respond(crane, ff.t, ff.u, plan.q[0], effects, t_end=ff.t[-1])
    rec = Recording(r.t, r.u, r.q, r.p_a, r.p_b).with_noise(crane, noise, seed)
    return rec.positions_only() if positions_only else rec


def observable_joints(crane: Crane, name: str) -> list[str]:
    """The joints on which the effect ``name`` leaves a trace in positions and pressures (its
    class's ``observable`` rule): the ones trials draw it on."""
    return _effect_class(name).observable_joints(crane)


def _effect_class(name: str) -> type[Effect]:
    if name not in CATALOGUE:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(CATALOGUE)}")
    return CATALOGUE[name]


def draw(crane: Crane, name: str, rng, joint: str | None = None, sequence=None) -> Effect:
    """A hidden effect ``name`` of realistic magnitude (:meth:`Effect.trial`), for the test
    ``sequence`` (a :class:`TrialSequence`; None: a pump-limited sequence is assumed)."""
    return _effect_class(name).trial(crane, rng, joint, sequence)


def hidden_trial(crane: Crane, effect: str | None, seed: int, duration: float = 60.0,
                 joint: str | None = None, noise=True):
    """(recording, plan, feed-forward, truth) — ``truth`` the injected effect (None: clean)."""
    if effect is not None:
        _effect_class(effect)
    rng = np.random.default_rng(seed + 7919)
    plan, ff = excitation(crane, duration, seed=seed)
    truth = draw(crane, effect, rng, joint, TrialSequence(crane, plan, ff)) if effect else None
    rec = record(crane, plan, ff, (truth,) if truth else (), noise=noise, seed=seed)
    return rec, plan, ff, truth
