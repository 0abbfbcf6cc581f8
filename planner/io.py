"""Small file helpers: writes that never leave a half-written file, JSON output, and progress
reports on stderr.

Where an output goes (:func:`output_target`):

- a regular file (or a new name) is written to a temporary file in the same folder, flushed,
  and renamed over the target: a reader sees the old or the new content, never a part;
- a symbolic link is followed and its *target* is replaced that way (the link stays a link);
- anything that is not a regular file (``/dev/stdout``, ``/dev/full``, a FIFO, a terminal) and
  every path under ``/dev/`` (but ``/dev/shm/``) or ``/proc/`` is written in place (appended to, so a ``/dev/stdout``
  redirected to a file is not truncated); a device node is never replaced by a file.

Every failure is an :class:`OutputError` that names the user's path, never the hidden temporary
file. Missing parent folders of an output file are created (:func:`missing_dirs` lists them
beforehand so that a command can say so); :func:`check_output` finds every other path problem
before a long computation starts.
"""
from __future__ import annotations

import json
import math
import os
import stat
import sys
import tempfile
from pathlib import Path

import numpy as np

IN_PLACE_ROOTS = ("/dev/", "/proc/")  # streams and devices: written in place, never replaced
FILE_ROOTS = ("/dev/shm/",)  # ... except for these ordinary (tmpfs) folders


def _in_place_path(p) -> bool:
    s = str(p)
    return s.startswith(IN_PLACE_ROOTS) and not s.startswith(FILE_ROOTS)


class OutputError(OSError):
    """An output that cannot be written; the message names the user's path and the reason."""

    def __init__(self, path, why: str):
        super().__init__(f"cannot write {path}: {why}")
        self.path = str(path)


def output_target(path) -> tuple[Path, bool]:
    """(the file to write, whether to write it in place) for the output path ``path``.

    Symbolic links are resolved to their final target; devices, FIFOs and /dev, /proc paths are
    written in place. Raises OutputError for a directory or a symlink loop."""
    p = Path(path)
    if _in_place_path(p):
        return p, True
    try:
        st = os.stat(p)  # follows symbolic links
    except FileNotFoundError:
        st = None
    except OSError as e:  # a symlink loop, a file used as a folder, ...
        raise OutputError(path, e.strerror) from None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise OutputError(path, "is a directory (a file name is expected)")
    if st is not None and not stat.S_ISREG(st.st_mode):
        return p, True
    if p.is_symlink():
        real = Path(os.path.realpath(p))
        return real, _in_place_path(real)
    return p, False


def missing_dirs(path) -> list[Path]:
    """The folders that writing the output file ``path`` would create (outermost first); raises
    OutputError when an existing ancestor is not a folder."""
    target, in_place = output_target(path)
    if in_place:
        return []
    out, d = [], target.parent
    while not d.exists():
        if d.is_symlink():
            raise OutputError(path, f"{d} is a dangling symbolic link")
        out.append(d)
        d = d.parent
    if not d.is_dir():
        raise OutputError(path, f"{d} is not a directory")
    return out[::-1]


def check_output(path) -> list[Path]:
    """Check, before any work, that ``path`` ('-': stdout) can be written: not a directory, its
    nearest existing folder writable, a device or FIFO writable. Returns :func:`missing_dirs`;
    raises OutputError naming the problem."""
    if str(path) == "-":
        return []
    target, in_place = output_target(path)
    if in_place:
        if not target.exists():
            raise OutputError(path, "no such file (under /dev and /proc only existing devices "
                                    "and streams are written)")
        if not os.access(target, os.W_OK):
            raise OutputError(path, "permission denied")
        return []
    missing = missing_dirs(path)
    folder = missing[0].parent if missing else target.parent
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(path, f"directory {folder} is not writable")
    return missing


def check_output_dir(path) -> list[Path]:
    """Check an output *folder* before any work: an existing directory, or creatable (its nearest
    existing ancestor a writable folder). Returns the folders that would be created."""
    d = Path(path)
    if d.exists():
        if not d.is_dir():
            raise OutputError(path, "exists and is not a directory")
        return []
    missing = []
    while not d.exists():
        missing.append(d)
        d = d.parent
    if not d.is_dir():
        raise OutputError(path, f"{d} is not a directory")
    if not os.access(d, os.W_OK | os.X_OK):
        raise OutputError(path, f"directory {d} is not writable")
    return missing[::-1]


def atomic_write_text(path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` as described in the module docstring."""
    write_output(path, text.encode("utf-8"))


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` as described in the module docstring."""
    write_output(path, data)


def write_output(path, data: bytes) -> None:
    """Write ``data`` to the output ``path``: a regular file atomically (temporary file and
    rename, through symbolic links), a device / FIFO / stream in place. OutputError on failure."""
    target, in_place = output_target(path)
    if in_place:
        sys.stdout.flush()  # /dev/stdout: keep the order of what was printed before
        try:
            with open(target, "ab") as fh:
                fh.write(data)
                fh.flush()
        except OSError as e:
            raise OutputError(path, e.strerror or str(e)) from None
        return
    for d in missing_dirs(path):
        try:
            d.mkdir(exist_ok=True)
        except OSError as e:
            raise OutputError(path, f"cannot create directory {d}: {e.strerror}") from None
    _replace(path, target, data)


def _replace(path, target: Path, data: bytes) -> None:
    """Write ``data`` to a temporary file next to ``target`` and rename it over ``target``."""
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as e:
        raise OutputError(path, f"directory {target.parent}: {e.strerror}") from None
    try:
        try:
            mode = stat.S_IMODE(os.stat(target).st_mode)  # keep an existing file's permissions
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass  # the temporary file is already gone: nothing left to clean
        if isinstance(e, OSError) and not isinstance(e, OutputError):
            raise OutputError(path, e.strerror or str(e)) from None
        raise


def _default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _clean(o):
    """Replace non-finite floats by None (strict JSON)."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def dumps(obj) -> str:
    """Strict JSON (non-finite floats as null; numpy values and paths converted), indented."""
    return json.dumps(_clean(json.loads(json.dumps(obj, default=_default))), indent=2)


def write_json(target, obj) -> None:
    """Write JSON to a path (:func:`write_output`), or to stdout when target is '-'."""
    text = dumps(obj) + "\n"
    if str(target) == "-":
        sys.stdout.write(text)
        sys.stdout.flush()
    else:
        atomic_write_text(target, text)


class LineProgress:
    """Progress as one plain line per update on stderr (``desc: k/total``): what a log file or a
    CI console shows well, where a tqdm bar would write carriage returns and escape codes."""

    def __init__(self, total: int, desc: str):
        self.total, self.desc, self.n, self.note = total, desc, 0, ""

    def set_postfix_str(self, note: str, refresh: bool = False) -> None:
        """What the next line names (tqdm's postfix: the item being worked on)."""
        self.note = note

    def update(self, k: int = 1) -> None:
        self.n += k
        tail = f" ({self.note})" if self.note else ""
        print(f"{self.desc}: {self.n}/{self.total}{tail}", file=sys.stderr, flush=True)

    def close(self) -> None:
        """Nothing to finish (the lines are already written)."""


def progress(total: int, desc: str, unit: str = "it", enabled: bool = True):
    """A progress reporter with ``update(k)`` and ``close()``: a tqdm bar when stderr is a
    terminal, plain lines (:class:`LineProgress`) when it is not, nothing when not ``enabled``."""
    from tqdm import tqdm   # imported with the first progress report, not with every output
    if enabled and sys.stderr.isatty():
        return tqdm(total=total, desc=desc, unit=unit)
    if enabled:
        return LineProgress(total, desc)
    return tqdm(total=total, disable=True)
