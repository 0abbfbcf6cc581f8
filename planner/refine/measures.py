"""What :func:`planner.refine.refine_commands` measures on the twin: the horizon its cost
sees (:func:`horizon`), the twin's landing measures of a command sequence (:func:`predict`),
how far they are from landed (:func:`score`) and which of two refinements lands better
(:func:`keep_better`)."""
from __future__ import annotations

import math
from dataclasses import asdict
from typing import TYPE_CHECKING

import numpy as np

from planner.landing import landing_measures
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.model.twin import Twin

__all__ = ["horizon", "score", "predict", "keep_better"]


def horizon(twin: Twin, traj: Trajectory, opts):
    """(tail [s], settle [s], the slowest oil-spring frequency at the goal [Hz] or None): the
    options' own, lengthened to a quarter and to ``periods`` periods of that mode."""
    if opts.periods <= 0:
        return opts.tail, opts.settle, None
    f = float(np.min(twin.oil_spring_frequencies(traj.q[-1])))
    T = opts.periods / f if f > 0 else 0.0
    return max(opts.tail, min(0.25 * T, 10.0)), max(opts.settle, min(T, 60.0)), f


def score(measures: dict) -> float:
    """How far a prediction is from landed: the larger of its rest offset and ringing [m]."""
    return max(measures["rest_offset_m"], measures["residual_oscillation_m"])


def keep_better(r, r2, key: str, name: str, opts):
    """The better landing (by the twin) of a refinement ``r`` and a second try ``r2`` (each a
    :class:`planner.refine.Refinement`), the second's record in ``predicted[key]`` (taken,
    the threshold, ``first``, ``name`` and its status and iterations); the costs of both
    counted."""
    taken = str(r2.status) == "improved" and \
        score(r2.predicted["refined"]) < score(r.predicted["refined"])
    out = r2 if taken else r
    out.predicted = dict(out.predicted, **{key: {
        "taken": bool(taken), "above_m": opts.fallback_above, "first": r.predicted["refined"],
        name: r2.predicted.get("refined"), f"{name}_status": str(r2.status),
        f"{name}_iterations": r2.iterations}})
    out.options, out.wall_s = asdict(opts), r.wall_s + r2.wall_s
    out.iterations, out.evaluations = r.iterations + r2.iterations, r.evaluations + r2.evaluations
    return out


def predict(crane: Crane, twin: Twin, traj: Trajectory, t_u, U, K: int,
             opts, x0=None):
    """Twin measures of commands ``U`` held from ``t_u`` (valves closed after the last), run
    in full (the integrator's recovery substeps included) over the cost's horizon, and
    the pump's work over it (``pump_J``, at the shaft: :meth:`Twin.pump_energy
    <planner.model.twin.Twin.pump_energy>`), with the swing's (:func:`planner.model.twin.pendulum.swing_measures`) when the twin carries the
    load on its link; None when the twin diverges."""
    t_end = traj.t[0] + K * twin.step
    tu = np.append(t_u, t_u[-1] + 1.0 / opts.rate)
    uu = np.vstack([U, np.zeros((1, crane.n))])
    run = twin.simulate(tu, uu, traj.q[0], t_end=t_end, x0=x0)
    if not run.ok:
        return None
    ts = traj.t[0] + np.arange(int(math.floor((t_end - traj.t[0]) * opts.rate + 1e-9)) + 1) \
        / opts.rate
    q = run.sample(ts)[0]
    out = landing_measures(crane, ts, q, traj, opts.rest_window)
    out["pump_J"] = twin.pump_energy(run)
    if run.swing is not None:
        from planner.model.twin.pendulum import swing_measures
        out.update(swing_measures(twin.pendulum, run.t, run.swing, traj.t[-1]))
    return out
