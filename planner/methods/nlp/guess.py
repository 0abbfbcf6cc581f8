"""Warm starts for the move NLP, as trajectories (:meth:`MoveNLP.guess_from
<planner.methods.nlp.move.MoveNLP.guess_from>` puts any trajectory on the NLP's grid).

- :func:`ruckig_guess`: the jerk-limited rest-to-rest move between the ends (Ruckig) at the
  lower bound's best telescope values, and that move slowed to 1.05 × the combined bound when
  it is faster (the pump limits);
- :func:`over_obstacles_guess`: Ruckig segments through a via point above every obstacle the
  move meets (a guess through a wall leaves IPOPT in a poor local optimum);
- :func:`path_guess`: a coarse DP along a tip path retimed by TOPP-RA (line and curve modes);
- :func:`stretch`: any trajectory slowed uniformly to a longer duration;
- :class:`Guesses`: one move NLP's guesses (``guess_from``, ``default_guess``, the Ruckig
  move it shares with the exact-move check), held by :class:`~planner.methods.nlp.move.MoveNLP`
  as ``guesses``.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.bounds import lower_bound
from planner.geometry.paths import Line
from planner.methods.dp import dp
from planner.methods.nlp.tip import CHECKS
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["stretch", "ruckig_guess", "vias", "over_obstacles_guess", "path_guess", "Guesses",
           "GUESS_BOUND"]

# the lower bound the default guess is taken at: a coarser telescope grid than the reported
# bound's, refining the combined bound only (only the guess's telescopes and its slowing
# depend on it). Four refinements (telescopes to ~1e-4 m): the exact Ruckig move taken at
# them was up to 0.02 % (p90 on s100f) slower than at the best telescopes with two
# (issue 31: up to 0.125 % of the plan's distance to the optimum came from here)
GUESS_BOUND = dict(n_grid=41, refine=4, starts=4, combined_only=True)


def stretch(traj: Trajectory, T: float) -> Trajectory:
    """The same joint path slowed uniformly to duration T ≥ traj.duration: velocities scale by
    1/k, accelerations 1/k², jerks 1/k³, pump flows 1/k — still within every limit."""
    k = T / traj.duration
    return Trajectory(traj.t * k, traj.q, traj.qd / k, traj.qdd / k ** 2,
                      joint_names=traj.joint_names, method=traj.method, objective="stretched",
                      limits=traj.limits, meta=dict(traj.meta, stretched_by=k))


def ruckig_guess(crane: Crane, start, goal, lb, q_start=None, q_goal=None) -> tuple:
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


def over_obstacles_guess(crane: Crane, obstacles, start, goal, lb) -> Trajectory:
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


def path_guess(crane: Crane, path) -> Trajectory:
    """A coarse DP (5 cm stations and telescope grid) along ``path`` retimed by TOPP-RA
    (velocity, acceleration, pump); ValueError with the method's reason when either fails."""
    from planner.methods.topp import retime   # toppra (and its matplotlib): only for a path
    d = dp(crane, path, step=0.05, tele_step=0.05, window=3)
    if not d.ok:
        raise ValueError(d.reason)
    t = retime(crane, d.path_q, gridpoints=100, adapt=0)   # a guess: no grid adaptation
    if not t.ok:
        raise ValueError(t.reason)
    return t.trajectory


class Guesses:
    """The primal guesses of one built move NLP on ``crane``: its variable ``layout``
    (:class:`~planner.methods.nlp.transcription.Layout`), variable bounds ``lbw``/``ubw``,
    ``N`` intervals, ``path`` ("free", "line" or "curve") and ``curve`` (the curve of the
    curve mode, else None). Keeps the Ruckig move of the last move asked for: the default
    guess and the exact-move check share it."""

    def __init__(self, crane: Crane, layout, lbw, ubw, N: int, path: str, curve=None):
        self.crane, self.layout, self.lbw, self.ubw = crane, layout, lbw, ubw
        self.N, self.path, self.curve = N, path, curve
        self._plain = (None, None)   # (key, plain_traj result) of the last move: built once

    def guess_from(self, traj) -> np.ndarray:
        """Primal guess from any Trajectory (resampled to the NLP's grid; slacks at bounds)."""
        N, lay = self.N, self.layout
        t = np.linspace(traj.t[0], traj.t[-1], N + 1)
        q, qd, qdd, _ = traj.sample(t)
        h = (t[-1] - t[0]) / N
        w0 = np.zeros(lay.nw)
        lay.pack(w0, "X", np.vstack([q.T, qd.T, qdd.T]))
        lay.pack(w0, "U", np.diff(qdd, axis=0).T / h)
        lay.pack(w0, "T", traj.duration)
        rest = lay.slice("T").stop
        w0[rest:] = np.clip(0.0, self.lbw[rest:], self.ubw[rest:])  # slacks: the solver lifts them
        if lay.has("QC"):   # the joints at the interior obstacle check points
            tc = t[:-1, None] + h * np.asarray(CHECKS)[None, :]          # (N, checks)
            qc = traj.sample(tc.ravel())[0].reshape(N, len(CHECKS) * q.shape[1])
            lay.pack(w0, "QC", qc.T)
        if self.curve is not None:  # θ per node: the nearest point of the curve to each tip
            u = np.linspace(*self.curve.u_range, 4001)
            P = np.asarray(self.curve.p(u))
            tips = self.crane.fk(q)
            k = np.argmin(((tips[:, None, :] - P[None, :, :]) ** 2).sum(-1), axis=1)
            th = np.maximum.accumulate(u[k]) if u[-1] > u[0] else np.minimum.accumulate(u[k])
            th[0], th[-1] = u[0], u[-1]
            lay.pack(w0, "TH", th)
        return w0

    def default_guess(self, start, goal, q_ends=(None, None)):
        """Free path: Ruckig rest-to-rest between the ends (``q_ends``: joint configurations,
        else the tips at the best telescope values of a coarse lower bound,
        :data:`GUESS_BOUND`), slowed to the pump bound when the pump limits. Line: a coarse DP
        along the line retimed by TOPP-RA (velocity, acceleration, pump)."""
        crane = self.crane
        if self.path in ("line", "curve"):
            lb = lower_bound(crane, start, goal, **GUESS_BOUND)
            geo = self.curve if self.path == "curve" else Line(start, goal)
            return self.guess_from(path_guess(crane, geo)), lb
        lb = self.bound(start, goal, q_ends)
        return self.plain_guess(start, goal, lb, q_ends), lb

    def bound(self, start, goal, q_ends=(None, None)):
        """The coarse lower bound the guess is taken at (fixed joint ends when given)."""
        qs, qg = q_ends
        return lower_bound(self.crane, None if qs is not None else start,
                           None if qg is not None else goal, q_start=qs, q_goal=qg,
                           **GUESS_BOUND)

    def plain_guess(self, start, goal, lb, q_ends=(None, None)):
        """Ruckig rest-to-rest at the bound's best telescopes, slowed to the pump bound."""
        return self.guess_from(self.plain_traj(start, goal, lb, q_ends)[0])

    def plain_traj(self, start, goal, lb, q_ends=(None, None)):
        """(the guess trajectory: Ruckig slowed to 1.05 × the combined bound when faster, the
        Ruckig move itself). Kept for the last move: the guess and the exact-move check share it."""
        qk = tuple(None if q is None else tuple(map(float, q)) for q in q_ends)
        key = (tuple(map(float, start)), tuple(map(float, goal)), lb.tele_start, lb.tele_goal,
               lb.combined_s, qk)
        if self._plain[0] != key:
            self._plain = (key, ruckig_guess(self.crane, start, goal, lb, *q_ends))
        return self._plain[1]
