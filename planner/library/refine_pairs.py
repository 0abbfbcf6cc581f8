"""``library refine``'s last pass: an energy entry never dearer than its own time entry (issue 30).

An energy entry is refined with its pump work priced (:func:`planner.refine.for_objective`,
weight :data:`~planner.refine.ENERGY_ENTRY_WEIGHT`), but the price is a trade against
tracking, and where the plan saves little the refinement can spend more than that: on the
400-entry s100f run 9 of 200 refined energy entries used 2–34 % more pump work on Exudyn than
their own refined time entry (d03-p08: 103 kJ against 77; the twin agreed on all nine to
within 1–2 kJ: 102.8 against 77.0). An energy entry is what a user picks to save energy.

So, once every entry is refined, each move with both a time and an energy entry (same start
and goal) is checked on the twin that refined them: the pump work at the shaft of the
commands each replays (refined where present, else nominal; :func:`planner.library.refined.
entry_commands`), the valves closed after the last command and ``SETTLE`` s more
(:meth:`Twin.pump_energy <planner.model.twin.Twin.pump_energy>`). Where the energy entry's is
above its time entry's, it is refined again from its nominal commands with its pump work
weighed :data:`PAIR_FACTORS` × more, in turn, and the first refinement that is cheaper than the
time entry on the twin and still lands on it as well as the first one did (rest offset and
ringing no larger than the larger of ``fallback_above`` and the first's; the tries run
without the landing-first fallback, whose plain refinement is never the cheaper) replaces it. Where
none is, the first stays and its info says ``costlier``. Either way the entry's info records
the check (``pair``: the time entry, both pump works, the factor taken, the two command sets'
digests), so a rerun skips it while neither entry's commands changed.
"""
from __future__ import annotations

import hashlib
import time as _time
from dataclasses import asdict, replace

import numpy as np

__all__ = ["PAIR_FACTORS", "SETTLE", "CHECK", "move_pairs", "commands_digest", "pump_work",
           "pair_state", "cheaper_task", "pair_info"]

#: factors on the energy entry's pump-work weight, tried in turn where it is dearer than its
#: time entry (s100f d00-p18:energy on the spec's twin: × 1 87.0 kJ against the time entry's
#: 81.9; × 3 74.8 kJ, ringing 3.2 mm)
PAIR_FACTORS = (3.0, 10.0)
#: s the check runs past the last command with the valves closed (the library bench's settle)
SETTLE = 3.0
#: the check's version: a stored check of another is made again (2: the tries without the
#: landing-first fallback)
CHECK = 2


def move_pairs(rows: list[dict], ids: list[str]) -> list[tuple[str, str]]:
    """(time id, energy id) of each move (start, goal) that has an ok entry of each among
    ``ids`` (``rows``: the library's index rows)."""
    keep = set(ids)
    by_move: dict = {}
    for r in rows:
        if r["id"] in keep and r.get("objective") in ("time", "energy"):
            by_move.setdefault((r["start"], r["goal"]), {})[r["objective"]] = r["id"]
    return [(m["time"], m["energy"]) for m in by_move.values() if len(m) == 2]


def commands_digest(u) -> str:
    """A digest (16 hex) of a command array: which commands a check was made on."""
    return hashlib.sha256(np.ascontiguousarray(u, float).tobytes()).hexdigest()[:16]


def pump_work(twin, q0, t_u, u) -> float | None:
    """Pump work at the shaft [J] of commands ``u`` held from ``t_u`` on ``twin`` from rest at
    ``q0``, the valves closed after the last row and ``SETTLE`` s more; None when it
    diverged."""
    rate_dt = float(np.median(np.diff(t_u))) if len(t_u) > 1 else 0.02
    tu = np.append(np.asarray(t_u, float), float(t_u[-1]) + rate_dt)
    uu = np.vstack([np.atleast_2d(np.asarray(u, float)), np.zeros((1, twin.crane.n))])
    run = twin.simulate(tu, uu, q0, t_end=float(tu[-1]) + SETTLE)
    return twin.pump_energy(run) if run.ok else None


def pair_state(db, time_id: str, energy_id: str, twin) -> dict:
    """What the check needs of one move: each entry's trajectory and the commands it replays,
    their digests, and (unless the energy entry's stored check covers these very commands)
    both pump works on ``twin``."""
    from planner.library.refined import entry_commands
    out = dict(time_id=time_id, energy_id=energy_id)
    for k, i in (("time", time_id), ("energy", energy_id)):
        tr = db.trajectory(i)
        t_u, u, used, info = entry_commands(db, i, tr, "auto")
        out[k] = dict(traj=tr, t_u=t_u, u=u, used=used, info=info,
                      digest=None if u is None else commands_digest(u))
    e, t = out["energy"], out["time"]
    done = (e["info"] or {}).get("pair") or {}
    out["current"] = (done.get("time_commands") == t["digest"]
                      and done.get("energy_commands") == e["digest"]
                      and done.get("check") == CHECK)
    if not out["current"] and e["u"] is not None and t["u"] is not None:
        out["time_J"] = pump_work(twin, t["traj"].q[0], t["t_u"], t["u"])
        out["energy_J"] = pump_work(twin, e["traj"].q[0], e["t_u"], e["u"])
    return out


def pair_info(st: dict, base: dict, **kw) -> dict:
    """The ``pair`` record of a check (module doc)."""
    return dict(time_id=st["time_id"], time_pump_J=st.get("time_J"),
                first_pump_J=st.get("energy_J"), time_commands=st["time"]["digest"],
                options=base, check=CHECK, **kw)


def cheaper_task(lib_spec: str, model_spec: str, model_where: str, entry_id: str,
                 arrays: dict, options: dict, grapple, bound_J: float, first_score: float,
                 factors=PAIR_FACTORS) -> dict:
    """The energy entry ``entry_id`` refined again with its pump-work weight × each of
    ``factors`` in turn (runs in a worker) until a refinement costs less than ``bound_J`` on
    the twin and lands as well as the first (``first_score`` [m]); returns the taken one
    (t_u, u, info, factor) or none, and every try."""
    from planner.library.twins import spec_twin
    from planner.refine import RefineOptions, refine_commands
    from planner.refine.measures import score
    from planner.trajectory import Trajectory
    c0 = _time.process_time()
    opts = RefineOptions(**options)
    crane, _ = spec_twin(lib_spec, "<library spec>", opts.step)
    _, twin = spec_twin(model_spec, model_where, opts.step, grapple)
    traj = Trajectory(t=arrays["t"], q=arrays["q"], qd=arrays["qd"], qdd=arrays["qdd"],
                      joint_names=tuple(arrays["joint_names"]))
    tries = []
    limit = max(opts.fallback_above, first_score)
    try:
        for f in factors:
            # no landing-first fallback inside: the plain refinement it would take is never
            # the cheaper one (d02-p07: both prices fell back to it, 94 kJ against 72); the
            # landing is checked here instead
            o = replace(opts, energy_weight=opts.energy_weight * f, fallback_above=0.0)
            r = refine_commands(crane, traj, arrays["t_u"], arrays["u"], twin=twin, options=o)
            J = pump_work(twin, traj.q[0], r.t_u, r.u) if r.ok else None
            s = score(r.predicted["refined"]) if r.ok and "refined" in r.predicted else np.inf
            tries.append(dict(factor=f, status=str(r.status), pump_J=J, score_m=float(s)))
            if J is not None and J < bound_J and s <= limit:
                return dict(id=entry_id, t_u=r.t_u, u=r.u, info=r.info(), factor=f,
                            pump_J=J, tries=tries, cpu_s=_time.process_time() - c0)
    except Exception as e:     # one entry must not stop the others: the first one stays
        tries.append(dict(status="failed", reason=f"{type(e).__name__}: {e}"))
    return dict(id=entry_id, t_u=None, u=None, info=None, factor=None, pump_J=None,
                tries=tries, cpu_s=_time.process_time() - c0)

