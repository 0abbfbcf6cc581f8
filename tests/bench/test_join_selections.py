"""``benchmarks/join_selections.py``: the 100-entry loop's selection library joined from
refinement parts — the named entries, in id order, each with its refinement unchanged."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from planner.library.refined import read_refined, write_refined
from planner.library.store import LibraryStore
from planner.model import Crane
from tests.library.helpers import move_library

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import join_selections  # noqa: E402


@pytest.fixture(scope="module")
def parts(tmp_path_factory):
    """A library of four moves and two parts of it (entries 0, 2 and 1, 3), each entry
    'refined' with commands that name it (write_refined: the stored form)."""
    d = tmp_path_factory.mktemp("join")
    crane = Crane.from_id("s100f")
    pairs = [(0.3, 0.6), (0.4, 0.5), (0.6, 0.35), (0.5, 0.45)]
    move_library(d / "all.h5", crane, pairs, scale=0.8).close()
    out = []
    for k, ids in enumerate((["m0:time", "m2:time"], ["m1:time", "m3:time"])):
        p = d / f"part{k}.h5"
        with LibraryStore.open(d / "all.h5") as src, LibraryStore.create(p, crane.spec) as dst:
            for i in ids:
                join_selections.copy_entry(src, dst, i)
                n = int(i[1])
                write_refined(dst, i, [0.0, 0.02], np.full((2, crane.n), 0.1 * n),
                              dict(status="improved", entry=i))
        out.append(p)
    return d, out


def test_the_named_entries_are_joined_in_id_order_with_their_refinements(parts):
    d, (p0, p1) = parts
    ids = join_selections.join([p1, p0], d / "sel.h5",
                               join_selections.wanted(d / "all.h5", 2, [0, 1]))
    assert ids == ["m0:time", "m1:time", "m2:time", "m3:time"]
    with LibraryStore.open(d / "sel.h5") as db:
        assert db.ids() == ids
        for i in ids:
            t_u, u, info = read_refined(db, i)
            assert info["entry"] == i and np.all(u == 0.1 * int(i[1]))
    only = join_selections.join([p0, p1], d / "one.h5", ["m2:time"])
    assert only == ["m2:time"]


def test_an_entry_no_part_holds_is_refused(parts):
    d, (p0, _) = parts
    with pytest.raises(SystemExit, match="'m1:time' .* is in none of the parts"):
        join_selections.join([p0], d / "bad.h5",
                             join_selections.wanted(d / "all.h5", 2, [0, 1]))
    assert not (d / "bad.h5").exists()
