"""Export of a library database (:mod:`planner.library.store`) for other tools, and the
trajectory files a controller takes.

- ``csv``: one trajectory CSV per entry that has a trajectory (CONTRACT: trajectory CSV: t,
  q_*, qd_*, qdd_*, u_*, then the hydraulic channels the HDF5 file stores: x_*, xd_*, p_*_a,
  p_*_b, q_pump, power) and ``index.csv`` (columns :data:`INDEX_CSV_COLUMNS`; empty ``file``
  for failed entries);
- ``mat``: ``library.mat`` with struct ``entries`` (one field per entry, named by
  :func:`matlab_name`), struct ``index``, ``crane_id`` and ``spec_toml``;
- ``json``: ``library.json`` with the index rows and the entries' arrays as lists (strict JSON:
  non-finite numbers are null);
- ``ros`` / ``ros-yaml``: one ``trajectory_msgs/JointTrajectory``-shaped document per entry
  (:func:`joint_trajectory_msg`; JSON, or YAML with PyYAML) plus ``index.csv``;
- ``rosbag2`` (``library export`` only): one ROS 2 bag per entry, written by
  :mod:`planner.library.rosbag` (the ``ros`` extra).

``rate`` (Hz, csv and ros): resample every entry on a fixed control grid t0 + k/rate with the
valve commands recomputed at that rate (:func:`planner.feedforward.commands`) and the hydraulic
channels evaluated on the new rows (:func:`fixed_rate`). ``units_row`` (csv): a second line
``# s,rad,...`` with each column's unit (a comment line, so numpy / pandas ``comment="#"``
and the trajectory-CSV reader skip it).

Every file is written atomically; the library is opened read-only.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import csv
import json
import math
import os
import re
import tempfile
import tomllib
from io import BytesIO, StringIO
from pathlib import Path

import numpy as np

from planner.feedforward import commands, fills_oil
from planner.io import OutputError, atomic_write_bytes, atomic_write_text
from planner.library.journal import WriteFailed
from planner.library.store import FORMAT, LibraryStore, StoreError, as_str
from planner.model.spec import parse_spec
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane

INDEX_CSV_COLUMNS = ("id", "file", "start_r", "start_z", "start_slew", "goal_r", "goal_z",
                     "goal_slew", "objective", "method", "status", "duration_s", "energy_J",
                     "robustness", "reason")
#: index.csv's columns after those of a library built with a grapple (planner.library.swing)
SWING_CSV_COLUMNS = ("grapple_m", "swing_residual_m", "swing_peak_m", "clearance_m",
                     "load_clearance_m")


def _unique(name: str, used: set, maxlen: int) -> str:
    base, k = name[:maxlen], 1
    out = base
    while out.lower() in used:  # case-insensitive: file names on macOS / Windows
        k += 1
        suffix = f"_{k}"
        out = base[:maxlen - len(suffix)] + suffix
    used.add(out.lower())
    return out


def file_stem(entry_id: str, used: set) -> str:
    """A safe, unique file stem for an entry id ([A-Za-z0-9_.+-], no leading dot, not
    'index', <= 100 chars; unique case-insensitively among ``used``, which it extends)."""
    stem = re.sub(r"[^A-Za-z0-9_.+-]", "_", entry_id).lstrip(".") or "entry"
    if stem.lower() == "index":
        stem = "entry_index"
    return _unique(stem, used, 100)


def matlab_name(entry_id: str, used: set) -> str:
    """A valid, unique MATLAB identifier (letter first, [A-Za-z0-9_], <= 63 chars) for an id."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", entry_id)
    if not name or not name[0].isalpha():
        name = "e_" + name
    return _unique(name, used, 63)


def _jsonable(o):
    """Plain JSON types; non-finite floats -> None (strict JSON)."""
    if isinstance(o, np.ndarray):
        if o.dtype.kind == "f" and not np.all(np.isfinite(o)):
            return _jsonable(o.astype(object))
        if o.dtype.kind in "fiub":
            return o.tolist()
        return [_jsonable(v) for v in o.tolist()]
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, np.generic):
        o = o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, bytes):
        return as_str(o)
    if o is None or isinstance(o, (str, int, float, bool)):
        return o
    return str(o)


def _fmt(v: float) -> str:
    return "" if not math.isfinite(v) else f"{v:.10g}"


# ----------------------------------------------------------------------------- channel tables
EXPORT_FORMATS = ("csv", "mat", "json", "ros", "ros-yaml")
HYD_CSV_CHANNELS = ("x", "xd", "p_a", "p_b")  # per joint; then q_pump, power (per machine)


def _csv_name(channel: str, joint: str) -> str:
    """Column of a per-joint channel: p_a -> p_<joint>_a (as in the measured-data CSV)."""
    if channel in ("p_a", "p_b"):
        return f"p_{joint}_{channel[-1]}"
    return f"{channel}_{joint}"


def channel_table(traj: Trajectory, hyd: dict | None = None, spec=None):
    """Columns, units and rows of a trajectory CSV (CONTRACT: t, q_*, qd_*, qdd_*, then u_*
    when the trajectory has commands), followed by the hydraulic channels of ``hyd`` (arrays on
    the trajectory's rows: x_*, xd_* [m | rad (rotary motors)], p_*_a, p_*_b [Pa], q_pump
    [m³/s], power [W]) when given. ``spec`` (the CraneSpec) sets the units of revolute /
    prismatic joints and rotary actuators; without it they read 'rad|m'.
    Returns (columns, units, data (N, C))."""
    names = list(traj.joint_names)
    joints = {j.name: j for j in spec.joints} if spec is not None else {}

    def unit(j, kind, suffix=""):
        """'rad' | 'm' (+ suffix) of a joint's position (kind 'q') or actuator stroke ('x')."""
        jt = joints.get(j)
        if jt is None:
            return f"rad{suffix}|m{suffix}"
        if kind == "x":
            return ("rad" if jt.actuator.kind == "rotary" else "m") + suffix
        return ("rad" if jt.revolute else "m") + suffix

    cols, units, data = ["t"], ["s"], [traj.t[:, None]]
    for p, suffix in (("q", ""), ("qd", "/s"), ("qdd", "/s^2")):
        cols += [f"{p}_{j}" for j in names]
        units += [unit(j, "q", suffix) for j in names]
        data.append(getattr(traj, p))
    if traj.u is not None:
        cols += [f"u_{j}" for j in names]
        units += ["1"] * len(names)
        data.append(traj.u)
    if hyd is not None:
        for c in HYD_CSV_CHANNELS:
            cols += [_csv_name(c, j) for j in names]
            if c in ("p_a", "p_b"):
                units += ["Pa"] * len(names)
            else:
                units += [unit(j, "x", "/s" if c == "xd" else "") for j in names]
            data.append(np.asarray(hyd[c], float).reshape(len(traj.t), len(names)))
        cols += ["q_pump", "power"]
        units += ["m^3/s", "W"]
        data += [np.asarray(hyd["q_pump"], float).reshape(-1, 1),
                 np.asarray(hyd["power"], float).reshape(-1, 1)]
    return cols, units, np.hstack(data)


def table_csv_text(cols, units, data, units_row: bool = False) -> str:
    """CSV text: the header row, optionally the units as a comment row ``# s,rad,...`` (one
    cell per column), then one row per sample (10 significant digits; empty for non-finite)."""
    lines = [",".join(cols)]
    if units_row:
        lines.append("# " + ",".join(units))
    lines += [",".join(_fmt(v) for v in row) for row in data]
    return "\n".join(lines) + "\n"


def fixed_rate(crane: Crane, traj: Trajectory, rate: float):
    """``traj`` on the fixed control grid t0 + k/rate (k = 0 … ceil(duration·rate)) with the
    valve commands of :func:`planner.feedforward.commands` at that rate (zero-order hold, "mean"
    hold; the machine's: the oil springs filled where the crane has ``[dynamics]``) and the
    hydraulic channels of the crane model on the same rows.
    Returns (Trajectory with ``u``, hydraulics dict)."""
    if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate = {rate!r}: must be a positive number of Hz")
    out = commands(crane, traj, float(rate), oil=fills_oil(crane)).attach(traj)
    return out, crane.hydraulics(out.q, out.qd, out.qdd)


def write_trajectory_csv(path, crane: Crane, traj: Trajectory, *, rate: float | None = None,
                         units_row: bool = False) -> Trajectory:
    """A controller's trajectory CSV: with ``rate`` the fixed-rate samples with valve commands
    ``u_*`` (:func:`fixed_rate`), else the trajectory's own samples (``u_*`` if it has them);
    both followed by the hydraulic channels (:func:`channel_table`). Written atomically;
    returns the trajectory written."""
    if rate is not None:
        traj, hyd = fixed_rate(crane, traj, rate)
    else:
        hyd = crane.hydraulics(traj.q, traj.qd, traj.qdd)
    cols, units, data = channel_table(traj, hyd, crane.spec)
    atomic_write_text(path, table_csv_text(cols, units, data, units_row))
    return traj


# ----------------------------------------------------------------------------- ROS
def ros_time(t: float) -> dict:
    """builtin_interfaces/Duration of ``t`` >= 0 seconds: {sec, nanosec} (nanosec < 1e9)."""
    ns = int(round(float(t) * 1e9))
    return dict(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def joint_trajectory_msg(traj: Trajectory, frame_id: str = "base_link") -> dict:
    """A ``trajectory_msgs/JointTrajectory``-shaped dict: header (frame_id, stamp 0),
    joint_names, and one point per sample with positions [rad | m], velocities, accelerations,
    empty effort and time_from_start {sec, nanosec} relative to the first sample."""
    t0 = float(traj.t[0])
    points = [dict(positions=traj.q[k].tolist(), velocities=traj.qd[k].tolist(),
                   accelerations=traj.qdd[k].tolist(), effort=[],
                   time_from_start=ros_time(float(traj.t[k]) - t0))
              for k in range(len(traj.t))]
    return dict(header=dict(stamp=dict(sec=0, nanosec=0), frame_id=frame_id),
                joint_names=list(traj.joint_names), points=points)


def _dump_ros(doc: dict, fmt: str) -> str:
    if fmt == "ros":
        return json.dumps(doc, allow_nan=False, indent=1) + "\n"
    try:
        import yaml  # optional (PyYAML): only for --format ros-yaml
    except ImportError:
        raise StoreError("export format 'ros-yaml' needs PyYAML (pip install pyyaml); "
                         "'ros' writes the same message as JSON") from None
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


# ----------------------------------------------------------------------------- one-entry database
def write_single_entry(path, crane: Crane, traj: Trajectory, *, entry_id: str, start, goal,
                       objective: str, method: str, evaluation=None, attrs=None) -> Path:
    """``plan --out FILE.h5``: a library database holding this one entry (CONTRACT: trajectory
    database), written to a temporary file beside ``path`` and renamed over it, so an existing
    file is replaced whole or not at all. Refuses to replace a library of more than one entry."""
    path = Path(path)
    if path.exists():
        try:
            with LibraryStore.open(path, "r") as db:
                n = len(db)
        except (StoreError, OSError):
            n = 0  # not a library (or unreadable): replaced like any other output file
        if n > 1:
            raise StoreError(f"{path} is a library of {n} entries; a one-entry database "
                             "replaces only a file of at most one: choose another file name")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.chmod(tmp, 0o666 & ~umask)
        with LibraryStore.create(tmp, crane.spec, overwrite=True) as db:
            db.add(entry_id, traj, start=start, goal=goal, objective=objective, method=method,
                   status="ok", evaluation=evaluation, attrs=attrs)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass  # already gone
        if isinstance(e, WriteFailed):   # a full disk: name the user's file, not the temporary
            raise OutputError(path, e.why) from None
        raise
    return path


# ----------------------------------------------------------------------------- library export
def _entry_hyd(db, eid):
    """The stored hydraulic channels of an entry (None when it was stored without them)."""
    e = db.entry(eid)
    if not all(k in e for k in HYD_CSV_CHANNELS + ("q_pump", "power")):
        return None
    return e


def index_csv_text(rows, files, reasons, swing=None) -> str:
    """index.csv: one row per entry (:data:`INDEX_CSV_COLUMNS`); ``files`` maps an id to the
    file (or folder) written for it, empty for entries without a trajectory. ``swing`` (a
    library built with a grapple): per id its stored :data:`SWING_CSV_COLUMNS` (the model's
    swing and the load's clearance, planner.library.swing), appended as columns."""
    buf = StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(INDEX_CSV_COLUMNS + (SWING_CSV_COLUMNS if swing else ()))
    for r in rows:
        extra = ([_fmt(swing[r["id"]].get(k, math.nan)) for k in SWING_CSV_COLUMNS]
                 if swing else [])
        w.writerow([r["id"], files[r["id"]], *(_fmt(v) for v in r["start"]),
                    *(_fmt(v) for v in r["goal"]), r["objective"], r["method"],
                    r["status"], _fmt(r["duration_s"]), _fmt(r["energy_J"]),
                    _fmt(r["robustness"]), reasons[r["id"]], *extra])
    return buf.getvalue()


def swing_columns(db, rows) -> dict | None:
    """Per entry id its stored swing attributes (:data:`SWING_CSV_COLUMNS`), or None when no
    entry has them (a library built without a grapple)."""
    out = {}
    for r in rows:
        a = db.entry_attrs(r["id"])
        out[r["id"]] = {k: a[k] for k in SWING_CSV_COLUMNS if a.get(k) is not None}
    return out if any(out.values()) else None


def _replayed(db, eid, traj, which):
    """The entry's trajectory carrying the commands a controller replays (``which``: auto |
    nominal | refined; :func:`planner.library.refined.entry_commands`) and which they are."""
    from planner.feedforward import on_command_grid
    from planner.library.refined import entry_commands
    t_u, u, used, _ = entry_commands(db, eid, traj, which)
    return (on_command_grid(traj, t_u, u) if used == "refined" else traj), used


def _export_per_entry(db, rows, reasons, out_dir, fmt, rate, units_row,
                      which="auto") -> list[Path]:
    """csv / ros: one file per entry with a trajectory (its refined commands on their 50 Hz
    grid when ``which`` takes them), and index.csv."""
    spec = parse_spec(tomllib.loads(db.spec_toml), "<library spec>") if db.spec_toml else None
    crane = None
    if rate is not None:
        from planner.model import Crane  # the CasADi model: only to resample
        if spec is None:
            raise StoreError(f"{db.path}: no embedded crane spec; `rate` needs the model")
        crane = Crane(spec)
    ext = {"csv": ".csv", "ros": ".json", "ros-yaml": ".yaml"}[fmt]
    used: set = set()
    files, written = {}, []
    for r in rows:
        eid = r["id"]
        if not db.has_trajectory(eid):
            files[eid] = ""
            continue
        name = file_stem(eid, used) + ext
        p = out_dir / name
        traj = db.trajectory(eid)
        hyd = None
        traj, which_used = _replayed(db, eid, traj, which)
        if which_used == "refined":
            if rate is not None and abs(rate - 1.0 / (traj.t[1] - traj.t[0])) > 1e-6 * rate:
                raise StoreError(f"{db.path}: entry '{eid}': refined commands are on their "
                                 f"{1.0 / (traj.t[1] - traj.t[0]):g} Hz grid, not {rate:g} Hz; "
                                 "export them at that rate, or the nominal commands")
            if fmt == "csv":
                from planner.model import Crane
                crane_r = crane or Crane(spec)
                hyd = crane_r.hydraulics(traj.q, traj.qd, traj.qdd)
        elif crane is not None:
            traj, hyd = fixed_rate(crane, traj, rate)
        elif fmt == "csv":
            hyd = _entry_hyd(db, eid)
        if fmt == "csv":
            cols, units, data = channel_table(traj, hyd, spec)
            atomic_write_text(p, table_csv_text(cols, units, data, units_row))
        else:
            atomic_write_text(p, _dump_ros(joint_trajectory_msg(traj), fmt))
        files[eid] = name
        written.append(p)
    p = out_dir / "index.csv"
    atomic_write_text(p, index_csv_text(rows, files, reasons, swing_columns(db, rows)))
    written.append(p)
    return written


def export(db_path, out_dir, fmt: str, *, rate: float | None = None,
           units_row: bool = False, commands: str = "auto") -> list[Path]:
    """Export a library: fmt "csv" (one trajectory CSV per entry with a trajectory, per the
    trajectory-CSV contract plus the stored hydraulic channels, and index.csv), "mat"
    (library.mat: struct ``entries`` with one field per entry, struct ``index``, ``crane_id``,
    ``spec_toml``), "json" (library.json: index rows and entries as lists), "ros" / "ros-yaml"
    (one JointTrajectory-shaped JSON / YAML file per entry, and index.csv). ``rate`` [Hz]
    (csv, ros): resample on a fixed grid with the valve commands at that rate
    (:func:`fixed_rate`); ``units_row`` (csv): a units comment line under the header.
    ``commands`` (csv, ros): which valve commands an entry's file carries — "auto" (the
    refined ones of ``library refine`` where present), "nominal", "refined"; mat and json
    carry both (``t_u_refined``, ``u_refined`` beside ``u``).
    Every file is written atomically. Returns the paths."""
    if fmt not in EXPORT_FORMATS:
        raise StoreError(f"export format must be one of {', '.join(EXPORT_FORMATS)}, "
                         f"got {fmt!r}")
    if rate is not None and fmt not in ("csv", "ros", "ros-yaml"):
        raise StoreError(f"`rate` applies to the csv and ros formats, not {fmt!r}")
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise StoreError(f"`rate` {rate}: must be a positive number of Hz")
    if units_row and fmt != "csv":
        raise StoreError(f"`units_row` applies to the csv format, not {fmt!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with LibraryStore.open(db_path, "r") as db:
        rows = db.index_rows()
        reasons = {r["id"]: db.entry_attrs(r["id"]).get("reason", "") for r in rows}
        if fmt in ("csv", "ros", "ros-yaml"):
            return _export_per_entry(db, rows, reasons, out_dir, fmt, rate, units_row,
                                     commands)
        if fmt == "mat":
            from scipy.io import savemat
            used = set()
            entries, names = {}, []
            for r in rows:
                e = _with_refined(db, r["id"], db.entry(r["id"]))
                a = e.pop("attrs")
                name = matlab_name(r["id"], used)
                names.append(name)
                s = {k: np.asarray(v, float) for k, v in e.items()}
                s.update(id=r["id"], status=r["status"], method=r["method"],
                         objective=r["objective"], reason=str(a.get("reason", "")),
                         joint_names=np.array(list(a.get("joint_names", [])), dtype=object),
                         solver_stats=json.dumps(a.get("solver_stats", {}), default=str),
                         refined=json.dumps(a.get("refined", {}), default=str),
                         provenance=json.dumps(a.get("provenance", {})))
                entries[name] = s
            n = len(rows)
            index = dict(
                id=np.array([r["id"] for r in rows], dtype=object).reshape(n, 1),
                field=np.array(names, dtype=object).reshape(n, 1),
                start=np.array([r["start"] for r in rows], float).reshape(n, 3),
                goal=np.array([r["goal"] for r in rows], float).reshape(n, 3),
                objective=np.array([r["objective"] for r in rows], dtype=object).reshape(n, 1),
                method=np.array([r["method"] for r in rows], dtype=object).reshape(n, 1),
                status=np.array([r["status"] for r in rows], dtype=object).reshape(n, 1),
                duration_s=np.array([r["duration_s"] for r in rows], float).reshape(n, 1),
                energy_J=np.array([r["energy_J"] for r in rows], float).reshape(n, 1),
                robustness=np.array([r["robustness"] for r in rows], float).reshape(n, 1))
            buf = BytesIO()
            savemat(buf, dict(crane_id=db.crane_id, spec_toml=db.spec_toml, index=index,
                              entries=entries), long_field_names=True, do_compression=True,
                    oned_as="column")
            p = out_dir / "library.mat"
            atomic_write_bytes(p, buf.getvalue())
            written.append(p)
        else:
            entries = []
            for r in rows:
                e = _with_refined(db, r["id"], db.entry(r["id"]))
                a = e.pop("attrs")
                d = dict(id=r["id"], **{k: v for k, v in a.items()})
                if "solve_s" in d:  # the unified name beside the stored one (docs/json-keys.md)
                    d.setdefault("solve_time_s", d["solve_s"])
                d.update({k: np.asarray(v, float) for k, v in e.items()})
                entries.append(d)
            doc = dict(format=FORMAT, format_version=db.format_version, crane_id=db.crane_id,
                       planner_version=db.attrs.get("planner_version"),
                       index=[dict(r, reason=reasons[r["id"]]) for r in rows], entries=entries)
            p = out_dir / "library.json"
            # one pass, arrays via tolist(): planner.io.dumps round-trips the whole document
            # three times, which is ~10x slower on large libraries
            atomic_write_text(p, json.dumps(_jsonable(doc), allow_nan=False,
                                            separators=(",", ":")) + "\n")
            written.append(p)
    return written


def _with_refined(db, eid, e: dict) -> dict:
    """An entry's arrays plus its refined commands (``t_u_refined``, ``u_refined``) and their
    provenance (attrs ``refined``), when it has them."""
    from planner.library.refined import read_refined
    r = read_refined(db, eid) if "t" in e else None
    if r is not None:
        e["t_u_refined"], e["u_refined"] = r[0], r[1]
        e["attrs"] = dict(e["attrs"], refined=r[2])
    return e
