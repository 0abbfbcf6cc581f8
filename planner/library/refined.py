"""Refined commands kept beside an entry's nominal ones (issue 27).

Layout inside an entry group (:mod:`planner.library.store`)::

    /entries/<id>/refined   group; attrs: info (JSON: status, reason, iterations, evaluations,
                            predicted twin measures nominal / refined, lengthened_s, model
                            provenance — the twin's machine, spec, fingerprint, step — the
                            refine options, wall_s), complete (1, written last)
        t_u                 (M,)     s, the control grid from the plan's start
        u                   (M, n)   valve commands (-1..1), held; the valves close after the
                                     last row (which may lie up to ``tail`` past the plan's end)

The nominal commands stay where they were (the entry's ``u``). A refinement replaces the
previous one of the entry. Writing goes through the store's journal: the group is written,
flushed and committed as one step, so a killed ``library refine`` leaves each entry either
with its old refinement (or none) or with the new one complete, and a rerun resumes.

:func:`entry_commands` is what replays, exports and the fixed-rate controller CSV take: the
refined commands when present (or asked for), else the nominal ones, and which they are.
"""
from __future__ import annotations

import json

import numpy as np

from planner.library.fields import StoreError, as_str

__all__ = ["write_refined", "read_refined", "refined_info", "entry_commands", "COMMAND_CHOICES"]

GROUP = "refined"
COMMAND_CHOICES = ("auto", "nominal", "refined")


def write_refined(store, entry_id: str, t_u, u, info: dict) -> None:
    """Store refined commands ``u`` (M, n) held from ``t_u`` (M,) with their ``info`` (JSON-
    ready dict) in the entry ``entry_id`` of the writable ``store`` (replacing an earlier
    refinement), then commit."""
    from planner.io import dumps
    g = store.group(entry_id)
    t_u = np.asarray(t_u, float).ravel()
    u = np.atleast_2d(np.asarray(u, float))
    if u.shape[0] != t_u.size or not np.all(np.isfinite(u)) or np.max(np.abs(u)) > 1.0 + 1e-12:
        raise StoreError(f"entry '{entry_id}': refined commands of shape {u.shape} for "
                         f"{t_u.size} times; expected finite commands within -1..1, one row "
                         "per time")
    if GROUP in g:
        del g[GROUP]
    r = g.create_group(GROUP)
    r.create_dataset("t_u", data=t_u).attrs["units"] = "s"
    r.create_dataset("u", data=u).attrs["units"] = "1 (valve command, -1..1)"
    r.attrs["info"] = dumps(info)
    r.attrs["complete"] = 1
    store.commit()


def refined_info(store, entry_id: str) -> dict | None:
    """The info of the entry's refinement (None when it has none, or an incomplete one)."""
    g = store.group(entry_id)
    if GROUP not in g or int(g[GROUP].attrs.get("complete", 0)) != 1:
        return None
    try:
        return json.loads(as_str(g[GROUP].attrs["info"]))
    except (KeyError, ValueError):
        return None


def read_refined(store, entry_id: str):
    """(t_u, u, info) of the entry's refinement, or None."""
    info = refined_info(store, entry_id)
    if info is None:
        return None
    g = store.group(entry_id)[GROUP]
    return np.asarray(g["t_u"][()], float), np.asarray(g["u"][()], float), info


def entry_commands(store, entry_id: str, traj, which: str = "auto", rate: float = 50.0):
    """(t_u, u, "refined" | "nominal", info) of an entry: ``which`` = "auto" (refined when
    present), "nominal" or "refined" (StoreError when the entry has none). ``traj`` is the
    entry's trajectory (its nominal commands on the ``rate`` grid); (None, None, "nominal",
    None) when it stores no commands."""
    from planner.feedforward import stored_commands
    if which not in COMMAND_CHOICES:
        raise StoreError(f"commands = {which!r}; allowed: {', '.join(COMMAND_CHOICES)}")
    if which != "nominal":
        r = read_refined(store, entry_id)
        if r is not None:
            return r[0], r[1], "refined", r[2]
        if which == "refined":
            raise StoreError(f"{store.path}: entry '{entry_id}' has no refined commands; run "
                             f"`crane-planner library refine {store.path}` first, or choose "
                             "--commands nominal")
    cmd = stored_commands(traj, rate)
    if cmd is None:
        return None, None, "nominal", None
    return cmd[0], cmd[1], "nominal", None
