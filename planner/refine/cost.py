"""The cost that :func:`planner.refine.refine_commands` minimises over the valve openings on
the control grid, with its exact gradient by the twin's adjoint (the terms are described in
:mod:`planner.refine`'s module doc).

**The landing tube** (the calm stage's, ``RefineOptions.tube_weight``): after the plan's end
the tip's distance d from the goal past the radius r (``calm_below``, 2.5 mm: half the landing
tolerance) costs ``tube_weight``·(d² − r²)² [mm⁴] per second; inside the tube, nothing. The
squared error the other terms integrate barely prices a peak: a move that reaches its goal
9 mm late at the plan's end and creeps in within 0.15 s costs 30·81·0.05 ≈ 120 mm²·s against
thousands for the tip error during the move, so the optimiser kept the lateness — and a landing
is judged by its largest distance from the rest point after the plan's end. On the eight
moves of ``calibrate_loop_100.md`` that the calibrated twins predicted furthest off (5.0–9.8 mm,
the largest at the plan's end in six: late, not ringing), refined again from the same warm
start: 3.0–5.6 mm with the tube (5 of 8 within 4 mm); without it, refined again from the
nominal commands with 150 or 400 iterations, four of them stayed at 7.3–9.1 mm. Its price on
those eight (by the twin): the tip error during the move 54–185 mm against 40–85 mm, up to
1.4 × the pump work. On the loop's 600 (``benchmarks/results/calibrate_loop_100t.md``, judged
on Exudyn): 553 land against 533 without it; the tip error during the move median 30.9 mm
against 30.2, p90 63.9 against 59.3; the twin's pump work 1.3 % more over the sums. d is
measured as the tracking term measures the tip: Σ_j ℓ_j²·e_j², each joint's own tip
displacement.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.landing import tip_levers
from planner.model.valves import past_deadband
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["CommandCost"]


class CommandCost:
    """The cost of :mod:`planner.refine`'s module doc and its gradient with respect to the control-grid commands."""

    def __init__(self, shooting, traj: Trajectory, Ku: int, R: int, K: int, opts, crane: Crane,
                 pendulum=None, x0=None, end_weight: float | None = None,
                 tube: tuple[float, float] = (0.0, 0.0)):
        self.sh, self.Ku, self.R, self.K, self.pendulum = shooting, Ku, R, K, pendulum
        n = traj.n
        h = shooting.h
        self.tk = traj.t[0] + h * np.arange(K + 1)
        self.q_ref = traj.sample(np.clip(self.tk, traj.t[0], traj.t[-1]))[0]
        w_end = opts.end_weight if end_weight is None else end_weight
        w_t = np.where(self.tk > traj.t[-1] + 1e-9, w_end, 1.0)
        # the levers along the reference (a slew's lever is the reach: 1.8 m folded at an s100f
        # goal, 6 m stretched out on the way; weighted at the goal only, the optimiser paid a
        # mid-move slew error an eleventh of its tip error); J in mm²·s (the scale L-BFGS-B's
        # default tolerances suit)
        lev2 = tip_levers(crane, self.q_ref) ** 2
        self.W = 1e6 * h * w_t[:, None] * lev2
        self.W_swing = 1e6 * h * opts.swing_weight * (self.tk > traj.t[-1] + 1e-9)
        # the landing tube (calm stage): after the plan's end the tip's distance from the goal
        # [mm] past ``tube[0]`` [m] costs tube[1]·(d² − r²)² — nothing inside it, steeply
        # outside, so the peak (a late arrival, a swing) is what it pays for, not the mean
        self.after = self.tk > traj.t[-1] + 1e-9
        self.r2 = (1e3 * tube[0]) ** 2
        self.w_tube = h * tube[1] if tube[0] > 0 else 0.0
        self.L2 = 1e6 * lev2[self.after]
        self.smooth = 1e6 * opts.smooth
        # the pump's work [kJ] over the whole record, in mm²·s per kJ (energy entries)
        self.w_energy = 1e-3 * h * opts.energy_weight
        self.power = shooting.twin.pump_power() if opts.energy_weight > 0 else None
        self.P = np.asarray(shooting.twin.P, float)
        self.energy_kJ = float("nan")
        self.x0 = shooting.twin.rest_state(traj.q[0]) if x0 is None else np.asarray(x0, float)
        self.n, self.evaluations = n, 0
        self.fail = 1e30
        self.db = np.asarray(shooting.twin.params.per["deadband"], float)

    def tube(self, ea):
        """The landing tube's cost of the joint errors ``ea`` after the plan's end (one row
        per step) and its gradient: the tip's distance² [mm²] taken as Σ_j ℓ_j²·e_j² (the
        tracking term's measure: each joint's tip displacement, squared and summed)."""
        x = np.maximum(np.sum(self.L2 * ea * ea, axis=1) - self.r2, 0.0)
        return self.w_tube * float(np.sum(x * x)), (4.0 * self.w_tube * x)[:, None] * self.L2 * ea

    def steps(self, U):
        us = np.zeros((self.K, self.n))
        us[:self.Ku * self.R] = np.repeat(U, self.R, axis=0)
        return us

    def __call__(self, z):
        U = z.reshape(self.Ku, self.n)           # openings; the valves get past_deadband(U)
        us = self.steps(past_deadband(U, self.db))
        run = self.sh.run(self.x0, us)
        self.evaluations += 1
        e = run.x[:, :self.n] - self.q_ref
        if not np.all(np.isfinite(e)):   # the twin left its range: a wall, not a slope
            return self.fail, np.zeros_like(z)
        J = float(np.sum(self.W * e * e))
        dJdx = np.zeros_like(run.x)
        dJdx[:, :self.n] = 2.0 * self.W * e
        if self.w_tube:
            Jt, dt = self.tube(e[self.after])
            J += Jt
            dJdx[self.after, :self.n] += dt
        if self.pendulum is not None:    # the swing's states follow the twin's (5n + 1)
            from planner.model.twin.pendulum import amplitude2, amplitude2_gradient
            nb = 5 * self.n + 1
            S = run.x[:, nb:]
            J += float(np.sum(self.W_swing * amplitude2(self.pendulum, S)))
            dJdx[:, nb:] += self.W_swing[:, None] * amplitude2_gradient(self.pendulum, S)
        if self.power is not None:       # the pump's work: p_s·Σ q_in, a function of states
            w, dw = self.power(run.x, self.P[None, :])
            self.energy_kJ = 1e-3 * self.sh.h * float(np.sum(w))
            J += self.w_energy * float(np.sum(w))
            dJdx += self.w_energy * dw
        g = self.sh.gradient(run, us, dJdx)[:self.Ku * self.R]
        g = g.reshape(self.Ku, self.R, self.n).sum(axis=1) * (1.0 - self.db)
        dU = np.diff(U, axis=0)
        J += self.smooth * float(np.sum(dU * dU))
        g[1:] += 2.0 * self.smooth * dU
        g[:-1] -= 2.0 * self.smooth * dU
        return J, g.ravel()
