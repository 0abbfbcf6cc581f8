"""One writer per library file: a lock next to the database that names the build holding it.

A build takes :class:`BuildLock` on ``LIB.h5.lock`` (an ``flock``: the kernel releases it when the
holder dies, however it dies, so a stale lock file is never an obstacle) and writes its pid into
it; a second build, ``library info`` or a query on a file that cannot be opened then say *who*
holds it (:func:`busy_message`) instead of HDF5's "unable to lock file, errno = 11". The lock
file is removed when the build ends.
"""
from __future__ import annotations

import fcntl
import os
from pathlib import Path

from planner.io import OutputError


class LibraryBusy(OSError):
    """The library file is being written by another process (the message says which)."""


def lock_path(path) -> Path:
    """The lock file of the library ``path``: ``LIB.h5.lock`` next to it."""
    p = Path(path)
    return p.with_name(p.name + ".lock")


def _read_pid(fd: int) -> int | None:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").split()
        return int(text[0]) if text else None
    except (OSError, ValueError):
        return None


def holder(path) -> int | None:
    """The pid of the build holding the lock of library ``path`` (0 when held but the pid is not
    yet written), or None when no build holds it."""
    try:
        fd = os.open(lock_path(path), os.O_RDONLY | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_pid(fd) or 0
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def proc_lock_holders(path) -> list[int]:
    """Pids that hold a lock on ``path`` according to Linux's /proc/locks ([] elsewhere)."""
    try:
        st = os.stat(path)
        with open("/proc/locks", encoding="ascii", errors="replace") as fh:
            lines = fh.read().splitlines()
    except OSError:
        return []
    want = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    pids = []
    for line in lines:
        f = line.split()
        if "->" in f:  # a waiter, not a holder
            continue
        if len(f) >= 6 and f[5] == want and f[4].isdigit() and int(f[4]) not in pids:
            pids.append(int(f[4]))
    return pids


def _process_name(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/comm", encoding="utf-8", errors="replace") as fh:
            return fh.read().strip()
    except OSError:
        return ""


def busy_message(path) -> str | None:
    """Why the library ``path`` cannot be opened because someone else has it open for writing:
    the build's pid from the lock file, else the lock holders from /proc/locks; None when
    neither is known."""
    pid = holder(path)
    if pid == os.getpid():   # this build's own lock: the file itself is what cannot be opened
        return None
    if pid is not None:
        who = f"pid {pid}" if pid else "pid not yet recorded"
        return (f"{path} is being written by another build ({who}); wait for it to finish or "
                "stop it (an interrupted build resumes when rerun)")
    pids = [p for p in proc_lock_holders(path) if p != os.getpid()]
    if pids:
        who = ", ".join(f"pid {p}" + (f" {_process_name(p)}" if _process_name(p) else "")
                        for p in pids)
        return (f"{path} is locked by another process ({who}), e.g. an open h5py.File in a "
                "notebook; close it there")
    return None


class BuildLock:
    """The exclusive writer lock of one library file (a context manager).

    ``acquire`` raises :class:`LibraryBusy` naming the holder's pid when another build has it.
    Take it *after* starting worker processes (a forked child shares the lock otherwise)."""

    def __init__(self, path):
        self.path = Path(path)
        self.file = lock_path(path)
        self._fd: int | None = None

    def acquire(self) -> "BuildLock":
        for _ in range(20):  # retried only when the previous holder removed the file meanwhile
            try:
                fd = os.open(self.file, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            except OSError as e:
                raise OutputError(self.path, f"cannot create the lock file {self.file}: "
                                             f"{e.strerror}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = _read_pid(fd)
                os.close(fd)
                who = f"pid {pid}" if pid else "pid not yet recorded"
                raise LibraryBusy(f"{self.path} is being written by another build ({who}); "
                                  "wait for it to finish or stop it") from None
            try:
                mine = os.fstat(fd).st_ino == os.stat(self.file).st_ino
            except FileNotFoundError:
                mine = False
            if mine:
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
                self._fd = fd
                return self
            os.close(fd)
        raise LibraryBusy(f"{self.path}: could not take the lock {self.file} (it keeps being "
                          "replaced by other builds)")

    def release(self) -> None:
        """Remove the lock file and drop the lock (idempotent)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.file)
        except FileNotFoundError:
            pass  # removed by hand: the flock is what counts
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> "BuildLock":
        return self.acquire()

    def __exit__(self, *exc) -> bool:
        self.release()
        return False
