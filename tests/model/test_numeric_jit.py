"""The compiled numeric face's cache (planner.model.numeric): the optimisation level a user
chooses, one compile when several workers need the same function at once, and a damaged
library compiled again rather than loaded."""
import threading

import casadi as ca
import numpy as np
import pytest

from planner.model import numeric


def _f(name="jit_probe"):
    x = ca.SX.sym("x", 3)
    return ca.Function(name, [x], [ca.sin(x) * ca.exp(-x[0] ** 2) + x[2]])


def test_the_optimisation_level_comes_from_the_environment_and_a_bad_one_is_refused(
        monkeypatch):
    monkeypatch.delenv("CRANE_PLANNER_JIT_OPT", raising=False)
    assert numeric.jit_flags() == numeric.JIT_FLAGS
    monkeypatch.setenv("CRANE_PLANNER_JIT_OPT", "1")
    assert numeric.jit_flags() == ("-O1",)
    monkeypatch.setenv("CRANE_PLANNER_JIT_OPT", "fast")
    with pytest.raises(ValueError, match=r"CRANE_PLANNER_JIT_OPT = 'fast'; allowed: 0, 1, 2, 3"):
        numeric.jit(_f())


def test_workers_that_need_one_function_at_once_compile_it_once(monkeypatch, tmp_path):
    if numeric.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CRANE_PLANNER_CACHE", str(tmp_path))
    monkeypatch.setenv("CRANE_PLANNER_JIT_OPT", "0")
    runs, real = [], numeric.subprocess.run

    def counted(*a, **k):
        runs.append(a[0][0])
        return real(*a, **k)
    monkeypatch.setattr(numeric.subprocess, "run", counted)
    f = _f()
    out = [None] * 4
    go = threading.Barrier(4)

    def work(i):
        go.wait()
        out[i] = numeric.jit(f)
    th = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in th:
        t.start()
    for t in th:
        t.join()
    assert len(runs) == 1                      # one compile; the others waited and loaded it
    x = np.array([0.3, -1.2, 0.7])
    for g in out:
        assert g.is_a("External")
        np.testing.assert_allclose(np.asarray(g(x)).ravel(), np.asarray(f(x)).ravel(),
                                   rtol=1e-14)


def test_a_damaged_library_is_compiled_again_not_loaded(monkeypatch, tmp_path):
    if numeric.compiler() is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CRANE_PLANNER_CACHE", str(tmp_path))
    monkeypatch.setenv("CRANE_PLANNER_JIT_OPT", "0")
    f = _f("jit_probe_damaged")
    numeric.jit(f)
    (so,) = (tmp_path / "jit").glob("*.so")
    so.write_bytes(so.read_bytes()[:1000])     # a half-written library
    g = numeric.jit(f)
    assert so.stat().st_size > 1000            # compiled again
    x = np.array([0.1, 0.2, 0.3])
    np.testing.assert_allclose(np.asarray(g(x)).ravel(), np.asarray(f(x)).ravel(), rtol=1e-14)
