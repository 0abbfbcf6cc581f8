"""One registration makes a planning method available everywhere: the CLI's plan, the library
build and the benchmark find it through the registry (planner.methods.registry)."""
import json

import pytest

from planner import Crane
from planner.bounds import lower_bound
from planner.cli import main
from planner.library.store import LibraryStore
from planner.methods import (PlanRequest, Planner, UnsupportedRequest, available, get, plan,
                             register, unregister)
from planner.methods.ruckig import rest_to_rest

NAME = "test:half-ruckig"
START, GOAL = "6,-1,0", "3,2.5,1.5"


class HalfRuckig(Planner):
    """A method defined here only: Ruckig at half the velocity and acceleration limits."""
    name = NAME
    objectives = ("time",)
    paths = ("free",)

    def plan(self, crane, request):
        lb = lower_bound(crane, request.start, request.goal)
        return rest_to_rest(crane, crane.ik(request.start, lb.tele_start),
                            crane.ik(request.goal, lb.tele_goal), scale=0.5)


@pytest.fixture
def dummy():
    register(HalfRuckig())
    yield NAME
    unregister(NAME)


def _json(path):
    return json.loads(path.read_text())


def test_builtin_methods_are_registered():
    names = available()
    for n in ("nlp", "dp", "topp", "ruckig", "law:least_norm", "law:max_velocity",
              "law:max_lift", "law:jla", "law:q_optimal", "law:p_optimal"):
        assert n in names
    assert get("nlp").default_path == "free" and get("dp").default_path == "line"


def test_registered_method_plans_through_the_cli(dummy, tmp_path):
    assert dummy in available()
    for m in (dummy, "ruckig"):
        assert main(["plan", "s100f", "--start", START, "--goal", GOAL, "--method", m,
                     "--json", str(tmp_path / f"{m.replace(':', '_')}.json")]) == 0
    mine = _json(tmp_path / "test_half-ruckig.json")
    full = _json(tmp_path / "ruckig.json")
    assert mine["status"] == "ok" and mine["method"] == dummy and mine["path"] == "free"
    assert mine["max_limit_violation"] <= 1e-3
    # the independent oracle: the same move at full limits (velocity and acceleration halved,
    # jerk unchanged, so a little less than twice as long)
    assert 1.5 * full["duration_s"] < mine["duration_s"] < 2.0 * full["duration_s"] + 1e-6


def test_registered_method_builds_a_library(dummy, tmp_path):
    suite = tmp_path / "two.toml"
    suite.write_text('[pickups]\nr = [5.0]\nslew = ["0deg"]\nz = -1.0\n'
                     '[drops]\nr = [3.0]\nslew = ["60deg"]\nz = 1.5\n')
    lib = tmp_path / "lib.h5"
    assert main(["library", "build", "s100f", "--tasks", str(suite), "--out", str(lib),
                 "--method", dummy, "--no-robustness", "--json", str(tmp_path / "b.json")]) == 0
    assert _json(tmp_path / "b.json")["statuses"] == {"ok": 2}
    with LibraryStore.open(lib, "r") as db:
        rows = db.index_rows()
    assert {r["method"] for r in rows} == {dummy} and {r["status"] for r in rows} == {"ok"}


def test_a_request_the_method_cannot_plan_is_refused_before_anything_is_written(dummy,
                                                                                  tmp_path):
    lib = tmp_path / "lib.h5"
    assert main(["library", "build", "s100f", "--tasks", "forwarder-cycle", "--out", str(lib),
                 "--method", dummy, "--objectives", "energy", "--limit", "1"]) == 2
    assert not lib.exists()
    with pytest.raises(UnsupportedRequest, match="free"):
        plan(Crane.from_id("s100f"), PlanRequest((6, -1, 0), (3, 2.5, 1.5), path="line"), dummy)


def test_unknown_method_names_the_registered_ones(dummy, capsys):
    with pytest.raises(SystemExit) as e:
        main(["plan", "s100f", "--start", START, "--goal", GOAL, "--method", "nope"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "nope" in err and dummy in err and "law:jla" in err


def test_registered_method_runs_in_the_bench(dummy, tmp_path):
    from planner.bench.context import Settings
    from planner.bench.methods import METHODS, method_names
    from planner.bench.run import run_bench
    from planner.bench.suites import build_suite
    assert dummy in method_names() and dummy not in METHODS      # joins after the variants
    quick = Settings.make(quick=True)
    # where its declared paths / obstacle handling do not fit, it is n/a with the reason
    assert "obstacles" in build_suite("forwarder-cycle", quick).methods[dummy]
    assert "free paths" in build_suite("seed003-paths", quick).methods[dummy]
    res = run_bench("seed000-abc", tmp_path, quick=True, progress=False,
                    methods=[dummy, "ruckig"])
    rows = res["suites"]["seed000-abc"]["rows"]
    mine = {r["move"]: r for r in rows if r["method"] == dummy}
    full = {r["move"]: r for r in rows if r["method"] == "ruckig"}
    assert set(mine) == {"A-B", "B-C", "A-C"}
    for mv, r in mine.items():
        assert r["status"] == "ok" and r["success"], r["verdict"]
        # oracle: the registry's own ruckig on the same move at full limits. Halving velocity
        # and acceleration (jerk kept) makes the time-optimal move slower, and at most twice
        # as long (the full-limit move stretched ×2 is feasible at the halved limits)
        assert full[mv]["duration_s"] < r["duration_s"] <= 2.0 * full[mv]["duration_s"] + 1e-6
    assert res["suites"]["seed000-abc"]["summary"][dummy]["success_rate"] == 1.0
    assert f"| {dummy} |" in (tmp_path / "bench.md").read_text()
