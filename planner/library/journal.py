"""A library file that survives a failed write: HDF5 through a rollback journal.

HDF5 updates its metadata (the superblock's end-of-file address, group and chunk indices, the
index table) in place. A write that fails half-way (a full disk, a file-size limit, ``EIO``)
leaves those structures half-updated: the file no longer opens ("truncated file", "addr
overflow") and every finished entry is lost with it, and closing the library after such an
error can even crash HDF5. :class:`JournaledFile` is the file object the writer hands to h5py
(its ``fileobj`` driver) instead of the path:

- before any byte of the file as it was at the last :meth:`~JournaledFile.commit` is
  overwritten (or cut off by a truncation), the old bytes are appended to the journal
  ``LIB.h5.journal`` (after a header with the committed size); bytes appended past that size
  need no copy;
- :meth:`~JournaledFile.commit` (after each entry is complete and flushed, and on close) drops
  the journal: the file as it is now is the state to come back to;
- the first failed write (or journal write) puts the object in *failed* mode: nothing more
  reaches the disk (HDF5 can close without further errors) and :func:`roll_back` writes the
  saved bytes back in reverse order and truncates the file to its committed size. The same
  happens on the next opening for append when a killed writer left a journal behind.

So a write failure costs at most the entry being written; the finished ones stay readable and
a rerun resumes. ``flock`` (exclusive) is taken on the file as HDF5 itself does, so readers
that open the file meanwhile are refused as before (the lock file names the build).
"""
from __future__ import annotations

import errno
import fcntl
import os
import struct
from pathlib import Path

MAGIC = b"CPJRNL01"
_HEAD = struct.Struct("<8sQ")     # magic, committed size [bytes]
_REC = struct.Struct("<QQ")       # offset, length (the old bytes follow)


class WriteFailed(OSError):
    """A write to the library (or its journal) failed; ``cause`` is the OSError that did it."""

    def __init__(self, path, cause: OSError):
        why = cause.strerror or str(cause)
        if cause.errno == errno.EFBIG and "ulimit" not in why:
            why += " (the file-size limit, ulimit -f)"
        super().__init__(f"cannot write {path}: {why}")
        self.errno, self.path, self.cause, self.why = cause.errno, str(path), cause, why


def journal_path(path) -> Path:
    """The journal of the library file ``path``: ``LIB.h5.journal`` next to it."""
    p = Path(path)
    return p.with_name(p.name + ".journal")


def roll_back(path) -> bool:
    """Undo an unfinished transaction of ``path`` from its journal (if any): the saved bytes
    written back, the file cut to its committed size (removed when that is 0: nothing was ever
    committed), the journal removed. Returns whether there was one. A journal cut short (the
    writer died while writing it) is applied as far as its complete records go: the bytes of
    an incomplete record were never overwritten."""
    jp = journal_path(path)
    try:
        data = jp.read_bytes()
    except FileNotFoundError:
        return False
    if len(data) < _HEAD.size or data[:8] != MAGIC:
        jp.unlink()   # no complete header: the writer died before touching the file
        return True
    _, size = _HEAD.unpack_from(data)
    recs, k = [], _HEAD.size
    while k + _REC.size <= len(data):
        off, n = _REC.unpack_from(data, k)
        if k + _REC.size + n > len(data):
            break
        recs.append((off, data[k + _REC.size:k + _REC.size + n]))
        k += _REC.size + n
    if size == 0:
        Path(path).unlink(missing_ok=True)
    else:
        fd = os.open(path, os.O_RDWR)
        try:
            for off, old in reversed(recs):   # the earliest copy of a byte is applied last
                os.pwrite(fd, old, off)
            os.ftruncate(fd, size)
            os.fsync(fd)
        finally:
            os.close(fd)
    jp.unlink()
    return True


class JournaledFile:
    """The file object of a library opened for writing (see the module doc). ``mode``: "w"
    (create or replace) or "a" (existing file; a journal left by a killed writer is rolled
    back first)."""

    def __init__(self, path, mode: str = "a"):
        self.path = Path(path)
        self.journal = journal_path(path)
        self.failed: WriteFailed | None = None
        self._sink = False
        if mode == "a":
            roll_back(self.path)
            flags = os.O_RDWR
        else:
            self.journal.unlink(missing_ok=True)
            flags = os.O_RDWR | os.O_CREAT | os.O_TRUNC
        self._fd = os.open(self.path, flags | os.O_CLOEXEC, 0o666)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._fd)
            raise
        self._pos = 0
        self._jfd: int | None = None
        self._base = os.fstat(self._fd).st_size  # the committed size
        self._size = self._base

    # ------------------------------------------------------------------ the journal
    def _save(self, off: int, n: int) -> None:
        """Copy the committed bytes [off, off + n) to the journal before they change (the
        journal, with the committed size, is started by the first change of a transaction)."""
        if self._jfd is None:
            self._jfd = os.open(self.journal, os.O_WRONLY | os.O_CREAT | os.O_TRUNC
                                | os.O_CLOEXEC, 0o644)
            self._write_all(self._jfd, _HEAD.pack(MAGIC, self._base))
        n = min(off + n, self._base) - off
        if n <= 0:
            return
        old = os.pread(self._fd, n, off)
        self._write_all(self._jfd, _REC.pack(off, len(old)) + old)

    @staticmethod
    def _write_all(fd: int, data: bytes, off: int | None = None) -> None:
        view = memoryview(data)
        while view:
            k = os.write(fd, view) if off is None else os.pwrite(fd, view, off)
            if k <= 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            view = view[k:]
            if off is not None:
                off += k

    def _guard(self, fn, *a):
        try:
            return fn(*a)
        except OSError as e:
            self.failed = self.failed or WriteFailed(self.path, e)
            raise self.failed from None

    def commit(self) -> None:
        """The file as it is now (flushed by HDF5) is the state a failure comes back to."""
        if self.failed:
            raise self.failed
        if self._jfd is not None:
            os.close(self._jfd)
            self._jfd = None
        self.journal.unlink(missing_ok=True)
        self._base = self._size

    def abandon(self) -> None:
        """Close and roll the file back to its last commit (see the module doc)."""
        self._sink = True
        self.close()
        if not roll_back(self.path) and self._base == 0:
            self.path.unlink(missing_ok=True)   # never committed: no file

    # ------------------------------------------------------------------ what h5py calls
    def seek(self, pos: int, whence: int = 0) -> int:
        self._pos = pos if whence == 0 else (self._pos + pos if whence == 1 else self._size + pos)
        return self._pos

    def tell(self) -> int:
        return self._pos

    def readinto(self, buf) -> int:
        view = memoryview(buf).cast("B")
        data = os.pread(self._fd, len(view), self._pos)
        view[:len(data)] = data
        self._pos += len(data)
        return len(data)

    def read(self, n: int = -1) -> bytes:
        n = self._size - self._pos if n < 0 else n
        data = os.pread(self._fd, n, self._pos)
        self._pos += len(data)
        return data

    def write(self, data) -> int:
        data = memoryview(data).cast("B")
        if self.failed or self._sink:   # nothing more reaches the disk: HDF5 closes quietly
            self._pos += len(data)
            return len(data)
        self._guard(self._save, self._pos, len(data))
        self._guard(self._write_all, self._fd, data, self._pos)
        self._pos += len(data)
        self._size = max(self._size, self._pos)
        return len(data)

    def truncate(self, size: int | None = None) -> int:
        size = self._pos if size is None else size
        if not (self.failed or self._sink):
            self._guard(self._save, size, self._base - size)
            self._guard(os.ftruncate, self._fd, size)
            self._size = size
        return size

    def flush(self) -> None:
        """Nothing buffered here (every write is a system call)."""

    def close(self) -> None:
        if self._jfd is not None:
            os.close(self._jfd)
            self._jfd = None
        if self._fd is not None:
            os.close(self._fd)   # drops the flock
            self._fd = None

    @property
    def closed(self) -> bool:
        return self._fd is None

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True


def open_h5(path, mode: str):
    """(h5py.File, its JournaledFile) for writing ``path``: mode "w" (new file) or "a"."""
    import h5py
    jf = JournaledFile(path, mode)
    try:
        return h5py.File(jf, "w" if mode == "w" else "r+"), jf
    except BaseException:
        jf.abandon() if mode == "w" else jf.close()
        raise


def abandon_h5(f, jf: JournaledFile, e: BaseException):
    """Close ``f`` after the error ``e`` and roll its file back to the last commit; re-raise
    the write failure behind ``e`` (one line) or ``e`` itself."""
    try:
        f.close()
    except Exception:
        pass  # HDF5's own complaint about the write that failed: jf.failed says it in one line
    failed = jf.failed
    jf.abandon()
    if failed is not None and isinstance(e, Exception):
        raise failed from None
    raise e


def close_h5(f, jf: JournaledFile) -> None:
    """Close a file of :func:`open_h5`: committed when every write went through, else rolled
    back to its last commit (and :class:`WriteFailed` raised)."""
    try:
        if f.id.valid:
            f.close()
    except Exception as e:
        abandon_h5(f, jf, e)
    if jf.failed:
        abandon_h5(f, jf, jf.failed)
    jf.commit()
    jf.close()
