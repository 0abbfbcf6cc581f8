"""``library refine LIB.h5 --cycle ID,ID,…``: the entries of one work cycle refined as one
(issue 27, the work cycle; :func:`planner.refine.cycle.refine_cycle`).

A move refined alone assumes it starts at rest with the load-holding pressures and the
unloaded chambers at tank. Back to back it starts from what the move before left: on the
twin, a forwarder's slew keeps 10–40 bar in both chambers and its telescope's rod side climbs
to 250 bar over 20 moves; on Exudyn 20 moves that land alone land 1 of 20 back to back
(``refine_robust.md``), and with the trapped pressures reset they would land again
(``twin_cycle.md``). Here each entry of the cycle, in the order given, is refined on the twin
from the state the refined entry before it leaves (its commands, then ``gap`` s with the
valves closed after the later of its plan's end and its last command). The result is stored
as each entry's refined commands, with the provenance ``cycle`` (the cycle's ids, this entry's
position, the gap) beside the twin's and the options: the library is then tuned to that cycle
(``simulate``, ``library export`` and the controller CSV take them as any refined commands).

The entries must chain: each one starts where the one before ends (within
:data:`CHAIN_TOL`). Resume: entries already refined for this cycle (same ids, gap, twin
fingerprint and options) are kept and their stored commands replayed on the twin to find where
the next one starts, so a killed run, rerun, gives the same file.
"""
from __future__ import annotations

import time as _time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from planner.library.lock import BuildLock
from planner.library.workers import SignalGuard

__all__ = ["refine_cycle_library", "CHAIN_TOL"]

CHAIN_TOL = 1e-3   # [rad | m] how far an entry may start from the previous one's end


def refine_cycle_library(path, ids, *, model=None, gap: float = 3.0, options=None,
                         force: bool = False) -> dict:
    """Refine the entries ``ids`` of the library ``path`` as one work cycle (module doc) on
    the twin of ``model`` (default the library's spec). Returns a summary dict. ValueError
    naming the entry when one is missing, not ok, or does not chain."""
    from planner.library.twins import spec_twin
    from planner.library.refined import refined_info, read_refined, write_refined
    from planner.library.store import LibraryStore
    from planner.refine import RefineOptions, for_objective, refine_commands
    from planner.refine.cycle import after_move
    from planner.feedforward import commands, stored_commands
    opts = options or RefineOptions()
    path, ids = Path(path), [str(i) for i in ids]
    if len(ids) < 2:
        raise ValueError(f"cycle: {len(ids)} entries; a cycle needs at least 2")
    if not (np.isfinite(gap) and 0.0 <= gap <= 600.0):
        raise ValueError(f"gap = {gap!r} s; allowed 0 .. 600 s (the valves closed between moves)")
    t0 = _time.perf_counter()
    with LibraryStore.open(path, "r") as db:
        lib_spec = db.spec_toml
        ok = {r["id"]: r["status"] for r in db.index_rows()}
        objective = {r["id"]: r.get("objective") for r in db.index_rows()}
        for i in ids:
            if ok.get(i) != "ok":
                raise ValueError(f"cycle: entry '{i}' is {ok.get(i, 'not in the library')}; "
                                 "allowed: ok entries of this library")
        trajs = [db.trajectory(i) for i in ids]
    for k in range(1, len(ids)):
        gapq = np.abs(trajs[k].q[0] - trajs[k - 1].q[-1])
        if np.max(gapq) > CHAIN_TOL:
            raise ValueError(f"cycle: entry '{ids[k]}' starts {np.max(gapq):.3g} from where "
                             f"'{ids[k - 1]}' ends (joint {int(np.argmax(gapq))}); allowed: "
                             f"{CHAIN_TOL:g} (the entries of a cycle chain)")
    model_where, model_spec = ("<library spec>", lib_spec) if model is None else (
        str(model), Path(model).read_text(encoding="utf-8"))
    crane, _ = spec_twin(lib_spec, "<library spec>", opts.step)
    _, twin = spec_twin(model_spec, model_where, opts.step)
    fingerprint = twin.provenance()["fingerprint"]
    kept, rows, x = 0, [], None
    with SignalGuard() as guard, BuildLock(path), LibraryStore.open(path, "a") as db:
        for k, (i, tr) in enumerate(zip(ids, trajs)):
            cyc = dict(ids=ids, position=k, gap_s=float(gap), from_rest=x is None)
            o = for_objective(opts, objective[i])      # an energy entry: priced
            info = refined_info(db, i)
            if (not force and info is not None and info.get("cycle") == cyc
                    and info.get("model", {}).get("fingerprint") == fingerprint
                    and info.get("options") == asdict(o)):
                t_u, u = read_refined(db, i)[:2]
                kept += 1
                rows.append(dict(id=i, status="kept", predicted=info.get("predicted", {})))
            else:
                cmd = stored_commands(tr, opts.rate)
                if cmd is None:
                    ff = commands(crane, tr, opts.rate, oil=fills_oil(crane))
                    cmd = (ff.t, ff.u)
                c0 = _time.process_time()
                r = refine_commands(crane, tr, cmd[0], cmd[1], twin=twin, options=o, x0=x)
                t_u, u = r.t_u, r.u
                with guard.critical():
                    write_refined(db, i, t_u, u, dict(r.info(), cycle=cyc,
                                                     cpu_s=_time.process_time() - c0))
                rows.append(dict(id=i, status=str(r.status), predicted=r.predicted))
            x = after_move(twin, tr, t_u, u, x, gap, opts.rate)
    return dict(library=str(path), model=model_where, twin_fingerprint=fingerprint,
                cycle=ids, gap_s=float(gap), refined=len(ids) - kept, kept=kept,
                entries=[dict(id=r["id"], status=r["status"],
                              rest_offset_m=(r["predicted"].get("refined") or {}).get(
                                  "rest_offset_m")) for r in rows],
                seconds=_time.perf_counter() - t0)
