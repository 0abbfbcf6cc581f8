"""``library refine``: every ok entry's feed-forward re-computed on the dynamic twin and stored
beside the nominal commands (issue 27; :mod:`planner.refine`, :mod:`planner.library.refined`).

The twin is the library's own machine (the spec stored in the file) or ``model`` — another
spec of the same machine, e.g. one written by ``calibrate`` with fitted ``[dynamics]``. The
driver holds the file (the single writer; another build or refine on it is refused), reads the
entries and sends each entry's trajectory and nominal commands to the workers (local
processes or a Dask cluster, as the build); each worker builds the twin once and refines;
the driver writes each result as it arrives, through the journal.

Resume: an entry whose stored refinement was made by the same twin (its fingerprint: machine,
parameters, step) with the same options is skipped, so a killed refine, rerun, does only
the rest and gives the same file as an uninterrupted run (each entry's refinement depends
on that entry and the twin only). ``force`` redoes every entry.
"""
from __future__ import annotations

import signal
import time as _time
from contextlib import nullcontext
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.io import progress
from planner.library.journal import WriteFailed
from planner.library.lock import BuildLock
from planner.library.twins import entry_arrays, entry_grapple, model_crane, spec_twin
from planner.library.workers import Interrupted, SignalGuard, WorkerPool

if TYPE_CHECKING:
    from planner.model import Crane

#: where ``library refine`` starts each entry's search (:func:`refine_library`)
START_CHOICES = ("nominal", "refined")

__all__ = ["START_CHOICES", "refine_library", "refine_task", "model_crane", "spec_twin", "entry_grapple"]


def refine_task(lib_spec: str, model_spec: str, model_where: str, entry_id: str, arrays: dict,
                options: dict, grapple: tuple | None = None) -> dict:
    """One entry refined (runs in a worker): ``arrays`` holds the trajectory (t, q, qd, qdd,
    joint_names), the nominal commands (t_u, u) and optionally the commands to start from
    (t_start, u_start); ``grapple``: the twin carries the load
    on that link (:func:`spec_twin`). Never raises: a failure comes back as a status "failed"
    with its reason."""
    from planner.refine import RefineOptions, refine_commands
    from planner.trajectory import Trajectory
    c0 = _time.process_time()
    try:
        opts = RefineOptions(**options)
        crane, _ = spec_twin(lib_spec, "<library spec>", opts.step)
        _, twin = spec_twin(model_spec, model_where, opts.step, grapple) \
            if model_spec != lib_spec else spec_twin(lib_spec, "<library spec>", opts.step,
                                                     grapple)
        traj = Trajectory(t=arrays["t"], q=arrays["q"], qd=arrays["qd"], qdd=arrays["qdd"],
                          joint_names=tuple(arrays["joint_names"]))
        start = (arrays["t_start"], arrays["u_start"]) if "t_start" in arrays else None
        r = refine_commands(crane, traj, arrays["t_u"], arrays["u"], twin=twin, options=opts,
                            start=start)
        info = dict(r.info(), cpu_s=_time.process_time() - c0)
        return dict(id=entry_id, t_u=r.t_u, u=r.u, info=info)
    except Exception as e:   # one entry must not stop the others
        return dict(id=entry_id, t_u=None, u=None,
                    info=dict(status="failed", reason=f"{type(e).__name__}: {e}",
                              cpu_s=_time.process_time() - c0))


def refine_library(path, *, model=None, workers: int = 1, scheduler: str | None = None,
                   limit: int | None = None, options=None, force: bool = False,
                   show_progress: bool = True, swing_weight: float | None = None,
                   start: str = "nominal") -> dict:
    """Refine the ok entries of the library ``path`` (the first ``limit``) on the twin of
    ``model`` (a spec file; default the library's spec) with
    :class:`~planner.refine.RefineOptions` ``options``. An entry planned with a grapple
    (``library build --grapple``, :func:`entry_grapple`) is refined on the twin that carries
    the load on that link, its swing after the plan's end costing ``swing_weight`` (None:
    :data:`planner.refine.SWING_WEIGHT`; 0: the tip alone, the twin without the link): the
    refined commands end with the load at rest under the tip. ``start`` "refined": each
    entry's search starts from its stored refined commands where it has them (an earlier
    refinement — on the spec's twin, before a calibration) instead of its nominal ones, where
    the new twin prices them lower (:func:`planner.refine.refine_commands`); "nominal" (the
    default) always from the nominal ones. Returns a summary dict; SIGINT /
    SIGTERM stop it promptly (the entry being written completed) and raise
    :class:`~planner.library.workers.Interrupted` with the summary so far."""
    from planner.library.refined import read_refined, refined_info, write_refined
    from planner.library.store import LibraryStore
    from planner.refine import SWING_WEIGHT, RefineOptions, for_objective
    opts = options or RefineOptions()
    sw = SWING_WEIGHT if swing_weight is None else float(swing_weight)
    if not (np.isfinite(sw) and sw >= 0):
        raise ValueError(f"swing_weight = {swing_weight!r}; allowed: >= 0")
    path = Path(path)
    if workers < 1:
        raise ValueError(f"workers = {workers}; allowed: >= 1")
    if start not in START_CHOICES:
        raise ValueError(f"start = {start!r}; allowed: {', '.join(START_CHOICES)}")
    t0 = _time.perf_counter()
    with LibraryStore.open(path, "r") as db:
        lib_spec = db.spec_toml
        rows = [r for r in db.index_rows() if r["status"] == "ok"]
    ids = [r["id"] for r in rows]
    objective = {r["id"]: r.get("objective") for r in rows}
    if model is not None:
        model_where = str(model)
        model_spec = Path(model).read_text(encoding="utf-8")
    else:
        model_where, model_spec = "<library spec>", lib_spec
    crane, _ = spec_twin(lib_spec, "<library spec>", opts.step)
    m_crane, twin = spec_twin(model_spec, model_where, opts.step)
    if tuple(m_crane.names) != tuple(crane.names):
        raise ValueError(f"model {model}: joints {list(m_crane.names)}; the library's "
                         f"machine has {list(crane.names)} (a model of the same machine is "
                         "needed)")
    fingerprint = twin.provenance()["fingerprint"]
    ids = ids[:limit] if limit is not None else ids
    state = dict(written=0, skipped=0, counts={}, failed=[], cpu=[], swing=0, warm=0)
    with SignalGuard() as guard:
        pool = None
        if scheduler:
            from planner.library.cluster import DaskPool
            pool = DaskPool(scheduler)
        elif workers > 1:
            pool = WorkerPool(workers)
        try:
            with (pool or nullcontext()):
                with BuildLock(path):
                    with LibraryStore.open(path, "a") as db:
                        tasks = []
                        for i in ids:
                            info = refined_info(db, i)
                            link = entry_grapple(db.entry_attrs(i)) if sw > 0 else None
                            o = for_objective(opts, objective[i])   # energy: priced
                            o = replace(o, swing_weight=sw) if link else o
                            fp = (fingerprint if link is None else spec_twin(
                                model_spec, model_where, opts.step, link)[1]
                                .provenance()["fingerprint"])
                            if (not force and info is not None
                                    and info.get("model", {}).get("fingerprint") == fp
                                    and asdict(o) in (info.get("options"),
                                                      (info.get("pair") or {}).get("options"))):
                                state["skipped"] += 1
                                continue
                            arrays = entry_arrays(crane, db.trajectory(i), opts.rate)
                            got = read_refined(db, i) if start == "refined" else None
                            if got is not None:
                                arrays.update(t_start=got[0], u_start=got[1])
                                state["warm"] += 1
                            tasks.append((lib_spec, model_spec, model_where, i, arrays,
                                          asdict(o), link))
                            state["swing"] += link is not None
                        state["todo"] = len(tasks)
                        bar = progress(len(tasks), f"refine {path.name}", "entry",
                                       enabled=show_progress)
                        results = (pool.imap_unordered(refine_task, tasks) if pool is not None
                                   else (refine_task(*a) for a in tasks))
                        try:
                            for r in results:
                                with guard.critical():
                                    _write(db, r, state, write_refined)
                                bar.update(1)
                        finally:
                            bar.close()
                        if opts.energy_entries == "priced":
                            _check_pairs(db, rows, ids, pool, guard, state, crane,
                                         (lib_spec, model_spec, model_where), opts, sw)
        except Interrupted as e:
            e.summary = _summary(path, model_where, fingerprint, ids, state, t0,
                                 status="interrupted", signal=signal.Signals(e.signum).name)
            raise
        except WriteFailed as e:
            raise WriteFailed(path, OSError(e.errno, f"{e.why}; the refinements finished "
                                                     f"before it are kept ({state['written']}"
                                                     "): make room and rerun to resume")) \
                from None
    return _summary(path, model_where, fingerprint, ids, state, t0, status="ok")


def _check_pairs(db, rows, ids, pool, guard, state, crane: Crane, specs, opts, sw) -> None:
    """The energy entries checked against their time entries on the twin and refined again
    where dearer (:mod:`planner.library.refine_pairs`)."""
    from planner.library.refine_pairs import (cheaper_task, commands_digest, move_pairs,
                                              pair_info, pair_state)
    from planner.library.refined import write_refined
    from planner.refine import for_objective
    from planner.refine.measures import score
    st_all, tasks = {}, []
    pairs = state["pairs"] = dict(moves=0, checked=0, dearer=0, made_cheaper=0, costlier=[])
    for t_id, e_id in move_pairs(rows, ids):
        pairs["moves"] += 1
        link = entry_grapple(db.entry_attrs(e_id)) if sw > 0 else None
        o = for_objective(opts, "energy")
        o = replace(o, swing_weight=sw) if link else o
        twin = spec_twin(specs[1], specs[2], opts.step, link)[1]
        st = pair_state(db, t_id, e_id, twin)
        if st["current"] or st["energy"]["used"] != "refined" or st.get("energy_J") is None \
                or st.get("time_J") is None:
            continue
        pairs["checked"] += 1
        if st["energy_J"] <= st["time_J"]:
            e = st["energy"]
            with guard.critical():
                write_refined(db, e_id, e["t_u"], e["u"], dict(e["info"], pair=pair_info(
                    st, asdict(o), factor=1.0, pump_J=st["energy_J"], costlier=False,
                    energy_commands=e["digest"])))
            continue
        pairs["dearer"] += 1
        st_all[e_id] = (st, o)
        tasks.append((*specs, e_id, entry_arrays(crane, st["energy"]["traj"], opts.rate),
                      asdict(o), link, st["time_J"], score(_predicted(st["energy"]["info"]))))
    results = (pool.imap_unordered(cheaper_task, tasks) if pool is not None
               else (cheaper_task(*a) for a in tasks))
    for r in results:
        st, o = st_all[r["id"]]
        e = st["energy"]
        with guard.critical():
            if r["u"] is not None:
                pairs["made_cheaper"] += 1
                write_refined(db, r["id"], r["t_u"], r["u"], dict(r["info"], pair=pair_info(
                    st, asdict(o), factor=r["factor"], pump_J=r["pump_J"], costlier=False,
                    energy_commands=commands_digest(r["u"]), tries=r["tries"])))
            else:
                pairs["costlier"].append(r["id"])
                write_refined(db, r["id"], e["t_u"], e["u"], dict(e["info"], pair=pair_info(
                    st, asdict(o), factor=None, pump_J=st["energy_J"], costlier=True,
                    energy_commands=e["digest"], tries=r["tries"])))


def _predicted(info: dict) -> dict:
    """A refinement's predicted landing on the twin (never landed where it has none)."""
    p = (info.get("predicted") or {}).get("refined")
    return p if p else dict(rest_offset_m=float("inf"), residual_oscillation_m=float("inf"))


def _write(db, r: dict, state: dict, write_refined) -> None:
    info = r["info"]
    st = info.get("status", "failed")
    state["counts"][st] = state["counts"].get(st, 0) + 1
    state["cpu"].append(info.get("cpu_s", float("nan")))
    rs = (info.get("predicted") or {}).get("restart")
    if rs:      # refined again from the nominal commands (a given start predicted off)
        state["restarted"] = state.get("restarted", 0) + 1
        state["restart_taken"] = state.get("restart_taken", 0) + bool(rs.get("taken"))
    if st == "failed" or r["u"] is None:
        state["failed"].append(dict(id=r["id"], reason=info.get("reason", "")))
        return
    write_refined(db, r["id"], r["t_u"], r["u"], info)
    state["written"] += 1


def _summary(path, model_where, fingerprint, ids, state, t0, **kw) -> dict:
    cpu = np.asarray(state["cpu"], float)
    cpu = cpu[np.isfinite(cpu)]
    return dict(library=str(path), model=model_where, twin_fingerprint=fingerprint,
                entries=len(ids), refined=state["written"], skipped_existing=state["skipped"],
                with_swing=state["swing"], started_from_refined=state.get("warm", 0),
                restarted=state.get("restarted", 0), restart_taken=state.get("restart_taken", 0),
                energy_pairs=state.get("pairs"),
                statuses=state["counts"], failed=state["failed"],
                cpu_per_entry_s=dict(median=float(np.median(cpu)) if cpu.size else None,
                                     p90=float(np.percentile(cpu, 90)) if cpu.size else None),
                seconds=_time.perf_counter() - t0, **kw)
