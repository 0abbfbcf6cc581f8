"""Open-loop replay of valve commands on a plant model, the measured-data CSV, and seed 003's
robustness score (how far an open-loop replay drifts when the plant is not the model).

Plant model (one step per fixed time step; everything per actuator unless said otherwise):

* **pressure-compensated valves**: flow = gain·(|u| − db)/(1 − db)·sign(u) for |u| > db, else 0
  (commands clipped to [−1, 1]) — the valve convention of :mod:`planner.feedforward`, whose
  helpers are reused (``valve_parameters``, ``_command_to_stroke_rate``), so that
  ``replay(commands(traj))`` reproduces ``traj`` on the nominal plant.
* **areas by direction**: stroke rate = flow / A with A = area_a extending, area_b retracting;
  a *single-acting* cylinder meters the oil leaving its piston side while lowering (A = area_a).
* **flow sharing**: every function that draws pump flow (extending, or retracting a
  double-acting cylinder / motor) takes its valve flow from the pump; when the sum exceeds the
  pump's maximum flow (``spec.pump.max_flow``·``pump_flow_scale``), all of them are slowed by the
  same factor Q_max/ΣQ (post-compensated valves, LUDV). A single-acting cylinder lowering under
  gravity draws nothing from the pump: it still moves at its valve flow, to tank.
* the stroke is integrated over fixed steps; since the valve flows depend on the commands only,
  the stroke rate is piecewise constant between command instants and each step's displacement is
  the *exact* integral of the held rates over the step (steps need not line up with the command
  grid). The stroke stops at the **end stops** (the strokes at the joint limits — the model is
  defined only inside them); clipping is reported in ``meta["clipped"]``.
* joint positions from the inverse stroke map (``crane.joint_from_stroke`` + Newton polish);
  an actuator whose stroke did not change stands exactly still (no round-off drift).
* qd, qdd by consistent finite differences of the positions on the step grid (central first
  and second differences; one-sided at the ends). With held commands the true acceleration is a
  train of impulses at the command instants; the differences smear each over one step — what a
  differentiated measurement would show too.
* pressures (for the "measured" output) from the model's dynamics:
  ``crane.hydraulics(q, qd, qdd, payload)`` at the simulated states (:func:`pressures`).

Not modelled: pressure limits (relief valve) and load-dependent flow, hydraulic compliance, the
optional hydraulic transformer of s100f (as in :mod:`planner.feedforward`). The catalogue of
hidden effects (friction, leakage, …) is meant to augment this plant (DESIGN "Core ideas" 3);
:class:`Plant` covers the parameter perturbations of the robustness study.
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, replace

import numpy as np

from planner.feedforward import _command_to_stroke_rate, commands, valve_parameters
from planner.io import atomic_write_text
from planner.trajectory import Trajectory

__all__ = ["Plant", "replay", "pressures", "measured_table", "write_measured_csv",
           "read_measured_csv", "default_perturbations", "robustness", "simulate_to_csv",
           "NOISE_DEFAULTS"]

# seed 001's sensor accuracies (resolvers ±0.1°, pressure transducers 0.17 MPa); telescope: 2 mm
NOISE_DEFAULTS = dict(angle=math.radians(0.1), length=0.002, pressure=0.17e6)


# ----------------------------------------------------------------------------- plant
@dataclass(frozen=True)
class Plant:
    """Deviations of the "true" plant from the nominal model (defaults: the nominal plant).

    q0_offset: (n,) added to the initial configuration [rad | m] (None: no mismatch);
    flow_gain_scale: scalar or (n,) factor on every valve's flow gain;
    pump_flow_scale: factor on the pump's maximum flow;
    deadband: scalar or (n,) dead band replacing the spec's (None: the spec's);
    payload: [kg] for the pressures (None: the spec's load + tool)."""
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


def _plant_valves(crane, plant: Plant):
    vp = valve_parameters(crane)
    n = crane.n
    vp = replace(vp, flow_gain=vp.flow_gain * _n_vector(plant.flow_gain_scale, n,
                                                        "flow_gain_scale"))
    if plant.deadband is not None:
        vp = replace(vp, deadband=_n_vector(plant.deadband, n, "deadband").copy())
    return vp


def _stroke_stops(crane):
    """Strokes at the joint limits (the end stops of the replay): (lo, hi), each (n,)."""
    L = crane.limit_arrays()
    x, _ = crane.stroke(np.vstack([L["q_min"], L["q_max"]]))
    return x.min(axis=0), x.max(axis=0)


def stroke_rates(crane, u, plant: Plant = Plant()):
    """Commands (M, n) -> (stroke rates (M, n), pump flow drawn (M,), sharing factor (M,)).

    The sharing factor is 1 while the pump keeps up, Q_max/ΣQ when it does not."""
    u = np.atleast_2d(np.asarray(u, float))
    vp = _plant_valves(crane, plant)
    xd = _command_to_stroke_rate(u, vp)
    area = np.where(u > 0, vp.area_extend, vp.area_retract)
    Q = np.abs(xd) * area
    draws = (u > 0) | ~vp.single                         # single-acting lowering: to tank
    demand = np.sum(np.where(draws, Q, 0.0), axis=1)
    qmax = crane.spec.pump.max_flow * plant.pump_flow_scale
    share = np.where(demand > qmax, qmax / np.where(demand > qmax, demand, 1.0), 1.0)
    xd = np.where(draws, xd * share[:, None], xd)
    return xd, np.minimum(demand, qmax), share


# ----------------------------------------------------------------------------- replay
def _differences(q, dt):
    """Central first and second differences on a uniform grid (one-sided at the ends)."""
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


def replay(crane, t_u, u, q0, plant: Plant = Plant(), dt: float | None = None,
           t_end: float | None = None, joint_names=None) -> Trajectory:
    """Open-loop replay of valve commands on the plant (see the module doc).

    ``t_u`` (M,) strictly increasing command instants [s], ``u`` (M, n): u[k] is held over
    [t_u[k], t_u[k+1]) (zero-order hold); the last row is held until ``t_end`` (default t_u[-1],
    i.e. the last row is unused — as in :func:`planner.feedforward.predict_motion`). ``q0``: the
    nominal initial configuration (``plant.q0_offset`` is added; the result is clipped to the
    joint limits). ``dt``: the fixed step [s] (default: the command period, the shortest
    interval of ``t_u``); the grid is t_u[0] + k·dt up to t_end. The step is exact for any dt
    (held rates integrated exactly), so smaller steps only give more samples.

    Returns a :class:`Trajectory` (quintic interpolation through q and the difference-based qd,
    qdd) with ``u`` = the command in effect at each sample, and ``meta``: plant, dt, clipped
    (joint -> [(t0, t1)] at an end stop while commanded beyond it), pump (peak flow drawn,
    time the pump was short of the demand, smallest sharing factor)."""
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

    # initial state (mismatch), clipped into the joint range
    L = crane.limit_arrays()
    off = np.zeros(n) if plant.q0_offset is None else _n_vector(plant.q0_offset, n, "q0_offset")
    q_start = np.clip(q0 + off, L["q_min"], L["q_max"])

    # held stroke rates per command interval (valves, dead band, areas, flow sharing)
    xd, qpump, share = stroke_rates(crane, u, plant)
    # exact integral of the held rates at the grid instants: X(τ) = X_j + xd_j·(τ − T_j)
    X = np.vstack([np.zeros((1, n)), np.cumsum(xd[:-1] * np.diff(t_u)[:, None], axis=0)])
    # command in effect at each step instant; instants within round-off of a command instant
    # are snapped onto it (t0 + k·dt vs t_u[k])
    j = np.clip(np.searchsorted(t_u, t + 1e-9 * dt, side="right") - 1, 0, t_u.size - 1)
    t = np.where(np.abs(t - t_u[j]) <= 1e-9 * dt, t_u[j], t)
    Xt = X[j] + xd[j] * (t - t_u[j])[:, None]
    dx = np.diff(Xt, axis=0)                                   # (K, n) per step

    x_start, _ = crane.stroke(q_start)
    lo, hi = _stroke_stops(crane)
    x_start = np.clip(x_start, lo, hi)
    x = x_start[None, :] + np.vstack([np.zeros((1, n)), np.cumsum(dx, axis=0)])
    tol = 1e-12
    at_stop = np.zeros((K + 1, n), bool)
    out = np.flatnonzero(np.any((x < lo - tol) | (x > hi + tol), axis=0))
    if out.size:                                               # the sequential part, rarely
        xs = x[:, out].copy()
        lo_o, hi_o = lo[out], hi[out]
        for k in range(K):
            nxt = xs[k] + dx[k, out]
            c = np.clip(nxt, lo_o, hi_o)
            at_stop[k + 1, out] = c != nxt
            xs[k + 1] = c
        x[:, out] = xs

    # joint positions: inverse stroke map + polish; unchanged strokes stand exactly still
    q = crane.joint_from_stroke(x)
    q[0] = q_start
    for _ in range(2):
        xq, d = crane.stroke(q[1:])
        q[1:] -= (xq - x[1:]) / d
    kk = np.arange(K + 1)[:, None]
    moved = np.vstack([np.ones((1, n), bool), x[1:] != x[:-1]])
    last = np.maximum.accumulate(np.where(moved, kk, 0), axis=0)
    q = np.take_along_axis(q, last, axis=0)
    q = np.clip(q, L["q_min"], L["q_max"])
    qd, qdd = _differences(q, dt)

    names = tuple(joint_names) if joint_names else tuple(crane.names)
    clipped = {}
    for i in range(n):
        for a, b in _runs(at_stop[:, i]):
            clipped.setdefault(names[i], []).append((float(t[a - 1] if a else t[a]),
                                                     float(t[b - 1])))
    # pump statistics over the replayed span (interval k of the commands covers its hold time)
    Tk = np.diff(np.append(t_u, max(t_end, t_u[-1])))
    short = float(np.sum(Tk[share < 1.0]))
    meta = dict(plant=plant.to_dict(), plant_str=str(plant), dt=dt,
                payload=plant.payload, clipped=clipped,
                pump=dict(peak_flow_m3s=float(np.max(qpump)), short_s=short,
                          min_share=float(np.min(share)),
                          max_flow_m3s=crane.spec.pump.max_flow * plant.pump_flow_scale))
    return Trajectory(t, q, qd, qdd, joint_names=names, method="replay",
                      interpolation="quintic", u=u[j], meta=meta)


def pressures(crane, sim: Trajectory, payload=None):
    """Chamber pressures p_a, p_b (N, n) [Pa] at the samples of a replay, from the model's
    inverse dynamics (``payload`` default: the replay's plant payload, else the spec's)."""
    if payload is None:
        payload = sim.meta.get("payload")
    h = crane.hydraulics(sim.q, sim.qd, sim.qdd, payload)
    return np.atleast_2d(h["p_a"]), np.atleast_2d(h["p_b"])


# ----------------------------------------------------------------------------- measured CSV
def _noise_levels(noise):
    if noise is None or noise is False:
        return None
    levels = dict(NOISE_DEFAULTS)
    if isinstance(noise, dict):
        bad = set(noise) - set(levels)
        if bad:
            raise ValueError(f"noise: unknown key(s) {sorted(bad)}; allowed: {sorted(levels)}")
        levels.update({k: float(v) for k, v in noise.items()})
    elif noise is not True:
        raise ValueError("noise must be None/False, True (seed 001's levels) or a dict "
                         f"with keys {sorted(levels)}")
    return levels


def add_noise(crane, q, p_a, p_b, noise=None, seed: int = 0):
    """Sensor readings (new arrays) with Gaussian noise at ``noise``'s levels (see
    :func:`measured_table`): q (N, n) per joint type, p_a, p_b (N, n) [Pa]; drawn from
    ``numpy.random.default_rng(seed)`` in that order (deterministic)."""
    q, p_a, p_b = np.array(q, float), np.array(p_a, float), np.array(p_b, float)
    levels = _noise_levels(noise)
    if levels is not None:
        rng = np.random.default_rng(seed)
        sq = np.array([levels["angle"] if j.revolute else levels["length"]
                       for j in crane.spec.joints])
        q = q + rng.normal(size=q.shape) * sq
        p_a = p_a + rng.normal(size=p_a.shape) * levels["pressure"]
        p_b = p_b + rng.normal(size=p_b.shape) * levels["pressure"]
    return q, p_a, p_b


def measured_table(crane, sim: Trajectory, u_at_samples=None, noise=None, seed: int = 0,
                   payload=None):
    """(column names, (N, cols) array) of the measured-data CSV contract (see
    :func:`write_measured_csv`)."""
    n = crane.n
    names = tuple(crane.names)
    u = sim.u if u_at_samples is None else np.atleast_2d(np.asarray(u_at_samples, float))
    if u is None or u.shape != sim.q.shape:
        raise ValueError(f"measured_table: commands needed at every sample, shape {sim.q.shape}")
    pa, pb = pressures(crane, sim, payload)
    q, pa, pb = add_noise(crane, sim.q, pa, pb, noise, seed)
    cols = (["t"] + [f"u_{j}" for j in names] + [f"q_{j}" for j in names]
            + [f"p_{j}_{s}" for j in names for s in ("a", "b")])
    P = np.empty((len(sim.t), 2 * n))
    P[:, 0::2], P[:, 1::2] = pa, pb
    return cols, np.hstack([sim.t[:, None], u, q, P])


def write_measured_csv(path, crane, traj_sim: Trajectory, u_at_samples=None, noise=None,
                       seed: int = 0, payload=None) -> list:
    """Write the measured-data CSV (CONTRACT, DESIGN.md): header; ``t`` [s]; ``u_<joint>``
    (command in effect at t); ``q_<joint>`` [rad | m]; ``p_<joint>_a``, ``p_<joint>_b`` [Pa]
    for every actuator (rotary drives: motor port pressures). ``noise``: None/False (exact),
    True (seed 001's levels, :data:`NOISE_DEFAULTS`: 0.1° on angles, 2 mm on the telescope,
    0.17 MPa on pressures; Gaussian standard deviations) or a dict overriding some of them
    (keys angle, length, pressure). Noise comes from ``numpy.random.default_rng(seed)``: the
    same inputs and seed give identical bytes. Atomic write. Returns the column names."""
    cols, M = measured_table(crane, traj_sim, u_at_samples, noise, seed, payload)
    lines = [",".join(cols)] + [",".join(f"{v:.10g}" for v in row) for row in M]
    atomic_write_text(path, "\n".join(lines) + "\n")
    return cols


def read_measured_csv(path, joint_names) -> dict:
    """Read a measured-data CSV (CONTRACT, see :func:`write_measured_csv`): a header row;
    ``t`` [s] first; ``u_<joint>`` (valve command, −1…1), ``q_<joint>`` [rad | m] and
    ``p_<joint>_a``, ``p_<joint>_b`` [Pa, absolute]; other columns are ignored (not parsed).

    Returns dict t (N,), u (N, n) or None (no command columns), q (N, n), p_a, p_b (N, n) or
    None (no pressure columns: "positions only") and columns (the header names, a list).

    A missing or unreadable file raises OSError. Every other rejection is a ValueError that
    starts with the path and names the line (1-based, header = line 1), the column (number and
    name), the value found and what is allowed: an empty file, a blank header or fewer than
    2 data rows; a first column other than ``t``; duplicate column names; ``u_``/``q_``/``p_``
    columns of unknown joints; a missing ``q_<joint>``; command or pressure columns for some
    joints only, or one side of a cylinder only; a row with the wrong number of fields or a
    blank line inside the data; a used cell that is not a number, or NaN/inf; time not strictly
    increasing; a time step off the median step by more than 1e-6 relative (plus 1e-9·|t|,
    the rounding of the 10 significant digits :func:`write_measured_csv` prints), since the
    workflow needs a fixed sample rate; |u| > 1 + 1e-9; a pressure below −1e6 Pa or above
    1e9 Pa (wrong unit). Blank lines at the end of the file and a UTF-8 BOM are ignored."""
    import csv
    import io

    names = tuple(joint_names)
    n = len(names)
    joints = ", ".join(names)

    def fail(msg):
        return ValueError(f"{path}: {msg}")

    with open(path, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise fail(f"line {line}: byte {raw[e.start:e.start + 1]!r} is not UTF-8 text; "
                   "expected a UTF-8 (or ASCII) comma-separated file") from None
    reader = csv.reader(io.StringIO(text, newline=""))

    def read():
        """(first physical line of the row, row) or None at the end of the file."""
        before = reader.line_num
        try:
            row = next(reader)
        except StopIteration:
            return None
        except csv.Error as e:
            raise fail(f"line {reader.line_num}: not valid CSV ({e})") from None
        return before + 1, row

    def blank(row):
        return not row or (len(row) == 1 and not row[0].strip())

    # ------------------------------------------------------------------ header
    first = read()
    if first is None or blank(first[1]):
        rest = read()
        while rest is not None and blank(rest[1]):
            rest = read()
        if rest is None:
            raise fail("line 1: empty file; expected a header row starting with 't' and at "
                       "least 2 data rows")
        raise fail("line 1: blank line where the header row is expected (first column 't')")
    header = [c.strip() for c in first[1]]
    if header[0] != "t":
        hint = (" (the file must be comma-separated)"
                if any(d in header[0] for d in ";\t|") else "")
        raise fail(f"line 1, column 1: first column must be 't' (time in s), "
                   f"found {header[0]!r}{hint}")
    col = {}
    for c, name in enumerate(header):
        if name and name in col:
            raise fail(f"line 1, column {c + 1}: duplicate column name {name!r} (also column "
                       f"{col[name] + 1}); every column name must be unique")
        col.setdefault(name, c)
        if name.startswith(("u_", "q_")):
            joint = name[2:]
        elif name.startswith("p_") and name.endswith(("_a", "_b")):
            joint = name[2:-2]
        else:
            continue                                         # extra column: ignored
        if joint not in names:
            raise fail(f"line 1, column {c + 1}: unknown joint {joint!r} in column name "
                       f"{name!r} (joints: {joints})")
    missing = [f"q_{j}" for j in names if f"q_{j}" not in col]
    if missing:
        raise fail(f"line 1: missing column(s) {', '.join(missing)}; every joint needs its "
                   f"q_<joint> column (joints: {joints})")
    u_cols = [f"u_{j}" for j in names]
    has_u = [k for k in u_cols if k in col]
    if has_u and len(has_u) < n:
        raise fail(f"line 1: command column(s) {', '.join(k for k in u_cols if k not in col)} "
                   f"missing (found {', '.join(has_u)}); give u_<joint> for every joint or "
                   "for none")
    for j in names:
        a, b = f"p_{j}_a", f"p_{j}_b"
        if (a in col) != (b in col):
            have, lack = (a, b) if a in col else (b, a)
            raise fail(f"line 1, column {col[have] + 1} ({have}): {lack} missing; a cylinder "
                       f"needs both {a} and {b}")
    p_joints = [j for j in names if f"p_{j}_a" in col]
    if p_joints and len(p_joints) < n:
        lack = [j for j in names if j not in p_joints]
        raise fail(f"line 1: pressure columns missing for joint(s) {', '.join(lack)} ("
                   + ", ".join(f"p_{j}_{s}" for j in lack for s in "ab")
                   + "); give p_<joint>_a and p_<joint>_b for every joint, or none "
                   "(positions only)")
    used = [0] + ([col[k] for k in u_cols] if has_u else []) + [col[f"q_{j}"] for j in names]
    if p_joints:
        used += [col[f"p_{j}_a"] for j in names] + [col[f"p_{j}_b"] for j in names]

    # ------------------------------------------------------------------ data rows
    width = len(header)
    rows, lines = [], []
    blank_line = None
    while (item := read()) is not None:
        line, row = item
        if blank(row):
            blank_line = blank_line or line
            continue
        if blank_line is not None:
            raise fail(f"line {blank_line}: blank line inside the data; expected {width} "
                       "fields (only blank lines at the end of the file are ignored)")
        if len(row) != width:
            raise fail(f"line {line}: {len(row)} field(s), expected {width} (as many as the "
                       "header, line 1)")
        try:
            vals = [float(row[i]) for i in used]
        except ValueError:
            vals = None
        if vals is None or not all(map(math.isfinite, vals)):
            for i in used:
                s = row[i].strip()
                where = f"line {line}, column {i + 1} ({header[i]})"
                try:
                    v = float(s)
                except ValueError:
                    what = "empty cell" if not s else f"{s!r} is not a number"
                    raise fail(f"{where}: {what}; expected a decimal number") from None
                if not math.isfinite(v):
                    raise fail(f"{where}: {s!r} is not a finite number; NaN and inf are "
                               "not allowed")
        rows.append(vals)
        lines.append(line)
    if len(rows) < 2:
        at = f"line {lines[0]}: only 1 data row" if rows else "line 1: header only, no data rows"
        raise fail(f"{at}; at least 2 data rows are needed (fixed sample rate)")

    # ------------------------------------------------------------------ values
    A = np.array(rows, dtype=float)

    def first_bad(mask, a0):
        """(line, header column, value) of the first True of mask (N, k) over A[:, a0:a0+k],
        in file order."""
        r = int(np.argmax(mask.any(axis=1)))
        c = min(used[a0 + j] for j in np.flatnonzero(mask[r]))
        return lines[r], c, float(A[r, used.index(c)])

    t = A[:, 0].copy()
    dt = np.diff(t)
    k = np.flatnonzero(dt <= 0)
    if k.size:
        k = int(k[0])
        raise fail(f"line {lines[k + 1]}, column 1 (t): time {float(t[k + 1])!r} is not after "
                   f"{float(t[k])!r} (line {lines[k]}); time must increase strictly")
    h = float(np.median(dt))
    k = np.flatnonzero(np.abs(dt - h) > 1e-6 * h + 1e-9 * np.abs(t[1:]))
    if k.size:
        k = int(k[0])
        raise fail(f"line {lines[k + 1]}, column 1 (t): time step {float(dt[k]):.9g} s (from "
                   f"{float(t[k])!r} to {float(t[k + 1])!r}) differs from the median step "
                   f"{h:.9g} s by more than 1e-6 relative; a fixed sample rate is required "
                   "(resample the recording)")
    a = 1
    u = None
    if has_u:
        u = A[:, a:a + n].copy()
        bad = np.abs(u) > 1.0 + 1e-9
        if bad.any():
            line, c, v = first_bad(bad, a)
            raise fail(f"line {line}, column {c + 1} ({header[c]}): command {v!r} outside "
                       "[-1, 1]; valve commands are normalised to -1...1")
        a += n
    q = A[:, a:a + n].copy()
    a += n
    p_a = p_b = None
    if p_joints:
        P = A[:, a:]
        bad = (P < -1e6) | (P > 1e9)
        if bad.any():
            line, c, v = first_bad(bad, a)
            why = ("below -1e6 Pa: not an absolute pressure in Pa (MPa or bar given?)" if v < 0
                   else "above 1e9 Pa (10 000 bar): not a pressure in Pa (wrong unit or "
                   "scale factor?)")
            raise fail(f"line {line}, column {c + 1} ({header[c]}): pressure {v!r} Pa is "
                       f"{why}; allowed: -1e6 ... 1e9 Pa")
        p_a, p_b = P[:, :n].copy(), P[:, n:].copy()
    return dict(t=t, u=u, q=q, p_a=p_a, p_b=p_b, columns=header)

# ----------------------------------------------------------------------------- robustness
def default_perturbations(crane, angle=math.radians(1.0), length=0.02, gain=0.02,
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


def robustness(crane, traj: Trajectory, perturbations=None, rate: float = 50.0,
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


# ----------------------------------------------------------------------------- CLI helper
def simulate_to_csv(crane, traj: Trajectory, out, plant: Plant = Plant(), rate: float = 50.0,
                    noise=None, seed: int = 0, effects=()) -> dict:
    """What ``crane-planner simulate`` does: replay ``traj``'s valve commands (its own ``u``
    when it carries them on a uniform grid, else :func:`commands` at ``rate``) on ``plant``
    with the hidden ``effects`` (:mod:`planner.simulation.effects`, through :func:`planner.simulation.plant.respond`)
    and write the measured-data CSV to ``out`` (noise as in :func:`measured_table`). Nothing
    is written when anything fails. Returns a JSON-ready summary."""
    from planner.simulation.plant import respond
    from planner.calibration.trials import Recording
    if traj.u is not None and len(traj.t) > 2 and np.ptp(np.diff(traj.t)) < 1e-9:
        t_u, u, src = traj.t, traj.u, "trajectory"
    else:
        ff = commands(crane, traj, rate)
        t_u, u, src = ff.t, ff.u, f"feedforward@{rate:g}Hz"
    r = respond(crane, t_u, u, traj.q[0], effects, plant=plant)
    q, pa, pb = add_noise(crane, r.q, r.p_a, r.p_b, noise, seed)
    levels = _noise_levels(noise)
    rec = Recording(r.t, r.u, q, pa, pb)
    rec.to_csv(out, crane)
    q_plan = traj.sample(r.t)[0]
    tip_err = np.linalg.norm(crane.fk(r.state.q) - crane.fk(q_plan), axis=1)
    names = tuple(crane.names)
    cols = (["t"] + [f"u_{j}" for j in names] + [f"q_{j}" for j in names]
            + [f"p_{j}_{s}" for j in names for s in ("a", "b")])
    return dict(status="ok", out=str(out), samples=len(r.t), columns=cols, commands=src,
                plant=plant.to_dict(), effects=[e.to_dict() for e in r.effects],
                noise=levels, seed=seed,
                max_tip_error_m=float(tip_err.max()), final_tip_error_m=float(tip_err[-1]),
                clipped=r.meta["clipped"], pump=r.meta["pump"])
