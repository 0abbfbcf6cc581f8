"""The compiled NLP cache (planner.methods.nlp.cache): a stored solver gives the same numbers as
the one built in memory, a broken entry is rebuilt rather than trusted, the key separates
machines, and two builders at once leave one good entry."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planner.methods.nlp import MoveNLP
from planner.methods.nlp import cache as nlp_cache

ROOT = Path(__file__).resolve().parents[2]
START, GOAL = (2.65, 2.2, 0.2), (3.2, 1.6, -0.4)
N = 6   # a small NLP: its C compiles in seconds

pytestmark = pytest.mark.skipif(nlp_cache.compiler() is None, reason="no C compiler")


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("CRANE_PLANNER_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _own_solution(nlp):
    """The NLP's own optimum (the explicit default guess keeps the Ruckig swap-in out)."""
    res = nlp.solve(START, GOAL, w0=nlp.default_guess(START, GOAL)[0])
    assert res.ok, res.reason
    return res, nlp._last.copy()


def test_a_stored_solver_gives_the_same_numbers(umea_lab, cache_dir):
    ref, w_ref = _own_solution(MoveNLP(umea_lab, "time", "free", N=N, cache="off"))
    built = MoveNLP(umea_lab, "time", "free", N=N, cache="build")
    assert built.cache_status == "stored", built.cache_error
    loaded = MoveNLP(umea_lab, "time", "free", N=N, cache="use")
    assert loaded.cache_status == "hit"
    assert loaded.build_time_s < built.build_time_s
    res, w = _own_solution(loaded)
    assert np.array_equal(w, w_ref)                       # bit for bit
    assert res.duration_s == ref.duration_s and res.iterations == ref.iterations
    assert np.array_equal(res.trajectory.q, ref.trajectory.q)
    # the loaded layout serves the numeric bookkeeping
    assert loaded.layout.nw == built.layout.nw == len(loaded.lbw)


@pytest.mark.slow   # a second compiled solver (~4 s): make bench
def test_a_stored_energy_solver_gives_the_same_energy(umea_lab, cache_dir):
    """The NLP's own energy estimate comes from the stored function too."""
    ref, _ = _own_solution(MoveNLP(umea_lab, "time", "free", N=N, cache="off"))
    e_off = MoveNLP(umea_lab, "energy", "free", N=N, cache="off")
    e_on = MoveNLP(umea_lab, "energy", "free", N=N, cache="build")
    a = e_off.solve(START, GOAL, T_max=1.2 * ref.duration_s)
    b = MoveNLP(umea_lab, "energy", "free", N=N, cache="use").solve(
        START, GOAL, T_max=1.2 * ref.duration_s)
    assert e_on.cache_status == "stored" and a.ok and b.ok
    assert a.energy_model_J == b.energy_model_J and a.duration_s == b.duration_s


def test_a_broken_entry_is_rebuilt_not_trusted(umea_lab, cache_dir):
    MoveNLP(umea_lab, "time", "free", N=N, cache="build")
    (entry,) = (cache_dir / "nlp").iterdir()
    so = entry / "nlp.so"
    so.write_bytes(so.read_bytes()[:1000])               # truncated library
    nlp = MoveNLP(umea_lab, "time", "free", N=N, cache="use")
    assert nlp.cache_status == "miss" and not entry.exists()
    assert _own_solution(nlp)[0].ok
    again = MoveNLP(umea_lab, "time", "free", N=N, cache="build")
    assert again.cache_status == "stored"


def test_the_key_separates_machines_and_formulations(umea_lab, s100f, cache_dir):
    MoveNLP(umea_lab, "time", "free", N=N, cache="build")
    assert MoveNLP(s100f, "time", "free", N=N, cache="use").cache_status == "miss"
    assert MoveNLP(umea_lab, "time", "line", N=N, cache="use").cache_status == "miss"
    assert MoveNLP(umea_lab, "time", "free", N=N + 1, cache="use").cache_status == "miss"
    assert MoveNLP(umea_lab, "time", "free", N=N, cache="off").cache_status == "off"
    assert MoveNLP(umea_lab, "time", "free", N=N, cache="use",
                   solver="fatrop").cache_status == "miss"


@pytest.mark.slow   # a FATROP compile (~10 s)
def test_a_stored_fatrop_solver_gives_the_same_numbers(umea_lab, cache_dir):
    ref, w_ref = _own_solution(MoveNLP(umea_lab, "time", "free", N=N, cache="off",
                                       solver="fatrop"))
    built = MoveNLP(umea_lab, "time", "free", N=N, cache="build", solver="fatrop")
    assert built.cache_status == "stored", built.cache_error
    loaded = MoveNLP(umea_lab, "time", "free", N=N, cache="use", solver="fatrop")
    assert loaded.cache_status == "hit"
    res, w = _own_solution(loaded)
    np.testing.assert_allclose(w, w_ref, rtol=1e-9, atol=1e-12)
    assert res.duration_s == pytest.approx(ref.duration_s, rel=1e-9)


@pytest.mark.slow   # two compiles at once (~20 s); benchmarks/bench_nlp_cache.py runs it too
def test_two_builders_at_once_leave_one_good_entry(cache_dir):
    env = dict(os.environ, CRANE_PLANNER_CACHE=str(cache_dir))
    cmd = [sys.executable, "-m", "planner", "plan", "umea-lab", "--start", "2.65,2.2,0.2",
           "--goal", "3.2,1.6,-0.4", "--method", "nlp", "--intervals", "4", "--compile",
           "--json", "-"]
    procs = [subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e for _, e in outs]
    got = [json.loads(o) for o, _ in outs]
    assert {g["nlp_cache"] for g in got} <= {"stored", "hit"}
    assert got[0]["duration_s"] == got[1]["duration_s"]
    assert len(list((cache_dir / "nlp").iterdir())) == 1   # no half-written folder left
    r = subprocess.run(cmd[:-3] + ["--json", "-"], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=600)
    assert json.loads(r.stdout)["nlp_cache"] == "hit"


@pytest.mark.slow   # a compile and a library build (~10 s)
def test_library_build_compiles_once_and_its_workers_load_it(cache_dir, tmp_path):
    from planner.library.build import build, clear_planner_caches
    clear_planner_caches()
    suite = tmp_path / "two.toml"
    suite.write_text('[pickups]\nr = [2.6]\nslew = ["10deg"]\nz = 2.1\n'
                     '[drops]\nr = [3.2]\nslew = ["-20deg"]\nz = 1.6\n')
    s = build("umea-lab", str(suite), tmp_path / "lib.h5", N=4, robustness=False,
              progress=False, compile=True)
    assert s["statuses"] == {"ok": 2} and s["prepare_s"] > 0
    assert len(list((cache_dir / "nlp").iterdir())) == 1
    clear_planner_caches()   # a new process would now load the compiled solver
    from planner.methods import get
    from planner import Crane
    assert get("nlp").built(Crane.from_id("umea-lab"), "time", "free", 4).cache_status == "hit"
    clear_planner_caches()


def test_without_a_compiler_the_nlp_is_built_in_memory(umea_lab, cache_dir, monkeypatch):
    monkeypatch.setattr(nlp_cache, "compiler", lambda: None)
    nlp = MoveNLP(umea_lab, "time", "free", N=N, cache="build")
    assert nlp.cache_status == "no-compiler" and "compiler" in nlp.cache_error
    assert not (cache_dir / "nlp").exists() or not list((cache_dir / "nlp").iterdir())
    assert _own_solution(nlp)[0].ok
