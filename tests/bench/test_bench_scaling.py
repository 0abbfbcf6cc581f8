"""benchmarks/bench_scaling.py on tiny settings: grid counts, accuracy vs resolution, NLP
convergence in N, the frozen-joint variant, the library runs and the written report. No
wall-clock assertions."""
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from planner import Crane
from planner.methods.nlp import MoveNLP

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_scaling.py"
_spec = importlib.util.spec_from_file_location("bench_scaling", SCRIPT)
bs = importlib.util.module_from_spec(_spec)
sys.modules["bench_scaling"] = bs  # dataclasses look their module up while it loads
_spec.loader.exec_module(bs)

TINY = bs.Config(dp_steps=(0.08, 0.04, 0.02), dp_window_step=0.04, dp_windows=(1, 3),
                 dp_lengths=(0.5, 1.0), dp_length_step=0.04, dp_repeats=1, nlp_N=(10, 20),
                 nlp_moves=1, nlp_repeats=1, lib_moves=2, lib_workers=(1, 2), lib_rounds=1,
                 lib_robustness=False)


@pytest.fixture(scope="module")
def report():
    return bs.run(TINY)


def test_dp_edges_counts_in_grid_transitions():
    # brute force: pairs (m, m') on the grid with |m − m'| ≤ w, per stage
    for M, w in ((1, 5), (3, 5), (10, 2), (141, 5)):
        brute = sum(abs(a - b) <= w for a in range(M) for b in range(M))
        assert bs.dp_edges(7, M, w) == 7 * brute


def test_slope_recovers_power_law():
    x = np.array([1.0, 2.0, 4.0, 8.0])
    assert bs.slope(x, 3 * x ** 2) == pytest.approx(2.0)
    assert np.isnan(bs.slope([1.0], [2.0]))


@pytest.mark.slow  # the scaling study's quick run (~40 s): make bench
def test_dp_grid_grows_fourfold_and_times_converge(report):
    for name, rows in report["dp"]["resolution"].items():
        assert all(r["status"] == "ok" for r in rows), name
        for coarse, fine in zip(rows, rows[1:]):
            assert fine["step_m"] == pytest.approx(coarse["step_m"] / 2)
            # halving Δ and the telescope step: ~2× stages, ~2× telescope nodes
            assert 3.5 < fine["nodes"] / coarse["nodes"] < 4.5, name
            assert 3.5 < fine["edges"] / coarse["edges"] < 4.5, name
        assert rows[-1]["gap_to_finest"] == 0.0
        # the minimum time barely depends on the grid here (≤ 2 % coarse vs finest)
        assert all(abs(r["gap_to_finest"]) < 0.02 for r in rows), name


@pytest.mark.slow  # the scaling study's quick run (~40 s): make bench
def test_dp_window_and_length_sweeps(report):
    w = report["dp"]["window"]
    assert [r["window"] for r in w] == list(TINY.dp_windows)
    assert w[1]["edges"] > w[0]["edges"] and w[1]["tele_nodes"] == w[0]["tele_nodes"]
    # a wider window is a superset of transitions: the minimum time cannot get worse
    assert w[1]["duration_s"] <= w[0]["duration_s"] + 1e-9
    g = report["dp"]["length"]
    assert [round(r["length_m"], 9) for r in g] == list(TINY.dp_lengths)
    assert abs(g[1]["stages"] - 2 * g[0]["stages"]) <= 1  # stages = ceil(length / Δ)
    assert g[1]["duration_s"] > g[0]["duration_s"]


@pytest.mark.slow  # the scaling study's quick run (~40 s): make bench
def test_nlp_larger_N_no_slower_move_and_linear_size(report):
    for label, c in report["nlp"].items():
        small, large = c["by_N"]
        assert large["ok"] == len(large["moves"]), label
        for a, b in zip(small["moves"], large["moves"]):
            if a["status"] == "ok":  # the finer horizon may only shorten the move (1 % slack)
                assert b["duration_s"] <= a["duration_s"] * 1.01, label
        per_interval = (large["variables"] - small["variables"]) / (large["N"] - small["N"])
        assert per_interval == int(per_interval) and per_interval > 0


@pytest.mark.slow  # the scaling study's quick run (~40 s): make bench
def test_frozen_telescope_is_a_3_dof_problem(report):
    free = next(c for k, c in report["nlp"].items() if "tele-mid" in k)
    frz = next(c for c in report["nlp"].values() if c["frozen"])
    for a, b in zip(free["by_N"], frz["by_N"]):
        # q, q̇, q̈ at N + 1 nodes and the jerk on N intervals are fixed
        assert a["free_variables"] - b["free_variables"] == 3 * (a["N"] + 1) + a["N"]
        for m1, m2 in zip(a["moves"], b["moves"]):
            if m1["status"] == m2["status"] == "ok":  # the redundancy can only help
                assert m2["duration_s"] >= m1["duration_s"] * (1 - 1e-3)


def test_freeze_joint_holds_the_telescope():
    crane = Crane.from_id("s100f")
    j = crane.chain.tele
    (a, b), = bs.nlp_moves(crane, 1, seed=3, frozen=(j, 0.8))
    nlp = MoveNLP(crane, "time", "free", N=10)
    bs.freeze_joint(nlp, j, 0.8)
    r = nlp.solve(a, b)
    assert r.ok
    assert np.allclose(r.trajectory.q[:, j], 0.8, atol=1e-8)


@pytest.mark.slow  # the scaling study's quick run (~40 s): make bench
def test_library_speedup_table(report):
    lib = report["library"]
    assert [r["workers"] for r in lib["by_workers"]] == [1, 2]
    assert all(r["statuses"] == {"ok": TINY.lib_moves} for r in lib["runs"])
    one = lib["by_workers"][0]
    assert one["speedup"] == 1.0 and one["efficiency"] == 1.0


@pytest.mark.slow  # the scaling study's quick run (~40 s): make bench
def test_outputs_written(report, tmp_path):
    paths = bs.write_outputs(report, tmp_path)
    names = {p.name for p in paths}
    assert names == {"scaling.json", "scaling.md", "scaling_dp.png", "scaling_nlp.png",
                     "scaling_library.png"}
    for p in paths:
        if p.suffix == ".png":
            assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = (tmp_path / "scaling.md").read_text()
    for head in ("| Δ [m] | stages |", "| window w | edges |", "| length [m] | stages |",
                 "| N | vars (free) |", "| workers | median [s] |", "## Findings", "CPUs",
                 "Python "):
        assert head in md, head
    js = json.loads((tmp_path / "scaling.json").read_text())
    assert {"machine", "config", "dp", "nlp", "library", "wall_s"} <= set(js)
    assert js["machine"]["cpu_count"] and js["machine"]["python"]
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporaries
