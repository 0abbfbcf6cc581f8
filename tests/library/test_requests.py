"""Each method shapes its own library request (Planner.library_request), and the build's
records (BuildSettings, MoveJob, EntryResult) travel to workers unchanged."""
import math
import pickle

import pytest

from planner import Crane
from planner.geometry.obstacles import Wall
from planner.library.build import (ENERGY_BUDGET, BuildSettings, MoveJob, WorkerSetup,
                                   plan_entry, plan_move)
from planner.methods import Planner, PlanResult, get, register, unregister
from planner.methods.ruckig import rest_to_rest
from planner.tasks.suites import Move

MOVE = Move("m0", (6.0, -1.0, 0.0), (3.0, 2.5, 1.5))
WALL = (Wall(2.2, 1.6, -0.5, 0.3),)


class Recorder(Planner):
    """A method defined here only: plans Ruckig between the ends at a fixed telescope, reads
    the duration for energy, and keeps every request it is given. Its own library request
    adds the option ``tele`` (the telescope it plans at)."""
    name = "test:recorder"
    objectives = ("time", "energy")
    paths = ("free",)
    obstacles = True
    uses_duration = ("energy",)

    def __init__(self):
        self.seen, self.results = [], []

    def library_request(self, crane, move, objective, *, time_result=None, settings):
        req = super().library_request(crane, move, objective, time_result=time_result,
                                      settings=settings)
        return type(req)(req.start, req.goal, objective=req.objective, path=req.path,
                         duration=req.duration, obstacles=req.obstacles,
                         options=dict(tele=1.0))

    def plan(self, crane, request):
        self.seen.append(request)
        tele = request.options["tele"]
        res = rest_to_rest(crane, crane.ik(request.start, tele), crane.ik(request.goal, tele))
        self.results.append(res)
        return res


@pytest.fixture
def recorder():
    r = Recorder()
    register(r)
    yield r
    unregister(r.name)


def test_the_default_request_is_plain_and_the_energy_budget_comes_from_the_time_result(
        s100f):
    st = BuildSettings("s100f", objectives=("time", "energy"), intervals=17, obstacles=WALL)
    p = Recorder()
    t = Planner.library_request(p, s100f, MOVE, "time", settings=st)
    assert (t.start, t.goal, t.objective, t.path) == (MOVE.start, MOVE.goal, "time", "free")
    assert t.duration is None and t.obstacles == WALL and dict(t.options) == {}
    rt = PlanResult("ok", duration_s=2.5)
    e = Planner.library_request(p, s100f, MOVE, "energy", time_result=rt, settings=st)
    assert math.isclose(e.duration, ENERGY_BUDGET * 2.5, rel_tol=1e-15)
    # before the minimum time is known (check, prepare): the budget on a nominal 1 s
    e0 = Planner.library_request(p, s100f, MOVE, "energy", settings=st)
    assert math.isclose(e0.duration, ENERGY_BUDGET, rel_tol=1e-15)
    # a method that does not read the duration gets none (it would refuse it)
    r = get("ruckig").library_request(s100f, MOVE, "time", time_result=rt, settings=st)
    assert r.duration is None and dict(r.options) == {}


def test_the_nlp_adds_its_own_options_and_nobody_else_gets_them(s100f):
    st = BuildSettings("s100f", intervals=17)
    rt = PlanResult("ok", duration_s=3.0)
    nlp = get("nlp").library_request(s100f, MOVE, "energy", time_result=rt, settings=st)
    assert nlp.option("intervals") == 17 and nlp.option("time_result") is rt
    assert math.isclose(nlp.duration, ENERGY_BUDGET * 3.0, rel_tol=1e-15)
    assert get("nlp").library_request(s100f, MOVE, "time", settings=st).option(
        "time_result") is None
    plain = get("ruckig").library_request(s100f, MOVE, "time", settings=st)
    assert "intervals" not in plain.options and "time_result" not in plain.options


def test_the_build_plans_what_the_method_asks_for(recorder):
    st = BuildSettings("s100f", method=recorder.name, objectives=("time", "energy"),
                       robustness=False, energy_budget=1.5)
    time_e, energy_e = plan_move(MoveJob(st, MOVE, ("time", "energy")))
    assert [r.objective for r in recorder.seen] == ["time", "energy"]
    assert all(r.option("tele") == 1.0 for r in recorder.seen)
    assert (time_e.status, energy_e.status) == ("ok", "ok"), time_e.reason
    assert energy_e.method == recorder.name
    # the oracle: the same move planned directly at that telescope; the energy request's
    # budget is 1.5 x its duration (the time entry's, planned first)
    crane = Crane.from_id("s100f")
    direct = rest_to_rest(crane, crane.ik(MOVE.start, 1.0), crane.ik(MOVE.goal, 1.0))
    assert math.isclose(recorder.results[0].duration_s, direct.duration_s, rel_tol=1e-12)
    assert math.isclose(recorder.seen[1].duration, 1.5 * direct.duration_s, rel_tol=1e-12)
    # what is stored is that plan (on the 50 Hz grid, so up to one sample longer)
    assert 0 <= time_e.trajectory.duration - direct.duration_s <= 0.02 + 1e-9


def test_a_refused_request_is_an_entry_with_the_reason_not_an_exception():
    st = BuildSettings("s100f", method="ruckig", objectives=("time",), obstacles=WALL,
                       robustness=False)
    e = plan_entry(st, MOVE, "time")
    assert e.status == "unsupported" and "obstacles" in e.reason and e.trajectory is None


def test_build_records_survive_pickling():
    st = BuildSettings("s100f", suite="forwarder-cycle", objectives=["time", "energy"],
                       obstacles=list(WALL))
    assert st.objectives == ("time", "energy") and isinstance(st.obstacles, tuple)
    for rec in (st, MoveJob(st, MOVE, ["time"]), WorkerSetup(st, MOVE)):
        back = pickle.loads(pickle.dumps(rec))
        assert back == rec
