"""Issue 16 (faults, signals, files): Ctrl-C and a killed driver during a 2-worker library
build, one build per file, outputs to devices / symlinks, paths checked before the work, the
one-line errors that used to be tracebacks, --version."""
import importlib.metadata
import json
import os
import re
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

import planner
from planner import Crane
from planner.cli import main
from planner.library.build import build
from planner.library.lock import BuildLock, LibraryBusy, holder, lock_path
from planner.library.store import LibraryStore
from planner.trajectory import Trajectory
from tests.library.helpers import assert_same_entries

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "planner"]
BUILD = CLI + ["library", "build", "s100f", "--tasks", "forwarder-cycle", "--limit", "4",
               "--no-robustness", "--intervals", "20"]
# generous on a loaded CI machine; the 10 s bound is measured by bench_faults.py (0.97 s)
WAIT_S = 30.0


# ------------------------------------------------------------------ helpers
def _stat(pid: int):
    try:
        with open(f"/proc/{pid}/stat") as fh:
            rest = fh.read().rsplit(")", 1)[1].split()
        return rest[0], int(rest[1])  # state, ppid
    except (OSError, IndexError):
        return None


def _alive(pid: int) -> bool:
    """Running (a zombie holds no file and no lock: it counts as gone)."""
    s = _stat(pid)
    return s is not None and s[0] not in "ZX"


def children(pid: int) -> list[int]:
    """The live child processes of ``pid`` (from /proc)."""
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            s = _stat(int(d))
            if s is not None and s[1] == pid and _alive(int(d)):
                out.append(int(d))
    return out


def _start(args, err: Path) -> subprocess.Popen:
    """The command in its own process group (a terminal's Ctrl-C reaches the whole group)."""
    return subprocess.Popen([str(a) for a in args], stdout=subprocess.DEVNULL,
                            stderr=open(err, "wb"), start_new_session=True)


def _wait_for(err: Path, text: str, p: subprocess.Popen, timeout=180.0):
    t0 = time.monotonic()
    while text not in err.read_text(errors="replace"):
        assert p.poll() is None, f"the build ended early: {err.read_text()}"
        assert time.monotonic() - t0 < timeout, f"no {text!r} on stderr: {err.read_text()}"
        time.sleep(0.05)


def _same_entries(a_path, b_path):
    assert_same_entries(a_path, b_path, 4)


def _resume(lib):
    """Rerun the build (in this process: the result is the same, the start-up is saved)."""
    s = build("s100f", "forwarder-cycle", lib, limit=4, objectives=("time",), robustness=False,
              progress=False, N=20)
    assert s["status"] == "ok" and s["skipped_existing"] >= 1


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The oracle: the same 4 entries built in one go, in this process."""
    lib = tmp_path_factory.mktemp("clean") / "clean.h5"
    build("s100f", "forwarder-cycle", lib, limit=4, objectives=("time",), robustness=False,
          progress=False, N=20)
    return lib


# ------------------------------------------------------------------ signals
def test_ctrl_c_stops_a_two_worker_build_promptly_and_the_file_resumes(tmp_path, clean):
    lib, err = tmp_path / "int.h5", tmp_path / "err.txt"
    p = _start(BUILD + ["--workers", "2", "--out", lib], err)
    _wait_for(err, "library s100f: 1/4", p)
    workers = children(p.pid)
    assert len(workers) >= 2
    os.killpg(p.pid, signal.SIGINT)                      # Ctrl-C: driver and workers
    assert p.wait(timeout=WAIT_S) == 130                 # 128 + SIGINT, the shell convention
    text = err.read_text()
    assert "Traceback" not in text and "\r" not in text and "\x1b" not in text
    lines = [ln for ln in text.splitlines() if not ln.startswith("library s100f: ")]
    assert len(lines) == 1, text                         # one line besides the progress lines
    m = re.fullmatch(r"crane-planner: interrupted \(SIGINT\): (\d+) entries written to "
                     r"(.+), (\d+) left; rerun the same command to resume", lines[0])
    assert m and m[2] == str(lib) and int(m[1]) + int(m[3]) == 4, lines[0]
    assert not any(_alive(w) for w in workers)           # the workers are gone
    assert not lock_path(lib).exists()
    with LibraryStore.open(lib, "r") as db:
        partial = len(db)
    assert 1 <= partial < 4 and partial == int(m[1])     # it really was interrupted
    _resume(lib)
    _same_entries(clean, lib)


def test_killing_the_driver_leaves_no_worker_and_no_lock(tmp_path, clean):
    lib, err = tmp_path / "kill.h5", tmp_path / "err.txt"
    p = _start(BUILD + ["--workers", "2", "--out", lib], err)
    _wait_for(err, "library s100f: 1/4", p)
    workers = children(p.pid)
    assert len(workers) >= 2 and all(_alive(w) for w in workers)
    p.kill()                                             # as the OOM killer would
    p.wait()
    t0 = time.monotonic()
    while any(_alive(w) for w in workers) and time.monotonic() - t0 < WAIT_S:
        time.sleep(0.05)
    assert not any(_alive(w) for w in workers), "a worker outlived its driver"
    # the file is not locked any more: it opens, and a rerun resumes past the stale lock file
    assert lock_path(lib).exists() and holder(lib) is None
    with LibraryStore.open(lib, "r") as db:
        assert 1 <= len(db) < 4
    _resume(lib)
    assert not lock_path(lib).exists()
    _same_entries(clean, lib)


# ------------------------------------------------------------------ one writer per file
def test_a_second_build_names_the_first_and_creates_nothing(tmp_path):
    lib = tmp_path / "lib.h5"
    with BuildLock(lib):
        r = subprocess.run([str(a) for a in BUILD + ["--out", lib]], capture_output=True,
                           text=True)
    assert r.returncode == 2
    assert r.stderr == (f"crane-planner: error: {lib} is being written by another build "
                        f"(pid {os.getpid()}); wait for it to finish or stop it\n")
    assert sorted(tmp_path.iterdir()) == []


def test_library_info_says_what_holds_a_locked_file(tmp_path, capsys):
    import h5py
    lib = tmp_path / "lib.h5"
    LibraryStore.create(lib, Crane.from_id("s100f").spec).close()
    info = CLI + ["library", "info", str(lib)]
    with BuildLock(lib), LibraryStore.open(lib, "a"):    # what a running build holds
        r = subprocess.run(info, capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.startswith(f"crane-planner: error: {lib} is being written by another "
                               f"build (pid {os.getpid()})")
    assert r.stderr.count("\n") == 1
    if os.path.exists("/proc/locks"):                    # a plain h5py handle, no build
        with h5py.File(lib, "a"):
            r = subprocess.run(info, capture_output=True, text=True)
        assert r.returncode == 2
        assert f"{lib} is locked by another process (pid {os.getpid()}" in r.stderr
    assert main(["library", "info", str(lib)]) == 0      # free again (and empty: no mean)
    assert capsys.readouterr().out == (f"{lib}: 0 entries (0 ok), failures none; duration "
                                       "mean - (no ok entry)\n")


def test_the_lock_names_its_holder_and_a_stale_lock_file_is_no_obstacle(tmp_path):
    lib = tmp_path / "lib.h5"
    lock_path(lib).write_text("999999\n")               # left by a killed build
    assert holder(lib) is None
    with BuildLock(lib) as lock:
        assert lock_path(lib).read_text() == f"{os.getpid()}\n"
        assert holder(lib) == os.getpid()
        with pytest.raises(LibraryBusy, match=f"pid {os.getpid()}"):
            BuildLock(lib).acquire()
    assert holder(lib) is None and not lock_path(lib).exists()
    lock.release()                                       # idempotent


# ------------------------------------------------------------------ outputs
def test_json_to_dev_stdout_writes_through(capfd):
    assert main(["bound", "cranab850", "--start", "1.5,1.0,0", "--goal", "5.5,1.0,0",
                 "--json", "/dev/stdout"]) == 0
    assert json.loads(capfd.readouterr().out)["status"] == "ok"


def test_json_to_dev_stdout_redirected_to_a_file_appends_and_keeps_the_file(tmp_path):
    out = tmp_path / "out.json"
    with open(out, "w") as fh:
        fh.write("before\n")
        fh.flush()
        ino = os.fstat(fh.fileno()).st_ino
        r = subprocess.run(CLI + ["bound", "cranab850", "--start", "1.5,1.0,0", "--goal",
                                  "5.5,1.0,0", "--json", "/dev/stdout"], stdout=fh,
                           stderr=subprocess.PIPE)
    assert r.returncode == 0, r.stderr
    assert os.stat(out).st_ino == ino                     # not replaced by another file
    text = out.read_text()
    assert text.startswith("before\n") and json.loads(text[7:])["status"] == "ok"


def test_json_to_a_symlink_writes_its_target(tmp_path, capsys):
    (tmp_path / "real.json").write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to("real.json")
    assert main(["bound", "cranab850", "--start", "1.5,1.0,0", "--goal", "5.5,1.0,0",
                 "--json", str(link)]) == 0
    assert link.is_symlink()
    assert json.loads((tmp_path / "real.json").read_text())["status"] == "ok"


def test_created_output_folders_are_announced(tmp_path, capsys):
    target = tmp_path / "a" / "b" / "out.json"
    assert main(["bound", "cranab850", "--start", "1.5,1.0,0", "--goal", "5.5,1.0,0",
                 "--json", str(target)]) == 0
    err = capsys.readouterr().err
    assert err == (f"crane-planner: note: created directory {tmp_path / 'a'}\n"
                   f"crane-planner: note: created directory {tmp_path / 'a' / 'b'}\n")
    assert json.loads(target.read_text())["status"] == "ok"


@pytest.mark.parametrize("flag", ["--out", "--json"])
def test_output_paths_are_checked_before_the_build(tmp_path, capsys, flag):
    blocker = tmp_path / "file"
    blocker.write_text("")
    args = ["library", "build", "s100f", "--tasks", "forwarder-cycle", "--out",
            str(tmp_path / "lib.h5")]
    args += [flag, str(blocker / "x")]                   # a regular file used as a folder
    with pytest.raises(SystemExit) as ei:
        main(args)
    assert ei.value.code == 2
    assert f"cannot write {blocker / 'x'}: Not a directory" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


# ------------------------------------------------------------------ former tracebacks
def test_scheduler_without_dask_is_refused_before_the_file_exists(tmp_path, capsys,
                                                                  monkeypatch):
    monkeypatch.setitem(sys.modules, "dask", None)       # as if Dask were not installed
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    lib = tmp_path / "lib.h5"
    assert main(["library", "build", "s100f", "--tasks", "forwarder-cycle", "--limit", "1",
                 "--scheduler", "local:2", "--out", str(lib)]) == 2
    err = capsys.readouterr().err
    assert err == ("crane-planner: error: --scheduler local:2: Dask is not installed; install "
                   "the 'cluster' extra: pip install 'crane-planner[cluster]'\n")
    assert not lib.exists() and not lock_path(lib).exists()


def test_query_from_a_non_finite_joint_state_is_refused(tmp_path, capsys):
    crane = Crane.from_id("s100f")
    lib = tmp_path / "lib.h5"
    q0 = crane.ik((5.0, -1.0, 0.0), 2.0)
    tr = Trajectory(t=[0.0, 1.0], q=np.vstack([q0, q0]), interpolation="linear",
                    joint_names=crane.names)
    with LibraryStore.create(lib, crane.spec) as db:
        db.add("m", tr, start=(5.0, -1.0, 0.0), goal=(5.0, -1.0, 0.0), objective="time",
               method="test", status="ok")
    for bad in ("nan,0,0,0", "0,inf,0,0"):
        assert main(["library", "query", str(lib), "--start", "5,-1,0", "--goal", "5,-1,0",
                     "--from", bad]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"crane-planner: error: --from {bad!r}: joint values must be "
                              "finite numbers (") and err.count("\n") == 1


def test_a_header_only_trajectory_csv_is_one_line(tmp_path, capsys):
    p = tmp_path / "empty.csv"
    p.write_text("t,q_slew,qd_slew,qdd_slew\n")
    out = tmp_path / "meas.csv"
    assert main(["simulate", "umea-lab", "--trajectory", str(p), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (f"crane-planner: error: {p}: 0 data row(s) after the "
                                       "header; a trajectory needs at least 2 samples\n")
    assert not out.exists()


# ------------------------------------------------------------------ version
def test_version_comes_from_the_package_metadata():
    r = subprocess.run(CLI + ["--version"], capture_output=True, text=True)
    assert r.returncode == 0
    assert r.stdout == f"crane-planner {importlib.metadata.version('crane-planner')}\n"


def test_one_version_string():
    with open(ROOT / "pyproject.toml", "rb") as fh:
        project = tomllib.load(fh)["project"]
    assert project["version"] == planner.__version__ == \
        importlib.metadata.version("crane-planner")
    numpy_floor = next(d for d in project["dependencies"] if d.startswith("numpy"))
    assert numpy_floor == "numpy>=2.0"                    # np.trapezoid is numpy 2
