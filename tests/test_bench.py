"""``crane-planner bench`` (planner/bench.py): the seed-000 suite with --quick, run once."""
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


def test_successful_trajectories_pass_evaluate(bench):
    _, res = bench
    ok = [r for r in res["suites"]["seed000-abc"]["rows"] if r["success"]]
    assert len(ok) >= 30
    for r in ok:
        assert r["status"] == "ok" and r["max_limit_violation"] <= 1e-3
        assert set(r["checked"]) >= {"position", "velocity", "pump_flow"}


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
