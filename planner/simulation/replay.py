"""Open-loop replay of valve commands on a plant model, and seed 003's robustness score (how far
an open-loop replay drifts when the plant is not the model).

Plant model (one step per fixed time step; everything per actuator unless said otherwise):

* **pressure-compensated valves**: flow = gain·(|u| − db)/(1 − db)·sign(u) for |u| > db, else 0
  (commands clipped to [−1, 1]) — the valve model of :mod:`planner.model.valves`, which the
  feed-forward inverts, so that ``replay(commands(traj))`` reproduces ``traj`` on the nominal
  plant.
* **areas by direction**: stroke rate = flow / A with A = area_a extending, area_b retracting;
  a *single-acting* cylinder meters the oil leaving its piston side while lowering (A = area_a).
* **flow sharing**: every function that draws pump flow (extending, or retracting a
  double-acting cylinder / motor) takes its valve flow from the pump; when the sum exceeds the
  pump's maximum flow (``spec.pump.max_flow`` times the plant's pump factor), all of them are
  slowed by the same factor Q_max/ΣQ (post-compensated valves, LUDV). A single-acting cylinder
  lowering under gravity draws nothing from the pump: it still moves at its valve flow, to tank.
* the stroke is integrated over fixed steps; since the valve flows depend on the commands only,
  the stroke rate is piecewise constant between command instants and each step's displacement is
  the *exact* integral of the held rates over the step (steps need not line up with the command
  grid). The stroke stops at the **end stops** (the strokes at the joint limits — the model is
  defined only inside them), through :func:`planner.simulation.stops.run_to_stops` — the one
  code path of every replay, the plant's and a diagnosis's alike (:func:`commanded` gives the
  free stroke motion it takes to the stops); clipping is reported in ``meta["clipped"]``.
* joint positions from the inverse stroke map (``crane.joint_from_stroke`` + Newton polish);
  an actuator whose stroke did not change stands exactly still (no round-off drift).
* qd, qdd by consistent finite differences of the positions on the step grid (central first
  and second differences; one-sided at the ends). With held commands the true acceleration is a
  train of impulses at the command instants; the differences smear each over one step — what a
  differentiated measurement would show too.
* pressures (for the "measured" output) from the model's dynamics:
  ``crane.hydraulics(q, qd, qdd, payload)`` at the simulated states (:func:`pressures`).

**The plant is the nominal model plus effects** (:mod:`planner.model.effects`): the replay
applies the effects of the commands, start and valves stages (delays and lags, the true start,
valve gains, dead bands, the pump); :func:`planner.simulation.plant.respond` adds the others
(forces, leakage, sensors). :class:`Plant` is a thin constructor of such an effect set for the
robustness study (start mismatch, gain error, pump shortfall, dead band, payload); every
function here takes a Plant or a sequence of effects.

Not modelled: pressure limits (relief valve) and load-dependent flow, hydraulic compliance, the
optional hydraulic transformer of s100f (as in :mod:`planner.feedforward`).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
import time as _time
from dataclasses import dataclass, replace

import numpy as np

from planner.feedforward import commands
from planner.model.valves import steady_flows, valve_params
from planner.model.effects import (FlowGain, GrappleLoad, PumpFlowLimit, StartOffset,
                                        ValveDeadband, ValveSet, as_effects, quasi_static,
                                        valve_commands)
from planner.simulation.stops import run_to_stops
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["Plant", "describe_plant", "replay", "Commanded", "commanded", "clipped_intervals",
           "pressures", "valve_set", "plant_valves",
           "stroke_rates", "stroke_stops", "differences", "default_perturbations", "robustness"]


# ----------------------------------------------------------------------------- plant
@dataclass(frozen=True)
class Plant:
    """Deviations of the "true" plant from the nominal model (defaults: the nominal plant), a
    thin constructor of an effect set (:meth:`effects`):

    q0_offset: (n,) added to the initial configuration [rad | m] (None: no mismatch)
      -> ``start_offset`` on every joint;
    flow_gain_scale: scalar or (n,) factor on every valve's flow gain -> ``flow_gain`` on
      every joint;
    pump_flow_scale: factor on the pump's maximum flow -> ``pump_flow_limit``;
    deadband: scalar or (n,) dead band replacing the spec's (None: the spec's)
      -> ``valve_deadband`` on every joint;
    payload: [kg] for the pressures (None: the spec's load + tool) -> ``grapple_load``.

    The values may lie outside the catalogue's plausible ranges (a perturbation study may ask
    for a bigger pump); they are checked here: gain factors ≥ 0, pump factor > 0, dead bands in
    [0, 1), and the number of per-joint values when the effects are made."""
    q0_offset: tuple | None = None
    flow_gain_scale: float | tuple = 1.0
    pump_flow_scale: float = 1.0
    deadband: float | tuple | None = None
    payload: float | None = None

    def __post_init__(self):
        # store arrays as tuples so the object stays hashable, comparable and printable
        for name in ("q0_offset", "flow_gain_scale", "deadband"):
            v = getattr(self, name)
            if v is not None and np.ndim(v) > 0:
                object.__setattr__(self, name, tuple(float(x) for x in np.ravel(v)))
            elif v is not None:
                object.__setattr__(self, name, float(v))
        if not (self.pump_flow_scale > 0 and math.isfinite(self.pump_flow_scale)):
            raise ValueError(f"Plant.pump_flow_scale must be > 0, got {self.pump_flow_scale}")
        if np.any(np.asarray(self.flow_gain_scale, float) < 0):
            raise ValueError(f"Plant.flow_gain_scale must be >= 0, got {self.flow_gain_scale}")
        if self.deadband is not None and not np.all((np.asarray(self.deadband) >= 0) &
                                                    (np.asarray(self.deadband) < 1)):
            raise ValueError(f"Plant.deadband must lie in [0, 1), got {self.deadband}")

    def effects(self, crane: Crane) -> tuple:
        """The effect set of this plant on ``crane`` (ValueError when a per-joint field has
        the wrong number of values)."""
        names = tuple(crane.names)
        n = len(names)
        out = []
        if self.q0_offset is not None:
            off = _n_vector(self.q0_offset, n, "q0_offset")
            out += [StartOffset.unbounded(j, offset=float(v)) for j, v in zip(names, off)]
        if self.flow_gain_scale != 1.0:
            g = _n_vector(self.flow_gain_scale, n, "flow_gain_scale")
            out += [FlowGain.unbounded(j, scale=float(v)) for j, v in zip(names, g)]
        if self.deadband is not None:
            db = _n_vector(self.deadband, n, "deadband")
            out += [ValveDeadband.unbounded(j, width=float(v)) for j, v in zip(names, db)]
        if self.pump_flow_scale != 1.0:
            out.append(PumpFlowLimit.unbounded(scale=self.pump_flow_scale))
        if self.payload is not None:
            out.append(GrappleLoad.unbounded(mass=self.payload))
        return tuple(out)

    @property
    def nominal(self) -> bool:
        return self == Plant()

    def to_dict(self) -> dict:
        """JSON-ready."""
        return dict(q0_offset=None if self.q0_offset is None else list(self.q0_offset),
                    flow_gain_scale=(list(self.flow_gain_scale)
                                     if isinstance(self.flow_gain_scale, tuple)
                                     else self.flow_gain_scale),
                    pump_flow_scale=self.pump_flow_scale,
                    deadband=list(self.deadband) if isinstance(self.deadband, tuple)
                    else self.deadband,
                    payload=self.payload)

    def __str__(self):
        parts = []
        if self.q0_offset is not None and any(self.q0_offset):
            parts.append("q0+[" + ", ".join(f"{v:.4g}" for v in self.q0_offset) + "]")
        g = self.flow_gain_scale
        if g != 1.0:
            parts.append("gain×" + (f"{g:.4g}" if not isinstance(g, tuple) else
                                    "[" + ", ".join(f"{v:.4g}" for v in g) + "]"))
        if self.pump_flow_scale != 1.0:
            parts.append(f"pump×{self.pump_flow_scale:.4g}")
        if self.deadband is not None:
            parts.append(f"deadband={self.deadband}")
        if self.payload is not None:
            parts.append(f"payload={self.payload:g} kg")
        return "Plant(" + (", ".join(parts) or "nominal") + ")"


def _n_vector(v, n, name):
    a = np.broadcast_to(np.asarray(v, float), (n,)) if np.ndim(v) == 0 else np.asarray(v, float)
    if a.shape != (n,):
        raise ValueError(f"Plant.{name}: expected a scalar or {n} values, got {np.shape(v)}")
    return a


def describe_plant(plant):
    """(JSON-ready form, text) of a Plant or an effect set (a replay's meta, a summary)."""
    if isinstance(plant, Plant):
        return plant.to_dict(), str(plant)
    effects = tuple(plant)
    return ([e.to_dict() for e in effects],
            "Plant(" + (", ".join(map(str, effects)) or "nominal") + ")")


def valve_set(crane: Crane, plant=Plant()) -> ValveSet:
    """The valves-stage effects of ``plant`` (a Plant or a sequence of effects) applied in
    order to the spec's valves: per-valve gain factors and dead bands, the pump factor."""
    vs = ValveSet(flow_gain_scale=np.ones(crane.n),
                  deadband=valve_params(crane).deadband.copy(), pump_flow_scale=1.0)
    for e in as_effects(crane, plant):
        vs = e.valves(crane, vs)        # the default hook changes nothing
    return vs


def plant_valves(crane: Crane, plant=Plant()):
    """(valve data :class:`planner.model.valves.ValveParams`, pump maximum flow [m³/s]) of the
    plant (a Plant or a sequence of effects)."""
    vs = valve_set(crane, plant)
    vp = valve_params(crane)
    vp = replace(vp, flow_gain=vp.flow_gain * vs.flow_gain_scale, deadband=vs.deadband)
    return vp, crane.spec.pump.max_flow * vs.pump_flow_scale


def stroke_stops(crane: Crane):
    """Strokes at the joint limits (the end stops of the replay): (lo, hi), each (n,)."""
    L = crane.limit_arrays()
    x, _ = crane.stroke(np.vstack([L["q_min"], L["q_max"]]))
    return x.min(axis=0), x.max(axis=0)


def stroke_rates(crane: Crane, u, plant=Plant()):
    """Commands (M, n) -> (stroke rates (M, n), pump flow drawn (M,), sharing factor (M,)) on
    the plant (a Plant or a sequence of effects: its valves stage).

    The sharing factor is 1 while the pump keeps up, Q_max/ΣQ when it does not."""
    u = np.atleast_2d(np.asarray(u, float))
    vp, qmax = plant_valves(crane, plant)
    xd, Q, draws = steady_flows(vp, u)                    # single-acting lowering: to tank
    demand = np.sum(np.where(draws, Q, 0.0), axis=1)
    share = np.where(demand > qmax, qmax / np.where(demand > qmax, demand, 1.0), 1.0)
    xd = np.where(draws, xd * share[:, None], xd)
    return xd, np.minimum(demand, qmax), share


# ----------------------------------------------------------------------------- replay
def differences(q, dt):
    """Central first and second differences (qd, qdd) of samples ``q`` (N, n) on a uniform
    grid of step ``dt`` (one-sided at the ends; qdd repeated at the ends)."""
    qd = np.empty_like(q)
    qdd = np.zeros_like(q)
    if len(q) >= 3:
        qd[1:-1] = (q[2:] - q[:-2]) / (2 * dt)
        qdd[1:-1] = (q[2:] - 2 * q[1:-1] + q[:-2]) / dt ** 2
        qdd[0], qdd[-1] = qdd[1], qdd[-2]
    qd[0] = (q[1] - q[0]) / dt
    qd[-1] = (q[-1] - q[-2]) / dt
    return qd, qdd


def _runs(mask):
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.flatnonzero(np.diff(m.astype(int)))
    return list(zip(d[::2], d[1::2]))


@dataclass(frozen=True)
class Commanded:
    """What the commands make of the strokes before the end stops (:func:`commanded`): sample
    times ``t`` (K+1,), ``j`` (K+1,) the row of the valves' grid (the commands' own,
    refined and extended by a delay) in effect at each, ``steps`` (K, n) the stroke
    change of each step as metered (no end stops), the true start ``q_start`` (n,) (start-stage
    effects, clipped into the joint range) and its strokes ``x_start``, ``dt``, ``pump``
    (statistics), ``payload`` (forces-stage effects' load, None: the spec's)."""
    t: np.ndarray
    j: np.ndarray
    steps: np.ndarray
    q_start: np.ndarray
    x_start: np.ndarray
    dt: float
    pump: dict
    payload: float | None


def commanded(crane: Crane, t_u, u, q0, plant=Plant(), dt: float | None = None,
              t_end: float | None = None) -> Commanded:
    """The commands, start and valves stages of :func:`replay` (same arguments): the free
    stroke motion, which :func:`planner.simulation.stops.run_to_stops` takes to the end stops
    from whichever start (the replay's own, or one fitted to a measurement)."""
    t_u = np.asarray(t_u, float).ravel()
    u = np.atleast_2d(np.asarray(u, float))
    q0 = np.asarray(q0, float).ravel()
    n = crane.n
    if u.shape != (t_u.size, n) or q0.shape != (n,):
        raise ValueError(f"replay: expected t_u (M,), u (M, {n}), q0 ({n},); got "
                         f"{t_u.shape}, {u.shape}, {q0.shape}")
    if t_u.size < 1 or np.any(np.diff(t_u) <= 0) or not np.all(np.isfinite(t_u)):
        raise ValueError("replay: t_u must be finite and strictly increasing")
    if not np.all(np.isfinite(u)):
        raise ValueError("replay: non-finite command")
    if dt is None:
        if t_u.size < 2:
            raise ValueError("replay: one command instant needs an explicit dt")
        dt = float(np.min(np.diff(t_u)))
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"replay: dt must be a positive number of seconds, got {dt}")
    t0 = float(t_u[0])
    t_end = float(t_u[-1]) if t_end is None else float(t_end)
    K = int(math.floor((t_end - t0) / dt + 1e-9))
    if K < 1:
        raise ValueError(f"replay: span {t_end - t0:g} s is shorter than one step of {dt:g} s")
    t = t0 + dt * np.arange(K + 1)

    effects = quasi_static(as_effects(crane, plant))
    # what the valves act on (delays, lags)
    # (the default hooks change nothing; a delay or lag carries the last command past t_u[-1])
    t_u, u, u_valves = valve_commands(crane, effects, t_u, u, t_end)
    # initial state (mismatch), clipped into the joint range
    L = crane.limit_arrays()
    q_start = q0
    for e in effects:
        q_start = e.start(crane, q_start)
    q_start = np.clip(q_start, L["q_min"], L["q_max"])

    # held stroke rates per command interval (valves, dead band, areas, flow sharing)
    _, qmax = plant_valves(crane, effects)
    xd, qpump, share = stroke_rates(crane, u_valves, effects)
    # exact integral of the held rates at the grid instants: X(τ) = X_j + xd_j·(τ − T_j)
    X = np.vstack([np.zeros((1, n)), np.cumsum(xd[:-1] * np.diff(t_u)[:, None], axis=0)])
    # command in effect at each step instant; instants within round-off of a command instant
    # are snapped onto it (t0 + k·dt vs t_u[k])
    j = np.clip(np.searchsorted(t_u, t + 1e-9 * dt, side="right") - 1, 0, t_u.size - 1)
    t = np.where(np.abs(t - t_u[j]) <= 1e-9 * dt, t_u[j], t)
    Xt = X[j] + xd[j] * (t - t_u[j])[:, None]
    x_start, _ = crane.stroke(q_start)
    # pump statistics over the replayed span (interval k of the commands covers its hold time)
    Tk = np.diff(np.append(t_u, max(t_end, t_u[-1])))
    payload = total = crane.spec.payload.total
    for e in effects:
        payload = e.payload(crane, payload)
    pump = dict(peak_flow_m3s=float(np.max(qpump)), short_s=float(np.sum(Tk[share < 1.0])),
                min_share=float(np.min(share)), max_flow_m3s=qmax)
    return Commanded(t=t, j=j, steps=np.diff(Xt, axis=0), q_start=q_start,
                     x_start=np.clip(np.ravel(x_start), *stroke_stops(crane)), dt=dt,
                     pump=pump, payload=None if payload == total else payload)


def clipped_intervals(t, at_stop, names) -> dict:
    """joint -> [(t0, t1)] of the runs of samples at an end stop while commanded beyond it."""
    clipped = {}
    for i, name in enumerate(names):
        for a, b in _runs(at_stop[:, i]):
            clipped.setdefault(name, []).append((float(t[a - 1] if a else t[a]),
                                                 float(t[b - 1])))
    return clipped


def replay(crane: Crane, t_u, u, q0, plant=Plant(), dt: float | None = None,
           t_end: float | None = None, joint_names=None) -> Trajectory:
    """Open-loop replay of valve commands on the plant (see the module doc): a :class:`Plant`
    or a sequence of effects, of which the commands, start and valves stages are applied.

    ``t_u`` (M,) strictly increasing command instants [s], ``u`` (M, n): u[k] is held over
    [t_u[k], t_u[k+1]) (zero-order hold); the last row is held until ``t_end`` (default t_u[-1],
    i.e. the last row is unused — as in :func:`planner.feedforward.predict_motion`). ``q0``: the
    nominal initial configuration (the start-stage effects move it, e.g. ``plant.q0_offset``
    is added; the result is clipped to the joint limits). ``dt``: the fixed step [s] (default: the command period, the shortest
    interval of ``t_u``); the grid is t_u[0] + k·dt up to t_end. The step is exact for any dt
    (held rates integrated exactly), so smaller steps only give more samples. The end stops:
    :func:`planner.simulation.stops.run_to_stops` (the plant's one code path for them).

    Returns a :class:`Trajectory` (quintic interpolation through q and the difference-based qd,
    qdd) with ``u`` = the command in effect at each sample (as commanded, before the
    commands-stage effects), and ``meta``: plant, plant_str, payload (the forces-stage
    effects' load in the grapple, None: the spec's), dt, clipped
    (joint -> [(t0, t1)] at an end stop while commanded beyond it), pump (peak flow drawn,
    time the pump was short of the demand, smallest sharing factor)."""
    c = commanded(crane, t_u, u, q0, plant, dt, t_end)
    u = np.atleast_2d(np.asarray(u, float))
    L = crane.limit_arrays()
    lo, hi = stroke_stops(crane)
    run = run_to_stops(c.x_start, c.steps, lo, hi)
    x = run.x
    K, n = c.steps.shape
    # joint positions: inverse stroke map + polish; unchanged strokes stand exactly still
    q = crane.joint_from_stroke(x)
    q[0] = c.q_start
    for _ in range(2):
        xq, d = crane.stroke(q[1:])
        q[1:] -= (xq - x[1:]) / d
    kk = np.arange(K + 1)[:, None]
    moved = np.vstack([np.ones((1, n), bool), x[1:] != x[:-1]])
    last = np.maximum.accumulate(np.where(moved, kk, 0), axis=0)
    q = np.take_along_axis(q, last, axis=0)
    q = np.clip(q, L["q_min"], L["q_max"])
    qd, qdd = differences(q, c.dt)

    names = tuple(joint_names) if joint_names else tuple(crane.names)
    as_dict, as_text = describe_plant(plant)
    meta = dict(plant=as_dict, plant_str=as_text, dt=c.dt, payload=c.payload,
                clipped=clipped_intervals(c.t, run.at_stop, names), pump=c.pump)
    # the command in effect at each sample (c.j counts on the valves' grid, which a delay
    # refines and extends)
    t_u = np.asarray(t_u, float).ravel()
    k = np.clip(np.searchsorted(t_u, c.t + 1e-9 * c.dt, side="right") - 1, 0, t_u.size - 1)
    return Trajectory(c.t, q, qd, qdd, joint_names=names, method="replay",
                      interpolation="quintic", u=np.atleast_2d(np.asarray(u, float))[k],
                      meta=meta)


def pressures(crane: Crane, sim: Trajectory, payload=None):
    """Chamber pressures p_a, p_b (N, n) [Pa] at the samples of a replay, from the model's
    inverse dynamics (``payload`` default: the replay's plant payload, else the spec's)."""
    if payload is None:
        payload = sim.meta.get("payload")
    h = crane.hydraulics(sim.q, sim.qd, sim.qdd, payload)
    return np.atleast_2d(h["p_a"]), np.atleast_2d(h["p_b"])



# ----------------------------------------------------------------------------- robustness
def default_perturbations(crane: Crane, angle=math.radians(1.0), length=0.02, gain=0.02,
                          pump=0.10) -> dict:
    """Seed 003's lesson as a default set: initial mismatch ±``angle`` on each revolute joint
    and ±``length`` on each prismatic one, flow-gain error ±``gain`` on every valve, pump flow
    −``pump``, and every mismatch combined with each gain error (the drift of a replay with
    both adds up). Returns name -> :class:`Plant`."""
    out = {}
    for i, j in enumerate(crane.spec.joints):
        for sgn in (1, -1):
            off = np.zeros(crane.n)
            off[i] = sgn * (angle if j.revolute else length)
            lab = (f"{sgn * math.degrees(angle):+g}deg" if j.revolute
                   else f"{sgn * 100 * length:+g}cm")
            out[f"q0:{j.name}{lab}"] = Plant(q0_offset=off)
    singles = dict(out)
    out[f"gain+{100 * gain:g}%"] = Plant(flow_gain_scale=1 + gain)
    out[f"gain-{100 * gain:g}%"] = Plant(flow_gain_scale=1 - gain)
    out[f"pump-{100 * pump:g}%"] = Plant(pump_flow_scale=1 - pump)
    for name, p in singles.items():
        for sgn in (1, -1):
            out[f"{name}&gain{sgn * 100 * gain:+g}%"] = Plant(q0_offset=p.q0_offset,
                                                            flow_gain_scale=1 + sgn * gain)
    return out


def robustness(crane: Crane, traj: Trajectory, perturbations=None, rate: float = 50.0,
               series: bool = False) -> dict:
    """Replay the feed-forward of ``traj`` (:func:`planner.feedforward.commands` at ``rate``)
    open loop on perturbed plants and record the tip drift vs the plan.

    ``perturbations``: name -> :class:`Plant` (or a list of Plants, named by ``str``); default
    :func:`default_perturbations`. The tip error is the Euclidean distance [m] between the
    replayed and the planned tip at every control instant (the plan holds its final state past
    its end). Returns a JSON-ready dict: ``score_m`` (worst max tip error over all
    perturbations), ``worst`` (its name), ``nominal`` (the unperturbed replay: the feed-forward's
    own error, e.g. pump shortage), ``perturbations`` (name -> max_tip_error_m, t_max_s,
    final_tip_error_m, initial_tip_error_m, final_joint_error, clipped, pump_short_s, plant),
    ``worst_final_m``. ``series=True`` adds ``t`` and per-perturbation ``tip_error_m`` lists
    and ``envelope_m`` (the largest error over the perturbations at each instant)."""
    t0 = _time.perf_counter()
    if perturbations is None:
        perturbations = default_perturbations(crane)
    elif not isinstance(perturbations, dict):
        perturbations = {str(p): p for p in perturbations}
    ff = commands(crane, traj, rate)
    q_plan = traj.sample(ff.t)[0]
    tip_plan = crane.fk(q_plan)
    cases = dict(nominal=Plant(), **{k: v for k, v in perturbations.items() if k != "nominal"})
    res, errs = {}, {}
    for name, plant in cases.items():
        sim = replay(crane, ff.t, ff.u, traj.q[0], plant)
        e = np.linalg.norm(crane.fk(sim.q) - tip_plan, axis=1)
        k = int(np.argmax(e))
        errs[name] = e
        res[name] = dict(max_tip_error_m=float(e[k]), t_max_s=float(ff.t[k] - ff.t[0]),
                         final_tip_error_m=float(e[-1]), initial_tip_error_m=float(e[0]),
                         final_joint_error={j: float(v) for j, v in
                                            zip(crane.names, sim.q[-1] - q_plan[-1])},
                         clipped={j: [list(iv) for iv in v]
                                  for j, v in sim.meta["clipped"].items()},
                         pump_short_s=sim.meta["pump"]["short_s"], plant=plant.to_dict())
    nominal = res.pop("nominal")
    pool = res or dict(nominal=nominal)
    worst = max(pool, key=lambda k: pool[k]["max_tip_error_m"])
    out = dict(score_m=max(pool[worst]["max_tip_error_m"], nominal["max_tip_error_m"]),
               worst=worst, worst_final_m=max(v["final_tip_error_m"] for v in pool.values()),
               nominal=nominal, perturbations=res, rate_hz=float(rate),
               feedforward_ok=ff.ok, duration_s=traj.duration,
               solve_time_s=_time.perf_counter() - t0)
    if series:
        out["t"] = (ff.t - ff.t[0]).tolist()
        out["tip_error_m"] = {k: v.tolist() for k, v in errs.items()}
        out["envelope_m"] = np.max(np.vstack([errs[k] for k in pool] if res else
                                             [errs["nominal"]]), axis=0).tolist()
    return out
