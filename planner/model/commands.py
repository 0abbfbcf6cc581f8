"""The valve-command input every plant and the dynamic twin take, checked once: commands ``u``
(M, n) held from the strictly increasing times ``t_u`` (M,) (zero-order hold), from rest at
``q0`` (n,), until ``t_end``.

A transport delay d between the command and the valves (``[dynamics] command_delay``: bus,
controller cycle, pilot stage) is a shift of that held signal: over an integration step
[t, t + h) the valves see the mean of u(τ − d), exactly (:func:`delayed_steps`), a function of
d that is continuous (piecewise linear), so a fit can move d by finite differences. Before the
first command the valves were closed (u = 0). On a grid of steps, d = (m + f)·h mixes two
earlier steps, (1 − f)·u[k − m] + f·u[k − m − 1] (:func:`shift_steps`, and its transpose for
gradients, :func:`shift_steps_transposed`)."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["held_commands", "delayed_steps", "delayed_held", "shift_steps", "shift_steps_transposed"]


def held_commands(t_u, u, q0, n: int, t_end, h: float, who: str, t_start=None):
    """(t_u, u, q0, t0, t_end, K) as float arrays and the step count K of step ``h`` [s]
    from ``t_start`` (default t_u[0]; a later one leaves the commands before it as the
    history a delay reads) to ``t_end`` (default t_u[-1]); ValueError naming ``who`` and what
    was expected."""
    t_u = np.asarray(t_u, float).ravel()
    u = np.atleast_2d(np.asarray(u, float))
    q0 = np.asarray(q0, float).ravel()
    if u.shape != (t_u.size, n) or q0.shape != (n,) or not np.all(np.isfinite(u)):
        raise ValueError(f"{who}: expected finite t_u (M,), u (M, {n}), q0 ({n},); got "
                         f"{t_u.shape}, {u.shape}, {q0.shape}")
    if t_u.size > 1 and np.any(np.diff(t_u) <= 0):
        raise ValueError(f"{who}: t_u must increase strictly")
    t0 = float(t_u[0]) if t_start is None else float(t_start)
    if not (math.isfinite(t0) and t0 >= t_u[0]):
        raise ValueError(f"{who}: t_start = {t_start!r}; allowed: a time >= the first "
                         f"command's ({t_u[0]:g} s)")
    t_end = float(t_u[-1]) if t_end is None else float(t_end)
    K = int(math.ceil((t_end - t0) / h - 1e-9))
    if K < 1:
        raise ValueError(f"{who}: span {t_end - t0:g} s shorter than one step")
    return t_u, u, q0, t0, t_end, K


def _held_integral(t_u, u, s):
    """∫ u(τ) dτ from −∞ to each of the times ``s`` (K,) of the commands ``u`` (M, n) held
    from ``t_u`` (0 before the first, the last one held on): (K, n)."""
    c = np.vstack([np.zeros((1, u.shape[1])), np.cumsum(u[:-1] * np.diff(t_u)[:, None],
                                                        axis=0)])
    j = np.searchsorted(t_u, s, side="right") - 1
    jj = np.clip(j, 0, t_u.size - 1)
    out = c[jj] + u[jj] * (s - t_u[jj])[:, None]
    return np.where((j < 0)[:, None], 0.0, out)


def delayed_steps(t_u, u, tk, h: float, delay: float) -> np.ndarray:
    """What the valves see over each step [t_k, t_k + h) of the times ``tk`` (K,): the mean
    of the held commands (``t_u`` (M,), ``u`` (M, n)) ``delay`` [s] earlier, 0 before the
    first command (the valves closed). (K, n)."""
    tk = np.asarray(tk, float) - float(delay)
    return (_held_integral(t_u, u, tk + h) - _held_integral(t_u, u, tk)) / h


def delayed_held(t_u, u, delay: float) -> np.ndarray:
    """The held commands (``t_u`` (M,), ``u`` (M, n)) ``delay`` [s] later, on the same grid:
    row k the mean of u(τ − delay) over [t_u[k], t_u[k+1]) (0 before the first command: the
    valves closed), the last row its value at t_u[-1] (held on). Exact for a grid that holds
    every t_u[k] + delay that falls inside it (:func:`planner.model.effects.valve_commands`
    adds them); on any other grid, the interval means. (M, n)."""
    t_u = np.asarray(t_u, float)
    u = np.asarray(u, float)
    if delay <= 0 or t_u.size == 0:
        return u
    s = t_u - float(delay)
    out = np.empty_like(u)
    if t_u.size > 1:
        out[:-1] = (_held_integral(t_u, u, s[1:]) - _held_integral(t_u, u, s[:-1])) \
            / np.diff(t_u)[:, None]
    j = int(np.searchsorted(t_u, s[-1] + 1e-12 * max(1.0, abs(s[-1])), side="right")) - 1
    out[-1] = u[j] if j >= 0 else 0.0
    return out


def _split(delay: float, h: float):
    m, f = divmod(float(delay) / h, 1.0)
    if f > 1.0 - 1e-9:              # a delay of whole steps, up to rounding
        m, f = m + 1.0, 0.0
    return int(m), (0.0 if f < 1e-9 else f)


def shift_steps(u_steps, delay: float, h: float, transpose: bool = False) -> np.ndarray:
    """Per-step commands ``u_steps`` (K, n) as the valves see them ``delay`` [s] later, on
    the step grid of ``h`` [s] (module doc; 0 before the first step); ``transpose``: the
    transposed map (a gradient with respect to the shifted commands taken back to the
    commands)."""
    u = np.asarray(u_steps, float)
    if delay <= 0:
        return u
    m, f = _split(delay, h)
    out = np.zeros_like(u)
    K = u.shape[0]
    for lag, w in ((m, 1.0 - f), (m + 1, f)):
        if w > 0 and lag < K:
            if transpose:
                out[:K - lag] += w * u[lag:]
            else:
                out[lag:] += w * u[:K - lag]
    return out


def shift_steps_transposed(g, delay: float, h: float) -> np.ndarray:
    """The transpose of :func:`shift_steps`: ∂J/∂u per step (K, n) from ``g`` = ∂J/∂(the
    shifted commands) (K, n)."""
    return shift_steps(g, delay, h, transpose=True)
