"""The valve-command input every plant and the dynamic twin take, checked once: commands ``u``
(M, n) held from the strictly increasing times ``t_u`` (M,) (zero-order hold), from rest at
``q0`` (n,), until ``t_end``."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["held_commands"]


def held_commands(t_u, u, q0, n: int, t_end, h: float, who: str):
    """(t_u, u, q0, t0, t_end, K) as float arrays and the step count K of step ``h`` [s] to
    ``t_end`` (default t_u[-1]); ValueError naming ``who`` and what was expected."""
    t_u = np.asarray(t_u, float).ravel()
    u = np.atleast_2d(np.asarray(u, float))
    q0 = np.asarray(q0, float).ravel()
    if u.shape != (t_u.size, n) or q0.shape != (n,) or not np.all(np.isfinite(u)):
        raise ValueError(f"{who}: expected finite t_u (M,), u (M, {n}), q0 ({n},); got "
                         f"{t_u.shape}, {u.shape}, {q0.shape}")
    if t_u.size > 1 and np.any(np.diff(t_u) <= 0):
        raise ValueError(f"{who}: t_u must increase strictly")
    t0 = float(t_u[0])
    t_end = float(t_u[-1]) if t_end is None else float(t_end)
    K = int(math.ceil((t_end - t0) / h - 1e-9))
    if K < 1:
        raise ValueError(f"{who}: span {t_end - t0:g} s shorter than one step")
    return t_u, u, q0, t0, t_end, K
