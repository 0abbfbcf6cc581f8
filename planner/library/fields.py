"""What the library store checks before it writes a field, and its error type: entry ids and
index strings (UTF-8, at most ``MAX_STR`` bytes), tip points (r, z, slew), and the pick of an
Evaluation's channels at a trajectory's sample times, the file's format attributes
(:mod:`planner.library.store`)."""
from __future__ import annotations

import numpy as np

MAX_STR = 64  # bytes, fixed-length strings of the index table


def as_str(v) -> str:
    """An h5py attribute or fixed-length index field (bytes, str, 0-d array) -> str."""
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace").rstrip("\x00")
    if isinstance(v, np.ndarray) and v.shape == ():
        return as_str(v[()])
    return str(v)


class StoreError(ValueError):
    """A library file that cannot be used (foreign, corrupt, newer, other crane) or a bad call."""


def check_text(what: str, value: str, allow_empty=False) -> str:
    if not isinstance(value, str):
        raise StoreError(f"{what} must be a string, got {type(value).__name__}")
    n = len(value.encode("utf-8"))
    if n > MAX_STR or (n == 0 and not allow_empty):
        raise StoreError(f"{what} = {value!r}: must be 1..{MAX_STR} bytes (UTF-8), has {n}")
    return value


def check_id(entry_id: str) -> str:
    check_text("entry id", entry_id)
    if ("/" in entry_id or entry_id in (".", "..") or entry_id != entry_id.strip()
            or any(ord(c) < 32 or ord(c) == 127 for c in entry_id)):
        raise StoreError(f"entry id {entry_id!r}: no '/', no control characters, no leading or "
                         "trailing blanks, not '.' or '..'")
    return entry_id


def tip3(what: str, p) -> np.ndarray:
    a = np.asarray(p, dtype=float).ravel()
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise StoreError(f"{what} must be 3 finite numbers (r, z, slew), got {p!r}")
    return a


def on_grid(ev_t, t, a):
    """Evaluation array ``a`` (on ev_t) at the times t: exact pick, else linear interpolation."""
    a = np.asarray(a, dtype=float)
    k = np.clip(np.searchsorted(ev_t, t), 0, len(ev_t) - 1)
    if np.array_equal(ev_t[k], t):
        return a[k]
    if a.ndim == 1:
        return np.interp(t, ev_t, a)
    return np.column_stack([np.interp(t, ev_t, a[:, j]) for j in range(a.shape[1])])


def check_format(f, path, FORMAT: str, FORMAT_VERSION: int) -> None:  # noqa: N803
    """StoreError (one line: file, what is wrong, what was expected) unless the open HDF5 file
    ``f`` is a library of format ``FORMAT`` at most version ``FORMAT_VERSION``."""
    fmt = f.attrs.get("format")
    if fmt is None:
        raise StoreError(f"{path}: HDF5 file without the root attribute format = '{FORMAT}' "
                         f"(root attributes: {sorted(f.attrs.keys())}); not a library")
    if as_str(fmt) != FORMAT:
        raise StoreError(f"{path}: root attribute format = {as_str(fmt)!r}, "
                         f"expected '{FORMAT}'")
    try:
        ver = int(f.attrs["format_version"])
    except (KeyError, TypeError, ValueError):
        raise StoreError(f"{path}: missing or invalid root attribute format_version "
                         f"({f.attrs.get('format_version')!r})") from None
    if ver > FORMAT_VERSION:
        raise StoreError(f"{path}: format_version {ver} is newer than this planner reads "
                         f"({FORMAT_VERSION}); update crane-planner")
    missing = [k for k in ("crane_id",) if k not in f.attrs] + \
              [k for k in ("index", "entries", "spec_toml") if k not in f]
    if missing:
        raise StoreError(f"{path}: corrupt library, missing {', '.join(missing)}")
    if f["index"].dtype.names is None or "id" not in f["index"].dtype.names:
        raise StoreError(f"{path}: corrupt library, 'index' is not the index table "
                         f"(dtype {f['index'].dtype})")
