"""What the library tests share: two databases with the same entries."""
import numpy as np
import pytest

from planner.library.store import LibraryStore


def assert_same_entries(a_path, b_path, n: int) -> None:
    """``b_path`` holds exactly the ``n`` entries of ``a_path`` (no duplicate, none missing),
    with the same statuses, durations and joint samples."""
    with LibraryStore.open(a_path, "r") as a, LibraryStore.open(b_path, "r") as b:
        ra = {r["id"]: r for r in a.index_rows()}
        rb = {r["id"]: r for r in b.index_rows()}
        assert set(ra) == set(rb) and len(rb) == n
        for k in ra:
            assert rb[k]["status"] == ra[k]["status"]
            assert rb[k]["duration_s"] == pytest.approx(ra[k]["duration_s"], rel=1e-9)
            np.testing.assert_allclose(b.trajectory(k).q, a.trajectory(k).q, atol=1e-9)


def move_library(path, crane, pairs, scale: float):
    """A library at ``path`` of Ruckig rest-to-rest time moves ``m0:time``, ``m1:time``, …,
    one per (a, b) in ``pairs`` (each a fraction of every joint's range: from a to b), with
    their 50 Hz feed-forward; left open for more entries: returns the store."""
    from planner.feedforward import commands
    from planner.library.store import LibraryStore
    from planner.methods.ruckig import rest_to_rest
    L = crane.limit_arrays()
    db = LibraryStore.create(path, crane.spec)
    for k, (a, b) in enumerate(pairs):
        q0, q1 = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (a, b))
        tr = rest_to_rest(crane, q0, q1, scale=scale).trajectory
        tr = commands(crane, tr, 50.0).attach(tr, knots=True)
        db.add(f"m{k}:time", tr, start=crane.tip(q0), goal=crane.tip(q1), objective="time",
               method="ruckig", status="ok")
    return db
