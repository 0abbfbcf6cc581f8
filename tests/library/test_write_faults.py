"""Issue 32 defect 1: a write that fails during a library build (a full disk, a file-size limit)
or a writer killed mid-entry. Before the rollback journal HDF5 printed tracebacks, segfaulted,
and left a file that no longer opened; now the command says one line (exit 2), the finished
entries stay readable and the rerun resumes."""
import errno
import os
import resource
import subprocess
import sys

import numpy as np
import pytest

from planner import Crane
from planner.library import journal
from planner.library.store import LibraryStore
from planner.trajectory import Trajectory
from tests.library.helpers import assert_same_entries

CLI = [sys.executable, "-m", "planner"]
# 3 moves, planned in about a second each: what a write failure costs does not depend on
# the method
BUILD = CLI + ["library", "build", "cranab850", "--tasks", "seed000-abc", "--method", "ruckig",
               "--no-robustness"]


def _traj(crane, k):
    t = np.linspace(0.0, 2.0, 400)
    q = np.outer(np.linspace(0.0, 0.1 * (k + 1), 400), np.ones(crane.n))
    return Trajectory(t=t, q=q, qd=np.zeros_like(q), qdd=np.zeros_like(q),
                      joint_names=crane.names)


def _add(db, crane, k):
    db.add(f"m{k}", _traj(crane, k), start=(3, 1, 0), goal=(4, 1, k), objective="time",
           method="test", status="ok")


def _limited(nbytes):
    """preexec_fn: a file-size limit (ulimit -f) for the child."""
    return lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))


def _count_pwrites():
    """How many writes adding one entry makes (to place the injected failures)."""
    calls = []
    real = os.pwrite

    def counting(fd, data, off):
        calls.append(1)
        return real(fd, data, off)
    return calls, counting


@pytest.mark.parametrize("at", [0, 1, 3, 8, -3, -1])  # from the first write to the last
def test_a_full_disk_mid_entry_keeps_the_finished_entries(tmp_path, monkeypatch, at):
    crane = Crane.from_id("s100f")
    path, real = tmp_path / "lib.h5", os.pwrite
    with LibraryStore.create(path, crane.spec) as db:
        _add(db, crane, 0)
        _add(db, crane, 1)
    calls, counting = _count_pwrites()
    monkeypatch.setattr(journal.os, "pwrite", counting)
    with LibraryStore.open(path, "a") as db:
        n = len(calls)
        _add(db, crane, 2)
        per_entry = len(calls) - n
    assert per_entry > 8
    k, start = at % per_entry, None

    def failing(fd, data, off):
        calls.append(1)
        if start is not None and len(calls) - start == k + 1:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(fd, data, off)
    path.unlink()                              # again, and now the k-th write of m2 fails
    with LibraryStore.create(path, crane.spec) as db:
        _add(db, crane, 0)
        _add(db, crane, 1)
    monkeypatch.setattr(journal.os, "pwrite", failing)
    db = LibraryStore.open(path, "a")
    start = len(calls)
    with pytest.raises(OSError) as exc:
        _add(db, crane, 2)
    db.close()
    monkeypatch.setattr(journal.os, "pwrite", real)
    msg = str(exc.value)
    assert msg == f"cannot write {path}: No space left on device", msg
    assert not journal.journal_path(path).exists()
    with LibraryStore.open(path, "r") as back:      # readable, the two finished entries intact
        assert back.ids() == ["m0", "m1"]
        np.testing.assert_array_equal(back.trajectory("m1").q, _traj(crane, 1).q)
    with LibraryStore.open(path, "a") as again:     # and it resumes
        _add(again, crane, 2)
    with LibraryStore.open(path, "r") as back:
        assert back.ids() == ["m0", "m1", "m2"]


_KILLED_WRITER = """
import os, sys
import numpy as np
from planner import Crane
from planner.library.store import LibraryStore
from planner.trajectory import Trajectory
crane = Crane.from_id("s100f")
t = np.linspace(0, 2, 400); q = np.outer(np.linspace(0, 0.1, 400), np.ones(crane.n))
tr = Trajectory(t=t, q=q, qd=0 * q, qdd=0 * q, joint_names=crane.names)
with LibraryStore.create(sys.argv[1], crane.spec) as db:
    db.add("m0", tr, start=(3, 1, 0), goal=(4, 1, 0), objective="time", method="t", status="ok")
db = LibraryStore.open(sys.argv[1], "a")
real, n = os.pwrite, [0]
def dying(fd, data, off):
    n[0] += 1
    if n[0] == int(sys.argv[2]):
        os._exit(9)                     # as SIGKILL would, between two writes
    return real(fd, data, off)
os.pwrite = dying
db.add("m1", tr, start=(3, 1, 0), goal=(4, 1, 1), objective="time", method="t", status="ok")
os._exit(0)
"""


@pytest.mark.parametrize("at", [3, 12, 30])
def test_a_writer_killed_mid_entry_is_rolled_back_on_the_next_open(tmp_path, at):
    path = tmp_path / "lib.h5"
    p = subprocess.run([sys.executable, "-c", _KILLED_WRITER, str(path), str(at)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode in (9, 0), p.stderr
    if p.returncode == 9:
        assert journal.journal_path(path).exists()   # the writer died inside a transaction
    with LibraryStore.open(path, "a") as db:          # rolled back, readable
        assert db.ids() in (["m0"], ["m0", "m1"])
        assert db.trajectory("m0").q.shape == (400, 4)
    assert not journal.journal_path(path).exists()


def _run(args, **kw):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=300,
                          **kw)


def test_library_build_past_the_file_size_limit_is_one_line_and_resumes(tmp_path):
    clean, lib = tmp_path / "clean.h5", tmp_path / "lib.h5"
    assert _run(BUILD + ["--out", clean]).returncode == 0
    size = clean.stat().st_size
    p = _run(BUILD + ["--out", lib], preexec_fn=_limited(int(size * 0.6)))
    assert p.returncode == 2, (p.returncode, p.stderr)   # was -11 (a segfault)
    lines = [ln for ln in p.stderr.splitlines() if not ln.startswith("library cranab850: ")]
    assert lines == [f"crane-planner: error: cannot write {lib}: File too large (the file-size "
                     "limit, ulimit -f); the entries finished before it are kept (1 of this "
                     "run): make room and rerun the same command to resume"], p.stderr
    with LibraryStore.open(lib, "r") as db:
        assert len(db) == 1
    p = _run(BUILD + ["--out", lib])                       # the rerun resumes
    assert p.returncode == 0 and "1 already there" in p.stdout, p.stdout + p.stderr
    assert_same_entries(clean, lib, 3)


def test_plan_out_h5_past_the_file_size_limit_is_one_line(tmp_path):
    out = tmp_path / "p.h5"
    p = _run(CLI + ["plan", "s100f", "--start", "3,1,0", "--goal", "5,2,30deg", "--method",
                    "ruckig", "--out", out], preexec_fn=_limited(50_000))
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert p.stderr.strip() == (f"crane-planner: error: cannot write {out}: File too large "
                                "(the file-size limit, ulimit -f)"), p.stderr
    assert os.listdir(tmp_path) == []                      # no file, no temporary left


def test_a_truncated_library_is_called_damaged_not_busy_with_the_own_pid(tmp_path):
    """Defect 12: the build's own lock was reported as 'another build (pid <own pid>)'."""
    from planner.library.lock import BuildLock
    from planner.library.store import StoreError
    crane = Crane.from_id("s100f")
    path = tmp_path / "lib.h5"
    with LibraryStore.create(path, crane.spec) as db:
        _add(db, crane, 0)
    size = path.stat().st_size
    os.truncate(path, size // 2)
    with BuildLock(path), pytest.raises(StoreError) as exc:
        LibraryStore.open(path, "a", spec=crane.spec)
    assert str(exc.value) == (f"{path}: damaged library: the file has {size // 2} of its "
                              f"{size} bytes (cut short, e.g. an interrupted copy); restore it, "
                              "or move it away and rebuild")
    # not "being written by another build (pid <own pid>)" (a bare pid of three digits can
    # occur in the path or the sizes: the phrase is what must not be there)
    assert f"(pid {os.getpid()})" not in str(exc.value)
    assert "another build" not in str(exc.value)


# ------------------------------------------------------------------ defect 3: a killed worker
def _killed_on_b_c(job):
    """plan_move, except that the worker planning move B-C is killed (as the OOM killer
    would)."""
    from planner.library import build as b
    if job.move.id == "B-C":
        os.kill(os.getpid(), 9)
    return b.plan_move.__wrapped__(job)


def test_a_killed_worker_names_its_move_and_the_rerun_resumes(tmp_path, monkeypatch, capsys):
    from planner.cli import main
    from planner.library import build as b
    clean, lib = tmp_path / "clean.h5", tmp_path / "lib.h5"
    argv = [str(a) for a in BUILD[3:]]
    assert main(argv + ["--out", str(clean)]) == 0
    _killed_on_b_c.__wrapped__ = b.plan_move
    monkeypatch.setattr(b, "plan_move", _killed_on_b_c)
    rc = main(argv + ["--workers", "2", "--out", str(lib)])
    err = capsys.readouterr().err
    assert rc == 3, err                                  # was 1 and a 20-line traceback
    lines = [ln for ln in err.splitlines() if not ln.startswith("library cranab850: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    with LibraryStore.open(lib, "r") as db:
        n = len(db)
        assert "B-C:time" not in db.ids()
    rerun = ("crane-planner library build cranab850 --tasks seed000-abc --out "
             f"{lib} --objectives time --workers 2 --intervals 40 --method ruckig "
             "--no-robustness")
    assert lines[0] == ("crane-planner: error: a worker of the build killed by SIGKILL while "
                        f"planning move B-C; {n} entries written to {lib} this run are kept "
                        f"(every earlier one too): rerun `{rerun}` to resume (with fewer "
                        "--workers if memory ran out)"), lines[0]
    monkeypatch.undo()
    assert main(argv + ["--workers", "2", "--out", str(lib)]) == 0   # resumes
    assert f"{n} already there" in capsys.readouterr().out
    assert_same_entries(clean, lib, 3)
