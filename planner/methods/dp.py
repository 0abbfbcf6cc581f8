"""Bellman dynamic programming along a tip path (seed 000, chapter 7, generalised).

Stages are stations along any :mod:`planner.geometry.paths` path; at each stage the redundant coordinate
(the telescope) is gridded, and every (stage, telescope) node gets its joints from the IK. Between
consecutive stages the telescope may move by at most ``window`` grid steps (the seed's q).

Edge costs (all edges at once, numpy):
* ``time``:   the slowest limit decides (seed 000): max over joints of |Δq|/q̇_lim (direction's
  limit when asymmetric), over cylinders of |Δx|/v_max, and the pump: swept volume / Q_max with
  the stroke rates at both ends of the edge (:func:`planner.model.flows.swept_volume`:
  direction-dependent areas, single-acting lowering free, transformer credit);
* ``energy``: pump energy of the edge at a given tip speed (quasi-static load-sensing model at
  the edge midpoint: power · Δt); edges that cannot be traversed that fast are infeasible;
* ``blend``:  time + λ·energy, the energy taken at the edge's minimum time.
Recursion J[n, m] = min_j J[n−1, m+j] + c(n−1, m+j → n, m); the loop runs over stages only.

The edge arrays hold (stages × telescope nodes × (2·window + 1)) entries per joint; the grid's
peak memory is estimated before anything is allocated (:func:`grid_bytes`) and a grid above
:data:`MAX_BYTES` is refused with the sizes and the limit.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import time as _time

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from planner.geometry.paths import Line, Path
from planner.methods.base import (Planner, PlanRequest, PlanResult, PlanStatus,
                                  UnsupportedRequest)
from planner.methods.registry import register
from planner.model.flows import swept_volume
from planner.trajectory import Trajectory

if TYPE_CHECKING:
    from planner.model import Crane


MAX_BYTES = 2 * 2 ** 30   # [B] largest DP grid planned (peak estimate of grid_bytes)
# peak bytes per edge-array entry (stage × node × window slot) per joint, measured with
# tracemalloc (benchmarks/dp_memory.py -> benchmarks/results/dp_memory.md: 56 B for time,
# 96–111 B for energy) and rounded up; plus per stage and joint (what dominates without a
# telescope: one node per stage) and a fixed allowance
BYTES_PER_EDGE = {"time": 80.0, "energy": 130.0, "blend": 130.0}
BYTES_PER_STAGE = 500.0
BYTES_FIXED = 16 * 2 ** 20


def grid_bytes(stages: int, tele_nodes: int, window: int, joints: int,
               objective: str = "time") -> float:
    """Estimated peak memory [B] of :func:`dp` on a grid of ``stages`` × ``tele_nodes`` with
    ``window`` telescope steps per stage for a crane with ``joints`` joints."""
    edges = float(stages) * tele_nodes * (2 * window + 1)
    return (BYTES_PER_EDGE[objective] * edges + BYTES_PER_STAGE * stages) * joints \
        + BYTES_FIXED


_STATS = dict(objective="time", path_q=None, s=None, times=None, tele_index=None,
              cost=float("nan"), energy_J=float("nan"), grid={})


def _result(status: PlanStatus, reason: str = "", **kw) -> PlanResult:
    """The DP's result: status "ok", or "unreachable" (a stage has no feasible node) /
    "infeasible" (no path through the graph) with ``reason``. Stats: ``path_q`` (N+1, n) the
    geometric joint path at the stations ``s`` [m]; ``times`` [s] its time stamps;
    ``tele_index`` the chosen telescope node per stage; ``cost``; ``energy_J`` (energy
    objectives); ``grid``. ``trajectory`` is the path in time (piecewise linear)."""
    return PlanResult(status, reason, **{**_STATS, **kw})


def _windows(a, w, fill):
    """(K, M+1, ...) -> (K, M+1, 2w+1, ...): entry [k, m, j] = a[k, m − w + j] (fill outside)."""
    pad = [(0, 0)] * a.ndim
    pad[1] = (w, w)
    ap = np.pad(a, pad, constant_values=fill)
    v = sliding_window_view(ap, 2 * w + 1, axis=1)  # (K, M+1, ..., 2w+1)
    return np.moveaxis(v, -1, 2)


def edge_times(crane: Crane, Q, dXdq, w, pump=True):
    """Minimum traversal time of every edge: array (N, M+1, 2w+1) (inf where infeasible), and
    the joint changes dq (N, M+1, 2w+1, n). Loops run over the few joints, each step works on
    whole edge arrays."""
    spec = crane.spec
    L = crane.limit_arrays()
    dq = Q[1:, :, None, :] - _windows(Q[:-1], w, np.nan)    # (N, M+1, 2w+1, n)
    Ds = _windows(dXdq[:-1], w, np.nan)
    Dd = dXdq[1:, :, None, :]
    T = np.zeros(dq.shape[:-1])
    for i in range(crane.n):
        d = dq[..., i]
        np.maximum(T, np.where(d >= 0, d / L["qd_max"][i], d / L["qd_min"][i]), out=T)
    vmax = [j.actuator.max_speed for j in spec.joints]
    if pump or any(vmax):
        dxa, dxb = Ds * dq, Dd * dq    # stroke changes with the map at each end of the edge
        for i, v in enumerate(vmax):
            if v:
                np.maximum(T, np.maximum(np.abs(dxa[..., i]), np.abs(dxb[..., i])) / v, out=T)
        if pump:
            V = np.maximum(swept_volume(spec, dxa).sum(-1), swept_volume(spec, dxb).sum(-1))
            np.maximum(T, V / spec.pump.max_flow, out=T)
    return np.where(np.isnan(T), np.inf, T), dq


def edge_energy(crane: Crane, Q, dq, dt, w, payload=None):
    """Pump energy [J] of every edge traversed in dt [s] (scalar or (N, M+1, 2w+1))."""
    Qs = _windows(Q[:-1], w, np.nan)
    mid = 0.5 * (Q[1:, :, None, :] + Qs)
    dt = np.broadcast_to(dt, dq.shape[:-1])
    ok = np.isfinite(mid).all(-1) & np.isfinite(dt) & (dt > 0)
    E = np.full(dq.shape[:-1], np.inf)
    if ok.any():
        qm, qdm = mid[ok], dq[ok] / dt[ok][:, None]
        P = crane.hydraulics(qm, qdm, np.zeros_like(qm), payload)["power"]
        E[ok] = P * dt[ok]
    return E


def _too_fast(T, start, w, dt, tip_speed, length) -> str:
    """Why a fixed-clock (energy) DP found no path, when the clock is simply too fast: the
    smallest possible largest edge time of any path through the grid (a min-max recursion on
    the edge times ``T``) exceeds the stage time ``dt``. Returns the reason naming the fastest
    constant tip speed and the shortest duration on this grid ("" when the clock is not what
    cuts the path: then the telescope window or the limits do)."""
    J = np.where(start, 0.0, np.inf)
    rows = np.arange(T.shape[1])
    for n in range(T.shape[0]):
        tot = np.maximum(_windows(J[None, :], w, np.inf)[0], T[n])
        J = tot[rows, np.argmin(tot, axis=1)]
    worst = float(J.min())
    if not np.isfinite(worst) or worst <= dt * (1 + 1e-9):
        return ""
    v = tip_speed * dt / worst
    return (f"tip speed {tip_speed:.4g} m/s (duration {length / tip_speed:.4g} s) is too fast "
            f"for the limits along this line: on this grid the fastest constant tip speed is "
            f"{v:.4g} m/s; allowed: `tip_speed` <= {v:.4g} m/s or `duration` >= "
            f"{length / v:.4g} s")


def dp(crane: Crane, path: Path, objective: str = "time", *, step: float = 0.01,
       stages: int | None = None, tele_step: float = 0.01, window: int = 5,
       tip_speed: float | None = None, duration: float | None = None, lam: float = 0.0,
       pump: bool = True, tele_start: float | None = None, tele_goal: float | None = None,
       payload: float | None = None) -> PlanResult:
    """Globally optimal joint path along ``path`` on the (stage × telescope) grid.

    objective: "time" | "energy" (needs ``tip_speed`` [m/s] or ``duration`` [s]) | "blend"
    (time + lam·energy, lam in s/J). ``step`` [m] path spacing (or ``stages`` steps);
    ``tele_step`` [m] telescope grid; ``window`` max telescope steps per stage. ``tele_start`` /
    ``tele_goal`` pin the telescope at the ends (default free). ``pump`` includes the shared
    pump-flow limit in the edge times.
    """
    t0 = _time.perf_counter()
    if objective not in ("time", "energy", "blend"):
        raise ValueError(f"objective must be 'time', 'energy' or 'blend', not {objective!r}")
    for name, v in (("tip_speed", tip_speed), ("duration", duration)):
        if v is not None and not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v!r}: allowed a finite number > 0")
    if objective == "energy":
        if (tip_speed is None) == (duration is None):
            raise ValueError("objective 'energy' needs exactly one of tip_speed [m/s] or "
                             "duration [s]")
        tip_speed = tip_speed if tip_speed is not None else path.length / duration
    if window < 1:
        raise ValueError(f"window must be >= 1 grid step, got {window}")
    if (step is None or not step > 0) and stages is None:
        raise ValueError(f"step = {step!r} m: allowed a number > 0")
    N = int(stages) if stages is not None else max(1, int(np.ceil(path.length / step - 1e-9)))
    tr = crane.tele_range
    if tr is None:
        window, M1 = 0, 1
    else:
        if tele_step <= 0:
            raise ValueError(f"tele_step must be > 0, got {tele_step}")
        M1 = int(round((tr[1] - tr[0]) / tele_step)) + 1
    grid = dict(stages=N, step_m=path.length / N, tele_nodes=M1, window=window,
                tele_step_m=(tr[1] - tr[0]) / (M1 - 1) if M1 > 1 else 0.0)

    def unreachable(tip, where):
        msg = crane.ik_batch(tip[None, :], teles[M1 // 2])[1][0]
        return _result(PlanStatus.UNREACHABLE, f"the path leaves the workspace at {where}: tip "
                       f"(r={tip[0]:.3f} m, z={tip[1]:.3f} m, slew={tip[2]:.3f} rad): {msg}",
                       objective=objective, grid=grid, solve_time_s=_time.perf_counter() - t0)
    need = grid_bytes(N + 1, M1, window, crane.n, objective)
    if need > MAX_BYTES:
        if grid_bytes(2, M1, window, crane.n, objective) <= MAX_BYTES:
            # an unreachable end is the better answer than "too big" (e.g. r = 1e4 m)
            teles = np.zeros(1) if tr is None else np.linspace(tr[0], tr[1], M1)
            ends = path.tip(np.array([0.0, path.length]))
            ok = (crane.ik_batch(np.repeat(ends, M1, axis=0), np.tile(teles, 2),
                                 explain=False)[1] == "").reshape(2, M1).any(axis=1)
            if not ok.all():
                k = int(np.argmin(ok))
                return unreachable(ends[k], ("the start", "the goal")[k])
        raise UnsupportedRequest(
            f"dp grid {N} stages × {M1} telescope nodes × {2 * window + 1} window steps "
            f"(path {path.length:.3g} m, step {path.length / N:.3g} m) needs ~{need / 2 ** 30:.1f}"
            f" GiB; allowed up to {MAX_BYTES / 2 ** 30:.1f} GiB: use a larger `step` or "
            "`tele_step`, a smaller `window`, or a shorter move")
    s = path.stations(n=N)
    tips = path.tip(s)
    teles = np.zeros(1) if tr is None else np.linspace(tr[0], tr[1], M1)
    warn: list[str] = []
    grid = dict(stages=N, step_m=float(s[1] - s[0]), tele_nodes=M1, window=window,
                tele_step_m=float(teles[1] - teles[0]) if M1 > 1 else 0.0)
    # --- nodes: IK of every (stage, telescope) pair
    qq, reason = crane.ik_batch(np.repeat(tips, M1, axis=0), np.tile(teles, N + 1),
                                explain=False)
    Q = qq.reshape(N + 1, M1, crane.n)
    feas = (reason == "").reshape(N + 1, M1)
    empty = np.flatnonzero(~feas.any(axis=1))
    if empty.size:
        k = int(empty[0])
        return unreachable(tips[k], "the start" if k == 0 else "the goal" if k == N
                           else f"s = {s[k]:.3f} m")
    _, dXdq = crane.stroke(np.where(np.isnan(Q), 0.0, Q).reshape(-1, crane.n))
    dXdq = np.where(np.isnan(Q), np.nan, dXdq.reshape(Q.shape))
    # --- edge costs
    w = window
    T, dq = edge_times(crane, Q, dXdq, w, pump=pump)
    if objective == "time":
        C, Tedge = T, T
    elif objective == "energy":
        dt = (s[1] - s[0]) / tip_speed
        if tr is not None:
            t_i = crane.chain.tele
            v_t = min(crane.spec.joints[t_i].limits.qd[1], -crane.spec.joints[t_i].limits.qd[0])
            if grid["tele_step_m"] > v_t * dt:
                warn.append(f"the telescope cannot move: one grid step ({grid['tele_step_m']:.4f}"
                            f" m) per stage ({dt:.4f} s) exceeds its speed limit {v_t} m/s; use "
                            f"tele_step <= {v_t * dt:.4f} m or a larger step along the path")
        E = edge_energy(crane, Q, dq, dt, w, payload)
        C = np.where(T <= dt * (1 + 1e-9), E, np.inf)
        Tedge = np.full_like(T, dt)
    else:
        E = edge_energy(crane, Q, dq, T, w, payload)
        C, Tedge = (T if lam == 0 else T + lam * E), T
    # --- Bellman recursion over stages (vectorised over nodes and transitions)
    J = np.where(feas[0], 0.0, np.inf)
    if tele_start is not None and tr is not None:
        J = np.where(np.abs(teles - tele_start) <= 0.5 * grid["tele_step_m"] + 1e-12, J, np.inf)
    J0 = J
    arg = np.empty((N, M1), dtype=np.int64)
    rows = np.arange(M1)
    for n in range(1, N + 1):
        tot = _windows(J[None, :], w, np.inf)[0] + C[n - 1]
        a = np.argmin(tot, axis=1)
        arg[n - 1] = a
        J = tot[rows, a]
        if not np.isfinite(J).any():
            why = (f"no feasible transition into stage {n} (s = {s[n]:.3f} m): the telescope "
                   f"window ±{w} steps or the limits cut the path")
            if objective == "energy":
                why = _too_fast(T, feas[0] & np.isfinite(J0), w, dt, tip_speed, path.length) \
                    or why
            return _result(PlanStatus.INFEASIBLE, why, objective=objective, grid=grid,
                           solve_time_s=_time.perf_counter() - t0)
    if tele_goal is not None and tr is not None:
        J = np.where(np.abs(teles - tele_goal) <= 0.5 * grid["tele_step_m"] + 1e-12, J, np.inf)
    if not np.isfinite(J).any():
        return _result(PlanStatus.INFEASIBLE, "the goal telescope value cannot be reached",
                        objective=objective, grid=grid, solve_time_s=_time.perf_counter() - t0)
    # --- back-tracking
    m = np.empty(N + 1, dtype=np.int64)
    m[N] = int(np.argmin(J))
    for n in range(N, 0, -1):
        m[n - 1] = m[n] - w + arg[n - 1, m[n]]
    path_q = Q[np.arange(N + 1), m]
    dts = Tedge[np.arange(N), m[1:], m[:-1] - m[1:] + w]
    times = np.concatenate([[0.0], np.cumsum(dts)])
    energy = float(np.sum(E[np.arange(N), m[1:], m[:-1] - m[1:] + w])) if objective != "time" \
        else float("nan")
    limits = ("position", "velocity") + (("pump_flow",) if pump else ())
    traj = Trajectory(times, path_q, joint_names=tuple(crane.names), method="dp",
                      objective=objective, interpolation="linear", limits=limits,
                      meta=dict(grid=grid, path=path.name, path_length_m=path.length))
    return _result(PlanStatus.OK, objective=objective, trajectory=traj, path_q=path_q, s=s,
                    times=times, tele_index=m, cost=float(J[m[N]]), duration_s=float(times[-1]),
                    energy_J=energy, solve_time_s=_time.perf_counter() - t0, grid=grid,
                    warnings=warn)


def dp_time_reference(crane: Crane, path: Path, *, step: float = 0.01, stages: int | None = None,
                      tele_step: float = 0.01, window: int = 5) -> float:
    """Minimum time by the same Bellman recursion written as plain per-node Python loops
    (velocity limits only, no pump). The readable reference that the vectorised :func:`dp`
    (with ``pump=False``) must equal; benchmarks time it as the naive baseline."""
    s = path.stations(step=step, n=stages)
    tips = path.tip(s)
    lo, hi = crane.tele_range
    teles = np.linspace(lo, hi, int(round((hi - lo) / tele_step)) + 1)
    L = crane.limit_arrays()
    nodes = []
    for tip in tips:
        row = []
        for t in teles:
            q, reason = crane.ik_batch(tip[None, :], t)
            row.append(q[0] if reason[0] == "" else None)
        nodes.append(row)
    INF = float("inf")
    cost = [0.0 if q is not None else INF for q in nodes[0]]
    for n in range(1, len(tips)):
        new = []
        for m, qb in enumerate(nodes[n]):
            best = INF
            if qb is not None:
                for j in range(-window, window + 1):
                    k = m + j
                    if 0 <= k < len(teles) and nodes[n - 1][k] is not None and cost[k] < INF:
                        qa = nodes[n - 1][k]
                        edge = 0.0
                        for i in range(crane.n):
                            d = qb[i] - qa[i]
                            lim = L["qd_max"][i] if d >= 0 else -L["qd_min"][i]
                            edge = max(edge, abs(d) / lim)
                        best = min(best, cost[k] + edge)
            new.append(best)
        cost = new
    return min(cost)


class DPPlanner(Planner):
    """``dp``: the Bellman DP along the straight tip line, minimum time or (with a tip speed or
    a duration fixing the clock) least pump energy. Options: ``step`` [m] (stage spacing,
    0.01), ``tele_step`` [m] (telescope grid, 0.01), ``window`` (telescope steps per stage, 5)."""
    name = "dp"
    description = "Bellman dynamic programming along the tip line (time or energy)"
    objectives = ("time", "energy")
    paths = ("line",)
    uses_tip_speed = ("energy",)
    uses_duration = ("energy",)

    def check(self, request: PlanRequest) -> None:
        super().check(request)
        if request.objective == "energy" and \
                (request.tip_speed is None) == (request.duration is None):
            raise UnsupportedRequest("`method` dp with `objective` energy needs exactly one "
                                     "of `tip_speed` [m/s] or `duration` [s] (the clock it "
                                     "saves energy on)")

    def plan(self, crane: Crane, request: PlanRequest) -> PlanResult:
        return dp(crane, Line(request.start, request.goal), objective=request.objective,
                  **self.grid(request))

    @staticmethod
    def grid(request: PlanRequest) -> dict:
        """The DP keyword arguments a request asks for (grid, tip speed, duration)."""
        return dict(step=request.option("step", 0.01), tele_step=request.option("tele_step", 0.01),
                    window=request.option("window", 5), tip_speed=request.tip_speed,
                    duration=request.duration)


register(DPPlanner())
