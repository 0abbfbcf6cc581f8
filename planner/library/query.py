"""Asking a library: the entry nearest to a requested move, the summary of its index, and the
join that brings the crane from its current joint state to a stored entry's start.

Distances between moves are measured in Cartesian space: a move's distance to an entry is
|start - start_e| + |goal - goal_e| [m] with the tips (r, z, slew) converted to (x, y, z), so a
slew difference counts as the arc it sweeps at the tip's radius.

These functions work on plain arrays and :class:`~planner.trajectory.Trajectory` objects;
:class:`planner.library.store.LibraryStore` reads the file and calls them (``db.nearest``,
``db.info``).
"""
from __future__ import annotations

import tomllib

import numpy as np

from planner.feedforward import commands, fills_oil
from planner.methods.ruckig import rest_to_rest
from planner.model import Crane
from planner.model.spec import parse_spec
from planner.trajectory import Trajectory

JOIN_RATE_HZ = 50.0  # control rate of the joined move's valve feed-forward
# the nearest entry is "far" from a request beyond max(FAR_MIN_M, FAR_FRACTION · move length)
FAR_MIN_M = 1.0
FAR_FRACTION = 0.5


class JoinError(ValueError):
    """The join from a joint state cannot be made (wrong number of values, or Ruckig's reason)."""


def cartesian(p) -> np.ndarray:
    """(…, 3) tips (r [m], z [m], slew [rad]) -> Cartesian (x, y, z) [m]."""
    p = np.asarray(p, dtype=float)
    r, z, s = p[..., 0], p[..., 1], p[..., 2]
    return np.stack([r * np.cos(s), r * np.sin(s), z], axis=-1)


def nearest_entry(index: dict, start, goal, objective: str | None = None,
                  where="library") -> tuple[str, float]:
    """The "ok" row of ``index`` (columns as :meth:`LibraryStore.index_columns`: id, status,
    objective, start, goal) nearest to the move ``start`` -> ``goal`` (tips r, z, slew), only
    rows of ``objective`` when given. Returns (entry id, distance [m]); LookupError (naming
    ``where``) when there is no candidate."""
    s, g = cartesian(start), cartesian(goal)
    if len(index["id"]) == 0:
        raise LookupError(f"{where}: the library has no entries")
    mask = np.asarray(index["status"]) == "ok"
    if objective is not None:
        mask &= np.asarray(index["objective"]) == objective
    if not mask.any():
        what = f" with objective '{objective}'" if objective is not None else ""
        raise LookupError(f"{where}: no 'ok' entries{what}")
    d = (np.linalg.norm(cartesian(np.asarray(index["start"])[mask]) - s, axis=1)
         + np.linalg.norm(cartesian(np.asarray(index["goal"])[mask]) - g, axis=1))
    k = int(np.argmin(d))
    return str(np.asarray(index["id"])[mask][k]), float(d[k])


def far_warning(distance: float, start, goal) -> str | None:
    """A warning when the nearest entry, ``distance`` [m] (start + goal, as
    :func:`nearest_entry`) from the move ``start`` -> ``goal``, is too far to stand for it:
    beyond max(:data:`FAR_MIN_M`, :data:`FAR_FRACTION` × the move's own length). None when
    it is near enough."""
    move = float(np.linalg.norm(cartesian(goal) - cartesian(start)))
    limit = max(FAR_MIN_M, FAR_FRACTION * move)
    if not distance > limit:
        return None
    return (f"the nearest entry is {distance:.3g} m from the request (start + goal distance), "
            f"more than {limit:.3g} m (the larger of {FAR_MIN_M:g} m and {FAR_FRACTION:g} × "
            f"the move's {move:.3g} m): the library does not cover this move; plan it with "
            "`crane-planner plan`")


def index_summary(rows: list[dict]) -> dict:
    """Counts and statistics of index rows (:meth:`LibraryStore.index_rows`): entries, ok,
    failures (by status), by_objective, by_method, and n / min / mean / max / total of
    duration_s, energy_J and robustness over the "ok" rows (None when no finite value)."""
    ok = [r for r in rows if r["status"] == "ok"]
    failures: dict[str, int] = {}
    for r in rows:
        if r["status"] != "ok":
            failures[r["status"]] = failures.get(r["status"], 0) + 1

    def stats(key):
        v = np.array([r[key] for r in ok], float)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return dict(n=0, min=None, mean=None, max=None, total=None)
        return dict(n=int(v.size), min=float(v.min()), mean=float(v.mean()),
                    max=float(v.max()), total=float(v.sum()))

    def count(key):
        out: dict[str, int] = {}
        for r in rows:
            out[r[key]] = out.get(r[key], 0) + 1
        return out
    return dict(entries=len(rows), ok=len(ok), failures=failures,
                by_objective=count("objective"), by_method=count("method"),
                duration_s=stats("duration_s"), energy_J=stats("energy_J"),
                robustness=stats("robustness"))


def library_crane(spec_toml: str) -> Crane:
    """The crane of a library, from the spec TOML embedded in the file."""
    return Crane(parse_spec(tomllib.loads(spec_toml), "<library spec>", spec_toml))


def join_from(crane: Crane, q, traj: Trajectory,
              rate: float = JOIN_RATE_HZ) -> tuple[Trajectory, float]:
    """Prepend a Ruckig rest-to-rest join from the joint state ``q`` (SI, one value per joint)
    to the start of ``traj`` (an entry, starting at rest). Returns (the joined trajectory with
    the valve feed-forward of the whole move at ``rate`` [Hz] attached, join duration [s]).
    JoinError when ``q`` has the wrong length or the join cannot be planned (its reason)."""
    q = np.asarray(q, dtype=float)
    if q.shape != (crane.n,):
        raise JoinError(f"needs {crane.n} joint values ({', '.join(crane.names)}), "
                         f"got {q.size}")
    j = rest_to_rest(crane, q, traj.q[0])
    if not j.ok:
        raise JoinError(j.reason)
    a, b = j.trajectory, traj
    t = np.concatenate([a.t, a.t[-1] + b.t[1:]])

    def cat(x, y):
        return np.vstack([x, y[1:]])
    joined = Trajectory(t, cat(a.q, b.q), cat(a.qd, b.qd), cat(a.qdd, b.qdd),
                        joint_names=b.joint_names, method=f"ruckig+{b.method}",
                        objective=b.objective)
    return (commands(crane, joined, rate, oil=fills_oil(crane)).attach(joined),
            float(a.duration))
