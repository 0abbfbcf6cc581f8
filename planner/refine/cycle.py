"""A work cycle refined as one (:func:`refine_cycle`): each move from the twin's state that
the refined move before it leaves (:func:`after_move`)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.refine import RefineOptions, refine_commands

if TYPE_CHECKING:
    from planner.model import Crane
    from planner.model.twin import Twin
    from planner.trajectory import Trajectory

__all__ = ["refine_cycle", "after_move"]


def refine_cycle(crane: Crane, moves, *, twin: Twin | None = None,
                 options: RefineOptions | None = None, gap: float = 3.0):
    """A work cycle refined as one: ``moves`` ((traj, t_u, u) per move, in the order the
    machine runs them, each move's nominal commands) each refined (:func:`refine_commands`)
    from the twin's state that the refined move before it leaves (:func:`after_move`): its
    position, residual motion and the chamber pressures it trapped (a forwarder's slew stops
    with 10–40 bar in both chambers, its telescope's rod side climbs to 250 bar over a cycle on
    the twin, where a move refined alone assumes the unloaded chamber at tank). The first move
    starts at rest. Returns (refinements, start states: None for rest, else the twin's state
    at that move's start)."""
    from planner.model.twin import Twin
    opts = options or RefineOptions()
    twin = twin if twin is not None else Twin(crane, step=opts.step)
    x, out, starts = None, [], []
    for traj, t_u, u in moves:
        r = refine_commands(crane, traj, t_u, u, twin=twin, options=opts, x0=x)
        out.append(r)
        starts.append(x)
        x = after_move(twin, traj, r.t_u, r.u, x, gap, opts.rate)
    return out, starts


def after_move(twin: Twin, traj: Trajectory, t_u, u, x0, gap: float, rate: float = 50.0):
    """The twin's state when the next move of a work cycle starts: commands ``u`` held from
    ``t_u`` (on ``traj``'s clock) from the state ``x0`` (None: rest at the plan's start), then
    the valves closed until ``gap`` s after the later of the plan's end and the last command
    (on the ``rate`` [Hz] grid). None when the twin diverges (it cannot say)."""
    n, dt = twin.crane.n, 1.0 / rate
    t_r = np.asarray(t_u, float) - traj.t[0]
    span = round((max(traj.duration, t_r[-1] + dt) + gap) * rate) / rate
    run = twin.simulate(np.append(t_r, t_r[-1] + dt),
                        np.vstack([np.asarray(u, float), np.zeros((1, n))]),
                        traj.q[0] if x0 is None else x0[:n], t_end=span, x0=x0)
    if not run.ok:
        return None
    return np.concatenate([run.q[-1], run.qd[-1], run.p_a[-1], run.p_b[-1], [run.p_s[-1]],
                           run.spool[-1]] + ([run.swing[-1]] if run.swing is not None else []))
