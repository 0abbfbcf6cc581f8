"""Fast numeric evaluation of the model's CasADi functions.

* :func:`jit` compiles a function with the system C compiler (falls back to CasADi's
  interpreter when no compiler is available, or when ``CRANE_PLANNER_JIT=0``).
* :class:`Batched` evaluates a function over N samples through CasADi's buffer interface on a
  mapped copy: a C-ordered numpy array of shape (N, m) has exactly the memory layout of CasADi's
  column-major (m, N) matrix, so inputs and outputs are copied straight between numpy arrays
  without DM conversion. Map sizes are powers of two (≤ ``max_chunk``), built on first use.
"""
from __future__ import annotations

import os
import tempfile
import warnings

import casadi as ca
import numpy as np


def _jit_dir() -> str:
    """Folder for the compiler's temporary files (never the working directory). CasADi deletes
    its files itself when a compiled function is freed; names carry random suffixes, so
    concurrent processes can share the folder."""
    d = os.path.join(tempfile.gettempdir(), "crane-planner-jit")
    os.makedirs(d, exist_ok=True)
    return d


def jit(f: ca.Function) -> ca.Function:
    """Machine-code copy of an SX function (≈4× faster), or ``f`` itself without a compiler."""
    if os.environ.get("CRANE_PLANNER_JIT", "1") == "0":
        return f
    try:
        ins = f.sx_in()
        return ca.Function(f.name(), ins, f.call(ins), f.name_in(), f.name_out(),
                           {"jit": True, "compiler": "shell", "jit_name": f"jit_{f.name()}",
                            "jit_temp_suffix": True,
                            "jit_options": {"flags": ["-O2"], "verbose": False,
                                            "directory": _jit_dir()}})
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
            buf, ev = fm.buffer()
            ins = [np.zeros((chunk, s)) for s in self.size_in]
            outs = [np.zeros((chunk, s)) for s in self.size_out]
            for i, a in enumerate(ins):
                buf.set_arg(i, memoryview(a))
            for i, a in enumerate(outs):
                buf.set_res(i, memoryview(a))
            m = self._maps[chunk] = (buf, ev, ins, outs)
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
