"""What the library store checks before it writes a field, and its error type: entry ids and
index strings (UTF-8, at most ``MAX_STR`` bytes), tip points (r, z, slew), and the pick of an
Evaluation's channels at a trajectory's sample times (:mod:`planner.library.store`)."""
from __future__ import annotations

import numpy as np

MAX_STR = 64  # bytes, fixed-length strings of the index table


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
