"""Hidden-effect trials: recordings of a plant with a hidden effect, for testing the discrepancy
workflow (:mod:`planner.calibration.discrepancy`), which sees only the measured CSV and the commands.

:func:`excitation` builds the commanded trajectory of a recording: rest-to-rest moves (Ruckig,
every joint at once) between random poses in the inner part of the joint ranges — the first
one across the whole inner range at full speed, the others at random speeds (30–100 % of the
limits) — with holds of 0.5–2 s between them: the kind of test sequence a calibration run uses
(motion in both directions, several speeds, the pump at its limit, loads held at rest).
:func:`hidden_trial` draws an effect and a realistic magnitude, records the plant with it and
with sensor noise, and returns the recording with the truth.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.simulation.effects import CATALOGUE, Effect, make
from planner.feedforward import commands
from planner.methods.ruckig import rest_to_rest
from planner.trajectory import Trajectory

__all__ = ["excitation", "Recording", "record", "hidden_trial", "trackable",
           "TRIAL_MAGNITUDES"]

# Realistic magnitudes of the hidden effects in the trials: (low, high) of |value − neutral| in
# the unit given per line — several relative to the machine, so that a lab crane and a log
# loader get comparable effects — drawn uniformly, sign random where both signs are physical.
# Assumed — typical of a worn or
# mis-calibrated mobile crane, and large enough to stand out of seed 001's sensor noise over a
# 60 s recording (the workflow's job is to name effects that are there, not to find the
# undetectable).
TRIAL_MAGNITUDES = {
    "joint_offset": (math.radians(1.0), math.radians(3.0)),  # rad; prismatic: same in m
    "flow_gain": (0.05, 0.20),            # relative gain error
    "valve_deadband": (0.08, 0.20),       # absolute width (spec's is smaller or zero)
    "valve_lag": (0.08, 0.25),            # s
    "time_delay": (0.06, 0.20),           # s
    "pump_flow_limit": (0.15, 0.40),      # shortfall relative to the sequence's peak demand
    "leakage": (0.5e-3, 2e-3),            # m/s: drift speed of the held cylinder at 10 MPa
    "coulomb_friction": (0.3, 1.0),       # × 5 % of the actuator's force at 10 MPa
    "viscous_friction": (0.3, 1.0),       # × the coefficient giving 1 MPa at full speed
    "payload_mass": (0.3, 1.0),           # × the spec's payload + tool (lighter: ≤ the load)
    "actuator_mass": (0.1, 0.4),          # × the mass of the link the actuator drives
    "pressure_offset": (0.3e6, 1.0e6),    # Pa
}


@dataclass
class Recording:
    """A measured recording on the sample grid: t (N,), commands u (N, n) in effect at t,
    positions q (N, n), pressures p_a, p_b (N, n) [Pa] or None (positions only)."""
    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    p_a: np.ndarray | None = None
    p_b: np.ndarray | None = None

    @classmethod
    def from_csv(cls, path, crane, plan: Trajectory | None = None) -> "Recording":
        """Read a measured CSV. Without command columns, the commands are the nominal
        feed-forward of ``plan`` (the commanded trajectory) at the file's sample rate, which
        must then start with the plan."""
        from planner.simulation.replay import read_measured_csv
        d = read_measured_csv(path, tuple(crane.names))
        u = d["u"]
        if u is None:
            if plan is None:
                raise ValueError(f"{path}: line 1: no command columns u_<joint>; give the "
                                 "commanded trajectory (--trajectory) to derive them")
            t = d["t"]
            dt = float(np.median(np.diff(t)))
            if abs(t[0] - plan.t[0]) > 1e-6 * max(1.0, abs(t[0])):
                raise ValueError(f"{path}: line 2, column 1 (t): the recording starts at "
                                 f"{t[0]:g} s, the commanded trajectory at {plan.t[0]:g} s; "
                                 "without u_<joint> columns they must start together")
            ff = commands(crane, plan, 1.0 / dt)
            k = np.clip(np.round((t - ff.t[0]) / dt).astype(int), 0, len(ff.t) - 1)
            u = ff.u[k]
        return cls(d["t"], u, d["q"], d["p_a"], d["p_b"])

    def to_csv(self, path, crane):
        from planner.io import atomic_write_text
        names = tuple(crane.names)
        cols = (["t"] + [f"u_{j}" for j in names] + [f"q_{j}" for j in names])
        blocks = [self.t[:, None], self.u, self.q]
        if self.p_a is not None:
            cols += [f"p_{j}_{s}" for j in names for s in ("a", "b")]
            P = np.empty((len(self.t), 2 * crane.n))
            P[:, 0::2], P[:, 1::2] = self.p_a, self.p_b
            blocks.append(P)
        M = np.hstack(blocks)
        lines = [",".join(cols)] + [",".join(f"{v:.10g}" for v in row) for row in M]
        atomic_write_text(path, "\n".join(lines) + "\n")


def excitation(crane, duration: float = 60.0, rate: float = 50.0, seed: int = 0,
               margin: float = 0.15) -> tuple[Trajectory, object]:
    """(plan, feed-forward) of a test sequence at least ``duration`` [s] long (see module doc).
    Poses are drawn in [margin, 1 − margin] of every joint range."""
    rng = np.random.default_rng(seed)
    L = crane.limit_arrays()
    lo = L["q_min"] + margin * (L["q_max"] - L["q_min"])
    hi = L["q_max"] - margin * (L["q_max"] - L["q_min"])
    q = 0.5 * (lo + hi)
    ts, qs, qds, qdds = [np.zeros(1)], [q[None]], [np.zeros((1, crane.n))], \
        [np.zeros((1, crane.n))]
    t_now = 0.0

    def hold(T):
        nonlocal t_now
        k = max(1, int(round(T * rate)))
        tt = t_now + np.arange(1, k + 1) / rate
        ts.append(tt)
        qs.append(np.repeat(qs[-1][-1:], k, axis=0))
        qds.append(np.zeros((k, crane.n)))
        qdds.append(np.zeros((k, crane.n)))
        t_now = float(tt[-1])

    hold(rng.uniform(0.5, 1.0))
    first = True
    while t_now < duration:
        if first:   # one long full-speed move of every joint: the pump gets to its limit
            side = rng.uniform(size=crane.n) < 0.5
            goal, scale = np.where(side, lo, hi), 1.0
            first = False
        else:
            goal, scale = rng.uniform(lo, hi), float(rng.uniform(0.3, 1.0))
        seg = rest_to_rest(crane, q, goal, scale=scale).trajectory
        ts.append(t_now + seg.t[1:] - seg.t[0])
        qs.append(seg.q[1:])
        qds.append(seg.qd[1:])
        qdds.append(seg.qdd[1:])
        t_now = float(ts[-1][-1])
        q = goal
        hold(rng.uniform(0.5, 2.0))
    plan = Trajectory(np.concatenate(ts), np.vstack(qs), np.vstack(qds), np.vstack(qdds),
                      joint_names=tuple(crane.names), method="excitation",
                      meta=dict(seed=seed, duration=duration))
    return plan, commands(crane, plan, rate)


def trackable(crane, plan: Trajectory, margin: float = 0.8, rate: float = 50.0) -> Trajectory:
    """``plan`` slowed uniformly until its nominal feed-forward asks at most ``margin`` of
    every valve (|u|) and of the pump: a plan the nominal plant can follow open loop (as every
    library entry is), for judging re-planned feed-forward on a calibrated model."""
    from planner.methods.nlp import stretch
    from planner.simulation.replay import stroke_rates
    ff = commands(crane, plan, rate)
    need = max(float(np.max(np.abs(ff.u_raw))),
               float(np.max(stroke_rates(crane, ff.u_raw)[1])) / crane.spec.pump.max_flow)
    if need <= margin:
        return plan
    return stretch(plan, plan.duration * need / margin)


def record(crane, plan: Trajectory, ff, effects=(), noise=True, seed: int = 0,
           positions_only: bool = False) -> Recording:
    """Replay ``ff`` on the plant with ``effects`` from the plan's start; sensor noise at
    seed 001's levels (``noise`` as in :func:`planner.simulation.replay.measured_table`)."""
    from planner.simulation.plant import respond
    from planner.simulation.replay import add_noise
    r = respond(crane, ff.t, ff.u, plan.q[0], effects, t_end=ff.t[-1])
    q, pa, pb = add_noise(crane, r.q, r.p_a, r.p_b, noise, seed)
    if positions_only:
        pa = pb = None
    return Recording(r.t, r.u, q, pa, pb)


# Joints on which an effect leaves no trace in joint positions and actuator pressures, so no
# data of this kind can name it: a position offset of the slew about its vertical axis (gravity
# does not depend on it; seed 001 needed an external calibrator for such offsets), and leakage
# of the slew drive (it holds no gravity load, so nothing drives a leak), and the slew drive's
# own mass (lumped near the axis, it adds almost nothing to the slew inertia). Trials do not draw
# these; the catalogue still offers them (a tilted machine would show them).
UNOBSERVABLE = {("joint_offset", 0), ("leakage", 0), ("actuator_mass", 0)}


def observable_joints(crane, name: str) -> list[str]:
    return [j for i, j in enumerate(crane.names) if (name, i) not in UNOBSERVABLE]


def _draw(crane, name: str, rng, joint=None, peak_demand: float = 1.0) -> Effect:
    lo, hi = TRIAL_MAGNITUDES[name]
    mag = float(rng.uniform(lo, hi))
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    cls = CATALOGUE[name]
    if cls.per_joint and joint is None:
        js = observable_joints(crane, name)
        joint = js[int(rng.integers(len(js)))]
    i = list(crane.names).index(joint) if joint else None
    act = crane.spec.joints[i].actuator if i is not None else None
    if name == "joint_offset":   # prismatic: the same number in m (1.7–5.2 cm)
        v = dict(offset=sign * mag)
    elif name == "flow_gain":
        v = dict(scale=1.0 + sign * mag)
    elif name == "valve_deadband":
        v = dict(width=min(act.deadband + mag, 0.4))
    elif name in ("valve_lag",):
        v = dict(tau=mag)
    elif name == "time_delay":
        v = dict(delay=mag)
    elif name == "pump_flow_limit":
        # a pump short of what the test sequence asks at its peak (else it never shows)
        v = dict(scale=max(peak_demand * (1.0 - mag), 0.1))
    elif name == "leakage":      # C = v·A / p: the drift speed at 10 MPa above tank
        v = dict(coefficient=mag * act.area_a / 10e6)
    elif name == "coulomb_friction":
        v = dict(force=min(mag * 0.05 * 10e6 * act.area_a, 3.0e4))
    elif name == "viscous_friction":
        vmax = act.flow_gain / act.area_a
        v = dict(coefficient=min(mag * 1e6 * act.area_a / vmax, 5.0e5))
    elif name == "payload_mass":
        m = mag * crane.spec.payload.total
        v = dict(mass=m if sign > 0 else -min(m, crane.spec.payload.mass))
    elif name == "actuator_mass":
        v = dict(mass=mag * crane.spec.joints[i].mass)
    elif name == "pressure_offset":
        v = dict(offset_a=sign * mag) if rng.uniform() < 0.5 else dict(offset_b=sign * mag)
    else:  # pragma: no cover - every catalogue name is handled above
        raise ValueError(name)
    return make(name, joint, **v)


def hidden_trial(crane, effect: str | None, seed: int, duration: float = 60.0,
                 joint: str | None = None, noise=True):
    """(recording, plan, feed-forward, truth) — ``truth`` the injected effect (None: clean)."""
    if effect is not None and effect not in CATALOGUE:
        raise ValueError(f"unknown effect {effect!r}; known: {', '.join(CATALOGUE)}")
    rng = np.random.default_rng(seed + 7919)
    plan, ff = excitation(crane, duration, seed=seed)
    peak = 1.0
    if effect == "pump_flow_limit":
        from planner.simulation.replay import stroke_rates
        peak = float(np.max(stroke_rates(crane, ff.u)[1])) / crane.spec.pump.max_flow
    truth = _draw(crane, effect, rng, joint, peak) if effect else None
    rec = record(crane, plan, ff, (truth,) if truth else (), noise=noise, seed=seed)
    return rec, plan, ff, truth
