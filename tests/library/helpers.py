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
