"""Trajectories and commands through the Exudyn plant: the measured-data CSV of a run (the same
contract as the fast plant's), and the helpers the validation and the claims studies share.
"""
from __future__ import annotations

import numpy as np

from planner.feedforward import commands
from planner.simulation.dynamic.exudyn_plant import ExudynPlant, PlantDiverged
from planner.simulation.recording import Recording, noise_levels
from planner.trajectory import Trajectory

__all__ = ["trajectory_commands", "slowed", "simulate_trajectory", "exudyn_to_csv"]


def trajectory_commands(crane, traj: Trajectory, rate: float = 50.0):
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


def simulate_trajectory(crane, traj: Trajectory, rate: float = 50.0, effects=(),
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


def exudyn_to_csv(crane, traj: Trajectory, out, rate: float = 50.0, noise=None, seed: int = 0,
                  effects=(), max_wall_s: float = 600.0) -> dict:
    """What ``crane-planner simulate --plant exudyn`` does: replay ``traj``'s commands on the
    Exudyn plant with the hidden ``effects`` and write the measured-data CSV at ``rate`` (the
    command grid). Nothing is written when the run fails: :class:`PlantDiverged` (status,
    t_fail) is raised. Returns a JSON-ready summary like the fast plant's."""
    plant = ExudynPlant(crane, effects)
    run, t_u, u, src = simulate_trajectory(crane, traj, rate, plant=plant,
                                           max_wall_s=max_wall_s)
    if not run.ok:
        raise PlantDiverged(run.status, run.t_fail, run.reason)
    t = np.arange(t_u[0], run.t[-1] + 1e-9, 1.0 / rate)
    q, p_a, p_b, u_s = run.sample(t)
    q_s, pa_s, pb_s = plant.sense(q, p_a, p_b, t)
    rec = Recording(t, u_s, q_s, pa_s, pb_s).with_noise(crane, noise, seed)
    cols = rec.to_csv(out, crane)
    q_plan = traj.sample(np.clip(t, traj.t[0], traj.t[-1]))[0]
    tip_err = np.linalg.norm(crane.fk(q) - crane.fk(q_plan), axis=1)
    return dict(status="ok", plant="exudyn", out=str(out), samples=len(t), columns=cols,
                commands=src, effects=[e.to_dict() for e in plant.effects],
                noise=noise_levels(noise), seed=seed,
                max_tip_error_m=float(tip_err.max()), final_tip_error_m=float(tip_err[-1]),
                steps=run.meta["steps"], step_s=run.meta["step"], wall_s=run.wall_s)
