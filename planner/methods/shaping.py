"""ZV and ZVD input shaping of the sway-blind minimum-time plan: the baselines of sway-free moves.

The load hangs on its grapple link below the tip (:mod:`planner.model.pendulum`), a lightly
damped oscillator of natural frequency ω₀ and damping ratio ζ. Convolving a command with a
train of impulses whose responses cancel at that frequency leaves no residual swing for a
linear system (Singer & Seering's zero-vibration shapers): with K = exp(−ζπ/√(1−ζ²)) and the
damped period T_d,

- ZV:  amplitudes (1, K)/(1 + K) at times (0, T_d/2);
- ZVD: amplitudes (1, 2K, K²)/(1 + K)² at (0, T_d/2, T_d) — zero derivative of the residual
  with respect to the frequency too (robust to a wrong link length), one half-period longer.

Here the joint trajectory of the ``nlp`` minimum-time plan is shaped: q_s(t) = Σ A_i q(t − t_i)
(q held at its ends outside the plan), q̇ and q̈ alike. The amplitudes are positive and sum to 1,
so every box limit (position, velocity, acceleration, jerk) still holds; the pump flow and the
pressures are not convex in the joints and the tip kinematics are not linear, so the shaped
move is judged again by :func:`~planner.trajectory.evaluate` at 1 kHz, and when it breaks a
limit the plan is slowed uniformly (:func:`~planner.methods.nlp.guess.stretch`, by the
largest relative excess plus a margin) and shaped again. The shaped joint path cuts the corners
of the planned one (a convex combination of its points a half-period apart), so with obstacles
the tip's clearance is checked on the same resampling as the NLP checks it (≥ 0.96 ×
clearance); where the shaped move comes too close, the base plan is made again with every
obstacle's clearance raised by the shortfall (twice at most) before the method gives up with
status ``obstacle``.

Options: ``grapple`` (link length [m]; default the spec's ``[dynamics.grapple]``: a machine
without one needs it), ``grapple_zeta`` (pin damping as a share of critical, default the
spec's damping or 0), ``intervals`` (the NLP's). Stats: ``shaper`` (times, amplitudes),
``pendulum_hz``, ``base_duration_s``, ``stretched_by``, ``swing_residual_m`` /
``swing_peak_m`` (the model's prediction, :func:`~planner.model.pendulum.predict_swing`) of
the shaped move and ``base_swing_residual_m`` of the plan it shaped.
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from planner.geometry.paths import tip_to_xyz, xyz_to_tip
from planner.methods.base import (Planner, PlanRequest, PlanResult, PlanStatus,
                                  UnsupportedRequest)
from planner.methods.nlp.guess import stretch
from planner.methods.registry import plan as plan_with, register
from planner.model.pendulum import Pendulum, predict_swing
from planner.trajectory import Trajectory, evaluate

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["shaper", "shape", "ShapingPlanner", "pendulum_of_request", "clearance_margin",
           "load_path", "load_distances", "load_clearance",
           "load_clearance_margin"]

RETIME_ROUNDS = 4          # slow-downs after a broken limit
CLEARANCE_ROUNDS = 2       # base plans with raised clearance after a too-close shaped move
CLEARANCE_SHARE = 0.96     # the share of the clearance a move must keep (as the NLP's check)


def shaper(kind: str, omega: float, zeta: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(times [s], amplitudes) of the ``kind`` ("zv" | "zvd") shaper for a mode of natural
    angular frequency ``omega`` [rad/s] and damping ratio ``zeta``."""
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"shaper `omega` = {omega!r} rad/s: allowed a finite number > 0")
    if not (0 <= zeta < 1):
        raise ValueError(f"shaper `zeta` = {zeta!r}: allowed a number in [0, 1)")
    wd = omega * math.sqrt(1 - zeta * zeta)
    K = math.exp(-zeta * math.pi / math.sqrt(1 - zeta * zeta))
    half = math.pi / wd
    if kind == "zv":
        return np.array([0.0, half]), np.array([1.0, K]) / (1 + K)
    if kind == "zvd":
        return np.array([0.0, half, 2 * half]), np.array([1.0, 2 * K, K * K]) / (1 + K) ** 2
    raise ValueError(f"shaper `kind` = {kind!r}: allowed zv, zvd")


def shape(traj: Trajectory, times, amps, method: str = "") -> Trajectory:
    """``traj`` (rest to rest) convolved with the impulses (``times`` [s], ``amps``): sampled
    at every sample time of each shifted copy, where the sum of the pieces is as smooth as
    the pieces, so the quintic interpolation between them is that of the pieces."""
    times, amps = np.asarray(times, float), np.asarray(amps, float)
    t0, T = traj.t[0], traj.duration
    grid = np.unique(np.concatenate([traj.t - t0 + ti for ti in times]))
    q = np.zeros((len(grid), traj.n))
    qd, qdd = np.zeros_like(q), np.zeros_like(q)
    for ti, A in zip(times, amps):
        s = np.clip(grid - ti, 0.0, T) + t0
        a, b, c, _ = traj.sample(s)
        outside = ((grid - ti) < 0) | ((grid - ti) > T)
        b[outside] = 0.0                      # held at rest outside the plan
        c[outside] = 0.0
        q += A * a
        qd += A * b
        qdd += A * c
    return Trajectory(grid, q, qd, qdd, joint_names=traj.joint_names, method=method or
                      traj.method, objective=traj.objective, limits=traj.limits,
                      meta=dict(traj.meta, shaped=dict(times=times.tolist(),
                                                       amplitudes=amps.tolist())))


def pendulum_of_request(crane: Crane, request: PlanRequest, who: str) -> Pendulum:
    """The grapple the request's options (``grapple``, ``grapple_zeta``) or the spec name;
    UnsupportedRequest (one line, naming the machine) when neither gives a link."""
    length = request.option("grapple")
    zeta = request.option("grapple_zeta")
    dyn = crane.spec.dynamics
    if length is None and (dyn is None or dyn.grapple is None):
        raise UnsupportedRequest(f"{who} on {crane.spec.id}: the machine has no "
                                 "[dynamics.grapple]; give `grapple` (link length [m], a "
                                 "number > 0)")
    try:
        return Pendulum.of(crane, length, zeta=zeta)
    except ValueError as e:
        raise UnsupportedRequest(str(e).replace("pendulum `length`", "`grapple`")
                                 .replace("pendulum `zeta`", "`grapple_zeta`")) from None


def clearance_margin(crane: Crane, traj: Trajectory, obstacles, rate: float = 1000.0) -> float:
    """The smallest distance minus CLEARANCE_SHARE × clearance over every obstacle [m]
    (≥ 0: clear) on a ``rate`` resampling."""
    if not obstacles:
        return math.inf
    cyl = crane.tip(traj.sample(traj.resample(rate))[0])
    xyz = tip_to_xyz(cyl)
    return min(float(ob.distance(xyz, cyl).min()) - CLEARANCE_SHARE * ob.clearance
               for ob in obstacles)


def load_path(crane: Crane, traj: Trajectory, pend: Pendulum,
              rate: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """(times [s] (K,), the load's centre of mass (K, 3) [m] in frame 0) on a ``rate``
    resampling of ``traj``: the tip's forward kinematics plus the link vector of the swing the
    model predicts along the plan (:func:`~planner.model.pendulum.predict_swing`, from hanging
    at rest)."""
    pred = predict_swing(crane, traj, pend, rate=rate)
    tip = tip_to_xyz(crane.tip(traj.sample(pred.t)[0]))
    return pred.t, tip + pend.link(pred.x)


def load_distances(crane: Crane, traj: Trajectory, pend: Pendulum, obstacles,
                   rate: float = 1000.0) -> list:
    """[(least distance [m] of the swinging load's centre of mass (:func:`load_path`) on a
    ``rate`` resampling, the obstacle's clearance [m])], one pair per obstacle."""
    if not obstacles:
        return []
    _, xyz = load_path(crane, traj, pend, rate)
    cyl = xyz_to_tip(xyz)
    return [(float(ob.distance(xyz, cyl).min()), float(ob.clearance)) for ob in obstacles]


def load_clearance(crane: Crane, traj: Trajectory, pend: Pendulum, obstacles,
                   rate: float = 1000.0) -> float:
    """The least distance [m] of the swinging load to any of ``obstacles`` at ``rate`` (inf:
    none), as a library entry reports the tip's (``clearance_m``)."""
    return min((d for d, _ in load_distances(crane, traj, pend, obstacles, rate)),
               default=math.inf)


def load_clearance_margin(crane: Crane, traj: Trajectory, pend: Pendulum, obstacles,
                          rate: float = 1000.0, share: float = CLEARANCE_SHARE) -> float:
    """As :func:`clearance_margin` for the swinging load: the smallest distance minus
    ``share`` × clearance over every obstacle [m] (≥ 0: clear; inf: none)."""
    return min((d - share * c for d, c in
                load_distances(crane, traj, pend, obstacles, rate)), default=math.inf)


class ShapingPlanner(Planner):
    """``zv`` / ``zvd``: the ``nlp`` minimum-time plan shaped at the grapple pendulum's
    frequency (module doc), re-timed until every limit holds and clear of the obstacles."""
    objectives = ("time",)
    paths = ("free",)
    obstacles = True
    grapple = True        # reads the ``grapple`` option (the link length)

    def __init__(self, kind: str):
        self.kind = kind
        self.name = kind
        self.description = (f"{kind.upper()} input shaping of the nlp minimum-time plan at the "
                            "grapple's swing frequency (re-timed, clearance checked)")

    def library_request(self, crane: Crane, move, objective: str, *, time_result=None,
                        settings) -> PlanRequest:
        """The plain library request with the build's ``intervals`` and grapple link
        (``settings.grapple``: length or None for the spec's, pin zeta)."""
        req = super().library_request(crane, move, objective, time_result=time_result,
                                      settings=settings)
        length, zeta = getattr(settings, "grapple", None) or (None, None)
        return replace(req, options=dict(req.options, intervals=settings.intervals,
                                         grapple=length, grapple_zeta=zeta))

    def check(self, request: PlanRequest) -> None:
        super().check(request)
        for k in ("grapple", "grapple_zeta"):
            v = request.options.get(k)
            if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool)
                                      and math.isfinite(v) and v >= 0):
                raise UnsupportedRequest(f"`{k}` = {v!r}: allowed a finite number "
                                         f"{'> 0 [m]' if k == 'grapple' else 'in [0, 1)'}")

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        t_start = _time.perf_counter()
        pend = pendulum_of_request(crane, request, self.name)
        times, amps = shaper(self.kind, pend.omega, pend.zeta)
        obstacles = tuple(request.obstacles)
        base_req = PlanRequest(request.start, request.goal, objective="time", path="free",
                               obstacles=obstacles,
                               options={"intervals": request.option("intervals", 40)})
        raised = 0.0
        for _ in range(CLEARANCE_ROUNDS + 1):
            base = plan_with(crane, base_req, "nlp")
            if not base.ok:
                base.method = self.name
                base.reason = f"the sway-blind nlp plan: {base.reason}"
                return base
            tr, k = base.trajectory, 1.0
            for _ in range(RETIME_ROUNDS + 1):
                shaped = shape(tr, times, amps, method=self.name)
                ev = evaluate(crane, shaped)
                if ev.max_limit_violation <= self.tolerance:
                    break
                f = 1.0 + 1.1 * ev.max_limit_violation + 0.01
                k *= f
                tr = stretch(tr, tr.duration * f)
            else:
                return PlanResult(PlanStatus.VIOLATION, f"{self.name}: the shaped move still exceeds "
                                  f"a limit by {100 * ev.max_limit_violation:.2f} % after "
                                  f"slowing the plan × {k:.2f}", method=self.name)
            short = clearance_margin(crane, shaped, obstacles)
            if short >= 0:
                break
            raised += -short + 0.02
            obstacles_raised = tuple(replace(ob, clearance=ob.clearance + raised)
                                     for ob in request.obstacles)
            base_req = replace(base_req, obstacles=obstacles_raised)
        else:
            return PlanResult(PlanStatus.OBSTACLE, f"{self.name}: the shaped move comes {-short:.3f} m "
                              "closer to an obstacle than allowed, after raising the "
                              f"clearance of the plan it shapes by {raised:.3f} m",
                              method=self.name)
        pred = predict_swing(crane, shaped, pend)
        base_pred = predict_swing(crane, base.trajectory, pend)
        return PlanResult(PlanStatus.OK, trajectory=shaped, duration_s=shaped.duration,
                          solve_time_s=_time.perf_counter() - t_start, method=self.name,
                          stats=dict(shaper=dict(times=times.tolist(), amplitudes=amps.tolist()),
                                     pendulum_hz=pend.omega / (2 * math.pi),
                                     base_duration_s=base.duration_s, stretched_by=k,
                                     clearance_raised_m=raised,
                                     swing_residual_m=pred.residual_m,
                                     swing_peak_m=pred.peak_during_m,
                                     base_swing_residual_m=base_pred.residual_m))


register(ShapingPlanner("zv"))
register(ShapingPlanner("zvd"))
