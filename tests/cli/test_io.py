"""planner.io: outputs written through symlinks, devices and FIFOs, errors that name the user's
path, path checks before the work, progress reports; and the trajectory CSV reader's errors."""
import io
import os
import stat
import sys
import threading

import numpy as np
import pytest

import planner.io as pio
from planner.io import (LineProgress, OutputError, atomic_write_text, check_output,
                        check_output_dir, missing_dirs, output_target, progress, write_json)
from planner.trajectory import Trajectory


def test_a_symlink_stays_a_link_and_its_target_is_replaced(tmp_path):
    target = tmp_path / "real.json"
    target.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to("real.json")
    write_json(link, {"a": 1})
    assert link.is_symlink() and os.readlink(link) == "real.json"
    assert target.read_text() == '{\n  "a": 1\n}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.json", "real.json"]


def test_a_dangling_symlink_creates_its_target(tmp_path):
    link = tmp_path / "link.txt"
    link.symlink_to(tmp_path / "made" / "t.txt")
    assert missing_dirs(link) == [tmp_path / "made"]
    atomic_write_text(link, "x")
    assert link.is_symlink() and (tmp_path / "made" / "t.txt").read_text() == "x"


def test_a_fifo_is_written_through_and_stays_a_fifo(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    assert output_target(fifo) == (fifo, True)
    atomic_write_text(fifo, "through the pipe\n")
    reader.join(30)
    assert got == [b"through the pipe\n"]
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_dev_full_fails_with_the_users_path_and_stays_a_device():
    with pytest.raises(OutputError) as ei:
        atomic_write_text("/dev/full", "x" * 100000)
    assert str(ei.value) == "cannot write /dev/full: No space left on device"
    assert stat.S_ISCHR(os.lstat("/dev/full").st_mode)


def test_a_failed_write_names_the_path_not_the_temporary_file(tmp_path, monkeypatch):
    target = tmp_path / "out.json"
    target.write_text("before")

    def full(fd):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(pio.os, "fsync", full)
    with pytest.raises(OutputError) as ei:
        write_json(target, {"a": 1})
    assert str(ei.value) == f"cannot write {target}: No space left on device"
    assert ".tmp" not in str(ei.value)
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]   # no temporary file left
    assert target.read_text() == "before"                         # the old content intact


def test_an_existing_files_permissions_are_kept(tmp_path):
    target = tmp_path / "secret.json"
    target.write_text("{}")
    target.chmod(0o600)
    write_json(target, [1])
    assert stat.S_IMODE(target.stat().st_mode) == 0o600


def test_check_output_refuses_before_any_work(tmp_path):
    f = tmp_path / "file"
    f.write_text("")
    assert check_output("-") == []
    assert check_output(tmp_path / "new.json") == []
    assert check_output(tmp_path / "a" / "b" / "x.json") == [tmp_path / "a", tmp_path / "a" / "b"]
    for bad, why in ((tmp_path, "is a directory"), (f / "x.json", "Not a directory"),
                     ("/dev/no-such-device", "no such file"), ("/proc/x.json", "no such file")):
        with pytest.raises(OutputError, match=why) as ei:
            check_output(bad)
        assert str(ei.value).startswith(f"cannot write {bad}:")
    assert not (tmp_path / "a").exists()                           # checking creates nothing
    assert check_output("/dev/full") == []
    with pytest.raises(OutputError, match="not a directory"):
        check_output_dir(f)
    assert check_output_dir(tmp_path / "d" / "e") == [tmp_path / "d", tmp_path / "d" / "e"]


def test_progress_lines_off_a_terminal_and_a_bar_on_one(monkeypatch):
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    bar = progress(2, "library x", "entry")
    assert isinstance(bar, LineProgress)
    bar.update(1)
    bar.update(1)
    bar.close()
    assert err.getvalue() == "library x: 1/2\nlibrary x: 2/2\n"   # no \r, no escape codes
    progress(2, "quiet", enabled=False).update(1)
    assert err.getvalue().count("\n") == 2

    class Tty(io.StringIO):
        def isatty(self):
            return True
    tty = Tty()
    monkeypatch.setattr(sys, "stderr", tty)
    bar = progress(3, "bar", "entry")
    assert not isinstance(bar, LineProgress)
    bar.update(3)
    bar.close()
    assert "\r" in tty.getvalue()                                  # a real tqdm bar


# ------------------------------------------------------------------ trajectory CSV reading
def _csv(tmp_path, text):
    p = tmp_path / "t.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, message", [
    ("t,q_a,qd_a,qdd_a\n", "0 data row(s) after the header; a trajectory needs at least 2"),
    ("", "empty file"),
    ("t,q_a,qd_a,qdd_a\n0,0,0,0\n1,x,0,0\n", "line 3, column q_a: 'x' is not a number"),
    ("t,q_a,qd_a,qdd_a\n0,0,0,0\n1,0,0\n", "line 3: 3 values, the header has 4 columns"),
    ("t,q_a,qd_a,qdd_a\n0,0,0,0\n# note\n1,0,nan,0\n", "line 4, column qd_a: nan is not a"),
    ("t,q_a,qd_a\n0,0,0\n1,1,0\n", "line 1: missing column(s) qdd_a"),
])
def test_bad_trajectory_csv_is_refused_with_line_and_column(tmp_path, text, message):
    p = _csv(tmp_path, text)
    with pytest.raises(ValueError) as ei:
        Trajectory.from_csv(p)
    assert message in str(ei.value)
    assert str(ei.value).startswith(str(p))


def test_csv_round_trip_reproduces_the_arrays(tmp_path):
    t = np.linspace(0.0, 2.0, 11)
    q = np.column_stack([np.sin(t), t ** 2])
    tr = Trajectory(t=t, q=q, qd=np.cos(t)[:, None] * [1, 0] + [0, 1] * (2 * t)[:, None],
                    qdd=np.zeros_like(q), u=0.1 * q, joint_names=("a", "b"))
    p = tmp_path / "x" / "tr.csv"
    tr.to_csv(p)
    text = p.read_text().splitlines()
    p.write_text("\n".join(text[:3] + ["# a comment", ""] + text[3:]) + "\n")
    back = Trajectory.from_csv(p)
    assert back.joint_names == ("a", "b")
    for name in ("t", "q", "qd", "qdd", "u"):
        np.testing.assert_allclose(getattr(back, name), getattr(tr, name), rtol=1e-9, atol=1e-12)
