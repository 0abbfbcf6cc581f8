"""Trajectory: the one container every method returns, and evaluate(): the one judge.

A :class:`Trajectory` holds a time grid and joint positions / velocities / accelerations (SI)
plus metadata. Between samples it is interpolated either as a piecewise quintic Hermite
polynomial (``interpolation="quintic"``, default: consistent with q, qd and qdd at every sample,
exact for polynomial pieces up to degree five) or piecewise linearly (``"linear"``: for paths that
are only defined by positions, e.g. a DP's node sequence, where the velocity is constant on each
segment).

:func:`evaluate` resamples finely, derives the actuator motion, hydraulics, power and energy
from the crane model, and returns the largest relative violation of every limit kind.
Benchmarks compare methods only through it.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import math
from dataclasses import dataclass, field, replace

import numpy as np

from planner.io import atomic_write_text
from planner.model.flows import actuator_table, held_hydraulics

if TYPE_CHECKING:
    from planner.model import Crane

LIMIT_KINDS = ("position", "velocity", "acceleration", "jerk", "pump_flow", "pressure", "tension")


def _arr(name, a, two_d: bool = False):
    """``a`` as a float array (2-D when ``two_d``), refused when any value is not finite."""
    a = np.asarray(a, dtype=float)
    if two_d and a.ndim != 2:
        a = np.atleast_2d(a)
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"Trajectory.{name}: non-finite value at index {tuple(bad)}")
    return a


_TRUSTED_DEFAULTS = dict(joint_names=(), method="", objective="", interpolation="quintic",
                         limits=LIMIT_KINDS, u=None)


@dataclass
class Trajectory:
    """Sampled joint trajectory. t [s] (N,), q/qd/qdd (N, n) in rad | m and their rates.

    ``u`` (N, n) optional valve commands; ``limits`` names the limit kinds the producing method
    claims to respect (evaluate() judges those by default; all kinds are always reported)."""
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray | None = None
    qdd: np.ndarray | None = None
    joint_names: tuple[str, ...] = ()
    method: str = ""
    objective: str = ""
    interpolation: str = "quintic"
    limits: tuple[str, ...] = LIMIT_KINDS
    u: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.t = _arr("t", self.t).ravel()
        self.q = _arr("q", self.q, True)
        N, n = self.q.shape
        if self.t.shape[0] != N:
            raise ValueError(f"Trajectory: t has {self.t.shape[0]} samples but q has {N} rows")
        if N < 2:
            raise ValueError("Trajectory: at least two samples are needed")
        dt = self.t[1:] - self.t[:-1]
        if not (dt > 0).all():
            k = int(np.argmax(~(dt > 0)))
            raise ValueError(f"Trajectory.t must be strictly increasing; t[{k}] = {self.t[k]} "
                             f">= t[{k + 1}] = {self.t[k + 1]}")
        if self.interpolation not in ("quintic", "linear"):
            raise ValueError(f"Trajectory.interpolation = {self.interpolation!r}; "
                             "allowed: 'quintic', 'linear'")
        if self.interpolation == "linear":
            v = np.diff(self.q, axis=0) / dt[:, None]
            if self.qd is None:  # velocity of the segment that starts at each sample
                self.qd = np.vstack([v, v[-1:]])
            if self.qdd is None:
                self.qdd = np.zeros_like(self.q)
        for name in ("qd", "qdd"):
            a = getattr(self, name)
            if a is None:
                raise ValueError(f"Trajectory.{name} is required for quintic interpolation")
            a = _arr(name, a, True)
            if a.shape != (N, n):
                raise ValueError(f"Trajectory.{name} has shape {a.shape}, expected {(N, n)}")
            setattr(self, name, a)
        if self.u is not None:
            self.u = _arr("u", self.u, True)
            if self.u.shape != (N, n):
                raise ValueError(f"Trajectory.u has shape {self.u.shape}, expected {(N, n)}")
        if not self.joint_names:
            self.joint_names = tuple(f"j{i}" for i in range(n))
        if len(self.joint_names) != n:
            raise ValueError(f"Trajectory.joint_names has {len(self.joint_names)} names for {n} joints")
        bad = [k for k in self.limits if k not in LIMIT_KINDS]
        if bad:
            raise ValueError(f"Trajectory.limits: unknown kind(s) {bad}; allowed: {LIMIT_KINDS}")

    @classmethod
    def trusted(cls, t, q, qd, qdd, *, block=None, **fields) -> "Trajectory":
        """A Trajectory from float arrays a producer has just computed itself — t (N,)
        strictly increasing, q/qd/qdd (N, n), ``fields`` complete (joint_names of length n,
        known limit kinds) — without the constructor's copies and checks (a few µs, which is
        most of a Ruckig move's cost); one finite-sum check still refuses NaN/inf (on
        ``block`` instead of q, q̇, q̈ when they are views of that one array). Users and
        readers of files construct ``Trajectory(...)``, which checks everything."""
        if not math.isfinite((q.sum() + qd.sum() + qdd.sum() if block is None else block.sum())
                             + t.sum()):
            return cls(t, q, qd, qdd, **fields)    # the checked path names the bad value
        self = cls.__new__(cls)
        d = self.__dict__
        d.update(_TRUSTED_DEFAULTS)
        d.update(fields, t=t, q=q, qd=qd, qdd=qdd)
        if "meta" not in fields:
            d["meta"] = {}
        return self

    # ------------------------------------------------------------------ basic properties
    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def n(self) -> int:
        return self.q.shape[1]

    # ------------------------------------------------------------------ interpolation
    def sample(self, t):
        """(q, qd, qdd, qddd) at times t (clipped to the trajectory's span)."""
        t = np.clip(np.asarray(t, float).ravel(), self.t[0], self.t[-1])
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        h = (self.t[k + 1] - self.t[k])[:, None]
        s = (t - self.t[k])[:, None] / h
        p0, p1 = self.q[k], self.q[k + 1]
        if self.interpolation == "linear":
            v = (p1 - p0) / h
            z = np.zeros_like(p0)
            return p0 + s * (p1 - p0), v, z, z
        v0, v1 = self.qd[k] * h, self.qd[k + 1] * h
        a0, a1 = self.qdd[k] * h * h, self.qdd[k + 1] * h * h
        dp = p1 - p0
        c3 = 10 * dp - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
        c4 = -15 * dp + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
        c5 = 6 * dp - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1
        c2 = 0.5 * a0
        q = p0 + s * (v0 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
        qd = (v0 + s * (2 * c2 + s * (3 * c3 + s * (4 * c4 + s * 5 * c5)))) / h
        qdd = (2 * c2 + s * (6 * c3 + s * (12 * c4 + s * 20 * c5))) / h ** 2
        qddd = (6 * c3 + s * (24 * c4 + s * 60 * c5)) / h ** 3
        # on very short intervals (< 1 ms, e.g. a plan's node next to a control instant) the
        # quintic's third derivative is dominated by round-off in q (∝ ε·|q|/h³): take the mean
        # jerk (qdd₁ − qdd₀)/h there, exact for the piecewise-cubic motion of a jerk-limited plan
        short = (h < 1e-3)[:, 0]
        if short.any():
            qddd[short] = ((self.qdd[k + 1] - self.qdd[k]) / h)[short]
        return q, qd, qdd, qddd

    def resample(self, rate: float = 1000.0) -> np.ndarray:
        """Fine time grid at ``rate`` [Hz] that also contains every original sample time."""
        n = max(2, int(math.ceil(self.duration * rate)) + 1)
        return np.union1d(np.linspace(self.t[0], self.t[-1], n), self.t)

    # ------------------------------------------------------------------ constructors / IO
    @classmethod
    def from_function(cls, f, duration: float, rate: float = 100.0, **kw) -> "Trajectory":
        """Sample a callable ``f(t) -> (q, qd, qdd)`` (vectorised over t) at ``rate`` [Hz]."""
        t = np.linspace(0.0, duration, max(2, int(math.ceil(duration * rate)) + 1))
        q, qd, qdd = f(t)
        return cls(t=t, q=q, qd=qd, qdd=qdd, **kw)

    def to_csv(self, path) -> None:
        """Trajectory CSV (CONTRACT): t, q_*, qd_*, qdd_*, then u_* when feed-forward exists."""
        cols = ["t"] + [f"{p}_{j}" for p in ("q", "qd", "qdd") for j in self.joint_names]
        data = [self.t[:, None], self.q, self.qd, self.qdd]
        if self.u is not None:
            cols += [f"u_{j}" for j in self.joint_names]
            data.append(self.u)
        M = np.hstack(data)
        lines = [",".join(cols)] + [",".join(f"{v:.10g}" for v in row) for row in M]
        atomic_write_text(path, "\n".join(lines) + "\n")

    @classmethod
    def from_csv(cls, path, joint_names=None) -> "Trajectory":
        """Read a trajectory CSV (CONTRACT: header row, ``t`` first, ``q_*``, ``qd_*``, ``qdd_*``,
        optional ``u_*``; lines starting with '#' are comments). Rejects a bad file with a
        ValueError that names the line and the column: a missing column, a cell that is not a
        finite number, a row of the wrong length, fewer than two samples."""
        header, rows, lines = read_csv_table(path)
        if not header or header[0] != "t":
            raise ValueError(f"{path}: line 1: first column must be 't', found {header[:1]}")
        if len(rows) < 2:
            raise ValueError(f"{path}: {len(rows)} data row(s) after the header; a trajectory "
                             "needs at least 2 samples")
        data = np.array(rows, dtype=float)
        bad = np.argwhere(~np.isfinite(data))
        if bad.size:
            r, c = bad[0]
            raise ValueError(f"{path}: line {lines[r]}, column {header[c]}: {data[r, c]} is not "
                             "a finite number")
        if joint_names is None:
            joint_names = [c[2:] for c in header if c.startswith("q_")]
        col = {c: i for i, c in enumerate(header)}

        def block(prefix, required=True):
            missing = [f"{prefix}_{j}" for j in joint_names if f"{prefix}_{j}" not in col]
            if missing:
                if required:
                    raise ValueError(f"{path}: line 1: missing column(s) {', '.join(missing)}")
                return None
            return data[:, [col[f"{prefix}_{j}"] for j in joint_names]]
        return cls(t=data[:, 0], q=block("q"), qd=block("qd"), qdd=block("qdd"),
                   u=block("u", required=False), joint_names=tuple(joint_names))


def read_csv_table(path) -> tuple[list[str], list[list[float]], list[int]]:
    """A numeric CSV: (header names, rows of floats, the file line number of each row).
    Blank lines and lines starting with '#' are skipped; a row of the wrong length or a cell
    that is not a number raises ValueError naming the line and the column."""
    with open(path, encoding="utf-8") as fh:
        text = fh.read().splitlines()
    if not text:
        raise ValueError(f"{path}: empty file (expected a header row starting with 't')")
    header = [c.strip() for c in text[0].split(",")]
    rows, where = [], []
    for k, line in enumerate(text[1:], start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = line.split(",")
        if len(cells) != len(header):
            raise ValueError(f"{path}: line {k}: {len(cells)} values, the header has "
                             f"{len(header)} columns")
        try:
            rows.append([float(c) for c in cells])
        except ValueError:
            j = next(i for i, c in enumerate(cells) if not _is_float(c))
            raise ValueError(f"{path}: line {k}, column {header[j]}: {cells[j].strip()!r} is "
                             "not a number") from None
        where.append(k)
    return header, rows, where


def _is_float(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


@dataclass
class Evaluation:
    """Everything evaluate() derives on the fine grid (arrays: samples first) and the verdict.

    violations[kind] is the largest relative excess of that limit (0 when clean); worst[kind]
    says where: time [s], joint (or None), value, limit. max_limit_violation covers ``checked``.
    """
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    qddd: np.ndarray
    tip: np.ndarray
    hyd: dict
    energy: np.ndarray
    duration: float
    energy_J: float
    peak_pump_flow: float
    violations: dict
    worst: dict
    checked: tuple
    max_limit_violation: float

    def ok(self, tol: float = 1e-3) -> bool:
        """True when no checked limit is exceeded by more than ``tol`` (relative; 1e-3 = 0.1 %)."""
        return self.max_limit_violation <= tol

    def at(self, t) -> "Evaluation":
        """The same judgement with its arrays only at the times ``t`` (exact samples when the
        fine grid holds them, as it holds every sample of the judged trajectory; else linear
        interpolation). The verdict and the scalars are those of the full grid. A library
        worker ships this (the store keeps the channels on the entry's own samples): 1/60 of
        the bytes of a 1 kHz evaluation."""
        t = np.asarray(t, float)
        k = np.clip(np.searchsorted(self.t, t), 0, len(self.t) - 1)
        exact = np.allclose(self.t[k], t, rtol=0, atol=1e-12)

        def pick(a):
            a = np.asarray(a, float)
            if a.ndim == 0 or a.shape[0] != len(self.t):   # not a channel on the grid
                return a
            if exact:
                return a[k]
            if a.ndim == 1:
                return np.interp(t, self.t, a)
            return np.column_stack([np.interp(t, self.t, a[:, j]) for j in range(a.shape[1])])
        return replace(self, t=t.copy(), q=pick(self.q), qd=pick(self.qd), qdd=pick(self.qdd),
                       qddd=pick(self.qddd), tip=pick(self.tip), energy=pick(self.energy),
                       hyd={name: pick(v) for name, v in self.hyd.items()})

    def summary(self) -> dict:
        """JSON-ready scalars (SI)."""
        return dict(duration_s=self.duration, energy_J=self.energy_J,
                    peak_pump_flow_m3s=self.peak_pump_flow,
                    max_limit_violation=self.max_limit_violation,
                    violations={k: float(v) for k, v in self.violations.items()},
                    checked=list(self.checked))

    def __str__(self):
        lines = [f"duration {self.duration:.3f} s, pump energy {self.energy_J / 1e3:.2f} kJ, "
                 f"peak pump flow {self.peak_pump_flow * 6e4:.1f} L/min"]
        for k, v in self.violations.items():
            w = self.worst.get(k)
            where = f" at t={w[0]:.3f} s{' (' + w[1] + ')' if w[1] else ''}" if w and v > 0 else ""
            mark = "" if k in self.checked else " (not checked)"
            lines.append(f"  {k:<13} {100 * v:8.3f} %{where}{mark}")
        return "\n".join(lines)


def evaluate(crane: Crane, traj: Trajectory, rate: float = 1000.0, kinds=None,
             payload: float | None = None) -> Evaluation:
    """Judge a trajectory on the crane model at ``rate`` [Hz] (plus every original sample).

    Returns an :class:`Evaluation`. ``kinds`` (default: ``traj.limits``) selects which limit
    kinds enter ``max_limit_violation``; all kinds are reported. ``payload`` [kg] defaults to
    the spec's load + tool. The hydraulics are the model's at every sample with, under the
    machine pricing, the held chamber pressures carried along the grid
    (:func:`planner.model.flows.held_hydraulics`).
    """
    spec = crane.spec
    if traj.n != crane.n:
        raise ValueError(f"trajectory has {traj.n} joints, crane '{spec.id}' has {crane.n}")
    if traj.joint_names and tuple(traj.joint_names) != tuple(crane.names) and \
            not all(n.startswith("j") for n in traj.joint_names):
        raise ValueError(f"trajectory joints {list(traj.joint_names)} do not match crane "
                         f"'{spec.id}' joints {crane.names}")
    t = traj.resample(rate)
    q, qd, qdd, qddd = traj.sample(t)
    hyd = held_hydraulics(crane, t, crane.hydraulics(q, qd, qdd, payload))
    tip = crane.tip(q)
    power = hyd["power"]
    energy = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    L = crane.limit_arrays()
    names = crane.names
    viol, worst = {}, {}

    def record(kind, rel, values, limits, per_joint=True):
        """rel: (N, n) or (N,) relative excess >= 0."""
        rel = np.maximum(rel, 0.0)
        if rel.size == 0:
            viol[kind] = 0.0
            return
        idx = np.unravel_index(int(np.argmax(rel)), rel.shape)
        viol[kind] = float(rel[idx])
        if viol[kind] <= 0.0:
            return  # clean: no "worst" location to report
        j = names[idx[1]] if per_joint and rel.ndim == 2 else None
        worst[kind] = (float(t[idx[0]]), j, float(values[idx]), float(limits[idx] if
                                                                       np.ndim(limits) else limits))

    span = L["q_max"] - L["q_min"]
    rel = np.maximum(q - L["q_max"], L["q_min"] - q) / span
    record("position", rel, q, np.where(q > L["q_max"], L["q_max"], L["q_min"]) + 0 * q)
    rel = np.maximum(qd / L["qd_max"], qd / L["qd_min"]) - 1.0
    record("velocity", rel, qd, np.where(qd >= 0, L["qd_max"], L["qd_min"]) + 0 * qd)
    rel = np.abs(qdd) / L["qdd_max"] - 1.0
    record("acceleration", rel, qdd, L["qdd_max"] + 0 * qdd)
    has_jerk = np.isfinite(L["qddd_max"])
    rel = np.where(has_jerk, np.abs(qddd) / np.where(has_jerk, L["qddd_max"], 1.0) - 1.0, 0.0)
    record("jerk", rel, qddd, L["qddd_max"] + 0 * qddd)
    qmax = spec.pump.max_flow
    record("pump_flow", hyd["q_pump"] / qmax - 1.0, hyd["q_pump"], qmax, per_joint=False)
    pmax = spec.pump.max_pressure
    pch = np.maximum(hyd["p_a"], hyd["p_b"])
    record("pressure", pch / pmax - 1.0 if math.isfinite(pmax) else 0 * pch, pch, pmax + 0 * pch)
    table = actuator_table(spec)
    pref = pmax if math.isfinite(pmax) else 20e6
    cap = table.area_a * pref
    F = hyd["force"]
    record("tension", np.where(table.single, -F / cap, 0.0), F, 0 * F)
    checked = tuple(traj.limits if kinds is None else kinds)
    mlv = max((viol[k] for k in checked if k in viol), default=0.0)
    return Evaluation(t=t, q=q, qd=qd, qdd=qdd, qddd=qddd, tip=tip, hyd=hyd, energy=energy,
                      duration=traj.duration, energy_J=float(energy[-1]),
                      peak_pump_flow=float(np.max(hyd["q_pump"])), violations=viol, worst=worst,
                      checked=checked, max_limit_violation=float(mlv))
