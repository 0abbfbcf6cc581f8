"""The measured-data CSV (docs/design.md, "CONTRACT: measured-data CSV"), once: the
:class:`Recording` it holds, reading (with every rejection naming line, column, value and what
is allowed), writing, and sensor noise.

Columns: ``t`` [s] first; ``u_<joint>`` (valve command in effect at t, −1…1); ``q_<joint>``
[rad | m]; ``p_<joint>_a``, ``p_<joint>_b`` [Pa, absolute] for every actuator (rotary drives:
motor port pressures), joint names as in the crane spec. Extra columns are ignored; missing
pressure columns mean "positions only"; missing command columns are derived from the commanded
trajectory (:meth:`Recording.from_csv`). Written with 10 significant digits, atomically.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import csv
import io
import math
from array import array
from dataclasses import dataclass, field
from decimal import Decimal

import numpy as np

from planner.feedforward import commands
from planner.io import atomic_write_text
from planner.simulation.replay import pressures
from planner.simulation.resample import resample_arrays
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

__all__ = ["NOISE_DEFAULTS", "noise_levels", "add_noise", "Recording", "measured_table",
           "write_measured_csv", "read_measured_csv", "resample_arrays", "check_units"]

MS_STEPS = (1.0, 100.0)   # [s] median steps refused as time in ms (a 10-1000 Hz log)
JITTER = 0.1          # timestamp jitter (share of the mean step) resampled on reading
T_OFFSET = 1e5        # [s] a first time this large is a clock's (epoch): subtracted on reading
P_MIN = -2e6          # [Pa] lowest pressure read: gauge readings with a transducer offset

# seed 001's sensor accuracies (resolvers ±0.1°, pressure transducers 0.17 MPa); telescope: 2 mm
NOISE_DEFAULTS = dict(angle=math.radians(0.1), length=0.002, pressure=0.17e6)


# ----------------------------------------------------------------------------- noise
def noise_levels(noise) -> dict | None:
    """Sensor noise standard deviations: ``noise`` None/False (none: returns None), True (seed
    001's levels, :data:`NOISE_DEFAULTS`: 0.1° on angles, 2 mm on lengths, 0.17 MPa on
    pressures) or a dict overriding some of them (keys angle, length, pressure)."""
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


def add_noise(crane: Crane, q, p_a, p_b, noise=None, seed: int = 0):
    """Sensor readings (new arrays) with Gaussian noise at ``noise``'s levels
    (:func:`noise_levels`): q (N, n) per joint type, p_a, p_b (N, n) [Pa]; drawn from
    ``numpy.random.default_rng(seed)`` in that order (deterministic)."""
    q, p_a, p_b = np.array(q, float), np.array(p_a, float), np.array(p_b, float)
    levels = noise_levels(noise)
    if levels is not None:
        rng = np.random.default_rng(seed)
        sq = np.array([levels["angle"] if j.revolute else levels["length"]
                       for j in crane.spec.joints])
        q = q + rng.normal(size=q.shape) * sq
        p_a = p_a + rng.normal(size=p_a.shape) * levels["pressure"]
        p_b = p_b + rng.normal(size=p_b.shape) * levels["pressure"]
    return q, p_a, p_b


# ----------------------------------------------------------------------------- the recording
@dataclass
class Recording:
    """A measured recording on the sample grid: t (N,), commands u (N, n) in effect at t,
    positions q (N, n), pressures p_a, p_b (N, n) [Pa] or None (positions only); ``notes``:
    what reading it changed (e.g. timestamp jitter resampled), one line each."""
    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    p_a: np.ndarray | None = None
    p_b: np.ndarray | None = None
    notes: tuple = ()
    # the readings as the logger wrote them (times not uniform), kept when reading resampled
    # them: the noise is estimated there (interpolation mixes neighbouring readings)
    logged: "Recording | None" = field(default=None, repr=False, compare=False)

    @classmethod
    def from_replay(cls, crane: Crane, sim: Trajectory, u_at_samples=None,
                    payload=None) -> "Recording":
        """The exact readings of a replay (:func:`planner.simulation.replay.replay`):
        positions, pressures from the model's dynamics (:func:`pressures`) and the commands in
        effect (``u_at_samples`` (N, n), default the replay's own)."""
        u = sim.u if u_at_samples is None else np.atleast_2d(np.asarray(u_at_samples, float))
        if u is None or u.shape != sim.q.shape:
            raise ValueError(f"measured_table: commands needed at every sample, shape "
                             f"{sim.q.shape}")
        pa, pb = pressures(crane, sim, payload)
        return cls(sim.t, u, sim.q, pa, pb)

    def with_noise(self, crane: Crane, noise=True, seed: int = 0) -> "Recording":
        """The readings with sensor noise (:func:`add_noise`; positions-only stays so)."""
        if self.p_a is None:
            q, _, _ = add_noise(crane, self.q, np.zeros_like(self.q), np.zeros_like(self.q),
                                noise, seed)
            return Recording(self.t, self.u, q)
        q, pa, pb = add_noise(crane, self.q, self.p_a, self.p_b, noise, seed)
        return Recording(self.t, self.u, q, pa, pb)

    def positions_only(self) -> "Recording":
        return Recording(self.t, self.u, self.q)

    def table(self, crane: Crane) -> tuple[list, np.ndarray]:
        """(column names, (N, columns) array) in the contract's order."""
        names = tuple(crane.names)
        cols = (["t"] + [f"u_{j}" for j in names] + [f"q_{j}" for j in names])
        blocks = [np.asarray(self.t, float)[:, None], self.u, self.q]
        if self.p_a is not None:
            cols += [f"p_{j}_{s}" for j in names for s in ("a", "b")]
            P = np.empty((len(self.t), 2 * crane.n))
            P[:, 0::2], P[:, 1::2] = self.p_a, self.p_b
            blocks.append(P)
        return cols, np.hstack(blocks)

    def to_csv(self, path, crane: Crane) -> list:
        """Write the CSV (atomically, 10 significant digits); returns the column names."""
        cols, M = self.table(crane)
        lines = [",".join(cols)] + [",".join(f"{v:.10g}" for v in row) for row in M]
        atomic_write_text(path, "\n".join(lines) + "\n")
        return cols

    @classmethod
    def from_csv(cls, path, crane: Crane, plan: Trajectory | None = None) -> "Recording":
        """Read a measured CSV (:func:`read_measured_csv`). Without command columns, the
        commands are the nominal feed-forward of ``plan`` (the commanded trajectory) at the
        file's sample rate, which must then start with the plan."""
        d = read_measured_csv(path, tuple(crane.names))
        check_units(crane, d, path)
        u = d["u"]
        if u is None:
            if plan is None:
                raise ValueError(f"{path}: line 1: no command columns u_<joint>; give the "
                                 "commanded trajectory (`plan`) to derive them")
            t = d["t"]
            dt = float(np.median(np.diff(t)))
            if abs(t[0] - plan.t[0]) > 1e-6 * max(1.0, abs(t[0])):
                raise ValueError(f"{path}: line 2, column 1 (t): the recording starts at "
                                 f"{t[0]:g} s, the commanded trajectory at {plan.t[0]:g} s; "
                                 "without u_<joint> columns they must start together")
            ff = commands(crane, plan, 1.0 / dt)
            k = np.clip(np.round((t - ff.t[0]) / dt).astype(int), 0, len(ff.t) - 1)
            u = ff.u[k]
        lg = d.get("logged")
        logged = None if lg is None else cls(lg["t"], lg["u"], lg["q"], lg["p_a"], lg["p_b"])
        return cls(d["t"], u, d["q"], d["p_a"], d["p_b"], tuple(d.get("notes", ())), logged)

    def resampled(self, rate: float) -> "Recording":
        """The recording on a uniform grid at ``rate`` [Hz] (:func:`resample_arrays`)."""
        t, (u, q, pa, pb) = resample_arrays(self.t, (self.u, self.q, self.p_a, self.p_b),
                                            rate)
        return Recording(t, u, q, pa, pb, self.notes,
                         self if self.logged is None else self.logged)


def check_units(crane: Crane, d: dict, path) -> None:
    """Refuse pressures that are all below 1 bar (bar, MPa or kPa given) and positions that
    are far outside the crane's joint ranges but inside them once converted (degrees for
    revolute joints, mm for prismatic ones), naming the conversion.
    ``d``: :func:`read_measured_csv`'s result."""
    if d["p_a"] is not None:
        top = float(max(np.max(np.abs(d["p_a"])), np.max(np.abs(d["p_b"]))))
        if top < 1e5:
            guess = ("MPa (multiply by 1e6) or bar (multiply by 1e5)" if top <= 60 else
                     "bar (multiply by 1e5)" if top <= 1000 else "kPa (multiply by 1e3)")
            raise ValueError(f"{path}: the largest pressure in every p_ column is {top:.6g}, "
                             f"below 1e5 Pa (1 bar), which no working crane shows: the "
                             f"pressures look like {guess}; allowed: pressures in Pa")
    L = crane.limit_arrays()
    for i, (j, spec) in enumerate(zip(crane.names, crane.spec.joints)):
        q = d["q"][:, i]
        lo, hi = float(L["q_min"][i]), float(L["q_max"][i])
        pad = 0.2 * (hi - lo) + 0.1
        out = (q < lo - pad) | (q > hi + pad)
        if not out.any():
            continue
        f, unit, conv = ((math.pi / 180, "degrees", "multiply by pi/180 = 0.0174533")
                         if spec.revolute else (1e-3, "mm", "multiply by 0.001"))
        if np.all((q * f >= lo - pad) & (q * f <= hi + pad)):
            k = int(np.argmax(out))
            where = "" if d.get("notes") else f"line {k + 2}, "
            raise ValueError(
                f"{path}: {where}column q_{j}: {float(q[k]):.6g} is outside {j}'s range "
                f"[{lo:.4g}, {hi:.4g}] {'rad' if spec.revolute else 'm'} by far; the "
                f"positions look like {unit}: {conv}")


def measured_table(crane: Crane, sim: Trajectory, u_at_samples=None, noise=None, seed: int = 0,
                   payload=None):
    """(column names, (N, cols) array) of the measured-data CSV of a replay (see
    :func:`write_measured_csv`)."""
    rec = Recording.from_replay(crane, sim, u_at_samples, payload).with_noise(crane, noise, seed)
    return rec.table(crane)


def write_measured_csv(path, crane: Crane, traj_sim: Trajectory, u_at_samples=None, noise=None,
                       seed: int = 0, payload=None) -> list:
    """Write the measured-data CSV of a replay ``traj_sim``: its commands, positions and the
    model's pressures (:meth:`Recording.from_replay`). ``noise``: None/False (exact), True
    (seed 001's levels) or a dict overriding some of them (:func:`noise_levels`). Noise comes
    from ``numpy.random.default_rng(seed)``: the same inputs and seed give identical bytes.
    Atomic write. Returns the column names."""
    rec = Recording.from_replay(crane, traj_sim, u_at_samples, payload)
    return rec.with_noise(crane, noise, seed).to_csv(path, crane)


# ----------------------------------------------------------------------------- reading
def read_measured_csv(path, joint_names, uniform: bool = True) -> dict:
    """Read a measured-data CSV (CONTRACT, see :func:`write_measured_csv`): a header row;
    ``t`` [s] first; ``u_<joint>`` (valve command, −1…1), ``q_<joint>`` [rad | m] and
    ``p_<joint>_a``, ``p_<joint>_b`` [Pa, absolute]; other columns are ignored (not parsed).

    Returns dict t (N,), u (N, n) or None (no command columns), q (N, n), p_a, p_b (N, n) or
    None (no pressure columns: "positions only"), columns (the header names, a list) and
    notes (what reading changed, one line each) and logged (None, or — when jitter was
    resampled — dict t, u, q, p_a, p_b of the samples as written, for the noise estimate).

    A missing or unreadable file raises OSError. Every other rejection is a ValueError that
    starts with the path and names the line (1-based, header = line 1), the column (number and
    name), the value found and what is allowed: an empty file, a blank header or fewer than
    2 data rows; a first column other than ``t``; duplicate column names; ``u_``/``q_``/``p_``
    columns of unknown joints; a missing ``q_<joint>``; command or pressure columns for some
    joints only, or one side of a cylinder only; a row with the wrong number of fields or a
    blank line inside the data; a used cell that is not a number, or NaN/inf; time not strictly
    increasing; with ``uniform`` (the default): a median step in :data:`MS_STEPS` (time in
    ms: the conversion is named), a step off the median by more than 2·:data:`JITTER` (a
    gap), a time off the uniform grid of the mean step by more than :data:`JITTER` of the
    step (jitter within it is resampled onto the mean rate — commands held, readings
    interpolated — and said in ``notes``); |u| > 1 + 1e-9; a pressure below :data:`P_MIN`
    or above 1e9 Pa. Blank lines at the end of the file and a UTF-8 BOM are ignored. Times
    from a clock (a first time of :data:`T_OFFSET` s or more, e.g. Unix epoch seconds) are
    read relative to the first (subtracted exactly; said in ``notes``)."""
    names = tuple(joint_names)
    n = len(names)
    joints = ", ".join(names)

    def fail(msg):
        return ValueError(f"{path}: {msg}")
    uniform = bool(uniform)

    with open(path, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise fail(f"line {line}: byte {raw[e.start:e.start + 1]!r} is not UTF-8 text; "
                   "expected a UTF-8 (or ASCII) comma-separated file") from None
    del raw
    reader = csv.reader(_lines(text) if text.count("\r") == text.count("\r\n") else
                        io.StringIO(text, newline=""))   # lone CRs: StringIO splits at them

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
    rows, lines = array("d"), array("q")   # 8 bytes a value: a 10^6-row log in ~0.5 GB
    stamps = []                            # the time column as written (exact offsets)
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
        rows.extend(vals)
        lines.append(line)
        stamps.append(row[0])
    if len(lines) < 2:
        at = f"line {lines[0]}: only 1 data row" if lines else "line 1: header only, no data rows"
        raise fail(f"{at}; at least 2 data rows are needed (fixed sample rate)")

    # ------------------------------------------------------------------ values
    A = np.frombuffer(rows, dtype=float).reshape(len(lines), len(used))
    del rows

    def first_bad(mask, a0):
        """(line, header column, value) of the first True of mask (N, k) over A[:, a0:a0+k],
        in file order."""
        r = int(np.argmax(mask.any(axis=1)))
        c = min(used[a0 + j] for j in np.flatnonzero(mask[r]))
        return lines[r], c, float(A[r, used.index(c)])

    t = A[:, 0].copy()
    notes = []
    if abs(t[0]) >= T_OFFSET:
        # a clock's time (Unix epoch seconds): the first time subtracted exactly, in decimal,
        # before float rounding at ~1e9 s (2e-7 s) makes a uniform log look non-uniform
        t0 = Decimal(stamps[0].strip())
        t = np.array([float(Decimal(s.strip()) - t0) for s in stamps])
        notes.append(f"times offset: t starts at {stamps[0].strip()} s (a clock's time, e.g. "
                     f"Unix epoch seconds); the first time was subtracted (t = 0 at line "
                     f"{lines[0]})")
    dt = np.diff(t)
    k = np.flatnonzero(dt <= 0)
    if k.size:
        k = int(k[0])
        raise fail(f"line {lines[k + 1]}, column 1 (t): time {float(t[k + 1])!r} is not after "
                   f"{float(t[k])!r} (line {lines[k]}); time must increase strictly")
    h = float(np.median(dt))
    if uniform and MS_STEPS[0] <= h <= MS_STEPS[1]:
        raise fail(f"line 1, column 1 (t): median time step {h:.6g} s ({1 / h:.3g} Hz); it "
                   f"looks like milliseconds: divide t by 1000 (a {1000 / h:.0f} Hz log); "
                   "allowed: time in s")
    jittered = False
    k = np.flatnonzero(np.abs(dt - h) > 1e-6 * h + 1e-9 * np.abs(t[1:]))
    if k.size and uniform:
        # a gap or a burst: two stamps jittered by ±JITTER of the step differ by ≤ 2·JITTER of
        # it — of the mean step (span / samples), which jitter leaves as it is; the median
        # step of a jittered log is not the nominal one (1 % for the mean's own end effects)
        mean = (t[-1] - t[0]) / (len(t) - 1)
        k = np.flatnonzero(np.abs(dt - mean) > (2 * JITTER + 0.01) * mean)
        if k.size:
            k = int(k[0])
            raise fail(f"line {lines[k + 1]}, column 1 (t): time step {float(dt[k]):.9g} s "
                       f"(from {float(t[k])!r} to {float(t[k + 1])!r}) differs from the mean "
                       f"step {mean:.9g} s (median step {h:.9g} s) by more than "
                       f"{200 * JITTER + 1:.0f} %: not timestamp jitter; a fixed sample rate "
                       "is required (resample the recording first: crane-planner resample FILE "
                       "--rate HZ --out FILE)")
        off = np.abs(t - (t[0] + np.arange(len(t)) * mean)) / mean
        if float(off.max()) > JITTER * (1 + 1e-6):
            k = int(np.argmax(off > JITTER * (1 + 1e-6)))
            raise fail(f"line {lines[k]}, column 1 (t): time {float(t[k])!r} is "
                       f"{100 * float(off[k]):.0f} % of the mean step ({mean:.9g} s) off the "
                       f"uniform grid; allowed: timestamp jitter within {100 * JITTER:.0f} % "
                       "(resampled on reading); resample the recording first: crane-planner "
                       "resample FILE --rate HZ --out FILE")
        notes.append(f"timestamp jitter up to {100 * float(off.max()):.1f} % of the step: "
                     f"resampled onto the mean rate {1 / mean:.6g} Hz (readings interpolated, "
                     "each command kept with its sample)")
        jittered = True
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
        bad = (P < P_MIN) | (P > 1e9)
        if bad.any():
            line, c, v = first_bad(bad, a)
            why = ("below -2e6 Pa: not an absolute pressure in Pa (MPa or bar given?) nor a "
                   "gauge one with a transducer offset" if v < 0
                   else "above 1e9 Pa (10 000 bar): not a pressure in Pa (wrong unit or "
                   "scale factor?)")
            raise fail(f"line {line}, column {c + 1} ({header[c]}): pressure {v!r} Pa is "
                       f"{why}; allowed: -2e6 ... 1e9 Pa")
        p_a, p_b = P[:, :n].copy(), P[:, n:].copy()
    logged = None
    if jittered:
        logged = dict(t=t, u=u, q=q, p_a=p_a, p_b=p_b)
        t, (u, q, p_a, p_b) = resample_arrays(t, (u, q, p_a, p_b), 1.0 / mean, "nearest")
    return dict(t=t, u=u, q=q, p_a=p_a, p_b=p_b, columns=header, notes=notes, logged=logged)


def _lines(text: str):
    """The lines of ``text`` with their endings, one at a time (io.StringIO would hold a
    4-byte-per-character copy of a large file)."""
    start, n = 0, len(text)
    while start < n:
        k = text.find("\n", start)
        k = n if k < 0 else k + 1
        yield text[start:k]
        start = k
