"""A library replayed on the Exudyn plant, on the build's executors (issue 13, item 5)."""
import numpy as np
import pytest

from planner import Crane
from planner.feedforward import commands
from planner.library.dynamic import replay_library
from planner.library.store import LibraryStore
from planner.methods.ruckig import rest_to_rest
from tests.library.helpers import move_library


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    """Two slow Ruckig moves with their 50 Hz feed-forward, and one failed entry."""
    crane = Crane.from_id("s100f")
    path = tmp_path_factory.mktemp("dyn") / "lib.h5"
    with move_library(path, crane, [(0.45, 0.55), (0.55, 0.4)], scale=0.3) as db:
        db.add("m2:time", None, start=(1, 1, 0), goal=(2, 1, 0), objective="time",
               method="ruckig", status="failed", reason="test")
    return path


def test_in_process_replay_judges_every_ok_entry(lib):
    """Every ok entry replayed, the failed one skipped; the fast plant replays its own
    feed-forward (tip within a few mm: the oracle that commands and clock line up), the
    Exudyn plant arrives near the goal and reports its settling."""
    res = replay_library(lib, settle=1.0)
    assert res["entries"] == 2 and res["executor"] == "in-process"
    assert sorted(r["id"] for r in res["rows"]) == ["m0:time", "m1:time"]
    for r in res["rows"]:
        assert r["status"] == "ok", r
        assert r["fast"]["max_track_m"] < 0.01
        assert np.isfinite(r["exudyn"]["arrival_m"]) and r["exudyn"]["arrival_m"] < 0.5


@pytest.mark.slow   # the same replays on worker processes and on a Dask LocalCluster
def test_process_and_dask_executors_give_the_same_measures(lib):
    base = {r["id"]: r for r in replay_library(lib, settle=1.0)["rows"]}
    for kw in (dict(workers=2), dict(scheduler="local:2")):
        got = {r["id"]: r for r in replay_library(lib, settle=1.0, **kw)["rows"]}
        assert set(got) == set(base)
        for k in base:
            for m, v in base[k]["exudyn"].items():
                np.testing.assert_allclose(got[k]["exudyn"][m], v, rtol=1e-9, err_msg=m)


def test_the_replay_reports_the_tips_clearance_from_the_suites_headboard(tmp_path):
    """An entry of the forwarder suite (its headboard an obstacle): the Exudyn replay's least
    tip distance to it. Oracle: a distance is 1-Lipschitz in the tip, so it lies within the
    replay's largest tip deviation from the plan of the plan's own clearance."""
    from planner.geometry.paths import tip_to_xyz
    from planner.tasks.suites import load_suite
    crane = Crane.from_id("s100f")
    L = crane.limit_arrays()
    q0, q1 = (L["q_min"] + f * (L["q_max"] - L["q_min"]) for f in (0.45, 0.55))
    tr = rest_to_rest(crane, q0, q1, scale=0.3).trajectory
    tr = commands(crane, tr, 50.0).attach(tr, knots=True)
    obs = load_suite("forwarder-cycle")[0]["obstacles"]
    assert obs
    cyl = crane.tip(tr.sample(tr.resample(1000.0))[0])
    plan = min(float(ob.distance(tip_to_xyz(cyl), cyl).min()) for ob in obs)
    path = tmp_path / "lib.h5"
    with LibraryStore.create(path, crane.spec) as db:
        db.add("m0:time", tr, start=crane.tip(q0), goal=crane.tip(q1), objective="time",
               method="ruckig", status="ok", attrs=dict(suite="forwarder-cycle",
                                                        clearance_m=plan))
        db.add("m1:time", tr, start=crane.tip(q0), goal=crane.tip(q1), objective="time",
               method="ruckig", status="ok")
    rows = {r["id"]: r for r in replay_library(path, settle=1.0)["rows"]}
    r = rows["m0:time"]
    assert r["status"] == "ok" and r["plan_clearance_m"] == plan
    e = r["exudyn"]
    dev = max(e["max_track_m"], e["peak_to_goal_m"])
    assert abs(e["clearance_m"] - plan) <= dev + 1e-9
    assert "clearance_m" not in rows["m1:time"]["exudyn"]     # no suite: no obstacles known
