"""Warm starts for the move NLP, as trajectories (:meth:`MoveNLP.guess_from
<planner.methods.nlp.move.MoveNLP.guess_from>` puts any trajectory on the NLP's grid).

- :func:`ruckig_guess`: the jerk-limited rest-to-rest move between the ends (Ruckig) at the
  lower bound's best telescope values, and that move slowed to 1.05 × the combined bound when
  it is faster (the pump limits);
- :func:`over_obstacles_guess`: Ruckig segments through a via point above every obstacle the
  move meets (a guess through a wall leaves IPOPT in a poor local optimum);
- :func:`path_guess`: a coarse DP along a tip path retimed by TOPP-RA (line and curve modes);
- :func:`stretch`: any trajectory slowed uniformly to a longer duration.
"""
from __future__ import annotations

import numpy as np

from planner.methods.dp import dp
from planner.methods.ruckig import rest_to_rest
from planner.methods.topp import retime
from planner.trajectory import Trajectory

__all__ = ["stretch", "ruckig_guess", "vias", "over_obstacles_guess", "path_guess"]


def stretch(traj: Trajectory, T: float) -> Trajectory:
    """The same joint path slowed uniformly to duration T ≥ traj.duration: velocities scale by
    1/k, accelerations 1/k², jerks 1/k³, pump flows 1/k — still within every limit."""
    k = T / traj.duration
    return Trajectory(traj.t * k, traj.q, traj.qd / k, traj.qdd / k ** 2,
                      joint_names=traj.joint_names, method=traj.method, objective="stretched",
                      limits=traj.limits, meta=dict(traj.meta, stretched_by=k))


def ruckig_guess(crane, start, goal, lb, q_start=None, q_goal=None) -> tuple:
    """(the guess: the Ruckig rest-to-rest move slowed to 1.05 × the combined bound when
    faster, the Ruckig move itself) between tips ``start`` and ``goal`` at the telescopes of
    the lower bound ``lb`` (:func:`~planner.bounds.lower_bound`), or between the joint
    configurations ``q_start``/``q_goal`` when given. ValueError when an end is unreachable."""
    q0 = crane.ik(start, lb.tele_start) if q_start is None else np.asarray(q_start, float)
    q1 = crane.ik(goal, lb.tele_goal) if q_goal is None else np.asarray(q_goal, float)
    tr = rest_to_rest(crane, q0, q1).trajectory
    slow = stretch(tr, 1.05 * lb.combined_s) if 1.05 * lb.combined_s > tr.duration else tr
    return slow, tr


def vias(obstacles, start, goal) -> list:
    """Via tips above the obstacles the move start → goal meets, in the order it meets them."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    out = [v for ob in obstacles for v in ob.vias(start, goal)]
    out.sort(key=lambda v: (abs(v[2] - start[2]), abs(v[0] - start[0])))
    return out


def over_obstacles_guess(crane, obstacles, start, goal, lb) -> Trajectory:
    """Rest-to-rest Ruckig segments through a via point above every obstacle crossed (at the
    wall's r, 1.5 clearances above its top, slew interpolated): a guess on the right side of
    the obstacles."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    tips = [start] + vias(obstacles, start, goal) + [goal]
    qs = [crane.ik(tips[0], lb.tele_start)]
    for k, tip in enumerate(tips[1:], 1):
        tele = lb.tele_goal if k == len(tips) - 1 else None
        qs.append(crane.ik(tip, tele))
    segs = [rest_to_rest(crane, a, b).trajectory for a, b in zip(qs[:-1], qs[1:])]
    t, q, qd, qdd, off = [], [], [], [], 0.0
    for s in segs:
        t.append(s.t[1:] + off if t else s.t)
        for lst, arr in ((q, s.q), (qd, s.qd), (qdd, s.qdd)):
            lst.append(arr[1:] if len(lst) else arr)
        off += s.duration
    return Trajectory(np.concatenate(t), np.vstack(q), np.vstack(qd), np.vstack(qdd),
                      joint_names=tuple(crane.names))


def path_guess(crane, path) -> Trajectory:
    """A coarse DP (5 cm stations and telescope grid) along ``path`` retimed by TOPP-RA
    (velocity, acceleration, pump); ValueError with the method's reason when either fails."""
    d = dp(crane, path, step=0.05, tele_step=0.05, window=3)
    if not d.ok:
        raise ValueError(d.reason)
    t = retime(crane, d.path_q, gridpoints=100)
    if not t.ok:
        raise ValueError(t.reason)
    return t.trajectory
