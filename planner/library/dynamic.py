"""A library's entries replayed open loop on the independent dynamic plant, on the build's
executors (issue 13: "the library replay of 400 entries runs on the existing process pool / Dask
executors").

Each ok entry's stored 50 Hz valve commands drive the Exudyn plant
(:func:`planner.simulation.dynamic.claims.replay_move`, valves closed for ``settle`` s after
the plan's end) and, beside it, the fast quasi-static replay plant. Per entry: tip tracking
error during the move and at arrival, the offset where the crane comes to rest, the residual
oscillation after arrival and the settling time to ``tol`` (judge: Exudyn, and the fast plant
for comparison), the pump energy of the run, and where the entry's suite has obstacles (the
forwarder's headboard) the tip's least distance to them over the Exudyn replay
(``exudyn.clearance_m``) beside the plan's (``plan_clearance_m``).

The executors are the library build's: in-process, local processes
(:class:`~planner.library.workers.WorkerPool`) or a Dask cluster
(:class:`~planner.library.cluster.DaskPool`). A task carries the file, the entry id and the
options; each worker opens the library read-only and builds the machine from the spec stored
in it once. The driver only collects (nothing is written into the library).
"""
from __future__ import annotations

import os
import time as _time
from contextlib import nullcontext

from planner.library.workers import WorkerPool

__all__ = ["replay_entry", "replay_library"]

_CRANES: dict = {}   # per worker process: library path -> its crane (built once)


def _crane_of(path: str, store):
    from planner.library.query import library_crane
    key = (os.path.abspath(path), os.path.getmtime(path))
    if key not in _CRANES:
        _CRANES[key] = library_crane(store.spec_toml)
    return _CRANES[key]


def replay_entry(path: str, entry_id: str, settle: float = 3.0, tol: float = 0.005,
                 commands: str = "nominal") -> dict:
    """One entry of the library ``path`` replayed on the Exudyn and the fast plant (runs in a
    worker) with its ``commands`` ("nominal", "refined" or "auto": :func:`planner.library.
    refined.entry_commands`). Never raises for a failed run: the status and reason come
    back."""
    from planner.library.refined import entry_commands
    from planner.library.store import LibraryStore
    from planner.simulation.dynamic.claims import replay_move
    t0, c0 = _time.perf_counter(), _time.process_time()
    out = dict(id=entry_id)
    try:
        with LibraryStore.open(path, "r") as store:
            crane = _crane_of(path, store)
            traj = store.trajectory(entry_id)
            attrs = store.entry_attrs(entry_id)
            objective = attrs.get("objective")
            t_u, u, used, info = entry_commands(store, entry_id, traj, commands)
        if t_u is None:
            return dict(out, status="no-commands", reason="the entry stores no 50 Hz commands",
                        seconds=_time.perf_counter() - t0)
        m, run, _ = replay_move(crane, traj, t_u=t_u, u=u, settle=settle, tol=tol,
                                keep_runs=True)
        extra = {} if info is None else dict(lengthened_s=info.get("lengthened_s"),
                                             predicted=info.get("predicted", {}).get("refined"))
        row = dict(out, objective=objective, duration_s=float(traj.duration), commands=used,
                   **extra, **m.as_dict(), seconds=_time.perf_counter() - t0,
                   cpu_s=_time.process_time() - c0)
        obstacles = _obstacles(attrs.get("suite"))
        if obstacles and m.status == "ok":
            from planner.geometry.obstacles import tip_clearance
            row["exudyn"]["clearance_m"] = tip_clearance(crane.tip(run.q), obstacles)
            row["plan_clearance_m"] = attrs.get("clearance_m")
        return row
    except Exception as e:   # one bad entry must not stop the replay of the others
        return dict(out, status="error", reason=f"{type(e).__name__}: {e}",
                    seconds=_time.perf_counter() - t0)


def _obstacles(suite) -> tuple:
    """The obstacles of the task suite ``suite`` (a name; none when unknown or absent)."""
    if not suite:
        return ()
    from planner.tasks.suites import load_suite
    try:
        return tuple(load_suite(str(suite))[0].get("obstacles") or ())
    except (OSError, ValueError, KeyError):
        return ()


def replay_library(path, *, workers: int = 1, scheduler: str | None = None,
                   limit: int | None = None, settle: float = 3.0, tol: float = 0.005,
                   on_result=None, commands: str = "nominal", ids=None) -> dict:
    """Replay the ok entries of the library ``path`` (the first ``limit``, in the file's
    order, or the entries ``ids``) with their ``commands`` on ``workers`` local processes or
    the Dask ``scheduler`` (``local:N`` or an address). ``on_result(row)`` is called as each entry completes. Returns dict(rows in
    completion order, seconds, entries, executor)."""
    from planner.library.store import LibraryStore
    path = str(path)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    with LibraryStore.open(path, "r") as store:
        ok = [r["id"] for r in store.index_rows() if r["status"] == "ok"]
    ids = ok if ids is None else [i for i in ids if i in set(ok)]
    ids = ids[:limit] if limit is not None else ids
    args = [(path, i, settle, tol, commands) for i in ids]
    t0 = _time.perf_counter()
    rows = []
    if scheduler:
        from planner.library.cluster import DaskPool
        pool = DaskPool(scheduler)
    else:
        pool = WorkerPool(workers) if workers > 1 else None
    with (pool or nullcontext()):
        results = (pool.imap_unordered(replay_entry, args) if pool is not None
                   else (replay_entry(*a) for a in args))
        for r in results:
            rows.append(r)
            if on_result is not None:
                on_result(r)
    executor = scheduler or (f"processes:{workers}" if workers > 1 else "in-process")
    return dict(rows=rows, seconds=_time.perf_counter() - t0, entries=len(ids),
                executor=executor)
