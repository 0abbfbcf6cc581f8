"""The "true" plant: the nominal open-loop replay plus effects from :mod:`planner.model.effects`.

:func:`respond` runs the stages in order (see :mod:`planner.model.effects`):

1. commands — what the valves act on (delay, spool lag);
2. valves — :func:`planner.simulation.replay.commanded` with the effects' valve and pump
   parameters (pressure-compensated valves, dead band, flow sharing) -> the free stroke motion,
   taken through the end stops by :func:`planner.simulation.stops.run_to_stops` -> strokes x(t);
3. forces — actuator forces from the model's inverse dynamics at the replayed states (payload
   from the effects) plus the effects' extra forces (friction, actuator mass); chamber pressures
   from the forces (:func:`chamber_pressures`, the load-holding model of
   :mod:`planner.model.hydraulics`);
4. strokes — pressure-driven extra motion (leakage), integrated on the sample grid;
   fixed-point passes (drift from the pressures of the drifted states, forces and pressures
   recomputed) until the drift settles, at most six (it converges fast: the drift changes the
   pressures far less than it changes the positions);
5. sensors — what the transducers report (offsets). Noise is added by the caller
   (:meth:`planner.simulation.recording.Recording.with_noise`).

Stages 1–2 and the true start are the replay's own (it takes the whole effect set and applies
the commands, start and valves stages). The effects are the spec's calibrated ones
(``[[effects]]``), then those of ``plant`` (a :class:`planner.simulation.replay.Plant` — the
robustness study's deviations, themselves effects), then the ones given.

With ``q_fit`` (measured positions) the initial strokes are not taken from ``q0`` but fitted to
the measurement (least squares per joint on ``fit_mask``): the start pose is a nuisance
parameter of every model, as in any calibration. The free stroke motion does not depend on the
start (valve flows depend on the commands only); the end stops do: a cylinder that reaches its
end forgets where it started. So the plant never re-anchors a clipped run: the free motion
(:func:`planner.simulation.replay.commanded`, plus the drift) goes through the end stops from
the start — the true one, or each trial start of the fit — by the one code path
:func:`planner.simulation.stops.run_to_stops`, and the plant that records and the model that
diagnoses reach a stroke end the same way, at the same time.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import CubicSpline

from planner.feedforward import commands
from planner.model import Crane, flows
from planner.model.effects import as_effects, effect_from_dict, quasi_static
from planner.simulation.recording import Recording, noise_levels
from planner.simulation.replay import (Plant, clipped_intervals, commanded, describe_plant,
                                       differences, stroke_stops)
from planner.simulation.stops import StopPath, run_to_stops
from planner.trajectory import Trajectory

__all__ = ["StrokeMap", "stroke_map", "PlantState", "Response", "respond", "chamber_pressures",
           "simulate_to_csv"]

_UNIT_MASS = 100.0     # [kg] step for the (exactly linear) actuator-mass force regressor
_UNIT_CACHE: dict = {}
_MAP_CACHE: dict = {}


class StrokeMap:
    """Per-joint stroke maps x(q), dx/dq and the inverse q(x) as cubic splines on 4001 points
    of each joint range (every actuator's stroke depends on its own joint only): the fitting
    loop calls them thousands of times, and numpy splines are ~50× cheaper than the symbolic
    model's calls. Agreement with ``crane.stroke`` is checked at construction (≤ 1e-9 of the
    stroke range at the midpoints)."""

    def __init__(self, crane: Crane, points: int = 4001):
        L = crane.limit_arrays()
        Q = np.linspace(L["q_min"], L["q_max"], points)
        X, D = crane.stroke(Q)
        self.fwd, self.inv = [], []
        for i in range(crane.n):
            sgn = np.sign(D[points // 2, i])
            if not np.all(np.sign(D[:, i]) == sgn):
                raise ValueError(f"crane '{crane.spec.id}': stroke map of joint "
                                 f"'{crane.names[i]}' is not monotone")
            self.fwd.append(CubicSpline(Q[:, i], X[:, i]))
            order = np.argsort(X[:, i])
            self.inv.append(CubicSpline(X[order, i], Q[order, i]))
        mid = 0.5 * (Q[1:] + Q[:-1])
        err = np.abs(self.x(mid) - crane.stroke(mid)[0]).max(axis=0)
        if np.any(err > 1e-9 * (np.ptp(X, axis=0) + 1e-12)):
            raise ValueError(f"crane '{crane.spec.id}': stroke spline error {err.max():.3g}")
        self.n = crane.n
        self.stops = stroke_stops(crane)

    def x(self, q):
        q = np.atleast_2d(q)
        return np.column_stack([f(q[:, i]) for i, f in enumerate(self.fwd)])

    def dxdq(self, q):
        q = np.atleast_2d(q)
        return np.column_stack([f(q[:, i], 1) for i, f in enumerate(self.fwd)])

    def q(self, x):
        x = np.atleast_2d(x)
        return np.column_stack([f(x[:, i]) for i, f in enumerate(self.inv)])


def stroke_map(crane: Crane) -> StrokeMap:
    """The crane's :class:`StrokeMap` (cached per model object; the cache holds the model, so
    its id cannot be reused)."""
    hit = _MAP_CACHE.get(id(crane))
    if hit is None or hit[0] is not crane:
        hit = _MAP_CACHE[id(crane)] = (crane, StrokeMap(crane))
    return hit[1]


def chamber_pressures(crane: Crane, force, xd=None):
    """Chamber pressures p_a, p_b (N, n) [Pa] from actuator forces (N, n), load-holding model
    (:func:`planner.model.flows.chamber_pressures`: F ≥ 0 the piston side carries it, the rod
    side at tank; F < 0 the other way round; single-acting: piston side only); with stroke
    rates ``xd`` priced as the crane prices them (:func:`planner.model.flows.
    priced_pressures`: the machine pricing adds friction and the outlets' counter-pressure).
    The plant does not model the hydraulic transformer (its replay does not): refused here."""
    spec = crane.spec
    if spec.transformer is not None and spec.transformer.enabled:
        raise ValueError(f"crane '{spec.id}': the plant with effects does not model the "
                         "hydraulic transformer; disable it in the spec ([transformer] "
                         "enabled = false)")
    if xd is not None:
        return flows.priced_pressures(crane, np.atleast_2d(force), np.atleast_2d(xd))
    return flows.chamber_pressures(spec, np.atleast_2d(force))


@dataclass
class PlantState:
    """The true plant at every sample: q, qd, qdd (N, n), strokes x, xd, actuator forces
    (model + effects), chamber pressures p_a, p_b [Pa], payload [kg]."""
    crane: object
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    x: np.ndarray
    xd: np.ndarray
    force_model: np.ndarray
    payload: float
    force: np.ndarray = None
    p_a: np.ndarray = None
    p_b: np.ndarray = None

    def unit_actuator_force(self, i: int) -> np.ndarray:
        """Actuator forces (N, n) per kg of extra mass of actuator i (lumped as the model
        lumps it); inverse dynamics is linear in the masses, so one difference is exact."""
        spec = self.crane.spec
        key = (id(self.crane), i)
        hit = _UNIT_CACHE.get(key)
        if hit is None or hit[0] is not self.crane:
            j = spec.joints[i]
            j2 = replace(j, actuator=replace(j.actuator, mass=j.actuator.mass + _UNIT_MASS))
            hit = _UNIT_CACHE[key] = (self.crane, Crane(replace(
                spec, joints=spec.joints[:i] + (j2,) + spec.joints[i + 1:])))
        tau = hit[1].inverse_dynamics(self.q, self.qd, self.qdd, self.payload)
        heavy = np.atleast_2d(tau) / stroke_map(self.crane).dxdq(self.q)
        return (heavy - self.force_model) / _UNIT_MASS


@dataclass
class Response:
    """What the plant did (``state``) and what its sensors report: ``q`` (N, n), ``p_a``,
    ``p_b`` (N, n) [Pa], at the sample times ``t`` with the commanded ``u`` (N, n) in effect;
    ``effects``: the spec's and the given ones (not the plant's deviations)."""
    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    p_a: np.ndarray
    p_b: np.ndarray
    state: PlantState
    sim: Trajectory
    effects: tuple = ()
    meta: dict = field(default_factory=dict)


def _by_stage(effects, stage):
    return [e for e in effects if e.stage == stage]


def _fit_start(crane: Crane, steps, x_guess, q_meas, bias, mask, gain=1.0, iters: int = 8):
    """Initial strokes (n,) so that bias + gain·q(x) fits q_meas on mask, x the run from them
    through the end stops (:func:`planner.simulation.stops.run_to_stops`, as the plant runs):
    per joint, Gauss-Newton on the 1-D problems with the run's own sensitivity (1 until the
    first contact with an end, 0 after: the stop has forgotten the start), a step that does not
    lower the misfit halved."""
    sm = stroke_map(crane)
    lo, hi = sm.stops
    qm = np.broadcast_to((q_meas - bias) / gain, np.shape(q_meas))[mask]

    path = StopPath(steps, lo, hi)

    def misfit(x0):
        run = path.run(x0)
        q = sm.q(run.x[mask])
        r = qm - q
        return r, run.free[mask] / sm.dxdq(q), np.sum(r * r, axis=0)

    x0 = np.clip(x_guess, lo, hi)
    r, J, cost = misfit(x0)
    done = np.zeros(len(x0), bool)     # per joint: converged, or no step lowers its misfit
    for _ in range(iters):
        step = np.sum(J * r, axis=0) / np.maximum(np.sum(J * J, axis=0), 1e-300)
        done |= np.abs(step) <= 1e-10 * (hi - lo)
        if done.all():
            break
        step = np.where(done, 0.0, step)
        for _ in range(4):
            x1 = np.clip(x0 + step, lo, hi)
            r1, J1, c1 = misfit(x1)
            worse = c1 > cost
            if not worse.any():
                break
            step = np.where(worse, 0.5 * step, step)
        keep = ~worse
        done |= worse
        x0 = np.where(keep, x1, x0)
        r, J, cost = np.where(keep, r1, r), np.where(keep, J1, J), np.where(keep, c1, cost)
    return x0


def _q_from_strokes(crane: Crane, x):
    q = stroke_map(crane).q(x)
    L = crane.limit_arrays()
    return np.clip(q, L["q_min"], L["q_max"])


def _forces(crane: Crane, effects, t, q, dt, x, payload):
    qd, qdd = differences(q, dt)
    dxdq = stroke_map(crane).dxdq(q)
    xd = dxdq * qd
    # actuator force by virtual work, F = τ / (dx/dq), as in planner.model.hydraulics
    Fm = np.atleast_2d(crane.inverse_dynamics(q, qd, qdd, payload)) / dxdq
    s = PlantState(crane, t, q, qd, qdd, x, xd, Fm, payload)
    F = Fm.copy()
    for e in _by_stage(effects, "forces"):
        dF = e.force(crane, s)
        if dF is not None:
            F = F + dF
    s.force = F
    s.p_a, s.p_b = chamber_pressures(crane, F, xd)
    return s


def respond(crane: Crane, t_u, u, q0, effects=(), *, plant=Plant(),
            dt: float | None = None, t_end: float | None = None, q_fit=None, fit_mask=None,
            replay_cache: dict | None = None) -> Response:
    """The plant's response to commands ``u`` (M, n) held over ``t_u`` (M,), from ``q0`` (n,)
    (or from the start fitted to ``q_fit`` (N, n) measured on the sample grid, rows
    ``fit_mask``), with ``effects`` (a sequence of :class:`planner.model.effects.Effect`).
    ``plant``: further deviations (a :class:`planner.simulation.replay.Plant` or a sequence of
    effects), applied before the spec's and the given effects. ``replay_cache``: a dict reused
    between calls that differ only in force/stroke/sensor effects (the fitting loop)."""
    # the spec's own (calibrated) effects are part of the model
    given = tuple(effect_from_dict(d) for d in crane.spec.effects) + as_effects(crane, effects)
    effects = quasi_static(as_effects(crane, plant) + given)
    t_u = np.asarray(t_u, float)
    u = np.atleast_2d(np.asarray(u, float))
    key = tuple(e for e in effects if e.replayed)
    if replay_cache is not None and key in replay_cache:
        cmd = replay_cache[key]
    else:
        cmd = commanded(crane, t_u, u, q0, key, dt=dt, t_end=t_end)
        if replay_cache is not None:
            replay_cache[key] = cmd
    dt, t = cmd.dt, cmd.t
    lo, hi = stroke_map(crane).stops
    payload = crane.spec.payload.total
    for e in _by_stage(effects, "forces"):
        payload = e.payload(crane, payload)
    sensors = _by_stage(effects, "sensors")
    # the position sensors as an affine map of the true position at each sample:
    # reading = bias + gain * q (offsets, gains, drifts); the start is fitted through it
    bias, gain = np.zeros((1, crane.n)), np.ones((1, crane.n))
    if sensors:
        bias, one = np.zeros((len(t), crane.n)), np.ones((len(t), crane.n))
        for e in sensors:
            bias, one = e.sense_q_at(crane, t, bias), e.sense_q_at(crane, t, one)
        gain = one - bias
    mask = np.ones(len(t), bool) if fit_mask is None else np.asarray(fit_mask, bool)

    def run(steps):
        # the start (the true one, or fitted to the measurement) and the strokes from it,
        # through the end stops: one code path for the plant and for every fit
        x0 = cmd.x_start if q_fit is None else _fit_start(
            crane, steps, cmd.x_start, np.asarray(q_fit, float), bias, mask, gain)
        r = run_to_stops(x0, steps, lo, hi)
        return r, _q_from_strokes(crane, r.x)

    stops, q = run(cmd.steps)
    s = _forces(crane, effects, t, q, dt, stops.x, payload)
    drifting = _by_stage(effects, "strokes")
    prev = None
    for _ in range(6 if drifting else 0):
        # fixed-point passes: the drift from the pressures of the current (drifted, re-anchored)
        # states, until it settles (1e-7 of the stroke range): the plant and a fit with a
        # fitted start then reach the same fixed point
        rate = sum(d for d in (e.drift(crane, s) for e in drifting) if d is not None)
        if np.isscalar(rate):
            break
        # trapezoid integral of the extra stroke rate over each step of the sample grid
        extra = 0.5 * (rate[1:] + rate[:-1]) * np.diff(t)[:, None]
        drift = np.cumsum(extra, axis=0)
        settled = prev is not None and np.all(np.abs(drift - prev).max(axis=0)
                                              <= 1e-7 * (hi - lo))
        prev = drift
        stops, q = run(cmd.steps + extra)
        s = _forces(crane, effects, t, q, dt, stops.x, payload)
        if settled:
            break
    q_s = q
    for e in sensors:
        q_s = e.sense_q_at(crane, t, q_s)
    p_a, p_b = s.p_a, s.p_b
    for e in sensors:
        p_a, p_b = e.sense_p_at(crane, t, p_a, p_b)
    # the commanded u in effect at each sample (not what the valves saw)
    # (1e-6 of a step: the replay's sample times carry rounding from summing steps)
    j = np.clip(np.searchsorted(t_u, t + 1e-6 * dt, side="right") - 1, 0, len(t_u) - 1)
    names = tuple(crane.names)
    clipped = clipped_intervals(t, stops.at_stop, names)
    plant_dict, plant_str = describe_plant(plant)
    sim = Trajectory.trusted(t, q, s.qd, s.qdd, joint_names=names, method="replay",
                             interpolation="quintic", u=u[j],
                             meta=dict(plant=plant_dict, plant_str=plant_str, dt=dt,
                                       payload=cmd.payload, clipped=clipped, pump=cmd.pump))
    return Response(t=t, u=u[j], q=q_s, p_a=p_a, p_b=p_b, state=s, sim=sim, effects=given,
                    meta=dict(pump=cmd.pump, clipped=clipped, dt=dt, payload=payload))


# ----------------------------------------------------------------------------- CLI helper
def simulate_to_csv(crane: Crane, traj: Trajectory, out, plant=Plant(), rate: float = 50.0,
                    noise=None, seed: int = 0, effects=(), plan=None) -> dict:
    """What ``crane-planner simulate`` does: replay ``traj``'s valve commands (its own ``u``
    when it carries them on a uniform grid, else :func:`planner.feedforward.commands` at
    ``rate``) on ``plant`` with the hidden ``effects`` (:func:`respond`) and write the
    measured-data CSV to ``out`` (noise as in :func:`planner.simulation.recording.noise_levels`).
    Nothing is written when anything fails. Returns a JSON-ready summary; with ``plan`` it
    adds how the run lands, as :func:`planner.simulation.plants.plant_to_csv`."""
    if traj.u is not None and len(traj.t) > 2 and np.ptp(np.diff(traj.t)) < 1e-9:
        t_u, u, src = traj.t, traj.u, "trajectory"
    else:
        ff = commands(crane, traj, rate)
        t_u, u, src = ff.t, ff.u, f"feedforward@{rate:g}Hz"
    r = respond(crane, t_u, u, traj.q[0], effects, plant=plant)
    rec = Recording(r.t, r.u, r.q, r.p_a, r.p_b).with_noise(crane, noise, seed)
    levels = noise_levels(noise)
    cols = rec.to_csv(out, crane)
    q_plan = traj.sample(r.t)[0]
    tip_err = np.linalg.norm(crane.fk(r.state.q) - crane.fk(q_plan), axis=1)
    extra = {}
    if plan is not None:
        from planner.refine import landing_measures
        extra = landing_measures(crane, r.t, r.state.q, plan)
    return dict(status="ok", out=str(out), samples=len(r.t), columns=cols, commands=src,
                plant=describe_plant(plant)[0], effects=[e.to_dict() for e in r.effects],
                noise=levels, seed=seed,
                max_tip_error_m=float(tip_err.max()), final_tip_error_m=float(tip_err[-1]),
                clipped=r.meta["clipped"], pump=r.meta["pump"], **extra)
