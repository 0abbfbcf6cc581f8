"""Export of a library database (:mod:`planner.library.store`) for other tools.

- ``csv``: one trajectory CSV per entry that has a trajectory (CONTRACT: trajectory CSV) and
  ``index.csv`` (columns :data:`INDEX_CSV_COLUMNS`; empty ``file`` for failed entries);
- ``mat``: ``library.mat`` with struct ``entries`` (one field per entry, named by
  :func:`matlab_name`), struct ``index``, ``crane_id`` and ``spec_toml``;
- ``json``: ``library.json`` with the index rows and the entries' arrays as lists (strict JSON:
  non-finite numbers are null).

Every file is written atomically; the library is opened read-only.
"""
from __future__ import annotations

import csv
import json
import math
import re
from io import BytesIO, StringIO
from pathlib import Path

import numpy as np

from planner.io import atomic_write_bytes, atomic_write_text
from planner.library.store import FORMAT, LibraryStore, StoreError, as_str

INDEX_CSV_COLUMNS = ("id", "file", "start_r", "start_z", "start_slew", "goal_r", "goal_z",
                     "goal_slew", "objective", "method", "status", "duration_s", "energy_J",
                     "robustness", "reason")


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


def export(db_path, out_dir, fmt: str) -> list[Path]:
    """Export a library: fmt "csv" (one trajectory CSV per entry with a trajectory, per the
    trajectory-CSV contract, plus index.csv), "mat" (library.mat: struct ``entries`` with one
    field per entry, struct ``index``, ``crane_id``, ``spec_toml``) or "json" (library.json:
    index rows and entries as lists). Every file is written atomically. Returns the paths."""
    if fmt not in ("csv", "mat", "json"):
        raise StoreError(f"export format must be 'csv', 'mat' or 'json', got {fmt!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    with LibraryStore.open(db_path, "r") as db:
        rows = db.index_rows()
        reasons = {r["id"]: db.entry_attrs(r["id"]).get("reason", "") for r in rows}
        if fmt == "csv":
            used: set = set()
            files = {}
            for r in rows:
                if not db.has_trajectory(r["id"]):
                    files[r["id"]] = ""
                    continue
                name = file_stem(r["id"], used) + ".csv"
                p = out_dir / name
                db.trajectory(r["id"]).to_csv(p)
                files[r["id"]] = name
                written.append(p)
            buf = StringIO()
            w = csv.writer(buf, lineterminator="\n")
            w.writerow(INDEX_CSV_COLUMNS)
            for r in rows:
                w.writerow([r["id"], files[r["id"]], *(_fmt(v) for v in r["start"]),
                            *(_fmt(v) for v in r["goal"]), r["objective"], r["method"],
                            r["status"], _fmt(r["duration_s"]), _fmt(r["energy_J"]),
                            _fmt(r["robustness"]), reasons[r["id"]]])
            p = out_dir / "index.csv"
            atomic_write_text(p, buf.getvalue())
            written.append(p)
        elif fmt == "mat":
            from scipy.io import savemat
            used = set()
            entries, names = {}, []
            for r in rows:
                e = db.entry(r["id"])
                a = e.pop("attrs")
                name = matlab_name(r["id"], used)
                names.append(name)
                s = {k: np.asarray(v, float) for k, v in e.items()}
                s.update(id=r["id"], status=r["status"], method=r["method"],
                         objective=r["objective"], reason=str(a.get("reason", "")),
                         joint_names=np.array(list(a.get("joint_names", [])), dtype=object),
                         solver_stats=json.dumps(a.get("solver_stats", {}), default=str),
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
                e = db.entry(r["id"])
                a = e.pop("attrs")
                d = dict(id=r["id"], **{k: v for k, v in a.items()})
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
