"""Trajectories and commands through the Exudyn plant: the measured-data CSV of a run (the same
contract as the fast plant's), and the helpers the validation and the claims studies share.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.feedforward import commands
from planner.simulation.dynamic.exudyn_plant import ExudynPlant, PlantDiverged
from planner.simulation.plants import plant_to_csv
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["trajectory_commands", "slowed", "simulate_trajectory", "exudyn_to_csv"]


def trajectory_commands(crane: Crane, traj: Trajectory, rate: float = 50.0):
    """(t_u, u, source): the trajectory's own commands when it carries them on a uniform grid,
    else the feed-forward of :func:`planner.feedforward.commands` at ``rate`` (as the fast
    plant's ``simulate`` does)."""
    if traj.u is not None and len(traj.t) > 2 and np.ptp(np.diff(traj.t)) < 1e-9:
        return traj.t, traj.u, "trajectory"
    ff = commands(crane, traj, rate)
    return ff.t, ff.u, f"feedforward@{rate:g}Hz"


def slowed(traj: Trajectory, factor: float) -> Trajectory:
    """The same path ``factor`` times slower (time × factor, velocities ÷ factor,
    accelerations ÷ factor²); the commands are not kept."""
    f = float(factor)
    return Trajectory(traj.t[0] + (traj.t - traj.t[0]) * f, traj.q,
                      None if traj.qd is None else traj.qd / f,
                      None if traj.qdd is None else traj.qdd / f ** 2,
                      joint_names=traj.joint_names, method=traj.method,
                      objective=traj.objective, interpolation=traj.interpolation)


def simulate_trajectory(crane: Crane, traj: Trajectory, rate: float = 50.0, effects=(),
                        settle: float = 0.0, plant: ExudynPlant | None = None, **run_kw):
    """Run ``traj``'s valve commands open loop on the Exudyn plant (``plant``, default one
    built with ``effects``), ``settle`` seconds past the end with the valves closed. Returns
    (run, t_u, u, source)."""
    t_u, u, src = trajectory_commands(crane, traj, rate)
    plant = plant or ExudynPlant(crane, effects)
    t_u = np.asarray(t_u, float)
    u = np.asarray(u, float)
    if settle > 0:
        dt = float(np.median(np.diff(t_u))) if len(t_u) > 1 else 1.0 / rate
        t_u = np.append(t_u, t_u[-1] + dt)
        u = np.vstack([u, np.zeros((1, crane.n))])
    t_end = float(max(traj.t[-1], t_u[-1]) + settle)
    run = plant.integrate(t_u, u, traj.q[0], t_end=t_end, **run_kw)
    return run, t_u, u, src


def exudyn_to_csv(crane: Crane, traj: Trajectory, out, rate: float = 50.0, noise=None,
                  seed: int = 0,
                  effects=(), max_wall_s: float = 600.0) -> dict:
    """What ``crane-planner simulate --plant exudyn`` does
    (:func:`planner.simulation.plants.plant_to_csv` on the Exudyn plant): nothing is written
    when the run fails (:class:`PlantDiverged`: status, t_fail)."""
    return plant_to_csv(crane, traj, out, "exudyn", rate=rate, noise=noise, seed=seed,
                        effects=effects, max_wall_s=max_wall_s)
