"""Issue 32, defects 5-8, 11, 13 and 15: input that used to give a silently wrong result or a
misleading message is refused (exit 2) or accepted with a note, with one line that names the
field, the value and what is allowed; Ctrl-C anywhere is exit 130 and one line."""
from __future__ import annotations

import numpy as np
import pytest

from planner import Crane
from planner.cli import main
from planner.trajectory import Trajectory
from tests.library.test_faults import children


def _cli(capsys, *argv):
    """(rc, stdout, stderr) of the CLI; argparse usage errors count as rc 2."""
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


def _refused(capsys, *argv, words=(), rc=2):
    code, out, err = _cli(capsys, *argv)
    assert code == rc, (code, out, err)
    assert "Traceback" not in err
    # one line (argparse's usage block may precede a usage error's)
    lines = [ln for ln in err.strip().splitlines()
             if not ln.startswith(("usage: ", "     "))]
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def _s100f_move(tele=2.2):
    """A rest-to-rest move of the S100F with its telescope out to ``tele`` (umea-lab's
    telescope ends at 1.55 m; both machines name their joints slew, boom, jib, tele)."""
    from planner.methods.ruckig import rest_to_rest
    crane = Crane.from_id("s100f")
    q0, q1 = crane.ik((6.0, -1.0, 0.0), tele=tele), crane.ik((5.0, 0.5, 0.3), tele=tele)
    return crane, rest_to_rest(crane, q0, q1).trajectory


# ------------------------------------------------------------------ 5: another crane's move
def test_simulate_refuses_another_cranes_trajectory_csv(tmp_path, capsys):
    crane, tr = _s100f_move()
    path = tmp_path / "s100f-move.csv"
    tr.to_csv(path)
    umea = Crane.from_id("umea-lab")
    assert umea.names == crane.names
    assert tr.q[:, 3].max() > umea.spec.joints[3].limits.q[1] + 0.5
    # the oracle: the first of umea-lab's joints that the move leaves by more than 5 % of
    # its range, and the first sample where it does
    for k, j in enumerate(umea.spec.joints):
        lo, hi = j.limits.q
        out = np.flatnonzero((tr.q[:, k] < lo - 0.05 * (hi - lo))
                             | (tr.q[:, k] > hi + 0.05 * (hi - lo)))
        if out.size:
            break
    last = _refused(capsys, "simulate", "umea-lab", "--trajectory", path,
                    "--out", tmp_path / "m.csv", words=(str(path), "joint range"))
    assert f"q_{j.name} = {tr.q[out[0], k]:.6g} " in last
    assert f"[{lo:.4g}, {hi:.4g}]" in last and f"data row {out[0] + 1} " in last
    assert not (tmp_path / "m.csv").exists()
    # the same file on its own machine replays
    assert _cli(capsys, "simulate", "s100f", "--trajectory", path,
                "--out", tmp_path / "ok.csv")[0] == 0


def test_simulate_refuses_a_library_entry_of_another_crane(tmp_path, capsys):
    from planner.library.store import LibraryStore
    crane, tr = _s100f_move(tele=1.0)     # inside umea-lab's ranges? the crane id still says no
    lib = tmp_path / "s100f.h5"
    with LibraryStore.create(lib, crane.spec) as db:
        db.add("m0", tr, start=(6.0, -1.0, 0.0), goal=(5.0, 0.5, 0.3), objective="time",
               method="ruckig", status="ok")
    _refused(capsys, "simulate", "umea-lab", "--trajectory", f"{lib}#m0",
             "--out", tmp_path / "m.csv", words=("crane_id = 's100f'", "umea-lab", "#m0"))
    assert not (tmp_path / "m.csv").exists()


def test_simulate_refuses_a_trajectory_with_other_joints(tmp_path, capsys):
    _, tr = _s100f_move()
    path = tmp_path / "s100f-move.csv"
    tr.to_csv(path)
    _refused(capsys, "simulate", "cat215b", "--trajectory", path, "--out", tmp_path / "m.csv",
             words=(str(path), "slew, boom, jib, tele", "swing, boom, stick"))


# ------------------------------------------------------------------ 6: Ctrl-C in the engine
# The child marks the first call of the engine's pre-step function (so SIGINT arrives while
# Exudyn runs the Python callbacks, not while the CLI starts up), then runs the CLI.
_CHILD = """
import os, sys
import exudyn
marker, argv = sys.argv[1], sys.argv[2:]
set_pre = exudyn.MainSystem.SetPreStepUserFunction
def marked(self, f):
    def g(mbs, t):
        if not os.path.exists(marker):
            open(marker, "w").close()
        return f(mbs, t)
    return set_pre(self, g)
exudyn.MainSystem.SetPreStepUserFunction = marked
from planner.cli import main
sys.exit(main(argv))
"""


def _default_sigint():
    """In the child before exec: SIGINT at its default (a test run started in the background
    of a shell inherits SIGINT ignored, as would the child: a terminal's Ctrl-C is not)."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_during_the_exudyn_plant_is_exit_130_and_one_line(tmp_path):
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    from planner.simulation.dynamic.simulate import slowed
    _, tr = _s100f_move(tele=1.0)
    move = tmp_path / "slow.csv"
    slowed(tr, 6.0).to_csv(move)           # ~25 s of plant time: tens of seconds of wall
    marker, out = tmp_path / "engine-running", tmp_path / "dyn.csv"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    p = subprocess.Popen([sys.executable, "-c", _CHILD, str(marker), "simulate", "s100f",
                          "--trajectory", str(move), "--plant", "exudyn", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         preexec_fn=_default_sigint)
    try:
        t0 = time.monotonic()
        while not marker.exists() and p.poll() is None and time.monotonic() - t0 < 120:
            time.sleep(0.05)
        assert marker.exists(), p.communicate()
        time.sleep(0.3)
        p.send_signal(signal.SIGINT)
        t1 = time.monotonic()
        stdout, stderr = p.communicate(timeout=20)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    assert p.returncode == 130, (p.returncode, stdout, stderr)
    assert time.monotonic() - t1 < 10
    assert stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "interrupted (SIGINT)" in lines[0], stderr
    assert "diverged" not in stderr and not out.exists()


def test_deferred_interrupt_keeps_a_handler_it_does_not_own():
    """Only Python's default SIGINT handler is replaced for a solve (a library worker that
    ignores SIGINT keeps ignoring it), and it is restored afterwards."""
    import signal

    from planner.simulation.dynamic.interrupt import DeferredInterrupt
    before = signal.getsignal(signal.SIGINT)
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with DeferredInterrupt() as stop:
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        assert not stop.requested
        signal.signal(signal.SIGINT, signal.default_int_handler)
        with pytest.raises(KeyboardInterrupt):
            with DeferredInterrupt() as stop:
                signal.raise_signal(signal.SIGINT)   # asks; does not raise inside the block
                assert stop.requested
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, before)


# ------------------------------------------------------------------ 7: --rate with u columns
def _with_commands(tmp_path, rate=50.0):
    """The S100F move carrying its feed-forward commands on a uniform ``rate`` grid (what an
    ``excite`` file or an exported entry looks like)."""
    from dataclasses import replace

    from planner.feedforward import commands
    crane, tr = _s100f_move(tele=1.0)
    ff = commands(crane, tr, rate)
    q, qd, qdd, _ = tr.sample(ff.t)
    path = tmp_path / "cmds.csv"
    replace(tr, t=ff.t, q=q, qd=qd, qdd=qdd, u=ff.u).to_csv(path)
    return crane, path, np.asarray(ff.t), np.asarray(ff.u)


@pytest.mark.parametrize("rate", [100.0, 20.0])
def test_simulate_rate_is_honoured_for_a_trajectory_with_commands(tmp_path, capsys, rate):
    import json
    crane, path, t_u, u = _with_commands(tmp_path)
    out = tmp_path / "m.csv"
    rc, stdout, err = _cli(capsys, "simulate", "s100f", "--trajectory", path, "--out", out,
                           "--rate", rate, "--json", "-")
    assert rc == 0, err
    assert "held at" in err and f"{rate:g} Hz" in err
    summary = json.loads(stdout)
    assert "held at" in summary["rate_note"]
    from planner.simulation.recording import read_measured_csv
    d = read_measured_csv(out, crane.names, uniform=False)
    step = np.diff(d["t"])
    assert np.allclose(step, 1.0 / rate, rtol=1e-6, atol=1e-9)
    # each recorded command is the one in effect (zero-order hold) at its instant
    k = np.searchsorted(t_u, d["t"] + 1e-9, side="right") - 1
    assert np.allclose(d["u"], u[np.clip(k, 0, len(u) - 1)], atol=1e-6)


def test_simulate_without_rate_keeps_the_files_own_commands(tmp_path, capsys):
    crane, path, t_u, u = _with_commands(tmp_path, rate=50.0)
    out = tmp_path / "m.csv"
    for extra in ((), ("--rate", "50")):
        rc, _, err = _cli(capsys, "simulate", "s100f", "--trajectory", path, "--out", out,
                          *extra)
        assert rc == 0 and "held at" not in err, err
        from planner.simulation.recording import read_measured_csv
        d = read_measured_csv(out, crane.names, uniform=False)
        assert np.allclose(np.diff(d["t"]), 0.02)
    _refused(capsys, "simulate", "s100f", "--trajectory", path, "--out", out, "--rate", "0",
             words=("--rate 0", "allowed"))


# ------------------------------------------------------------------ 8, 11, 15: library build
@pytest.fixture
def no_build(monkeypatch):
    """``library build`` up to the call of the builder: the arguments it would get."""
    import planner.cli.library as cli_library
    calls = []

    def fake(crane, suite, out, **kw):
        calls.append(dict(kw, crane=crane, suite=suite))
        return dict(status="ok", library=str(out), crane=crane, planned=0, statuses={},
                    skipped_existing=0, seconds=0.0, workers=[])
    monkeypatch.setattr(cli_library, "build", fake)
    return calls


def test_a_suite_of_another_machine_needs_force(tmp_path, capsys, no_build):
    import tomllib

    from planner.tasks.suites import suite_path
    declared = tomllib.loads(suite_path("forwarder-cycle").read_text())["suite"]["crane"]
    assert declared == "s100f"
    _refused(capsys, "library", "build", "cranab850", "--tasks", "forwarder-cycle",
             "--out", tmp_path / "lib.h5",
             words=("forwarder-cycle", "declared for crane 's100f'", "'cranab850'", "--force"))
    assert no_build == []
    rc, _, err = _cli(capsys, "library", "build", "cranab850", "--tasks", "forwarder-cycle",
                      "--out", tmp_path / "lib.h5", "--force", "--limit", "1")
    assert rc == 0 and "warning" in err and "declared for crane 's100f'" in err
    assert no_build[0]["crane"] == "cranab850"
    # the machine the suite names builds without a word
    rc, _, err = _cli(capsys, "library", "build", "s100f", "--tasks", "forwarder-cycle",
                      "--out", tmp_path / "lib2.h5", "--limit", "1")
    assert rc == 0 and err == ""


@pytest.mark.parametrize("workers,limit,cpus,expected", [
    (1000, 2, 16, 2), (1000, 50, 8, 8), (3, 50, 8, 3), (2, 1, 8, 1)])
def test_library_build_never_starts_more_workers_than_moves_or_cpus(
        tmp_path, capsys, no_build, monkeypatch, workers, limit, cpus, expected):
    import planner.cli.library as cli_library
    monkeypatch.setattr(cli_library, "cpu_count", lambda: cpus)
    rc, _, err = _cli(capsys, "library", "build", "s100f", "--tasks", "forwarder-cycle",
                      "--out", tmp_path / "lib.h5", "--workers", workers, "--limit", limit)
    assert rc == 0, err
    assert no_build[0]["workers"] == expected
    assert (f"--workers {workers}: {expected} started" in err) == (expected < workers)


def test_an_empty_task_grid_is_refused_naming_the_suite(tmp_path, capsys, no_build):
    suite = tmp_path / "empty.toml"
    suite.write_text('[suite]\nid = "empty-grid"\ncrane = "s100f"\n'
                     '[pickups]\nr = []\nslew = ["0deg"]\nz = -1.0\n'
                     '[drops]\nr = [3.0]\nslew = ["60deg"]\nz = 1.5\n')
    _refused(capsys, "library", "build", "s100f", "--tasks", suite, "--out", tmp_path / "l.h5",
             words=("'empty-grid'", str(suite), "no moves", "at least one move"))
    assert no_build == [] and not (tmp_path / "l.h5").exists()


@pytest.mark.slow
def test_ctrl_c_while_the_workers_start_is_exit_130(tmp_path):
    """``--workers 1000`` for 2 moves starts 2 processes; SIGINT to the process group while
    they set up ends the build in seconds with one line, no worker left."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    p = subprocess.Popen([sys.executable, "-m", "planner", "library", "build", "s100f",
                          "--tasks", "forwarder-cycle", "--workers", "1000", "--limit", "2",
                          "--out", str(tmp_path / "w.h5")], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=env, start_new_session=True,
                         preexec_fn=_default_sigint)
    t0 = time.monotonic()
    while len(kids := children(p.pid)) < 2 and p.poll() is None and time.monotonic() - t0 < 120:
        time.sleep(0.02)
    time.sleep(0.2)
    assert len(children(p.pid)) <= 3       # two workers (and the executor's manager thread)
    t1 = time.monotonic()
    os.killpg(p.pid, signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130 and time.monotonic() - t1 < 10, err
    assert not [k for k in kids if os.path.exists(f"/proc/{k}")]
    assert "Traceback" not in err and err.strip().splitlines()[-1].startswith(
        "crane-planner: interrupted (SIGINT)")


# ------------------------------------------------------------------ 13: epoch timestamps
def test_epoch_timestamps_are_read_relative_to_the_first(tmp_path):
    from planner.simulation.recording import read_measured_csv
    crane = Crane.from_id("s100f")
    names = crane.names
    N, step, t0 = 500, 0.02, 1764130000.0
    q = np.tile(crane.ik((6.0, -1.0, 0.0), tele=1.0), (N, 1))
    cols = ["t"] + [f"q_{j}" for j in names]

    def write(path, first):
        rows = [",".join(cols)] + [f"{first + k * step:.2f}," + ",".join(f"{v:.6f}" for v in r)
                                   for k, r in enumerate(q)]
        path.write_text("\n".join(rows) + "\n")
    epoch = tmp_path / "epoch.csv"
    write(epoch, t0)
    d = read_measured_csv(epoch, names)
    # the oracle: the grid the logger wrote, k * 20 ms from the first stamp
    assert np.allclose(d["t"], np.arange(N) * step, rtol=0, atol=1e-12)
    assert np.ptp(np.diff(d["t"])) <= 1e-6 * step       # uniform, as discrepancy requires
    assert any("1764130000.00" in n and "subtracted" in n for n in d["notes"])
    # a log of a few seconds' offset keeps its times (it must line up with its plan)
    late = tmp_path / "late.csv"
    write(late, 5.0)
    d = read_measured_csv(late, names)
    assert d["t"][0] == 5.0 and d["notes"] == []


# ------------------------------------------------------------------ 15: spec encoding, 720deg
def test_a_spec_with_a_byte_order_mark_is_read_as_without(tmp_path, capsys):
    from planner.model.spec import load_spec
    from planner.problems import crane_path
    plain = crane_path("umea-lab").read_bytes()
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + plain)
    a, b = load_spec(crane_path("umea-lab")), load_spec(bom)
    assert b.text == a.text and b.id == a.id and b.joints == a.joints
    rc, out, err = _cli(capsys, "problems", "show", bom, "--json", "-")
    assert rc == 0, err


def test_a_spec_that_is_not_utf8_names_file_line_column_and_byte(tmp_path, capsys):
    from planner.problems import crane_path
    raw = crane_path("umea-lab").read_bytes()
    lines = raw.split(b"\n")
    k = next(i for i, ln in enumerate(lines) if b"assumed" in ln)   # an ASCII comment word
    col = lines[k].index(b"assumed") + len("assum") + 1
    lines[k] = lines[k].replace(b"assumed", b"assum\xe9d", 1)       # Latin-1 e-acute
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b"\n".join(lines))
    _refused(capsys, "problems", "show", bad,
             words=(str(bad), f"line {k + 1}, column {col}", "\\xe9", "UTF-8"))


@pytest.mark.parametrize("slew,same", [("720deg", "0deg"), ("190deg", "-170deg"),
                                       ("-400°", "-40deg")])
def test_a_slew_in_degrees_out_of_range_is_answered_in_degrees(capsys, slew, same):
    last = _refused(capsys, "bound", "s100f", "--start", "6,-1,0", "--goal", f"4,0,{slew}",
                    words=(f"slew = {slew} ", "-180deg ... 180deg", same))
    assert "write degrees with a suffix" not in last


# ------------------------------------------------------------------ the README tour's messages
def test_plan_help_names_every_kind_of_method(capsys):
    for argv in (["--help"], ["plan", "--help"]):
        rc, out, _ = _cli(capsys, *argv)
        assert rc == 0
        text = " ".join(out.split())                       # argparse wraps the summary
        k = text.lower().index("plan one move (")
        summary = text[k:text.index(")", k)]
        for m in ("NLP", "DP", "TOPP-RA", "Ruckig", "local law"):
            assert m in summary, summary


def test_topp_says_plainly_that_it_has_no_jerk_limit(capsys, tmp_path):
    import json
    argv = ("plan", "s100f", "--start", "7,-1,0", "--goal", "3,2,0.5", "--method", "topp")
    rc, out, _ = _cli(capsys, *argv)
    assert rc == 0
    assert "exceeded by" not in out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("jerk:"))
    assert "topp plans without a jerk limit" in line
    rc, _, _ = _cli(capsys, *argv, "--json", tmp_path / "r.json")
    r = json.loads((tmp_path / "r.json").read_text())
    assert "jerk" not in r["checked_limits"]
    assert f"{1 + r['violations']['jerk']:.4g} x the machine's jerk limit" in line


def test_discrepancy_with_a_json_file_still_prints_the_verdict(capsys, tmp_path):
    import json
    from planner.simulation.dynamic.simulate import slowed
    _, tr = _s100f_move(tele=1.0)
    move, meas = tmp_path / "move.csv", tmp_path / "m.csv"
    slowed(tr, 4.0).to_csv(move)                       # 8 s: enough blocks for the fit
    assert _cli(capsys, "simulate", "s100f", "--trajectory", move, "--out", meas,
                "--effect", "coulomb_friction:joint=boom,force=8000", "--noise")[0] == 0
    rc, out, err = _cli(capsys, "discrepancy", "s100f", "--measured", meas, "--trajectory",
                        move, "--effects", "coulomb_friction,viscous_friction",
                        "--json", tmp_path / "r.json")
    assert rc == 0, err
    verdict = json.loads((tmp_path / "r.json").read_text())["verdict"]
    assert f"verdict: {verdict}" in out.splitlines()
