"""Fast numeric evaluation of the model's CasADi functions.

* :func:`jit` compiles a function with the system C compiler into the per-user cache
  (:func:`cache_root`/jit/<hash>.so, keyed by the function's serialisation, the CasADi version
  and the flags; written atomically, checked by its checksum before it is loaded), so every
  later process loads it in a millisecond instead of compiling again; falls back to CasADi's
  interpreter when no compiler is available, or when ``CRANE_PLANNER_JIT=0``. The C
  optimisation level is ``CRANE_PLANNER_JIT_OPT`` (0–3, default 2; measured on the s100f
  twin against 2: at 1 it compiles in 0.56 × the time and runs 1.15 × slower, at 0 in 0.37 ×
  and 1.85 × slower; the test suite on a fresh cache: 222.6 s at 1, 219.3 s at 2).
  Processes that need the same function at once compile it once: the others wait on its
  lock file and load it.
* :class:`Batched` evaluates a function over N samples through CasADi's buffer interface on a
  mapped copy: a C-ordered numpy array of shape (N, m) has exactly the memory layout of CasADi's
  column-major (m, N) matrix, so inputs and outputs are copied straight between numpy arrays
  without DM conversion. Map sizes are powers of two (≤ ``max_chunk``), built on first use.
* :class:`Elementwise` is the batched face of a *scalar* function (every input and output one
  number; e.g. one valve): its inputs broadcast against each other like numpy's, and its map
  is compiled as a whole at a few fixed sizes (:func:`jit_map`: one loop in C; mapping the
  compiled scalar function instead costs ~0.4 µs of call overhead per sample, 20× the work
  of a valve).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import warnings
from pathlib import Path

import casadi as ca
import numpy as np


JIT_FLAGS = ("-O2",)   # the default; see jit_flags()
JIT_OPT_LEVELS = ("0", "1", "2", "3")


def jit_flags() -> tuple:
    """The C compiler's flags: ``-O$CRANE_PLANNER_JIT_OPT`` when set (0–3), else
    :data:`JIT_FLAGS`; ValueError naming the variable for another value."""
    v = os.environ.get("CRANE_PLANNER_JIT_OPT")
    if v is None or v == "":
        return JIT_FLAGS
    if v.strip() not in JIT_OPT_LEVELS:
        raise ValueError(f"CRANE_PLANNER_JIT_OPT = {v!r}; allowed: {', '.join(JIT_OPT_LEVELS)}")
    return (f"-O{v.strip()}",)


def cache_root() -> Path:
    """The per-user cache: ``$CRANE_PLANNER_CACHE``, else ``$XDG_CACHE_HOME/crane-planner``,
    else ``~/.cache/crane-planner``."""
    if os.environ.get("CRANE_PLANNER_CACHE"):
        return Path(os.environ["CRANE_PLANNER_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "crane-planner"


def compiler() -> str | None:
    """The C compiler to use (``$CC`` or cc/gcc/clang on the PATH), None when there is none."""
    for c in filter(None, (os.environ.get("CC"), "cc", "gcc", "clang")):
        if shutil.which(c):
            return c
    return None


def file_digest(path: Path) -> str:
    """sha256 of a file (a cached library is loaded only when it matches what was stored)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _load(so: Path, digest: Path, name: str):
    """The cached library ``so`` as a CasADi function when it and its checksum match, else
    None (missing, half-written, unreadable or not loadable: never trusted)."""
    if so.exists() and digest.exists():
        try:
            if file_digest(so) == digest.read_text().strip():
                return ca.external(name, str(so))
        except (OSError, RuntimeError):
            pass
    return None


def _compiled(f: ca.Function) -> ca.Function:
    """The cached machine-code copy of ``f``: loaded when stored, else compiled and stored
    (under a lock per function: a second process that needs it meanwhile waits and loads)."""
    flags = jit_flags()
    key = hashlib.sha256(f.serialize().encode() + ca.__version__.encode()
                         + " ".join(flags).encode()).hexdigest()[:32]
    d = cache_root() / "jit"
    so, digest = d / f"{key}.so", d / f"{key}.sha256"
    got = _load(so, digest, f.name())
    if got is not None:
        return got
    cc = compiler()
    if cc is None:
        raise RuntimeError("no C compiler")
    d.mkdir(parents=True, exist_ok=True)
    with _Lock(d / f"{key}.lock"):
        got = _load(so, digest, f.name())     # compiled by another process while we waited
        if got is not None:
            return got
        tmp = Path(tempfile.mkdtemp(prefix=f".{key}-", dir=d))
        try:
            cg = ca.CodeGenerator(f"{f.name()}.c", {"with_header": False})
            cg.add(f)
            cg.generate(str(tmp) + os.sep)
            r = subprocess.run([cc, "-fPIC", "-shared", *flags, f"{f.name()}.c", "-o",
                                "f.so", "-lm"], cwd=tmp, capture_output=True, text=True)
            if r.returncode != 0:
                raise RuntimeError(f"{cc} failed: {r.stderr.strip()[-300:]}")
            (tmp / f"{key}.sha256").write_text(file_digest(tmp / "f.so"))
            os.replace(tmp / "f.so", so)               # the library first, then its checksum:
            os.replace(tmp / f"{key}.sha256", digest)  # a reader never trusts a half-written pair
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return ca.external(f.name(), str(so))


class _Lock:
    """An exclusive advisory lock on ``path`` (POSIX ``flock``; released when the process
    ends, so a killed compiler leaves no stale lock); no lock where flock is missing."""

    def __init__(self, path: Path):
        self.path, self.fd = path, None

    def __enter__(self):
        try:
            import fcntl
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            fcntl.flock(self.fd, fcntl.LOCK_EX)
        except (ImportError, OSError):
            if self.fd is not None:
                os.close(self.fd)
            self.fd = None
        return self

    def __exit__(self, *exc):
        if self.fd is not None:
            os.close(self.fd)     # closing releases the flock
        return False


def jit(f: ca.Function) -> ca.Function:
    """Machine-code copy of an SX function (≈4× faster), or ``f`` itself without a compiler."""
    if os.environ.get("CRANE_PLANNER_JIT", "1") == "0":
        return f
    jit_flags()   # a bad CRANE_PLANNER_JIT_OPT is an error, not a fallback
    try:
        ins = f.sx_in()
        return _compiled(ca.Function(f.name(), ins, f.call(ins), f.name_in(), f.name_out()))
    except Exception as e:  # no compiler: the interpreted function is exact, only slower
        warnings.warn(f"CasADi JIT unavailable ({type(e).__name__}: {e}); using the "
                      "interpreter", RuntimeWarning, stacklevel=3)
        return f


def jit_map(f: ca.Function, chunk: int) -> ca.Function:
    """Machine-code copy of ``f.map(chunk)`` (``f`` an SX function; the generated code loops
    over the samples in C), cached like :func:`jit`; the interpreted map without a compiler
    or with ``CRANE_PLANNER_JIT=0`` (:func:`jit_function` of the map)."""
    return jit_function(f.map(chunk))


def jit_function(f: ca.Function) -> ca.Function:
    """Machine-code copy of ``f`` as it is (a map, a mapaccum, an MX function: the generated
    code keeps its loops and calls instead of expanding them), cached like :func:`jit`; ``f``
    itself without a compiler or with ``CRANE_PLANNER_JIT=0``."""
    if os.environ.get("CRANE_PLANNER_JIT", "1") == "0":
        return f
    jit_flags()
    try:
        return _compiled(f)
    except Exception as e:  # no compiler: the interpreted function is exact, only slower
        warnings.warn(f"CasADi JIT unavailable ({type(e).__name__}: {e}); using the "
                      "interpreter", RuntimeWarning, stacklevel=3)
        return f


def densified(f: ca.Function) -> ca.Function:
    """Same function with dense column-vector inputs/outputs (required by the buffer path)."""
    ins = f.sx_in()
    for i, x in enumerate(ins):
        if x.size2() != 1:
            raise ValueError(f"{f.name()}: input {i} must be a column vector")
    outs = [ca.densify(ca.vec(o)) for o in f.call(ins)]
    return ca.Function(f.name(), ins, outs, f.name_in(), f.name_out())


def bound_buffer(fm: ca.Function, ins: list, outs: list) -> tuple:
    """(buffer, its eval, ins, outs): ``fm``'s call buffer bound to the numpy arrays ``ins``
    and ``outs`` (filled in place, evaluated without copies)."""
    buf, ev = fm.buffer()
    for i, a in enumerate(ins):
        buf.set_arg(i, memoryview(a))
    for i, a in enumerate(outs):
        buf.set_res(i, memoryview(a))
    return buf, ev, ins, outs


class Batched:
    """Evaluate ``f`` (column-vector inputs/outputs) on N samples at a time.

    ``self(*args)``: each arg is an array (N, size_in) or broadcastable to it (e.g. a scalar);
    returns a list of arrays (N, size_out)."""

    def __init__(self, f: ca.Function, max_chunk: int = 2048):
        dense = densified(f)
        self.f = jit(dense)
        self.compiled = self.f is not dense  # False: interpreted (no compiler / disabled)
        self.max_chunk = max_chunk
        self.size_in = [self.f.size1_in(i) for i in range(self.f.n_in())]
        self.size_out = [self.f.size1_out(i) for i in range(self.f.n_out())]
        self._maps: dict[int, tuple] = {}

    def _map(self, chunk: int):
        m = self._maps.get(chunk)
        if m is None:
            fm = self.f if chunk == 1 else self.f.map(chunk)
            m = self._maps[chunk] = bound_buffer(fm, [np.zeros((chunk, s)) for s in self.size_in],
                                           [np.zeros((chunk, s)) for s in self.size_out])
        return m

    def __call__(self, *args):
        if len(args) != len(self.size_in):
            raise TypeError(f"{self.f.name()} takes {len(self.size_in)} inputs, got {len(args)}")
        N = max(np.atleast_2d(np.asarray(a)).shape[0] if np.ndim(a) == 2 else 1 for a in args)
        arrs = [np.broadcast_to(np.asarray(a, float).reshape(-1, s) if np.ndim(a) == 2
                                else np.asarray(a, float).reshape(1, -1), (N, s))
                for a, s in zip(args, self.size_in)]
        res = [np.empty((N, s)) for s in self.size_out]
        start = 0
        while start < N:
            k = min(self.max_chunk, N - start)
            chunk = 1 << (k - 1).bit_length()  # next power of two ≥ k
            _, ev, ins, outs = self._map(chunk)
            for a, dst in zip(arrs, ins):
                dst[:k] = a[start:start + k]
                dst[k:] = a[start]  # padding: any valid sample
            ev()
            for r, src in zip(res, outs):
                r[start:start + k] = src[:k]
            start += k
        return res


class Elementwise:
    """Evaluate a scalar SX function ``f`` (every input and output 1×1) elementwise on numpy
    arrays: ``self(*args)`` broadcasts the args against each other and returns a list of
    arrays of the broadcast shape, one per output. The map is compiled at each of ``sizes``
    on first use (:func:`jit_map`); a batch runs on the smallest size that holds it (the
    largest in turns; a smaller one in turns where the next would be mostly padding), the
    unused tail of an evaluation ignored. Not thread-safe (one set of buffers per size)."""

    def __init__(self, f: ca.Function, sizes: tuple = (16, 128, 1024, 8192)):
        for i in range(f.n_in()):
            if f.numel_in(i) != 1:
                raise ValueError(f"{f.name()}: input {i} must be a scalar")
        for i in range(f.n_out()):
            if f.numel_out(i) != 1:
                raise ValueError(f"{f.name()}: output {i} must be a scalar")
        self.f = densified(f)
        self.sizes = tuple(sorted(int(s) for s in sizes))
        self.compiled = (os.environ.get("CRANE_PLANNER_JIT", "1") != "0"
                         and compiler() is not None)
        self._maps: dict[int, tuple] = {}

    def _map(self, chunk: int):
        m = self._maps.get(chunk)
        if m is None:
            m = self._maps[chunk] = bound_buffer(jit_map(self.f, chunk),
                                           [np.zeros(chunk) for _ in range(self.f.n_in())],
                                           [np.zeros(chunk) for _ in range(self.f.n_out())])
        return m

    def __call__(self, *args):
        if len(args) != self.f.n_in():
            raise TypeError(f"{self.f.name()} takes {self.f.n_in()} inputs, got {len(args)}")
        arrs = [np.asarray(a, dtype=float) for a in args]
        shape = np.broadcast_shapes(*(a.shape for a in arrs))
        flat = []
        for a in arrs:
            if a.shape != shape:                 # broadcast: one strided copy
                b = np.empty(shape)
                b[...] = a
                a = b
            flat.append(a.ravel())               # a view where the input is contiguous
        N = int(np.prod(shape))
        res = [np.empty(N) for _ in range(self.f.n_out())]
        start = 0
        while start < N:
            k = min(self.sizes[-1], N - start)
            chunk = next(s for s in self.sizes if s >= k)
            if chunk > 2 * k and chunk > self.sizes[0]:  # mostly padding: a smaller map, twice
                chunk = max(s for s in self.sizes if s <= k)
                k = chunk
            _, ev, ins, outs = self._map(chunk)
            for a, dst in zip(flat, ins):
                dst[:k] = a[start:start + k]
            ev()
            for r, src in zip(res, outs):
                r[start:start + k] = src[:k]
            start += k
        return [r.reshape(shape) for r in res]
