"""Library build: suite expansion, resume, failures recorded, Dask, and kill-and-resume."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from planner import Crane
from planner.library.build import build
from planner.tasks.suites import load_suite
from planner.library.store import LibraryStore
from planner.trajectory import evaluate
from tests.library.helpers import assert_same_entries

KW = dict(objectives=("time",), robustness=False, progress=False, N=20)


def test_forwarder_cycle_suite_has_200_reachable_moves():
    meta, moves = load_suite("forwarder-cycle")
    assert len(moves) >= 200 and len({m.id for m in moves}) == len(moves)
    crane = Crane.from_id(meta["crane"])
    pts = np.array(sorted({m.start for m in moves} | {m.goal for m in moves}))
    lo, hi = crane.tele_range
    ok = [(crane.ik_batch(np.tile(p, (29, 1)), np.linspace(lo, hi, 29))[1] == "").any()
          for p in pts]
    assert all(ok)


def test_build_then_resume_plans_only_the_missing_entries(tmp_path):
    lib = tmp_path / "lib.h5"
    s1 = build("s100f", "forwarder-cycle", lib, limit=2, **KW)
    assert s1["planned"] == 2 and s1["statuses"] == {"ok": 2}
    with LibraryStore.open(lib, "r") as db:
        before = {r["id"]: r["duration_s"] for r in db.index_rows()}
    s2 = build("s100f", "forwarder-cycle", lib, limit=3, **KW)
    assert s2["planned"] == 1 and s2["skipped_existing"] == 2
    crane = Crane.from_id("s100f")
    with LibraryStore.open(lib, "r") as db:
        rows = {r["id"]: r for r in db.index_rows()}
        assert len(rows) == 3
        for k, d in before.items():
            assert rows[k]["duration_s"] == d       # finished entries untouched
        for k in rows:                               # every stored move passes the judge
            tr = db.trajectory(k)
            assert tr.u is not None
            assert evaluate(crane, tr, kinds=("position", "velocity")).ok()


def test_failed_moves_are_stored_and_do_not_stop_the_build(tmp_path):
    suite = tmp_path / "bad.toml"
    suite.write_text('[suite]\nid = "bad"\ncrane = "s100f"\n'
                     '[pickups]\nr = [5.0, 30.0]\nslew = [0.0]\nz = -1.0\n'
                     '[drops]\nr = [2.0]\nslew = ["170deg"]\nz = 1.5\n'
                     '[options]\nboth_directions = false\n')
    lib = tmp_path / "lib.h5"
    s = build("s100f", str(suite), lib, **KW)
    assert s["planned"] == 2 and s["statuses"].get("ok") == 1
    with LibraryStore.open(lib, "r") as db:
        bad = [r for r in db.index_rows() if r["status"] != "ok"]
        assert len(bad) == 1 and bad[0]["status"] == "unreachable"
        assert "unreachable" in db.entry_attrs(bad[0]["id"])["reason"]


def test_dask_and_process_builds_write_the_same_entries_and_report_worker_setup(tmp_path):
    """Issue 18: the Dask path (LocalCluster) and the local process pool give identical
    entries; each worker is set up once (its own pid, seconds in the summary), and the Dask
    workers run without the allocator setting that slowed every solve."""
    pytest.importorskip("dask.distributed")
    s_dask = build("s100f", "forwarder-cycle", tmp_path / "dask.h5", limit=3,
                   scheduler="local:2", **KW)
    s_proc = build("s100f", "forwarder-cycle", tmp_path / "proc.h5", limit=3, workers=2, **KW)
    assert s_dask["statuses"] == s_proc["statuses"] == {"ok": 3}
    assert_same_entries(tmp_path / "proc.h5", tmp_path / "dask.h5", 3)
    for s in (s_dask, s_proc):
        assert len(s["workers"]) == 2 and len({w["pid"] for w in s["workers"]}) == 2
        assert all(w["error"] == "" and w["setup_s"] > 0 for w in s["workers"])
        assert s["worker_setup_s"] == [w["setup_s"] for w in s["workers"]]
        assert s["first_entry_s"] is not None and s["first_entry_s"] >= 0
        assert os.getpid() not in {w["pid"] for w in s["workers"]}
    for f in ("dask.h5", "proc.h5"):            # the set-up's solvers served every move
        with LibraryStore.open(tmp_path / f, "r") as db:
            assert [db.entry_attrs(e)["build_s"] for e in db.ids()] == [0.0] * 3
    for w in s_dask["workers"]:
        assert w["malloc_env"] is None            # the LocalCluster left it out
        if sys.platform.startswith("linux"):
            assert w["malloc_tuned"] is True


def test_in_process_build_reports_its_setup_in_the_driver(tmp_path):
    s = build("s100f", "forwarder-cycle", tmp_path / "lib.h5", limit=1, **KW)
    assert [w["pid"] for w in s["workers"]] == [os.getpid()]
    assert s["workers"][0]["error"] == "" and s["worker_setup_s"][0] > 0


def test_a_failing_worker_setup_is_reported_not_raised():
    from planner.library.workers import run_setup

    def broken():
        raise RuntimeError("no compiler")
    info = run_setup(broken)
    assert info["error"] == "RuntimeError: no compiler" and info["pid"] == os.getpid()
    assert info["setup_s"] >= 0


def test_local_cluster_workers_keep_dasks_thread_settings_but_not_the_malloc_trim():
    pytest.importorskip("dask.distributed")
    import dask
    from planner.library.cluster import worker_environ
    with dask.config.set({"distributed.nanny.pre-spawn-environ":
                          {"MALLOC_TRIM_THRESHOLD_": 65536, "OMP_NUM_THREADS": 1}}):
        assert worker_environ() == {"OMP_NUM_THREADS": 1}


def test_dask_chunks_cover_every_argument_once_and_start_with_single_tasks():
    """The Dask tasks carry chunks of moves (fewer tasks, less scheduler work per entry): every
    argument exactly once, in order; each worker's first task a single move (the first entry
    as early as before); none bigger than asked; the last ones single again."""
    from planner.library.cluster import chunk_sizes
    for n, w in [(0, 2), (1, 2), (3, 2), (200, 2), (401, 16), (57, 3)]:
        s = chunk_sizes(n, w, 4)
        assert sum(s) == n and all(1 <= k <= 4 for k in s)
        assert s[:min(n, w)] == [1] * min(n, w)
        assert s[w:] == sorted(s[w:], reverse=True)     # guided: shrinking towards the end
        if n > 8 * w:
            assert s[-1] == 1 and max(s) == 4


def test_dask_pool_with_chunks_returns_each_result_once():
    pytest.importorskip("dask.distributed")
    import operator
    from planner.library.cluster import DaskPool
    args = [(i, i + 1) for i in range(23)]
    with DaskPool("local:2", None, chunk=4) as pool:
        got = sorted(pool.imap_unordered(operator.mul, args))
        assert len(pool.setup_info) == 2
    assert got == sorted(a * b for a, b in args)


@pytest.mark.slow   # SIGKILL mid-build (~25 s); test_faults covers the signals in the default run
@pytest.mark.parametrize("kill_after", [2])
def test_kill_and_resume_equals_a_clean_build(tmp_path, kill_after):
    cmd = [sys.executable, "-m", "planner", "library", "build", "s100f", "--tasks",
           "forwarder-cycle", "--limit", "6", "--no-robustness", "--intervals", "20"]
    clean = tmp_path / "clean.h5"
    subprocess.run(cmd + ["--out", str(clean)], check=True, capture_output=True)
    killed = tmp_path / "killed.h5"
    p = subprocess.Popen(cmd + ["--out", str(killed)], stderr=subprocess.PIPE,
                         stdout=subprocess.DEVNULL)
    buf, t0 = b"", time.time()
    while f"{kill_after}/6".encode() not in buf and time.time() - t0 < 120:
        chunk = os.read(p.stderr.fileno(), 256)
        if not chunk:
            break
        buf += chunk
    p.send_signal(signal.SIGKILL)
    p.wait()
    with LibraryStore.open(killed, "a") as db:   # cleans an entry in flight, if any
        partial = len(db)
    assert 1 <= partial < 6                      # it really was interrupted
    subprocess.run(cmd + ["--out", str(killed)], check=True, capture_output=True)
    assert_same_entries(clean, killed, 6)   # no duplicates, nothing missing


def test_replay_with_gain_error_and_mismatch_stays_within_the_stored_envelope(tmp_path):
    """Issue acceptance: a from-rest library entry replayed open loop with a 2 % flow-gain error
    and a 1° start mismatch (through the independent simulate path) stays within the drift
    envelope its robustness field predicted. The fast plant has no oil: it replays the plan's
    plain feed-forward; the stored commands are the machine's (the oil springs filled)."""
    import math

    from planner.feedforward import commands, stored_commands
    from planner.simulation.replay import Plant, replay
    lib = tmp_path / "lib.h5"
    build("s100f", "forwarder-cycle", lib, limit=2, objectives=("time",), robustness=True,
          progress=False, N=20)
    crane = Crane.from_id("s100f")
    with LibraryStore.open(lib, "r") as db:
        for row in db.index_rows():
            tr = db.trajectory(row["id"])
            assert np.allclose(tr.qd[[0, -1]], 0.0, atol=1e-9)   # from rest, to rest
            assert tr.meta["feedforward"]["oil"]
            plain = commands(crane, tr, 50.0)
            stored = stored_commands(tr)[1]
            assert stored.shape == plain.u.shape and np.max(np.abs(plain.u - stored)) > 0.01
            for joint in ("slew", "boom", "jib"):
                off = np.zeros(crane.n)
                off[crane.names.index(joint)] = math.radians(1.0)
                sim = replay(crane, plain.t, plain.u, tr.q[0] + off,
                             Plant(q0_offset=None, flow_gain_scale=1.02))
                err = np.linalg.norm(crane.fk(sim.q) - crane.fk(tr.sample(sim.t)[0]), axis=1)
                assert 0 < err.max() <= row["robustness"] * (1 + 1e-6), (row["id"], joint)


def test_an_unreachable_scheduler_fails_before_any_file_is_created(tmp_path):
    pytest.importorskip("dask.distributed")
    import dask
    lib = tmp_path / "lib.h5"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(OSError, match="127.0.0.1:9"):
            build("s100f", "forwarder-cycle", lib, limit=1, scheduler="tcp://127.0.0.1:9", **KW)
    assert list(tmp_path.iterdir()) == []          # neither the library nor its lock file


def test_a_move_with_both_objectives_solves_minimum_time_once_and_gives_the_same_entries(
        monkeypatch):
    """One task per move: the time entry and the energy entry from one shared minimum-time
    solve are the entries the objectives give planned one by one (the oracle), and the
    NLP's minimum-time problem is solved once instead of twice."""
    from planner.library.build import BuildSettings, MoveJob, plan_entry, plan_move
    from planner.methods.nlp.move import MoveNLP
    from planner.tasks.suites import load_suite
    move = load_suite("forwarder-cycle")[1][3]
    st = BuildSettings("s100f", objectives=("time", "energy"), intervals=10, robustness=False)
    alone = [plan_entry(st, move, o) for o in ("time", "energy")]
    calls, solve = [], MoveNLP.solve
    monkeypatch.setattr(MoveNLP, "solve", lambda self, *a, **k: (
        calls.append(self.objective), solve(self, *a, **k))[1])
    both = plan_move(MoveJob(st, move, ("time", "energy")))
    assert calls.count("time") == 1 and calls.count("energy") >= 1
    for a, b in zip(alone, both):
        assert (a.id, a.status, b.status) == (b.id, "ok", "ok")
        assert np.array_equal(a.trajectory.t, b.trajectory.t)
        assert np.array_equal(a.trajectory.q, b.trajectory.q)
