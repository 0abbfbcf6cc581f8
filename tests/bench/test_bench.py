"""``crane-planner bench`` (planner/bench.py): the seed-000 suite with --quick, run once.

The tests of the bench's own run are marked ``slow`` (``make bench`` runs them): the bench is a
long study (20 s of the default suite's 180 s budget on 2 cores); its argument and task-file
checks stay in the default suite."""
from __future__ import annotations

import json

import pytest

from planner.bench.run import SUITE_NAMES, parse_suites
from planner.bench.methods import method_names
from planner.bench.figures import pareto
from planner.cli import main

METRICS = ("duration_s", "energy_J", "peak_pump_flow_m3s", "max_limit_violation", "gap_pct",
           "lower_bound_s", "solve_time_s", "success", "status", "reason", "verdict")
METHODS = method_names()
LAWS = [m for m in METHODS if m.startswith("law:")]


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    rc = main(["bench", "--suite", "seed000-abc", "--quick", "--out", str(out),
               "--json", str(out / "result.json")])
    assert rc == 0
    return out, json.loads((out / "bench.json").read_text())


@pytest.mark.slow
def test_outputs_exist(bench):
    out, res = bench
    for f in ("bench.md", "bench.json", "result.json", "seed000-abc_time_energy.png",
              "seed000-abc_bars.png", "seed000-abc_profiles.png"):
        assert (out / f).stat().st_size > 0, f
    assert json.loads((out / "result.json").read_text())["settings"]["quick"] is True
    assert res["machine"]["cpu_count"] and res["machine"]["platform"] and res["machine"]["date_utc"]
    assert res["wall_time_s"] > 0
    md = (out / "bench.md").read_text()
    assert "## Acceptance" in md and "seed000-abc" in md and "seed DP" in md


@pytest.mark.slow
def test_every_row_has_the_metrics(bench):
    _, res = bench
    rows = res["suites"]["seed000-abc"]["rows"]
    assert len(rows) == 3 * len(METHODS)           # the full (move, method) matrix
    for r in rows:
        if r["status"] == "n/a":
            assert r["reason"] and not r["success"]
            continue
        for k in METRICS:
            assert k in r, (r["move"], r["method"], k)
        assert r["solve_time_s"]["runs"] >= 1 and r["solve_time_s"]["median"] >= 0
        if r["status"] == "ok":
            assert r["duration_s"] > 0 and r["energy_J"] >= 0 and r["peak_pump_flow_m3s"] >= 0
            assert r["lower_bound_s"] > 0 and r["gap_pct"] > -0.1   # never below the bound
        else:
            assert r["reason"]                     # a failure says why (no traceback)
    summ = res["suites"]["seed000-abc"]["summary"]
    assert set(summ) == set(METHODS)
    assert summ["law:max_velocity"]["success_rate"] == 1.0


@pytest.mark.slow
def test_successful_trajectories_pass_evaluate(bench):
    _, res = bench
    ok = [r for r in res["suites"]["seed000-abc"]["rows"] if r["success"]]
    assert len(ok) >= 30
    for r in ok:
        assert r["status"] == "ok" and r["max_limit_violation"] <= 1e-3
        assert set(r["checked"]) >= {"position", "velocity", "pump_flow"}


@pytest.mark.slow
def test_nlp_beats_the_laws_on_seed000(bench):
    _, res = bench
    by = {}
    for r in res["suites"]["seed000-abc"]["rows"]:
        by.setdefault(r["move"], {})[r["method"]] = r
    for move, R in by.items():
        laws = [R[m]["duration_s"] for m in LAWS if R[m]["success"]]
        assert laws, move
        assert R["nlp:time-free-kin"]["success"]
        assert R["nlp:time-free-kin"]["duration_s"] < min(laws), move
    assert res["acceptance"]["seed000_nlp_vs_laws"]["nlp:time-free-kin"]["passed"]


@pytest.mark.slow
def test_nlp_beats_every_law_path_retimed_on_equal_limits(bench):
    """topp:law is the fastest law path made feasible under velocity, acceleration and pump
    limits; the free-path NLP on the same limit set is faster on every seed-000 move."""
    _, res = bench
    by = {}
    for r in res["suites"]["seed000-abc"]["rows"]:
        by.setdefault(r["move"], {})[r["method"]] = r
    for move, R in by.items():
        t, n = R["topp:law"], R["nlp:time-free-acc"]
        assert t["success"] and n["success"], move
        assert {"acceleration", "velocity", "pump_flow"} <= set(t["checked"]) & set(n["checked"])
        retimed = {k: v for k, v in t["info"]["per_law_s"].items() if isinstance(v, float)}
        assert "law:" + t["info"]["law"] in LAWS
        assert t["duration_s"] == pytest.approx(min(retimed.values()), rel=1e-9)
        for law, dur in retimed.items():     # retiming under acceleration limits is slower
            if R["law:" + law]["success"]:
                assert dur > R["law:" + law]["duration_s"], (move, law)
        assert n["duration_s"] < t["duration_s"], move
    assert res["acceptance"]["seed000_nlp_vs_laws"]["nlp:time-free-acc vs topp:law"]["passed"]


def test_bad_suite_name_exits_2_listing_the_suites(capsys):
    rc = main(["bench", "--suite", "seed000-abc,nope"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "nope" in err and all(s in err for s in SUITE_NAMES)


def test_parse_suites_and_pareto():
    assert parse_suites(None) == list(SUITE_NAMES)
    assert parse_suites(["seed000-abc,seed003-paths", "seed000-abc"]) == ["seed000-abc",
                                                                          "seed003-paths"]
    pts = [(1.0, 5.0), (2.0, 3.0), (1.5, 6.0), (3.0, 3.0), (4.0, 1.0)]
    assert pareto(pts) == [0, 1, 4]


# ------------------------------------------------------------------------------ task files
def test_seed_suites_are_task_files_with_the_seeds_numbers():
    import math

    from planner.tasks.suites import load_task_file
    s0 = load_task_file("seed000-abc")
    assert s0.crane == "cranab850" and [m.id for m in s0.moves] == ["A-B", "B-C", "A-C"]
    ab, bc, ac = s0.moves
    assert ab.start == ac.start == (1.5, 1.0, 0.0) and ab.goal == bc.start == (5.5, 1.0, 0.0)
    assert ac.reference_s == {"dp:time": 1.18, "law:max_velocity": 2.28, "law:max_lift": 2.81}
    s3 = {m.id: m for m in load_task_file("seed003-paths").moves}
    # analytic ends: the circle (xC, zC) = (3, 2.5), R = 0.7 starts and ends at θ = ±π
    assert s3["circle"].closed and s3["circle"].start == pytest.approx((2.3, 2.5, 0.0))
    # the parabola: x = 1.6 .. 3.07 m, y = tan(−45°)·x, z = 1.5 m at both ends
    par = s3["parabola"]
    assert par.start == pytest.approx((1.6 * math.sqrt(2), 1.5, -math.pi / 4))
    assert par.goal == pytest.approx((3.07 * math.sqrt(2), 1.5, -math.pi / 4))
    s2 = {m.id: m for m in load_task_file("seed002-hvd").moves}
    # seed 002's clock at 0.5 m/s: h ends at 59 s, v at 65 s, d at 41 s; at 1 m/s h ends at
    # 5 + 6 + 3 + 6 + 3 + 6 + 6 = 35 s
    assert [s2[k].duration_s for k in ("h@0.5", "v@0.5", "d@0.5", "h@1")] == [59, 65, 41, 35]
    assert s2["v@1"].cycle == ("v", 1.0) and s2["v@1"].reference_J["law:jla"] == 454e3


def test_bench_suites_follow_their_bench_tables():
    from planner.bench.context import Settings
    from planner.bench.suites import build_suite
    full, quick = Settings.make(False), Settings.make(True)
    s0 = build_suite("seed000-abc", full)
    assert s0.dp_kw(s0.moves[0]) == dict(stages=400, tele_step=0.01, window=5)  # 4 m / 0.01 m
    assert build_suite("seed000-abc", quick).dp_kw(s0.moves[0])["stages"] == 200
    assert [m.id for m in build_suite("seed002-hvd", quick).moves] == ["h@1", "v@1", "d@1"]
    fw = build_suite("forwarder-cycle", quick)
    assert len(fw.moves) == 2 and fw.kind == "p2p" and fw.obstacles
    assert all(m.path.name == "cylindrical" for m in fw.moves)
    assert "2 of the 200 forwarder-cycle moves" in fw.description
    assert fw.methods["nlp:kin-line"].startswith("the straight Cartesian line")
    assert build_suite("seed003-paths", full).methods["law:max_lift"].startswith(
        "umea-lab has no [laws] max_lift")


def test_malformed_task_files_name_the_field(tmp_path):
    from planner.bench.context import Settings
    from planner.bench.suites import build_suite
    from planner.model.spec import SpecError
    from planner.tasks.suites import load_task_file
    head = '[suite]\ncrane = "cranab850"\n[points]\nA = [1.5, 1.0, 0.0]\n'
    cases = {'[[moves]]\nid = "x"\nstart = "A"\ngoal = "Q"\n': "moves[0].goal",
             '[[moves]]\nid = "x"\npath = { kind = "spiral" }\n': "moves[0].path",
             '[[moves]]\nid = "x"\npath = { kind = "cycle", cycle = "z", speed = 1 }\n':
                 "cycle"}
    for i, (body, field) in enumerate(cases.items()):
        f = tmp_path / f"bad{i}.toml"
        f.write_text(head + body)
        with pytest.raises(SpecError, match=field.replace("[", r"\[").replace("]", r"\]")):
            load_task_file(str(f))
    ok = head + '[[moves]]\nid = "x"\nstart = "A"\ngoal = [5.5, 1.0, "0deg"]\n'
    for bench, msg in (('methods = ["dp:energy"]', "no runner for p2p"),
                       ('methods = ["law:nope"]', "unknown variant")):
        f = tmp_path / "b.toml"
        f.write_text(ok + f"[bench]\n{bench}\n")
        with pytest.raises(ValueError, match=msg):
            build_suite(str(f), Settings.make(True))


def test_a_cycle_judged_on_its_clock_overrun_named_with_its_size():
    """A timed cycle must end on its clock: a piece ending 0.5 s late fails with the overrun
    in the verdict; one ending within 1 µs of the clock passes (the TOPP-RA sections of
    topp:dp land on their durations to ~1e-15 s)."""
    import numpy as np
    from planner.bench.context import Ctx, Outcome, Settings
    from planner.bench.run import judge
    from planner.bench.suites import build_suite
    from planner.model import Crane
    from planner.trajectory import Trajectory
    st = Settings.make(quick=True)
    suite = build_suite("seed002-hvd", st)
    crane = Crane.from_id(suite.crane_id)
    ctx = Ctx(crane, st, suite)
    move = next(m for m in suite.moves if m.cycle)
    T = move.duration_s
    q0 = np.asarray(crane.ik(move.start), float).reshape(-1)

    def still(end):
        t = np.linspace(0.0, end, 50)
        z = np.zeros((50, crane.n))
        return Trajectory(t, np.tile(q0, (50, 1)), z, z, joint_names=tuple(crane.names))

    late = judge(ctx, move, "x", Outcome("ok", pieces=[(0.0, still(T + 0.5))]), [], {})
    assert not late["success"] and "overruns the cycle by 0.5 s" in late["verdict"]
    on = judge(ctx, move, "x", Outcome("ok", pieces=[(0.0, still(T + 5e-7))]), [], {})
    assert "overruns" not in on["verdict"]
