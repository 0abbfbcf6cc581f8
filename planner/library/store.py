"""The library database: one HDF5 file per library (CONTRACT: trajectory database). Its
CSV / MAT / JSON export is :mod:`planner.library.export`, the nearest-entry query and the join
from a joint state :mod:`planner.library.query`.

File layout (``format`` = "crane-planner-library", ``format_version`` = 1)::

    /                       attrs: format, format_version, crane_id, created (ISO 8601, UTC),
                                   planner_version, joint_names
    /spec_toml              scalar variable-length UTF-8 string: the crane spec's TOML verbatim
    /index                  resizable 1-D compound dataset, one row per *finished* entry:
                              id          fixed-length UTF-8 string (<= 64 bytes)
                              start, goal 3 x float64: tip (r [m], z [m], slew [rad])
                              objective, method, status   fixed-length UTF-8 strings (<= 64 bytes)
                              duration_s, energy_J, robustness   float64 (NaN = not available)
    /entries/<id>           one group per entry; attrs: method, objective, status, reason,
                            solver_stats (JSON: the producing method's Trajectory.meta),
                            provenance (JSON: crane_id, planner_version, date), joint_names,
                            interpolation, limits (JSON), evaluation (JSON summary, if given),
                            plus the caller's ``attrs``
        t                   (N,)      s
        q, qd, qdd          (N, n)    rad | m, and rates
        u                   (N, n)    valve commands (-1..1), when the trajectory has them
        x, xd, p_a, p_b     (N, n)    cylinder strokes [m], stroke rates [m/s], chamber pressures
        q_pump, power       (N,)      pump flow [m^3/s], pump power [W]
                            (these six only when an Evaluation was passed to add())

Arrays are row-major "samples x joints" (MATLAB's h5read shows them transposed, joints x
samples); each dataset carries a ``units`` attribute; datasets are uncompressed unless the
store was opened with ``compress=True`` (gzip + shuffle, readable by MATLAB). A failed entry
(status != "ok") has an index row and a group with attributes only (its ``reason``).

Derived channels: evaluate() samples on a fine grid that contains every original sample time, so
the stored x, xd, p_a, p_b, q_pump, power are evaluate()'s own values picked *exactly* at the
trajectory's times (no re-computation, no interpolation; linear interpolation is only a fallback
for an Evaluation made on a grid without them). Computing the Evaluation is the caller's job.

Crash safety and resume: an entry's group is written completely and flushed, *then* its index
row is appended and flushed. A group without an index row is an unfinished write: opening the
file in mode "a" deletes it (``LibraryStore.cleaned`` says how many), so a killed build loses at
most the entries in flight and resumes with ``has(id)``. A writer goes through a rollback journal
(:mod:`planner.library.journal`): a failed write (full disk, file-size limit) or a writer killed
mid-flush rolls the file back to its last complete entry. (HDF5 does not reclaim the space of
deleted groups; h5repack compacts a file if that matters.) The driver is the single writer.
"""
from __future__ import annotations

import json
import math
import re
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np

from planner.io import dumps
from planner.library.fields import (MAX_STR, StoreError, as_str, check_format, check_id,
                                    check_text, on_grid, tip3)
from planner.library.journal import abandon_h5, close_h5, open_h5
from planner.library.lock import LibraryBusy, busy_message
from planner.library.query import index_summary, nearest_entry
from planner.trajectory import LIMIT_KINDS, Trajectory

FORMAT = "crane-planner-library"
FORMAT_VERSION = 1

_STR = h5py.string_dtype("utf-8", MAX_STR)
INDEX_DTYPE = np.dtype([("id", _STR), ("start", "<f8", (3,)), ("goal", "<f8", (3,)),
                        ("objective", _STR), ("method", _STR), ("status", _STR),
                        ("duration_s", "<f8"), ("energy_J", "<f8"), ("robustness", "<f8")])
TRAJ_CHANNELS = ("t", "q", "qd", "qdd", "u")
HYD_CHANNELS = ("x", "xd", "p_a", "p_b", "q_pump", "power")
UNITS = dict(t="s", q="rad|m", qd="rad/s|m/s", qdd="rad/s^2|m/s^2", u="1 (valve command, -1..1)",
             x="m", xd="m/s", p_a="Pa", p_b="Pa", q_pump="m^3/s", power="W")
RESERVED_ATTRS = {"method", "objective", "status", "reason", "solver_stats", "provenance",
                  "joint_names", "interpolation", "limits", "evaluation"}


def _planner_version() -> str:
    from planner.version import __version__
    return __version__


def _now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _unreadable(path, e) -> str:
    """Why HDF5 cannot open the library ``path`` (``e``), in one line."""
    m = re.search(r"truncated file: eof = (\d+).*stored_eof = (\d+)", str(e))
    if m:
        return (f"{path}: damaged library: the file has {m[1]} of its {m[2]} bytes (cut "
                "short, e.g. an interrupted copy); restore it, or move it away and rebuild")
    return f"{path}: cannot open the HDF5 file ({e})"


def _abandon(f, jf, e):
    """Close ``f`` after ``e``: a writer's file is rolled back to its last commit."""
    if jf is None:
        f.close()
        raise e
    abandon_h5(f, jf, e)


class LibraryStore:
    """One library file. Use :meth:`create` or :meth:`open`; a context manager closes it.

    Writer API: :meth:`add` (one call per finished entry). Reader API: :meth:`has`, :meth:`ids`,
    :meth:`index_rows`, :meth:`trajectory`, :meth:`entry`, :meth:`info`, :meth:`nearest`."""

    def __init__(self, f: h5py.File, path: Path, mode: str, jf=None):
        self._f, self._jf = f, jf  # jf: the JournaledFile of a writer (planner.library.journal)
        self.path = path
        self.mode = mode
        self.cleaned = 0  # unfinished entry groups removed on open (mode "a")
        # gzip (deflate 4) + shuffle for new datasets: ~35 % smaller files, ~2x slower writes
        # (the samples are noisy floats); off by default. MATLAB reads either.
        self.compress = False
        self.crane_id = as_str(f.attrs["crane_id"])
        self.format_version = int(f.attrs["format_version"])
        self._load_index()

    # ------------------------------------------------------------------ opening
    @classmethod
    def create(cls, path, spec, *, overwrite: bool = False,
               compress: bool = False) -> "LibraryStore":
        """New library file for the crane ``spec`` (a CraneSpec). Refuses to replace an existing
        file unless ``overwrite``. ``compress``: gzip the entry datasets."""
        path = Path(path)
        if path.exists() and not overwrite:
            raise FileExistsError(f"{path}: library file exists already (open it with mode 'a' "
                                  "to resume, or pass overwrite=True)")
        if not getattr(spec, "id", ""):
            raise StoreError(f"{path}: a crane spec with an id is needed to create a library")
        path.parent.mkdir(parents=True, exist_ok=True)
        f, jf = open_h5(path, "w")
        try:
            f.attrs["format"] = FORMAT
            f.attrs["format_version"] = np.int64(FORMAT_VERSION)
            f.attrs["crane_id"] = spec.id
            f.attrs["created"] = _now()
            f.attrs["planner_version"] = _planner_version()
            f.attrs["joint_names"] = list(spec.joint_names)
            f.create_dataset("spec_toml", data=spec.text or "",
                             dtype=h5py.string_dtype("utf-8"))
            f.create_dataset("index", shape=(0,), maxshape=(None,), dtype=INDEX_DTYPE,
                             chunks=(256,))
            f.create_group("entries")
            f.flush()
            jf.commit()
            db = cls(f, path, "a", jf)
            db.compress = compress
            return db
        except BaseException as e:
            _abandon(f, jf, e)

    @classmethod
    def open(cls, path, mode: str = "r", spec=None, *, compress: bool = False) -> "LibraryStore":
        """Open an existing library: mode "r" (read) or "a" (append; removes unfinished entry
        groups). With ``spec``, refuse a library of another crane. ``compress``: gzip the
        datasets of entries added from now on."""
        if mode not in ("r", "a"):
            raise StoreError(f"LibraryStore.open: mode must be 'r' or 'a', got {mode!r}")
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such library file")
        if not h5py.is_hdf5(path):
            with open(path, "rb") as fh:
                head = fh.read(16)
            raise StoreError(f"{path}: not an HDF5 file (first bytes {head!r}); expected a "
                             f"'{FORMAT}' library")
        jf = None
        try:
            f, jf = open_h5(path, mode) if mode == "a" else (h5py.File(path, mode), None)
        except BlockingIOError:
            raise LibraryBusy(busy_message(path) or f"{path} is locked by another "
                              "process") from None
        except OSError as e:  # most often another process has it open for writing
            busy = busy_message(path)
            raise (LibraryBusy(busy) if busy else StoreError(_unreadable(path, e))) from None
        try:
            check_format(f, path, FORMAT, FORMAT_VERSION)
            if spec is not None and as_str(f.attrs["crane_id"]) != spec.id:
                raise StoreError(f"{path}: library is for crane '{as_str(f.attrs['crane_id'])}', "
                                 f"not '{spec.id}'")
            db = cls(f, path, mode, jf)
            db.compress = compress
            if mode == "a":
                db.cleaned = db._clean_unfinished()
                jf.commit()
            return db
        except BaseException as e:
            _abandon(f, jf, e)

    def _load_index(self):
        rows = self._f["index"][()]
        self._ids = [as_str(x) for x in rows["id"]]
        self._idset = set(self._ids)

    def _clean_unfinished(self) -> int:
        ent = self._f["entries"]
        stale = [k for k in ent.keys() if k not in self._idset]
        for k in stale:
            del ent[k]
        if stale:
            self._f.flush()
        return len(stale)

    def close(self):
        if self._jf is not None:
            jf, self._jf = self._jf, None
            close_h5(self._f, jf)
        elif self._f is not None and self._f.id.valid:
            self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return (f"LibraryStore({str(self.path)!r}, crane={self.crane_id!r}, "
                f"entries={len(self._ids)})")

    def __len__(self):
        return len(self._ids)

    def __contains__(self, entry_id):
        return entry_id in self._idset

    # ------------------------------------------------------------------ properties
    @property
    def spec_toml(self) -> str:
        return as_str(self._f["spec_toml"][()])

    @property
    def attrs(self) -> dict:
        return {k: (as_str(v) if isinstance(v, (bytes, str)) else v)
                for k, v in self._f.attrs.items()}

    def has(self, entry_id: str) -> bool:
        return entry_id in self._idset

    def ids(self) -> list[str]:
        """Ids of finished entries, in the order they were added."""
        return list(self._ids)

    # ------------------------------------------------------------------ writing
    def add(self, entry_id: str, traj: Trajectory | None, *, start, goal, objective: str,
            method: str, status: str, reason: str = "", evaluation=None,
            robustness: float = math.nan, attrs: dict | None = None) -> None:
        """Store one finished entry (crash-safe: group first, then its index row).

        ``traj`` is required for status "ok" and optional otherwise (a failed entry is just an
        index row and a group with attributes). ``evaluation`` (evaluate(crane, traj)) adds the
        derived channels and energy_J; ``attrs`` are extra group attributes (str / numbers stored
        as such, anything else as JSON)."""
        if self.mode != "a":
            raise StoreError(f"{self.path}: opened read-only; open with mode 'a' to add entries")
        check_id(entry_id)
        if entry_id in self._idset:
            raise StoreError(f"{self.path}: entry '{entry_id}' exists already (ids are unique)")
        start, goal = tip3("start", start), tip3("goal", goal)
        if isinstance(status, str):
            status = str(status)   # a PlanStatus member is stored as its plain code (h5py)
        for k, v in (("objective", objective), ("method", method), ("status", status)):
            check_text(k, v, allow_empty=(k != "status"))
        if status == "ok" and traj is None:
            raise StoreError(f"entry '{entry_id}': status 'ok' needs a trajectory")
        if evaluation is not None and traj is None:
            raise StoreError(f"entry '{entry_id}': an evaluation needs its trajectory")
        bad = sorted(RESERVED_ATTRS & set(attrs or {}))
        if bad:
            raise StoreError(f"entry '{entry_id}': attrs may not override {bad}")
        if entry_id in self._f["entries"]:  # leftover of an unfinished write in this session
            del self._f["entries"][entry_id]
        try:
            self._write_group(entry_id, traj, objective=objective, method=method, status=status,
                              reason=reason, evaluation=evaluation, attrs=attrs)
            self._f.flush()
        except BaseException as e:
            if self._jf is not None and self._jf.failed:
                self._fail(e)
            if entry_id in self._f["entries"]:
                del self._f["entries"][entry_id]
            raise
        duration = traj.duration if traj is not None else math.nan
        energy = float(evaluation.energy_J) if evaluation is not None else math.nan
        row = np.zeros((), dtype=INDEX_DTYPE)
        row["id"], row["start"], row["goal"] = entry_id.encode(), start, goal
        row["objective"], row["method"], row["status"] = (objective.encode(), method.encode(),
                                                          status.encode())
        row["duration_s"], row["energy_J"] = duration, energy
        row["robustness"] = float(robustness) if robustness is not None else math.nan
        self._append_row(row)

    def _write_group(self, entry_id, traj, *, objective, method, status, reason, evaluation,
                     attrs):
        """Write the complete entry group (no index row: on its own this is an unfinished write)."""
        g = self._f["entries"].create_group(entry_id)
        a = g.attrs
        a["method"], a["objective"], a["status"], a["reason"] = method, objective, status, reason
        a["provenance"] = json.dumps(dict(crane_id=self.crane_id,
                                          planner_version=_planner_version(), date=_now()))
        if traj is not None:
            a["joint_names"] = list(traj.joint_names)
            a["interpolation"] = traj.interpolation
            a["limits"] = json.dumps(list(traj.limits))
            a["solver_stats"] = dumps(traj.meta or {})
            for name in TRAJ_CHANNELS:
                arr = getattr(traj, name)
                if arr is not None:
                    self._dataset(g, name, arr)
            if evaluation is not None:
                ev_t = np.asarray(evaluation.t, float)
                if ev_t[0] > traj.t[0] + 1e-9 or ev_t[-1] < traj.t[-1] - 1e-9:
                    raise StoreError(f"entry '{entry_id}': evaluation covers t = [{ev_t[0]}, "
                                     f"{ev_t[-1]}], trajectory [{traj.t[0]}, {traj.t[-1]}]")
                qe = on_grid(ev_t, traj.t, evaluation.q)
                if qe.shape != traj.q.shape or not np.allclose(qe, traj.q, rtol=0, atol=1e-6):
                    raise StoreError(f"entry '{entry_id}': the evaluation is not of this "
                                     "trajectory (positions differ)")
                for name in HYD_CHANNELS:
                    if name in evaluation.hyd:
                        self._dataset(g, name, on_grid(ev_t, traj.t, evaluation.hyd[name]))
                a["evaluation"] = dumps(evaluation.summary())
            for name in g:
                g[name].attrs["units"] = UNITS.get(name, "")
        else:
            a["solver_stats"] = "{}"
        for k, v in (attrs or {}).items():
            if isinstance(v, (str, bool, int, float, np.integer, np.floating)):
                a[k] = v
            else:
                a[k] = dumps(v)

    def _dataset(self, g, name, data):
        data = np.asarray(data, dtype=float)
        kw = dict(compression="gzip", compression_opts=4, shuffle=True) \
            if self.compress and data.size >= 64 else {}
        g.create_dataset(name, data=data, **kw)

    def _append_row(self, row):
        ds = self._f["index"]
        n = ds.shape[0]
        try:
            ds.resize((n + 1,))
            ds[n] = row
            self._f.flush()
            if self._jf is not None:
                self._jf.commit()   # the entry is complete: the state to come back to
        except BaseException as e:
            if self._jf is not None and self._jf.failed:
                self._fail(e)
            raise
        eid = as_str(row["id"])
        self._ids.append(eid)
        self._idset.add(eid)

    def _fail(self, e):
        """A write failed: the file is rolled back to its last complete entry and closed
        (:mod:`planner.library.journal`); raises the one-line :class:`WriteFailed`."""
        jf, self._jf = self._jf, None
        _abandon(self._f, jf, e)

    # ------------------------------------------------------------------ reading
    def _index_array(self) -> np.ndarray:
        return self._f["index"][()]

    def index_columns(self) -> dict[str, np.ndarray]:
        """The index table column by column: id, objective, method, status (str arrays), start,
        goal ((n, 3) tips r, z, slew), duration_s, energy_J, robustness (NaN: not available)."""
        idx = self._index_array()
        out = {k: np.array([as_str(x) for x in idx[k]], dtype=object)
               for k in ("id", "objective", "method", "status")}
        out.update({k: np.asarray(idx[k], float) for k in ("start", "goal", "duration_s",
                                                            "energy_J", "robustness")})
        return out

    def index_rows(self) -> list[dict]:
        """One dict per finished entry: id, start, goal (tuples r, z, slew), objective, method,
        status, duration_s, energy_J, robustness (NaN when not available)."""
        out = []
        for r in self._index_array():
            out.append(dict(id=as_str(r["id"]), start=tuple(float(v) for v in r["start"]),
                            goal=tuple(float(v) for v in r["goal"]),
                            objective=as_str(r["objective"]), method=as_str(r["method"]),
                            status=as_str(r["status"]),
                            duration_s=float(r["duration_s"]), energy_J=float(r["energy_J"]),
                            robustness=float(r["robustness"])))
        return out

    def _group(self, entry_id):
        if entry_id not in self._idset:
            raise KeyError(f"{self.path}: no entry '{entry_id}' ({len(self._ids)} entries)")
        try:
            return self._f["entries"][entry_id]
        except KeyError:
            raise StoreError(f"{self.path}: corrupt library, index row '{entry_id}' has no "
                             "group") from None

    def entry_attrs(self, entry_id: str) -> dict:
        """The entry group's attributes (JSON attributes decoded)."""
        out = {}
        for k, v in self._group(entry_id).attrs.items():
            if isinstance(v, bytes):
                v = as_str(v)
            elif isinstance(v, np.ndarray):
                v = [as_str(x) for x in v] if v.dtype.kind in "OSU" else v.tolist()
            elif isinstance(v, np.generic):
                v = v.item()
            if k in ("solver_stats", "provenance", "limits", "evaluation") and isinstance(v, str):
                try:
                    v = json.loads(v)
                except ValueError:
                    pass  # not JSON (written by hand or an older file): keep the text
            out[k] = v
        return out

    def entry(self, entry_id: str) -> dict:
        """All datasets (arrays) and attributes of an entry: {'attrs': {...}, 't': ..., ...}."""
        g = self._group(entry_id)
        out = {name: g[name][()] for name in g if isinstance(g[name], h5py.Dataset)}
        out["attrs"] = self.entry_attrs(entry_id)
        return out

    def group(self, entry_id: str) -> h5py.Group:
        """The entry's HDF5 group, for data kept beside its trajectory (the refined commands of
        :mod:`planner.library.refined`); KeyError for an unknown id."""
        return self._group(entry_id)

    def commit(self) -> None:
        """Flush, and make the file as it is now the state a failed later write returns to."""
        if self.mode != "a":
            raise StoreError(f"{self.path}: opened read-only; open with mode 'a' to write")
        try:
            self._f.flush()
            if self._jf is not None:
                self._jf.commit()
        except BaseException as e:
            if self._jf is not None and self._jf.failed:
                self._fail(e)
            raise

    def has_trajectory(self, entry_id: str) -> bool:
        """Whether the entry stores sampled arrays (a failed entry has attributes only)."""
        return "t" in self._group(entry_id)

    def trajectory(self, entry_id: str) -> Trajectory:
        """The stored Trajectory (raises KeyError for unknown ids, StoreError when the entry has
        no trajectory, e.g. a failed one)."""
        g = self._group(entry_id)
        if "t" not in g:
            raise StoreError(f"{self.path}: entry '{entry_id}' has no trajectory (status "
                             f"'{as_str(g.attrs.get('status', ''))}': "
                             f"{as_str(g.attrs.get('reason', ''))})")
        a = self.entry_attrs(entry_id)
        limits = tuple(k for k in a.get("limits", LIMIT_KINDS) if k in LIMIT_KINDS)
        meta = a.get("solver_stats", {})
        return Trajectory(t=g["t"][()], q=g["q"][()], qd=g["qd"][()], qdd=g["qdd"][()],
                          u=g["u"][()] if "u" in g else None,
                          joint_names=tuple(a.get("joint_names", ())),
                          method=a.get("method", ""), objective=a.get("objective", ""),
                          interpolation=a.get("interpolation", "quintic"), limits=limits,
                          meta=meta if isinstance(meta, dict) else {})

    def info(self) -> dict:
        """Summary: file attributes, entry counts (total, ok, failures by status, by objective
        and method) and min / mean / max of duration_s, energy_J and robustness over the "ok"
        entries (:func:`planner.library.query.index_summary`)."""
        a = self.attrs
        return dict(file=str(self.path), format=a.get("format"),
                    format_version=self.format_version, crane_id=self.crane_id,
                    created=a.get("created"), planner_version=a.get("planner_version"),
                    **index_summary(self.index_rows()), cleaned=self.cleaned)

    def nearest(self, start, goal, objective: str | None = None) -> tuple[str, float]:
        """The "ok" entry (of ``objective``, if given) whose start and goal tips are nearest:
        distance = |start - start_e| + |goal - goal_e| in Cartesian space [m]. Returns
        (entry_id, distance_m); LookupError when there is no candidate.
        (:func:`planner.library.query.nearest_entry` on :meth:`index_columns`.)"""
        start, goal = tip3("start", start), tip3("goal", goal)
        return nearest_entry(self.index_columns(), start, goal, objective, where=self.path)
